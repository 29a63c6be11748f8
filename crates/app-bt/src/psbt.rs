//! The person search behavior tree of [Stüde 2024] §5.4 as jobs: the world (the planning grid
//! of a map's free cells and the pedestrian tracks, or a saved CoPA-Map told apart by its magic
//! word, [`FileKind`]), the grid Poisson model of eq. 5.7, the synthesis of §5.4.3 and the
//! model-based comparison with the baselines of §5.4.4 (Fig. 5.11).
//!
//! Files in, reports out: `chronomap psbt` and `chronomap bench psbt` translate flags and print.

use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_activity::disturbance::PlanningGrid;
use chronomap_activity::truth::TrackPoint;
use chronomap_core::Parallelism;
use chronomap_core::num::fmt_number;
use chronomap_core::progress::Progress;
use chronomap_io::psbt_xml::psbt_to_xml;
use chronomap_io::{
    DataError, ModelFileError, PlanningMapError, load_planning_grid, read_copa_map,
    read_track_point_files,
};
use chronomap_plot::{Panel, Series, SeriesStyle};
use chronomap_psbt::compare::{CompareError, Comparison, MethodSummary, compare};
use chronomap_psbt::world::grid_poisson_from_tracks;
use chronomap_psbt::{GridPoisson, PsbtConfig, PsbtError, copa_field, synthesize};
use serde::Serialize;
use serde_json::{Map, Value, json};

use chronomap_app::disturbance::OCCUPIED_PERCENT;
use chronomap_app::open::{FileKind, SniffError};
use chronomap_app::report::{Table, time};

