//! Lifelong spatio-temporal exploration on a real dataset ([Santos 2017] §7): the datasets
//! opened and checked, and the run behind Fig. 6 (what the robot believed, expected to learn
//! and visited in its busiest areas over its first days).
//!
//! Files in, result structs out: the faces print the tables and draw the figures.

use std::fmt;
use std::path::{Path, PathBuf};

use crate::datasets::{DatasetError, load_aruba, load_brayford};
use crate::report::{Table, time};
use chronomap_core::Parallelism;
use chronomap_core::num::count_of;
use chronomap_core::progress::Progress;
use chronomap_explore::table::{
    ModelKind, PAPER_TABLE_1_ARUBA, PAPER_TABLE_2_BRAYFORD, TableEntry, busiest_locations,
    explore_table, row_title,
};
#[cfg(feature = "plot")]
use chronomap_explore::table::{SWEEP_SEEDS, exploration_sweep};
use chronomap_explore::{
    ExploreConfig, ExploreError, ExploreResult, MAX_STEPS_PER_DAY, Strategy, World, explore,
};
#[cfg(feature = "plot")]
use chronomap_plot::{Panel, Series, SeriesStyle};
use serde_json::{Value, json};

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
    /// A strategy and model of the table have no result.
    #[error("missing result")]
    Incomplete,
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

impl Dataset {
    /// `aruba` or `brayford`.
    pub fn name(self) -> &'static str {
        match self {
            Dataset::Aruba => "aruba",
            Dataset::Brayford => "brayford",
        }
    }

    /// The paper's table of this dataset ([Santos 2017] Table 1 or 2).
    pub fn paper_table(self) -> &'static [[f64; 4]; 5] {
        match self {
            Dataset::Aruba => &PAPER_TABLE_1_ARUBA,
            Dataset::Brayford => &PAPER_TABLE_2_BRAYFORD,
        }
    }
}

/// What `chronomap explore` reports: every strategy with every temporal model on a dataset,
/// beside the paper's table ([Santos 2017] §7).
pub struct ExploreReport {
    /// The dataset.
    pub dataset: Dataset,
    /// Its folder.
    pub directory: String,
    /// Locations of the world.
    pub locations: usize,
    /// Its first time.
    pub start: f64,
    /// The exploration ratio e.
    pub ratio: f64,
    /// The seed.
    pub seed: u64,
    /// Days explored.
    pub days: usize,
    /// One run per strategy and model, every pair present.
    pub results: Vec<TableEntry>,
}

/// Explores `world` (of `dataset`, read from `dir`) by every strategy with every temporal
/// model at exploration ratio `ratio` for `days` days (default: all) with `seed`
/// ([`explore_table`]); `progress` hears the runs.
///
/// # Errors
/// [`ExploreJobError::Explore`] from a run; [`ExploreJobError::Incomplete`] when a pair has no
/// result.
pub fn explore_report(
    (dataset, dir, world): (Dataset, &Path, &World),
    ratio: f64,
    days: Option<usize>,
    seed: u64,
    progress: &dyn Progress,
) -> Result<ExploreReport, ExploreJobError> {
    let config = ExploreConfig {
        ratio,
        days,
        seed,
        ..ExploreConfig::default()
    };
    let results = explore_table(world, &config, Parallelism::Rayon(0), progress)?;
    let complete = Strategy::all().into_iter().all(|strategy| {
        ModelKind::ALL.into_iter().all(|model| {
            results
                .iter()
                .any(|e| e.strategy == strategy && e.model == model)
        })
    });
    let days = match results.first() {
        Some(first) if complete => first.result.daily_error_percent.len(),
        _ => return Err(ExploreJobError::Incomplete),
    };
    Ok(ExploreReport {
        dataset,
        directory: dir.display().to_string(),
        locations: world.locations.len(),
        start: world.start,
        ratio,
        seed,
        days,
        results,
    })
}

impl ExploreReport {
    /// The report as `chronomap explore --json` prints it.
    pub fn json(&self) -> Value {
        json!({
            "dataset": self.dataset.name(),
            "ratio": self.ratio,
            "seed": self.seed,
            "days": self.days,
            "results": self.results.iter().map(|e| json!({
                "strategy": e.strategy.name(),
                "model": e.model.name(),
                "error_percent": e.result.error_percent,
                "explored_fraction": e.result.explored_fraction,
                "redirects": e.result.redirects,
            })).collect::<Vec<_>>(),
        })
    }

