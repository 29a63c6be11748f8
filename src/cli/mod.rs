//! Command-line flags. Only parsing and validation of single flags happen here; the commands
//! turn them into models and readers.

use std::path::PathBuf;

use chronomap_core::PeriodSet;
use chronomap_core::select::Criterion;
use chronomap_models::spec::{FitOptions, ModelSpec};
use chronomap_models::stack::MAX_RECENT_DAYS;
use clap::{Args, Parser, Subcommand, ValueEnum};

mod activity;
mod bench;
mod bt;
mod events;
mod explore;
#[cfg(feature = "serve")]
mod export;
mod grid;
mod ingest;
mod lidar;
mod model;
mod psbt;
#[cfg(feature = "ros2")]
mod ros2;
#[cfg(feature = "serve")]
mod serve;
mod topo;

pub use activity::*;
pub use bench::*;
pub use bt::*;
pub use events::*;
pub use explore::*;
#[cfg(feature = "serve")]
pub use export::*;
pub use grid::*;
pub use ingest::*;
pub use lidar::*;
pub use model::*;
pub use psbt::*;
#[cfg(feature = "ros2")]
pub use ros2::*;
#[cfg(feature = "serve")]
pub use serve::*;
pub use topo::*;

const AFTER_HELP: &str = "\
Examples:
  chronomap demo                       # evaluate and plot on the bundled door datasets
  chronomap eval --train data/door_greg_2016/training_data.txt.xz \\
      --test data/door_greg_2016/test_times_1.txt.xz,data/door_greg_2016/test_data_1.txt.xz \\
      --models mean,fremen:2,fremen:auto,auto
  chronomap fit --train training_data.txt --model fremen:auto -o door.cmm
  chronomap predict door.cmm --at 1458561600 1458565200
  chronomap inspect door.cmm

Data files: `t value` lines (training) or one number per line (test times, test values);
plain, .xz or .gz. Times are seconds (unix time or relative), values in [0, 1].";

