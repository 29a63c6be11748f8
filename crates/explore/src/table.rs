//! The experiments of [Santos 2017] §7 over a recorded world: every strategy with every temporal
//! model (Tables 1 and 2), the model error against the exploration ratio (Fig. 5), and the
//! locations that Fig. 6 shows.
//!
//! ```
//! use chronomap_core::Parallelism;
//! use chronomap_core::progress::NoProgress;
//! use chronomap_explore::table::{ModelKind, explore_table};
//! use chronomap_explore::{ExploreConfig, Strategy, World};
//!
//! // Two rooms over three days at 10-minute steps: one occupied 9:00-17:00, one never.
//! let steps = 3 * 144;
//! let office: Vec<u8> = (0..steps).map(|s| u8::from((54..102).contains(&(s % 144)))).collect();
//! let world = World::one_state_per_location(
//!     0.0, 600.0, vec![office, vec![0; steps]], vec!["office".into(), "store".into()],
//! );
//! let config = ExploreConfig { ratio: 0.5, ..ExploreConfig::default() };
//! let table = explore_table(&world, &config, Parallelism::Rayon(0), &NoProgress)?;
//! assert_eq!(table.len(), 5 * 4);
//! assert_eq!((table[0].strategy, table[0].model), (Strategy::RoundRobin, ModelKind::ShortTerm));
//! assert!(table.iter().all(|r| (0.0..=100.0).contains(&r.result.error_percent)));
//! # Ok::<(), chronomap_explore::ExploreError>(())
//! ```

use chronomap_core::Parallelism;
use chronomap_core::fremen::FremenModel;
use chronomap_core::mean::MeanModel;
use chronomap_core::pergam::{PergamConfig, PergamModel};
use chronomap_core::progress::Progress;
use chronomap_core::stm::MarkovModel;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::{
    AutoOrder, DailyModel, ExploreConfig, ExploreError, ExploreResult, Strategy, World, explore,
};

/// The temporal models of [Santos 2017] §4 as its tables name them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum ModelKind {
    /// SM: short-term memory (a continuous-time Markov chain, §4.1.1).
    ShortTerm,
    /// LM: long-term memory (the mean, §4.1.2).
    Mean,
    /// FT: FreMEn with its order chosen every day (§4.1.3).
    Fremen,
    /// GM: periodic Gaussian mixture over the day (§4.1.4).
    Pergam,
}

impl ModelKind {
    /// The four models in the order of the tables' columns.
    pub const ALL: [ModelKind; 4] = [
        ModelKind::ShortTerm,
        ModelKind::Mean,
        ModelKind::Fremen,
        ModelKind::Pergam,
    ];

    /// Short name: `stm`, `mean`, `fremen`, `pergam`.
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::ShortTerm => "stm",
            ModelKind::Mean => "mean",
            ModelKind::Fremen => "fremen",
            ModelKind::Pergam => "pergam",
        }
    }

    /// Column title of the paper's tables: `SM`, `LM`, `FT`, `GM`.
    pub fn column(self) -> &'static str {
        match self {
            ModelKind::ShortTerm => "SM",
            ModelKind::Mean => "LM",
            ModelKind::Fremen => "FT",
            ModelKind::Pergam => "GM",
        }
    }

    /// A fresh model of one state.
    pub fn make(self) -> Box<dyn DailyModel> {
        match self {
            ModelKind::ShortTerm => Box::new(MarkovModel::new()),
            ModelKind::Mean => Box::new(MeanModel::new()),
            ModelKind::Fremen => Box::new(AutoOrder::new(FremenModel::with_order(0))),
            // One bin per 10-minute observation slot: the finest time the schedule resolves.
            ModelKind::Pergam => Box::new(
                PergamModel::new(PergamConfig {
                    components: 2,
                    bins: 144,
                    ..PergamConfig::default()
                })
                .expect("two components over 144 bins are a valid configuration"),
            ),
        }
    }
}

/// Row title of the paper's tables: `Round Robin`, `Random`, `Greedy`, `Monte-Carlo`,
/// `Novelty-driven`.
pub fn row_title(strategy: Strategy) -> &'static str {
    strategy.labels().1
}

/// [Santos 2017] Table 1 (Aruba, symbolic map), model error in percent: rows Round Robin, Random,
/// Greedy, Monte-Carlo, Novelty ([`Strategy::all`]); columns SM, LM, FT, GM
/// ([`ModelKind::ALL`]).
pub const PAPER_TABLE_1_ARUBA: [[f64; 4]; 5] = [
    [9.3, 9.7, 6.5, 7.5],
    [8.9, 9.5, 9.2, 7.5],
    [8.5, 8.7, 7.0, 9.4],
    [8.5, 8.9, 5.8, 6.4],
    [8.5, 8.9, 5.7, 6.1],
];