/// Why a person-search job failed.
#[derive(Debug, thiserror::Error)]
pub enum PsbtJobError {
    /// A value asked for does not fit the data (too many cells or intervals over the map and
    /// the tracked time: a usage error at the command line).
    #[error("{0}")]
    Usage(String),
    /// The map cannot be read or planned on.
    #[error(transparent)]
    Map(#[from] PlanningMapError),
    /// The tracks cannot be read.
    #[error("cannot read the tracks")]
    Tracks(#[source] DataError),
    /// A file of `--activity` cannot be sniffed.
    #[error(transparent)]
    Sniff(#[from] SniffError),
    /// Model files and track files given together.
    #[error(
        "--activity: give one CoPA-Map model file or pedestrian track files, not both \
         ({models} of {files} files are models)"
    )]
    MixedActivity {
        /// Model files among them.
        models: usize,
        /// Files given.
        files: usize,
    },
    /// The comparison was given a saved model.
    #[error(
        "--activity: psbt eval needs pedestrian tracks (it learns a planning model from the \
         hours before --time and scores on the hour itself); a saved model serves synthesis"
    )]
    EvalNeedsTracks,
    /// The CoPA-Map cannot be read.
    #[error(transparent)]
    CopaMap(#[from] ModelFileError),
    /// The request time is outside the ATC grid's time axis.
    #[error(
        "--time {}: outside 09:00-21:00 JST, which the ATC grid's time axis covers (give --model-t)",
        time(*.0)
    )]
    ModelTime(f64),
    /// The CoPA-Map's field cannot be evaluated.
    #[error("{name}: {error}")]
    CopaField {
        /// The model file.
        name: String,
        /// Why.
        error: PsbtError,
    },
    /// The tracks hold nobody.
    #[error("the tracks hold no detection")]
    NoDetection,
    /// The tracks hold nobody before the end of training.
    #[error("no detection before --train-until {0}")]
    NoTraining(f64),
    /// The synthesis failed from that help location.
    #[error("--from {},{}: {error}", fmt_number(from[0]), fmt_number(from[1]))]
    Synthesis {
        /// The help location.
        from: [f64; 2],
        /// Why.
        error: PsbtError,
    },
    /// The model cannot be fitted.
    #[error(transparent)]
    Psbt(#[from] PsbtError),
    /// The comparison failed.
    #[error(transparent)]
    Compare(#[from] CompareError),
}

/// Where the robot may drive and the tracks it learns people from.
pub struct World {
    /// The planning grid of the map's free cells.
    pub grid: PlanningGrid,
    /// The tracked people.
    pub points: Vec<TrackPoint>,
    /// Lower-left corner of the map (metres).
    origin: [f64; 2],
    /// Size of the map (metres).
    size: [f64; 2],
}

/// The planning grid of the map's free cells (occupied from [`OCCUPIED_PERCENT`]),
/// `planning_cell` metres a side, `clearance` metres from obstacles.
fn planning_grid(
    map: &Path,
    planning_cell: f64,
    clearance: f64,
) -> Result<chronomap_activity::planning::MapPlanningGrid, PsbtJobError> {
    Ok(load_planning_grid(
        map,
        OCCUPIED_PERCENT,
        planning_cell,
        clearance,
    )?)
}

/// Reads the map (the planning grid of its free cells) and the tracks.
///
/// # Errors
/// The map or the tracks cannot be read.
pub fn load_world(
    map: &Path,
    activity: &[impl AsRef<Path>],
    planning_cell: f64,
    clearance: f64,
) -> Result<World, PsbtJobError> {
    let planning = planning_grid(map, planning_cell, clearance)?;
    let points = read_track_point_files(activity).map_err(PsbtJobError::Tracks)?;
    Ok(World {
        grid: planning.grid,
        points,
        origin: planning.origin,
        size: planning.size,
    })
}

/// Whether `activity` names a saved model rather than tracks: one file that starts with the
/// model-file magic word or ends in `.cmcopa` ([`FileKind`]).
///
/// # Errors
/// A file cannot be sniffed; models and tracks are mixed.
pub fn is_model_source(activity: &[PathBuf]) -> Result<bool, PsbtJobError> {
    let mut models = 0;
    for path in activity {
        let model = FileKind::by_name(path).is_copa_map() || FileKind::of(path)?.is_model_file();
        models += usize::from(model);
    }
    match (models, activity.len()) {
        (0, _) => Ok(false),
        (1, 1) => Ok(true),
        (models, files) => Err(PsbtJobError::MixedActivity { models, files }),
    }
}

/// The grid Poisson model (eq. 5.7) over the map, `cell` metres and `interval` seconds a
/// bin, from the tracks `keep` accepts (by time); `None` when they hold nobody.
///
/// # Errors
/// [`PsbtJobError::Usage`] for too many cells or intervals (naming `--cell`/`--interval`).
pub fn fit_model(
    world: &World,
    cell: f64,
    interval: f64,
    keep: impl Fn(f64) -> bool,
) -> Result<Option<GridPoisson>, PsbtJobError> {
    grid_poisson_from_tracks(
        &world.points,
        world.origin,
        world.size,
        cell,
        interval,
        keep,
    )
    .map_err(|e| match e {
        PsbtError::TooMany {
            parameter, value, ..
        } => PsbtJobError::Usage(format!(
            "--{parameter} {}: {e} (over the map and the tracked time)",
            fmt_number(value)
        )),
        e => e.into(),
    })
}

/// The world of a person search: the map, the activity (tracks or one CoPA-Map) and the
/// model's and planner's grids.
#[derive(Clone, Copy, Debug)]
pub struct WorldSetup<'a> {
    /// ROS map YAML.
    pub map: &'a Path,
    /// Pedestrian track files, or one CoPA-Map model file.
    pub activity: &'a [PathBuf],
    /// Side of a cell of the activity model (metres).
    pub cell: f64,
    /// Length of a time interval of the activity model (seconds).
    pub interval: f64,
    /// Side of a planning cell (metres).
    pub planning_cell: f64,
    /// Metres kept from obstacles.
    pub clearance: f64,
}

/// A CoPA-Map's time and cell for a synthesis.
#[derive(Clone, Copy, Debug)]
pub struct CopaTime {
    /// The model time to use (default: the request time on the ATC grid's axis).
    pub model_t: Option<f64>,
    /// Side of the cells whose rates the model was trained on (metres).
    pub model_cell: f64,
}