/// World models that know time: learn how states change with daily and weekly rhythms from
/// sparse, irregular observations, and predict them.
#[derive(Debug, Parser)]
#[command(name = "chronomap", version, about, after_help = AFTER_HELP)]
pub struct Cli {
    /// Show no progress bars (they are also hidden when stderr is not a terminal).
    #[arg(long, short, global = true)]
    pub quiet: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Evaluate models on the bundled real door data and write plots (the main job).
    #[command(after_help = DEMO_HELP)]
    Demo(DemoArgs),
    /// Train models on a training file and score them on test sets (Brier score, binary
    /// error, paired t-tests).
    #[command(after_help = EVAL_HELP)]
    Eval(EvalArgs),
    /// Train one model and save it to a model file.
    #[command(after_help = FIT_HELP)]
    Fit(FitArgs),
    /// Predict with a saved model: probability and entropy at given times.
    #[command(after_help = PREDICT_HELP)]
    Predict(PredictArgs),
    /// Show what a saved model contains.
    #[command(after_help = INSPECT_HELP)]
    Inspect(InspectArgs),
    /// List observations that a saved model finds anomalous at a confidence level
    /// (FreMEn paper §V).
    #[command(after_help = ANOMALIES_HELP)]
    Anomalies(AnomaliesArgs),
    /// Compress a uniformly sampled binary series with FFT FreMEn and its outlier set
    /// (lossless), and report errors and compression ratios (FreMEn paper §III-B, §IV).
    #[command(after_help = COMPRESS_HELP)]
    Compress(CompressArgs),
    /// Learn from a ROS 2 bag (rosbag2, MCAP): list its topics, or turn one into a model
    /// (door states), a grid (occupancy maps), events (people), scans or poses.
    #[command(after_help = INGEST_HELP)]
    Ingest(IngestArgs),
    /// Spatio-temporal occupancy grids: build from frames, predict maps Nav2 can load.
    #[command(subcommand)]
    Grid(GridCommand),
    /// Benchmarks at paper scale, timed against a baseline in the same run.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Lifelong spatio-temporal exploration ([Santos 2017]): every strategy with every temporal
    /// model on a real dataset, beside the paper's table.
    #[command(after_help = EXPLORE_HELP)]
    Explore(ExploreArgs),
    /// Topological maps whose edges know time: fit, evaluate and inspect the models of
    /// navigation success and duration ([Fentanes 2015]).
    #[command(subcommand)]
    Topo(TopoCommand),
    /// Now or later? Plan a co-safe LTL task on a topological map for a time, or for every
    /// hour of a week ([Fentanes 2015] §V, Table III).
    #[command(after_help = PLAN_HELP)]
    Plan(PlanArgs),
    /// Events in space and time (people detected by a robot): score models of how many
    /// happen in each cell and time bin ([Krajník 2019] §V-D).
    #[command(subcommand)]
    Events(EventsCommand),
    /// Maps of human activity over space and time (CoPA-Map, dissertation chapter 4): score
    /// models of the rate of people per cell and hour against the baselines of §4.3.2.
    #[command(subcommand)]
    Activity(ActivityCommand),
    /// Person search behavior tree (dissertation §5.4): synthesise the stochastic behavior tree
    /// of searching and waiting most likely to find a helper, from pedestrian tracks; `eval`
    /// compares it with the baselines of §5.4.4 (Fig. 5.11).
    #[command(
        after_help = PSBT_HELP,
        args_conflicts_with_subcommands = true,
        subcommand_negates_reqs = true
    )]
    Psbt(PsbtArgs),
    /// Loop closure from laser scans (dissertation §3.2): scan descriptors, the AdaBoost loop
    /// classifier, loop detection along a log, registration of clouds.
    #[command(subcommand, after_help = LIDAR_HELP)]
    Lidar(LidarCommand),
    /// Modular multi-map management (dissertation §3.3): one map per room, linked at doors.
    #[command(subcommand, after_help = MAPS_HELP)]
    Maps(MapsCommand),
    /// Warped Hypertime for 2-D events ([Krajník 2019]): fit the intensity of detections over space
    /// and time, print the periodicities found, draw the predicted density at chosen times.
    #[command(after_help = HYPERTIME_HELP)]
    Hypertime(HypertimeArgs),
    /// Which features will be visible? Pick the n most likely at every test slot and count the
    /// visible ones ([Krajník 2017] §VII Table I, [Krajník 2019] §V-B).
    #[command(after_help = FEATURES_HELP)]
    Features(FeaturesArgs),
    /// Run the world-model service: an HTTP/JSON API over durable models (add observations,
    /// predict, forecast), with an OpenAPI description at /openapi.json.
    #[cfg(feature = "serve")]
    #[command(after_help = SERVE_HELP)]
    Serve(ServeArgs),
    /// Talk to a running service: add observations, predict, forecast, view, list, remove.
    #[cfg(feature = "serve")]
    Client(ClientArgs),
    /// Export a service store's history for analysis: observations and predictions of every
    /// model as Apache Parquet.
    #[cfg(feature = "serve")]
    #[command(subcommand)]
    Export(ExportCommand),
    /// Run as a ROS 2 node: learn states, maps and people from topics online, publish
    /// predicted maps, Nav2 costmap-filter masks and predictions; rewrite a Nav2 route graph.
    #[cfg(feature = "ros2")]
    #[command(after_help = ROS2_HELP)]
    Ros2(Ros2Args),
    /// Behavior trees in BehaviorTree.CPP 4 XML: check a file, or tick a tree whose leaves
    /// follow a script ([Stüde 2024] §5.2-5.3).
    #[command(subcommand)]
    Bt(BtCommand),
    /// System monitoring of [Stüde 2024] §5.3: a fault-injection simulation of monitors feeding a
    /// behavior-tree arbiter that blocks the patrol and runs the recoveries of Table 5.1.
    #[command(subcommand)]
    Monitor(MonitorCommand),
}

/// Options shared by commands that fit models.
#[derive(Debug, Args)]
pub struct FitFlags {
    /// Candidate periods of FreMEn models: week (604800/84: one week to 2 h), day, year,
    /// BASE/COUNT (BASE/k for k = 1..COUNT) or a comma list of seconds.
    #[arg(long, default_value = "week", value_parser = parse_periods)]
    pub periods: PeriodSet,
    /// Most recent fraction of the training time span held back to choose orders (`fremen:auto`,
    /// `pergam:auto`, ...; `auto` scores its candidates from six rolling origins instead).
    #[arg(long, default_value_t = 0.25, value_parser = parse_fraction)]
    pub holdout: f64,
    /// Largest FreMEn order that `fremen:auto` tries and `auto` combines.
    #[arg(long, default_value_t = 10)]
    pub max_order: usize,
    /// Error measure used to choose orders and models on held-back data.
    #[arg(long, value_enum, default_value_t = CriterionArg::Brier)]
    pub criterion: CriterionArg,
    /// Memories in days of `auto`'s drift candidates: for each, the mean and histograms of the
    /// last that many days only (comma-separated, 1 to 3650 each; `none` for none).
    #[arg(long, default_value = "7,14,28,56", value_parser = parse_recent_days)]
    pub recent_days: RecentDays,
}

/// `--recent-days`: memories in days (possibly none).
#[derive(Debug, Clone)]
pub struct RecentDays(pub Vec<usize>);

fn parse_recent_days(text: &str) -> Result<RecentDays, String> {
    if text.trim() == "none" {
        return Ok(RecentDays(Vec::new()));
    }
    text.split(',')
        .map(|d| match d.trim().parse::<usize>() {
            Ok(days) if (1..=MAX_RECENT_DAYS).contains(&days) => Ok(days),
            _ => Err(format!(
                "{:?} is not a whole number of days from 1 to {MAX_RECENT_DAYS} (or `none`)",
                d.trim()
            )),
        })
        .collect::<Result<Vec<_>, _>>()
        .map(RecentDays)
}