/// [Santos 2017] Table 2 (Brayford, people presence), laid out as [`PAPER_TABLE_1_ARUBA`].
pub const PAPER_TABLE_2_BRAYFORD: [[f64; 4]; 5] = [
    [23.7, 23.7, 16.3, 20.2],
    [23.7, 23.8, 23.0, 23.8],
    [20.2, 22.3, 19.2, 20.1],
    [23.5, 23.5, 16.4, 19.3],
    [23.4, 23.5, 15.2, 19.4],
];

/// One cell of the tables: a strategy with a model.
#[derive(Clone, Debug, PartialEq)]
pub struct TableEntry {
    /// The strategy.
    pub strategy: Strategy,
    /// The model of every state.
    pub model: ModelKind,
    /// What the exploration achieved.
    pub result: ExploreResult,
}

/// Runs every strategy of [`Strategy::all`] with every model of [`ModelKind::ALL`] on `world`
/// ([Santos 2017] Tables 1 and 2), as tasks of `parallelism`; reports one step per run to
/// `progress`. Entries come strategy by strategy, models in column order; they do not depend
/// on `parallelism` (every run has its own seeded randomness).
///
/// # Errors
/// The first run that fails (a malformed world or configuration).
pub fn explore_table(
    world: &World,
    config: &ExploreConfig,
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<Vec<TableEntry>, ExploreError> {
    let combos: Vec<(Strategy, ModelKind)> = Strategy::all()
        .into_iter()
        .flat_map(|s| ModelKind::ALL.map(|m| (s, m)))
        .collect();
    progress.stage("exploring", combos.len() as u64);
    let run = |(strategy, model): (Strategy, ModelKind)| {
        let result = explore(world, strategy, &move || model.make(), config)?;
        progress.advance(1);
        Ok(TableEntry {
            strategy,
            model,
            result,
        })
    };
    match parallelism {
        Parallelism::Sequential => combos.into_iter().map(run).collect(),
        Parallelism::Rayon(_) => combos.into_par_iter().map(run).collect(),
    }
}

/// Exploration ratios of the sweep of [Santos 2017] Fig. 5.
pub const SWEEP_RATIOS: [f64; 7] = [0.05, 0.1, 0.2, 0.3, 0.5, 0.7, 0.9];

/// Runs (seeds `seed..seed + SWEEP_SEEDS`) averaged per point of the sweep: the random
/// strategies vary from run to run, most at low ratios.
pub const SWEEP_SEEDS: u64 = 5;

/// Days explored per run of the sweep (two weeks, as in Fig. 5).
pub const SWEEP_DAYS: usize = 14;

/// One curve of the sweep: a strategy with a model, its mean error at each ratio.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepCurve {
    /// The strategy.
    pub strategy: Strategy,
    /// The model.
    pub model: ModelKind,
    /// `(ratio, mean model error in percent)` for each of [`SWEEP_RATIOS`].
    pub points: Vec<(f64, f64)>,
}

/// [Santos 2017] Fig. 5: the model error of FreMEn with each strategy after two weeks, against the
/// exploration ratio, with the static model (the mean, round robin) for reference; each point
/// the mean of [`SWEEP_SEEDS`] runs. Reports one step per run to `progress`.
///
/// # Errors
/// The first run that fails.
pub fn exploration_sweep(
    world: &World,
    seed: u64,
    parallelism: Parallelism,
    progress: &dyn Progress,
) -> Result<Vec<SweepCurve>, ExploreError> {
    let runs: Vec<(Strategy, ModelKind)> = Strategy::all()
        .into_iter()
        .map(|s| (s, ModelKind::Fremen))
        .chain([(Strategy::RoundRobin, ModelKind::Mean)])
        .collect();
    let jobs: Vec<(usize, f64, u64)> = (0..runs.len())
        .flat_map(|r| {
            SWEEP_RATIOS
                .into_iter()
                .flat_map(move |e| (0..SWEEP_SEEDS).map(move |k| (r, e, seed + k)))
        })
        .collect();
    progress.stage("sweeping ratios", jobs.len() as u64);
    let run = |(r, e, seed): (usize, f64, u64)| {
        let (strategy, model) = runs[r];
        let config = ExploreConfig {
            ratio: e,
            days: Some(SWEEP_DAYS),
            seed,
            ..ExploreConfig::default()
        };
        let x = explore(world, strategy, &move || model.make(), &config)?;
        progress.advance(1);
        Ok((r, e, x.error_percent))
    };
    let single: Vec<(usize, f64, f64)> = match parallelism {
        Parallelism::Sequential => jobs.into_iter().map(run).collect::<Result<_, _>>()?,
        Parallelism::Rayon(_) => jobs.into_par_iter().map(run).collect::<Result<_, _>>()?,
    };
    Ok(runs
        .iter()
        .enumerate()
        .map(|(r, &(strategy, model))| SweepCurve {
            strategy,
            model,
            points: SWEEP_RATIOS
                .map(|e| {
                    let errors = single.iter().filter(|x| x.0 == r && x.1 == e);
                    (e, errors.map(|x| x.2).sum::<f64>() / SWEEP_SEEDS as f64)
                })
                .to_vec(),
        })
        .collect())
}