/// What `chronomap psbt` reports: the synthesised tree as BehaviorTree.CPP XML with its
/// success probability and expected time ([Stüde 2024] §5.4.3) (serialises as its `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct SynthReport {
    /// The tree as BehaviorTree.CPP 4 XML.
    pub tree_xml: String,
    /// `p_s,T(t_max)` under the model.
    pub p_success: f64,
    /// `E[T | S]` (seconds), if success is possible.
    pub expected_time_s: Option<f64>,
    /// Milliseconds spent synthesising (timed on purpose: the report says it).
    pub synthesis_ms: f64,
    /// Candidate trees compared.
    pub candidates: usize,
    /// The places, in visiting order.
    pub places: Vec<[f64; 2]>,
    /// The chosen candidate's choice per place, or waiting at the start.
    pub choices: Value,
    /// The horizon t_max (seconds).
    pub horizon_s: f64,
    /// The seed.
    pub seed: u64,
    /// The CoPA-Map's time used, if the activity is one.
    pub model_t: Option<f64>,
    /// The help location.
    #[serde(skip)]
    pub from: [f64; 2],
    /// The request time.
    #[serde(skip)]
    pub time: f64,
}

/// Synthesises the person search tree for help at `from` at `time` with `config` and `seed`
/// ([Stüde 2024] §5.4.3) on the activity of `world`: the grid Poisson model of the tracks, or
/// the field of a CoPA-Map at its model time ([`copa_field`]).
///
/// # Errors
/// [`PsbtJobError`]: a file that cannot be read, a time outside a CoPA-Map's axis, tracks
/// without detections, a synthesis that fails from `from`.
pub fn synthesis(
    world: &WorldSetup<'_>,
    config: &PsbtConfig,
    (from, time): ([f64; 2], f64),
    seed: u64,
    copa: CopaTime,
) -> Result<SynthReport, PsbtJobError> {
    let (grid, model, model_t) =
        if is_model_source(world.activity)? {
            let grid = planning_grid(world.map, world.planning_cell, world.clearance)?.grid;
            let path = &world.activity[0];
            let model = read_copa_map(path)?;
            let model_t = match copa.model_t {
                Some(t) => t,
                None => chronomap_activity::atc::model_time(time)
                    .ok_or(PsbtJobError::ModelTime(time))?,
            };
            let field = copa_field(&model, copa.model_cell, model_t, Parallelism::Rayon(0))
                .map_err(|error| PsbtJobError::CopaField {
                    name: path.display().to_string(),
                    error,
                })?;
            (grid, field, Some(model_t))
        } else {
            let tracks = load_world(
                world.map,
                world.activity,
                world.planning_cell,
                world.clearance,
            )?;
            let model = fit_model(&tracks, world.cell, world.interval, |_| true)?
                .ok_or(PsbtJobError::NoDetection)?;
            (tracks.grid, model, None)
        };
    let started = Instant::now();
    let plan = synthesize(
        &grid,
        &model,
        from,
        time,
        config,
        seed,
        Parallelism::Sequential,
    )
    .map_err(|error| PsbtJobError::Synthesis { from, error })?;
    let synthesis_ms = started.elapsed().as_secs_f64() * 1e3;
    Ok(SynthReport {
        tree_xml: psbt_to_xml(&plan.tree),
        p_success: plan.p_success,
        expected_time_s: plan.expected_time_s,
        synthesis_ms,
        candidates: plan.candidates,
        places: plan.places,
        choices: match &plan.choices {
            None => json!("wait at the start (W)"),
            Some(c) => json!(c.iter().map(|c| c.name()).collect::<Vec<_>>()),
        },
        horizon_s: config.horizon_s,
        seed,
        model_t,
        from,
        time,
    })
}