    /// The report as `chronomap explore` prints it.
    pub fn text(&self) -> String {
        self.to_string()
    }
}

impl fmt::Display for ExploreReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: {} locations, {} days from {}, exploration ratio e = {}, 10-minute observations, seed {}",
            self.directory,
            self.locations,
            self.days,
            time(self.start),
            self.ratio,
            self.seed
        )?;
        writeln!(
            f,
            "Model error of eq. (2) [%], ours (paper{}):\n",
            if self.ratio == 0.5 {
                ", Table 1 / Table 2"
            } else {
                " at e = 0.5"
            }
        )?;
        let paper = self.dataset.paper_table();
        let mut header = vec!["strategy".to_string()];
        header.extend(ModelKind::ALL.map(|m| m.column().to_string()));
        let mut t = Table::new(header);
        for (row, strategy) in Strategy::all().into_iter().enumerate() {
            let mut cells = vec![row_title(strategy).to_string()];
            for (col, model) in ModelKind::ALL.into_iter().enumerate() {
                // Every pair has a result ([`explore_report`]).
                if let Some(e) = self
                    .results
                    .iter()
                    .find(|e| e.strategy == strategy && e.model == model)
                {
                    cells.push(format!(
                        "{:4.1} ({:4.1})",
                        e.result.error_percent, paper[row][col]
                    ));
                }
            }
            t.row(cells);
        }
        writeln!(f, "{}", t.render())?;
        if let Some(best) = self
            .results
            .iter()
            .min_by(|a, b| a.result.error_percent.total_cmp(&b.result.error_percent))
        {
            writeln!(
                f,
                "\nbest: {} + {} at {:.2} %; explored {:.1} % of the slots; novelty redirected {} slots",
                best.strategy.name(),
                best.model.name(),
                best.result.error_percent,
                100.0 * best.result.explored_fraction,
                self.results
                    .iter()
                    .filter(|e| matches!(e.strategy, Strategy::Novelty { .. })
                        && e.model == ModelKind::Fremen)
                    .map(|e| e.result.redirects)
                    .sum::<usize>()
            )?;
        }
        Ok(())
    }
}

/// [Santos 2017] Fig. 5: the model error after two weeks of exploration by exploration ratio
/// ([`exploration_sweep`], mean of [`SWEEP_SEEDS`] seeds from `seed`); `progress` hears the
/// runs.
///
/// # Errors
/// [`ExploreJobError::Explore`] from a run.
#[cfg(feature = "plot")]
pub fn sweep_panel(
    world: &World,
    seed: u64,
    progress: &dyn Progress,
) -> Result<Panel, ExploreJobError> {
    let curves = exploration_sweep(world, seed, Parallelism::Rayon(0), progress)?;
    let top = curves
        .iter()
        .flat_map(|c| c.points.iter().map(|p| p.1))
        .fold(0.0, f64::max)
        * 1.1;
    let series = curves
        .into_iter()
        .map(|curve| Series {
            label: if curve.model == ModelKind::Fremen {
                format!("{} + FreMEn", row_title(curve.strategy))
            } else {
                format!("{} + static (mean)", row_title(curve.strategy))
            },
            points: curve.points,
            style: SeriesStyle::Line,
        })
        .collect();
    Ok(Panel {
        title: format!(
            "Model error after two weeks of exploration by exploration ratio ([Santos 2017] Fig. 5, mean of {SWEEP_SEEDS} seeds)"
        ),
        x_label: "exploration ratio e".into(),
        y_label: "model error [%]".into(),
        y_range: (0.0, top.max(1.0)),
        series,
    })
}

