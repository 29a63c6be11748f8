//! Lifelong spatio-temporal exploration on a real dataset ([Santos 2017] §7): the datasets
//! opened and checked, and the run behind Fig. 6 (what the robot believed, expected to learn
//! and visited in its busiest areas over its first days).
//!
//! Files in, result structs out: the faces print the tables and draw the figures.

use std::path::{Path, PathBuf};

use crate::datasets::{DatasetError, load_aruba, load_brayford};
use chronomap_core::num::count_of;
use chronomap_explore::table::{ModelKind, busiest_locations};
use chronomap_explore::{
    ExploreConfig, ExploreError, ExploreResult, MAX_STEPS_PER_DAY, Strategy, World, explore,
};

/// The datasets of [Santos 2017] §7.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dataset {
    /// The Aruba smart home (Table 1).
    Aruba,
    /// The Brayford office (Table 2).
    Brayford,
}

/// Why an exploration job failed.
#[derive(Debug, thiserror::Error)]
pub enum ExploreJobError {
    /// The dataset cannot be read.
    #[error(transparent)]
    Read(#[from] DatasetError),
    /// The dataset cannot be explored (e.g. a step too short to count the steps of a day).
    #[error("{}: {error}", dir.display())]
    Invalid {
        /// The dataset's folder.
        dir: PathBuf,
        /// Why.
        error: ExploreError,
    },
    /// The run failed.
    #[error(transparent)]
    Explore(#[from] ExploreError),
    /// More steps a day than a trace may draw.
    #[error("step {step_secs} s: too many steps a day")]
    TooManySteps {
        /// The world's step (s).
        step_secs: f64,
    },
}

/// The world of `dataset` in the folder `dir`, checked for exploration.
///
/// # Errors
/// [`ExploreJobError::Read`] when the files cannot be read, [`ExploreJobError::Invalid`]
/// naming `dir` when the world cannot be explored.
pub fn load_world(dataset: Dataset, dir: &Path) -> Result<World, ExploreJobError> {
    let world = match dataset {
        Dataset::Aruba => load_aruba(dir)?,
        Dataset::Brayford => load_brayford(dir)?,
    };
    world.validate().map_err(|error| ExploreJobError::Invalid {
        dir: dir.to_path_buf(),
        error,
    })?;
    Ok(world)
}

/// The areas drawn in [Santos 2017] Fig. 6.
pub const BEHAVIOUR_AREAS: usize = 3;

/// The days drawn in [Santos 2017] Fig. 6.
pub const BEHAVIOUR_DAYS: usize = 4;

/// The run behind [Santos 2017] Fig. 6: FreMEn with the Monte-Carlo strategy over the first
/// [`BEHAVIOUR_DAYS`] days, traced.
#[derive(Clone, Debug)]
pub struct Behaviour {
    /// The run with its trace (per slot: the model's probabilities, the expected information
    /// of eq. (10), the visit).
    pub result: ExploreResult,
    /// The [`BEHAVIOUR_AREAS`] busiest locations, busiest first.
    pub areas: Vec<usize>,
    /// Steps of the world in the days drawn.
    pub steps: usize,
}

/// Explores `world` as [`Behaviour`] describes, at exploration ratio `ratio` with `seed`.
///
/// # Errors
/// [`ExploreJobError::Explore`] from [`explore`] (settings or a world that cannot be explored).
pub fn behaviour(world: &World, ratio: f64, seed: u64) -> Result<Behaviour, ExploreJobError> {
    let config = ExploreConfig {
        ratio,
        days: Some(BEHAVIOUR_DAYS),
        seed,
        trace_days: BEHAVIOUR_DAYS,
        ..ExploreConfig::default()
    };
    let result = explore(
        world,
        Strategy::MonteCarlo { iota: 0.01 },
        &|| ModelKind::Fremen.make(),
        &config,
    )?;
    // One state per location in these datasets.
    let areas = busiest_locations(world, BEHAVIOUR_AREAS);
    // `explore` above validated the world: at most MAX_STEPS_PER_DAY steps a day.
    let per_day = count_of((86_400.0 / world.step_secs).trunc(), MAX_STEPS_PER_DAY).ok_or(
        ExploreJobError::TooManySteps {
            step_secs: world.step_secs,
        },
    )?;
    Ok(Behaviour {
        result,
        areas,
        steps: BEHAVIOUR_DAYS * per_day,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_brayford_week_loads_and_its_first_four_days_are_traced() {
        let world = load_world(
            Dataset::Brayford,
            &chronomap_testutil::data_path("brayford_week"),
        )
        .unwrap();
        assert_eq!(world.locations.len(), 8);
        // Ten-minute observations: 144 a day.
        assert_eq!(world.step_secs, 600.0);
        let run = behaviour(&world, 0.5, 3).unwrap();
        assert_eq!(run.steps, 4 * 144);
        assert_eq!(run.areas.len(), BEHAVIOUR_AREAS);
        assert_eq!(
            run.result.trace.slot_times.len(),
            run.result.trace.visits.len()
        );
        // The same seed, the same run.
        assert_eq!(behaviour(&world, 0.5, 3).unwrap().result, run.result);
    }

    #[test]
    fn a_folder_without_the_dataset_is_a_read_error() {
        let missing = chronomap_testutil::data_path("no_such_dataset");
        assert!(matches!(
            load_world(Dataset::Aruba, &missing),
            Err(ExploreJobError::Read(_))
        ));
    }
}