impl fmt::Display for SynthReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "person search from ({}, {}) at {}: {} candidate trees over {} places in {:.1} ms",
            self.from[0],
            self.from[1],
            time(self.time),
            self.candidates,
            self.places.len(),
            self.synthesis_ms
        )?;
        writeln!(
            f,
            "p_s,T({} s) = {:.4}; expected time to success E[T|S] = {}",
            self.horizon_s,
            self.p_success,
            self.expected_time_s
                .map_or("-".into(), |t| format!("{t:.1} s"))
        )?;
        if let Some(t) = self.model_t {
            writeln!(f, "activity: CoPA-Map at model t = {t:.3}")?;
        }
        write!(f, "{}", self.tree_xml)
    }
}

/// What `chronomap psbt eval` reports: PSBT against the baselines from many help locations
/// ([Stüde 2024] §5.4.4, Fig. 5.11), on the planning model and on the model of the evaluated
/// hour.
pub struct PsbtEvalReport {
    /// The outcomes of every method from every start.
    pub comparison: Comparison,
    /// Mean and spread per method on the planning model.
    pub planned: Vec<MethodSummary>,
    /// The same on the scoring model, if the hour holds detections.
    pub scored: Option<Vec<MethodSummary>>,
    /// The request time.
    pub time: f64,
    /// The planning model learned from the tracks before this time.
    pub train_until: f64,
    /// Places per tree.
    pub places: usize,
    /// Seconds spent comparing (timed on purpose: the report says it).
    pub seconds: f64,
}

/// Compares PSBT with the baselines from `starts` random help locations at `time`
/// ([`compare`]): the plans from a model of the tracks before `train_until` (default: the
/// start of the interval of `time`), scored on it and on a model of that interval's tracks;
/// `progress` hears the stage `help locations`.
///
/// # Errors
/// [`PsbtJobError`]: a saved model instead of tracks, files that cannot be read, no detection
/// before `train_until`, a comparison that fails.
pub fn evaluation(
    world: &WorldSetup<'_>,
    config: &PsbtConfig,
    (time, train_until): (f64, Option<f64>),
    (starts, seed): (usize, u64),
    progress: &dyn Progress,
) -> Result<PsbtEvalReport, PsbtJobError> {
    if is_model_source(world.activity)? {
        return Err(PsbtJobError::EvalNeedsTracks);
    }
    let tracks = load_world(
        world.map,
        world.activity,
        world.planning_cell,
        world.clearance,
    )?;
    let interval = world.interval;
    let hour = (time / interval).floor() * interval;
    let train_until = train_until.unwrap_or(hour);
    let plan_model = fit_model(&tracks, world.cell, interval, |t| t < train_until)?
        .ok_or(PsbtJobError::NoTraining(train_until))?;
    let score_model = fit_model(&tracks, world.cell, interval, |t| {
        t >= hour && t < hour + interval
    })?;
    let started = Instant::now();
    let comparison = compare(
        &tracks.grid,
        &plan_model,
        score_model.as_ref(),
        time,
        config,
        starts,
        seed,
        Parallelism::Rayon(0),
        progress,
    )?;
    let seconds = started.elapsed().as_secs_f64();
    // The planning model scores every plan.
    let planned = comparison.summaries(false).unwrap_or_default();
    let scored = comparison.summaries(true);
    Ok(PsbtEvalReport {
        comparison,
        planned,
        scored,
        time,
        train_until,
        places: config.places,
        seconds,
    })
}

impl PsbtEvalReport {
    fn beaten(&self, scored: bool) -> Map<String, Value> {
        self.comparison
            .beats_psbt_fraction(scored)
            .into_iter()
            .map(|(m, f)| (m.name().to_string(), json!(f)))
            .collect()
    }