/// [Santos 2017] Fig. 6 from the run of [`behaviour`] at `ratio` with `seed`: the truth, the
/// model, the expected information and the visits of the three busiest areas over the first
/// four days of FreMEn with the Monte-Carlo strategy, each a panel of one series per area
/// stacked by rank.
///
/// # Errors
/// As [`behaviour`].
#[cfg(feature = "plot")]
pub fn behaviour_panels(
    world: &World,
    ratio: f64,
    seed: u64,
) -> Result<Vec<Panel>, ExploreJobError> {
    let Behaviour {
        result,
        areas,
        steps,
    } = behaviour(world, ratio, seed)?;
    let trace = &result.trace;
    let day = |t: f64| (t - world.start) / 86_400.0;
    let offset = |k: usize| 1.5 * (2 - k) as f64;
    // One series per area, stacked by its rank `k`.
    let per_area = |style: SeriesStyle, points: &dyn Fn(usize, usize) -> Vec<(f64, f64)>| {
        areas
            .iter()
            .enumerate()
            .map(|(k, &l)| Series {
                label: world.names[l].clone(),
                points: points(k, l),
                style,
            })
            .collect::<Vec<_>>()
    };
    let truth = per_area(SeriesStyle::Step, &|k, l| {
        (0..steps)
            .map(|s| {
                (
                    day(world.time(s)),
                    offset(k) + f64::from(world.truth[world.locations[l][0]][s]),
                )
            })
            .collect()
    });
    let per_slot = |values: &dyn Fn(usize, usize) -> f64| {
        per_area(SeriesStyle::Step, &|k, l| {
            trace
                .slot_times
                .iter()
                .enumerate()
                .map(|(s, &t)| (day(t), offset(k) + values(l, s)))
                .collect()
        })
    };
    let probability = per_slot(&|l, s| trace.probability[world.locations[l][0]][s]);
    let top_info = areas
        .iter()
        .flat_map(|&l| trace.information[l].iter().copied())
        .fold(0.0f64, f64::max)
        .max(1e-9);
    let information = per_slot(&|l, s| trace.information[l][s] / top_info);
    let visits = per_area(SeriesStyle::Dots, &|k, l| {
        trace
            .visits
            .iter()
            .zip(&trace.slot_times)
            .filter(|(v, _)| **v == Some(l))
            .map(|(_, &t)| (day(t), offset(k) + 0.5))
            .collect()
    });
    let panel = |title: &str, series: Vec<Series>, x_label: &str| Panel {
        title: title.into(),
        x_label: x_label.into(),
        y_label: String::new(),
        y_range: (-0.2, 4.2),
        series,
    };
    Ok(vec![
        panel(
            "True states s_i(t) of the three busiest areas (stacked)",
            truth,
            "",
        ),
        panel(
            "The robot's model p_i(t) when it planned each day (FreMEn, order chosen daily)",
            probability,
            "",
        ),
        panel(
            "Expected information I(L, t) of eq. (10) (scaled to the largest)",
            information,
            "",
        ),
        panel(
            &format!("Visits chosen by the Monte-Carlo strategy (e = {ratio})"),
            visits,
            "days since the start",
        ),
    ])
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

    #[test]
    fn the_brayford_table_has_every_strategy_with_every_model() {
        let dir = chronomap_testutil::data_path("brayford_week");
        let world = load_world(Dataset::Brayford, &dir).unwrap();
        let report = explore_report(
            (Dataset::Brayford, &dir, &world),
            0.5,
            Some(2),
            3,
            &chronomap_core::progress::NoProgress,
        )
        .unwrap();
        // 5 strategies × 4 models, two days explored.
        assert_eq!((report.results.len(), report.days), (20, 2));
        let json = report.json();
        assert_eq!(json["dataset"], "brayford");
        assert_eq!(json["results"].as_array().unwrap().len(), 20);
        let text = report.to_string();
        assert!(
            text.starts_with(&format!(
                "{}: 8 locations, 2 days from day 1 00:00 (+0 s), exploration ratio e = 0.5, \
                 10-minute observations, seed 3\nModel error of eq. (2) [%], ours (paper, Table 1 / Table 2):\n\n",
                dir.display()
            )),
            "{text}"
        );
        // The paper's Greedy + FreMEn on Brayford beside ours.
        let greedy = text.lines().find(|l| l.starts_with("Greedy")).unwrap();
        assert!(
            greedy.contains(&format!("({:4.1})", PAPER_TABLE_2_BRAYFORD[2][2])),
            "{greedy}"
        );
        assert!(text.contains("\nbest: "));
        #[cfg(feature = "plot")]
        assert_eq!(behaviour_panels(&world, 0.5, 3).unwrap().len(), 4);
    }
}