/// The `n` locations whose first state is occupied most often over the whole world, busiest
/// first (ties in location order): the areas [Santos 2017] Fig. 6 shows.
pub fn busiest_locations(world: &World, n: usize) -> Vec<usize> {
    let mut locations: Vec<usize> = (0..world.locations.len()).collect();
    locations.sort_by_key(|&l| {
        std::cmp::Reverse(
            world.truth[world.locations[l][0]]
                .iter()
                .map(|&v| u64::from(v))
                .sum::<u64>(),
        )
    });
    locations.truncate(n);
    locations
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_core::progress::NoProgress;

    /// Three rooms over 15 days at 10-minute steps: a kitchen at meals, an office by day,
    /// a store room never.
    fn world() -> World {
        let steps = 15 * 144;
        let kitchen = (0..steps)
            .map(|s| {
                u8::from(
                    [42..48, 72..78, 114..120]
                        .iter()
                        .any(|r| r.contains(&(s % 144))),
                )
            })
            .collect();
        let office = (0..steps)
            .map(|s| u8::from((54..102).contains(&(s % 144))))
            .collect();
        World::one_state_per_location(
            1_451_865_600.0,
            600.0,
            vec![kitchen, office, vec![0; steps]],
            vec!["kitchen".into(), "office".into(), "store".into()],
        )
    }

    #[test]
    fn the_table_does_not_depend_on_parallelism() {
        let world = world();
        let config = ExploreConfig {
            days: Some(4),
            ..ExploreConfig::default()
        };
        let one = explore_table(&world, &config, Parallelism::Sequential, &NoProgress).unwrap();
        let many = explore_table(&world, &config, Parallelism::Rayon(0), &NoProgress).unwrap();
        assert_eq!(one, many);
        assert_eq!(one.len(), 20);
        assert_eq!(one[19].strategy.name(), "novelty");
        assert_eq!(one[19].model, ModelKind::Pergam);
        // Nothing is ever in the store room; the office and kitchen follow the clock.
        for entry in &one {
            assert!(entry.result.error_percent < 50.0, "{entry:?}");
            assert_eq!(entry.result.daily_error_percent.len(), 4);
        }
    }

    #[test]
    fn sweeps_average_seeds_and_busiest_locations_rank_by_occupancy() {
        let world = world();
        let curves = exploration_sweep(&world, 0, Parallelism::Rayon(0), &NoProgress).unwrap();
        assert_eq!(curves.len(), 6);
        assert_eq!(
            (curves[5].strategy, curves[5].model),
            (Strategy::RoundRobin, ModelKind::Mean)
        );
        for curve in &curves {
            let ratios: Vec<f64> = curve.points.iter().map(|p| p.0).collect();
            assert_eq!(ratios, SWEEP_RATIOS);
        }
        // The point of one curve is the mean of its SWEEP_SEEDS runs.
        let runs: Vec<f64> = (0..SWEEP_SEEDS)
            .map(|seed| {
                let config = ExploreConfig {
                    ratio: 0.5,
                    days: Some(SWEEP_DAYS),
                    seed,
                    ..ExploreConfig::default()
                };
                explore(
                    &world,
                    Strategy::Random,
                    &|| ModelKind::Fremen.make(),
                    &config,
                )
                .unwrap()
                .error_percent
            })
            .collect();
        let mean = runs.iter().sum::<f64>() / SWEEP_SEEDS as f64;
        assert_eq!(curves[1].strategy, Strategy::Random);
        assert!((curves[1].points[4].1 - mean).abs() < 1e-12);
        // 48 office steps a day, 18 kitchen steps, none in the store.
        assert_eq!(busiest_locations(&world, 3), [1, 0, 2]);
        assert_eq!(busiest_locations(&world, 1), [1]);
        assert_eq!(
            ModelKind::ALL.map(ModelKind::column),
            ["SM", "LM", "FT", "GM"]
        );
        assert_eq!(row_title(Strategy::all()[4]), "Novelty-driven");
    }
}