    /// The report as `chronomap psbt eval --json` prints it.
    pub fn json(&self) -> Value {
        let summary_json = |summaries: &[MethodSummary]| -> Value {
            summaries
                .iter()
                .map(|s| {
                    (
                        s.method.name().to_string(),
                        json!({
                            "p_success_mean": s.p_mean,
                            "p_success_std": s.p_std,
                            "expected_time_mean_s": s.time_mean_s,
                            "expected_time_std_s": s.time_std_s,
                        }),
                    )
                })
                .collect::<Map<String, Value>>()
                .into()
        };
        let c = &self.comparison;
        let scored = self.scored.as_deref();
        json!({
            "starts": c.outcomes.len(),
            "time": self.time,
            "train_until": self.train_until,
            "times_s": c.times,
            "planning_model": summary_json(&self.planned),
            "scoring_model": scored.map(summary_json),
            "psbt_over_gm_at_140_percent": c.gain_over_gm_percent(&self.planned),
            "psbt_over_gm_at_140_percent_scored": scored.and_then(|s| c.gain_over_gm_percent(s)),
            "psbt_ge_all_at_tmax_fraction": c.psbt_at_least_all_fraction(false),
            "psbt_ge_all_at_tmax_fraction_scored": scored.map(|_| c.psbt_at_least_all_fraction(true)),
            "beats_psbt_at_tmax_fraction": self.beaten(false),
            "beats_psbt_at_tmax_fraction_scored": scored.map(|_| self.beaten(true)),
            "seconds": self.seconds,
        })
    }

    /// `p_s,T(t)` (mean ± std) at every time and `E[T|S]` per method.
    fn table(&self, summaries: &[MethodSummary]) -> String {
        let mut header = vec!["method".to_string()];
        header.extend(self.comparison.times.iter().map(|t| format!("t={t:.0} s")));
        header.push("E[T|S] (s)".into());
        let mut table = Table::new(header);
        for s in summaries {
            let mut row = vec![s.method.name().to_string()];
            row.extend(
                s.p_mean
                    .iter()
                    .zip(&s.p_std)
                    .map(|(a, b)| format!("{a:.3}±{b:.3}")),
            );
            row.push(format!("{:.1}±{:.1}", s.time_mean_s, s.time_std_s));
            table.row(row);
        }
        table.render()
    }

    /// How often PSBT is at least as good as every baseline at t_max, and how often each
    /// baseline beats it.
    fn verdict(&self, f: &mut fmt::Formatter<'_>, scored: bool) -> fmt::Result {
        let beaten = self
            .comparison
            .beats_psbt_fraction(scored)
            .iter()
            .map(|(m, f)| format!("{} {:.1} %", m.name(), 100.0 * f))
            .collect::<Vec<_>>()
            .join(", ");
        writeln!(
            f,
            "PSBT >= every baseline at t_max from {:.1} % of the starts; a baseline beats it from: {beaten}",
            100.0 * self.comparison.psbt_at_least_all_fraction(scored),
        )
    }

    /// Mean `p_s,T(t)` of every method over the starts: on the planning model, and on the
    /// scoring model if there is one.
    pub fn panels(&self) -> Vec<Panel> {
        let panel = |title: &str, summaries: &[MethodSummary]| Panel {
            title: title.into(),
            x_label: "t [s]".into(),
            y_label: "mean p_s,T(t)".into(),
            y_range: (0.0, 1.0),
            series: summaries
                .iter()
                .map(|s| Series {
                    label: s.method.name().into(),
                    points: self
                        .comparison
                        .times
                        .iter()
                        .copied()
                        .zip(s.p_mean.iter().copied())
                        .collect(),
                    style: SeriesStyle::Line,
                })
                .collect(),
        };
        let mut panels = vec![panel(
            &format!("planning model ({} starts)", self.comparison.outcomes.len()),
            &self.planned,
        )];
        if let Some(scored) = &self.scored {
            panels.push(panel("scored on the model of the evaluated hour", scored));
        }
        panels
    }
}