impl FitFlags {
    /// The core options these flags describe.
    pub fn options(&self) -> FitOptions {
        FitOptions {
            periods: self.periods.clone(),
            holdout: self.holdout,
            max_order: self.max_order,
            criterion: self.criterion.into(),
            recent_days: self.recent_days.0.clone(),
            parallelism: chronomap_core::Parallelism::Rayon(0),
            ..FitOptions::default()
        }
    }
}

/// `--criterion` values.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum CriterionArg {
    /// Mean squared error of the probability.
    Brier,
    /// Mean absolute error.
    Absolute,
    /// Fraction of wrongly predicted binary states.
    Binary,
}

impl From<CriterionArg> for Criterion {
    fn from(c: CriterionArg) -> Criterion {
        match c {
            CriterionArg::Brier => Criterion::Brier,
            CriterionArg::Absolute => Criterion::AbsoluteError,
            CriterionArg::Binary => Criterion::BinaryError,
        }
    }
}

/// A parsed `--models` list (a newtype so that clap treats it as one value).
#[derive(Debug, Clone)]
pub struct ModelList(pub Vec<ModelSpec>);

/// Where a series comes from.
#[derive(Debug, Clone)]
pub enum SeriesSource {
    /// One `t value` file.
    Pairs(PathBuf),
    /// Two line-aligned files: times, values.
    Split(PathBuf, PathBuf),
}

fn parse_periods(text: &str) -> Result<PeriodSet, String> {
    text.parse()
        .map_err(|e: chronomap_core::ConfigError| e.to_string())
}

fn parse_model(text: &str) -> Result<ModelSpec, String> {
    text.parse()
        .map_err(|e: chronomap_core::ConfigError| e.to_string())
}

fn parse_models(text: &str) -> Result<ModelList, String> {
    chronomap_models::spec::parse_model_list(text)
        .map(ModelList)
        .map_err(|e| e.to_string())
}

fn parse_probability(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(p) if (0.0..=1.0).contains(&p) => Ok(p),
        _ => Err(format!("{text:?} is not a probability in [0, 1]")),
    }
}

/// A coverage of a central interval: strictly between 0 and 1.
fn parse_open_probability(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(p) if p > 0.0 && p < 1.0 => Ok(p),
        _ => Err(format!("{text:?} is not a number strictly between 0 and 1")),
    }
}

fn parse_non_negative(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        _ => Err(format!("{text:?} is not a finite number >= 0")),
    }
}

fn parse_positive(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(x) if x.is_finite() && x > 0.0 => Ok(x),
        _ => Err(format!("{text:?} is not a finite number > 0")),
    }
}

/// `--order` of `compress` and `grid build`: a number, or `auto`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrderArg {
    /// This order (`compress`: this many spectral components; `grid build`: every cell).
    Fixed(usize),
    /// Chosen on held-back data (`compress`: by prediction error on the last 25 %, eq. 15;
    /// `grid build`: per cell on the held-back frames).
    Auto,
}

/// `auto`, or a whole number `k` (`Fixed(k)`).
fn parse_order(text: &str) -> Result<OrderArg, String> {
    match text {
        "auto" => Ok(OrderArg::Auto),
        k => k
            .parse()
            .map(OrderArg::Fixed)
            .map_err(|_| format!("{k:?} is not a whole number or 'auto'")),
    }
}

fn parse_fraction(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(f) if f > 0.0 && f < 1.0 => Ok(f),
        _ => Err(format!("{text:?} is not a number strictly between 0 and 1")),
    }
}

/// A time in seconds (unix or relative) or an ISO 8601 date-time (UTC unless it has an offset).
fn parse_time(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(t) if t.is_finite() => Ok(t),
        Ok(_) => Err(format!("{text:?} is not a finite time")),
        Err(_) if text.contains('-') => crate::format::parse_iso8601(text),
        Err(_) => Err(format!(
            "{text:?} is not a time in seconds nor an ISO 8601 date-time (2014-07-21T09:30Z)"
        )),
    }
}

fn parse_file_pair(text: &str) -> Result<(PathBuf, PathBuf), String> {
    match text.split_once(',') {
        Some((a, b)) if !a.is_empty() && !b.is_empty() && !b.contains(',') => {
            Ok((PathBuf::from(a), PathBuf::from(b)))
        }
        _ => Err(format!(
            "{text:?} is not TIMES,VALUES (two file names separated by one comma)"
        )),
    }
}

fn parse_series_source(text: &str) -> Result<SeriesSource, String> {
    if text.contains(',') {
        parse_file_pair(text).map(|(a, b)| SeriesSource::Split(a, b))
    } else if text.is_empty() {
        Err("empty file name".into())
    } else {
        Ok(SeriesSource::Pairs(PathBuf::from(text)))
    }
}