impl fmt::Display for PsbtEvalReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{} help locations at {} (planning model: tracks before {}; scoring model: the \
             tracks of that hour), {} places, {:.1} s",
            self.comparison.outcomes.len(),
            time(self.time),
            time(self.train_until),
            self.places,
            self.seconds
        )?;
        writeln!(
            f,
            "\np_s,T(t), mean ± std over the starts, on the planning model:"
        )?;
        writeln!(f, "{}", self.table(&self.planned))?;
        if let Some(p) = self.comparison.gain_over_gm_percent(&self.planned) {
            writeln!(
                f,
                "PSBT vs GM at 140 s: {p:+.1} % (the dissertation: +5.7 %)"
            )?;
        }
        self.verdict(f, false)?;
        if let Some(scored) = &self.scored {
            writeln!(
                f,
                "\nthe same plans scored on the model of the evaluated hour:"
            )?;
            writeln!(f, "{}", self.table(scored))?;
            if let Some(p) = self.comparison.gain_over_gm_percent(scored) {
                writeln!(f, "PSBT vs GM at 140 s: {p:+.1} %")?;
            }
            self.verdict(f, true)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn atc(relative: &str) -> PathBuf {
        chronomap_testutil::data_path(relative)
    }

    #[test]
    fn models_and_tracks_are_told_apart_by_magic_word_and_name() {
        let tracks = atc("atc_20121024_1hz/atc-1024-13_train.csv.xz");
        assert!(!is_model_source(std::slice::from_ref(&tracks)).unwrap());
        let tmp = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-psbt-{}", std::process::id())),
        );
        // A name ending in .cmcopa counts as a model, whatever it holds.
        let model = chronomap_testutil::write(&tmp, "m.cmcopa", "t,person,x,y\n");
        assert!(is_model_source(std::slice::from_ref(&model)).unwrap());
        let mixed = is_model_source(&[model, tracks]).unwrap_err();
        assert_eq!(
            mixed.to_string(),
            "--activity: give one CoPA-Map model file or pedestrian track files, not both \
             (1 of 2 files are models)"
        );
        assert_eq!(
            PsbtJobError::ModelTime(1_351_000_000.0).to_string(),
            "--time 2012-10-23 13:46 UTC: outside 09:00-21:00 JST, which the ATC grid's time \
             axis covers (give --model-t)"
        );
        let _ = std::fs::remove_dir_all(&tmp);
    }

    #[test]
    fn a_search_of_two_places_compares_ten_trees() {
        let map = atc("atc_copa_map_grid/atc_map.yaml");
        let activity = [atc("atc_20121024_1hz/atc-1024-13_train.csv.xz")];
        let world = WorldSetup {
            map: &map,
            activity: &activity,
            cell: 1.0,
            interval: 3600.0,
            planning_cell: 0.5,
            clearance: 0.3,
        };
        let mut config = PsbtConfig::default();
        config.places = 2;
        let copa = CopaTime {
            model_t: None,
            model_cell: 0.5,
        };
        // 2012-10-24 13:30 JST.
        let report = synthesis(&world, &config, ([10.0, -3.0], 1_351_053_000.0), 0, copa).unwrap();
        // Each place skipped, searched or searched and waited at (3²), or waiting at the start.
        assert_eq!(report.candidates, 10);
        assert_eq!(report.places.len(), 2);
        assert!((0.0..=1.0).contains(&report.p_success));
        assert_eq!(report.model_t, None);
        let text = report.to_string();
        assert!(
            text.starts_with("person search from (10, -3) at 2012-10-24 04:30 UTC: 10 candidate trees over 2 places in "),
            "{text}"
        );
        assert!(text.ends_with(&report.tree_xml));

        // Intervals of a picosecond: more since time 0 than a float counts exactly (2^53),
        // named by the flag.
        let tracks = load_world(&map, &activity, 0.5, 0.3).unwrap();
        let too_fine = fit_model(&tracks, 1.0, 1e-12, |_| true).err().unwrap();
        let PsbtJobError::Usage(message) = too_fine else {
            panic!("not a usage error: {too_fine}");
        };
        assert_eq!(
            message,
            "--interval 1e-12: the interval 1e-12 gives 1.351051200981e21 intervals since time \
             0; at most 9007199254740992 (over the map and the tracked time)"
        );
    }
}
