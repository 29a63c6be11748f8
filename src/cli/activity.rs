//! Flags of `chronomap activity`.

#[allow(unused_imports)]
use super::*;

pub(super) const ACTIVITY_HELP_EVAL: &str = "\
Examples (the bundled ATC grid of CoPA-Map, 10 days x 12 recorded hours, t = hour-bin index):
  # train on the first 8 days, test on the last 2
  chronomap activity eval \\
      --train data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz --split-at 96
  chronomap activity eval --train TRAIN.csv --test TEST.csv --json
  chronomap activity eval \
      --train data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz --split-at 96 --model copa

Files are CSV with the header x1,x2,t,y (cell centre in metres, time bin, people per hour of
observation), plain, .xz or .gz; see data/README.md. NRMSE is eq. (4.20) of the dissertation
(RMSE over the mean test rate), chi2 the chi-square distance of eq. (4.21). Every baseline is
scored; the top-level nrmse/chi2 are those of --model. `log-additive` (default) is Log-AM:
ln(1 + rate) as a level per cell, a profile of the day and their shrunken interaction, with a
memory of the recent days, predicting the median (under a second; docs/activity.md §6). `copa` is
CoPA-Map, the heteroscedastic sparse variational GP (about a minute with the defaults on 2 cores;
--inducing and --iterations trade time for accuracy; --init spectral starts its periods from
Algorithm 4.1 instead of the day).
`auto` picks the fast model of the least NRMSE on the last 20 % of the training times (never on
the test); CoPA-Map is not part of it. Fr-AAM treats each row as one hour of observation: the grid
files carry rates, not the dwell times behind them.";

/// `chronomap activity ...`.
#[derive(Debug, Subcommand)]
pub enum ActivityCommand {
    /// Fit activity models on training rates and score them on later ones: NRMSE and
    /// chi-square distance of every baseline and of the chosen model.
    #[command(after_help = ACTIVITY_HELP_EVAL)]
    Eval(ActivityEvalArgs),
    /// Build training rates from pedestrian detections as simulated patrol robots see them
    /// (§4.2.2, eqs. 4.5-4.6), or the ground truth of §4.3.2: CSV
    /// x1,x2,t,y,count,duration_s.
    #[command(after_help = ACTIVITY_HELP_EXTRACT)]
    Extract(ActivityExtractArgs),
    /// Ground truth from pedestrian tracks (§4.3.2): distinct people per cell and hour,
    /// counted over whole bins, in the cells of a training grid; writes `x1,x2,t,y`.
    #[command(after_help = ACTIVITY_HELP_TRUTH)]
    Truth(ActivityTruthArgs),
    /// Fit CoPA-Map (default) or Log-AM (--model log-additive) to training rates and save it as
    /// a model file (versioned, checksummed).
    #[command(after_help = ACTIVITY_HELP_FIT)]
    Fit(ActivityFitArgs),
    /// Predict the rate of people (mean and standard deviation) with a saved CoPA-Map or Log-AM
    /// over a grid of cells at chosen times; write CSV and/or a PNG of mean and std per time
    /// (Log-AM's "mean" is its prediction exp(m) − 1, the median).
    #[command(after_help = ACTIVITY_HELP_FIT)]
    Predict(ActivityPredictArgs),
    /// The service-disturbance benchmark (eq. 4.22): patrols planned on each model's predicted
    /// rates, and the people they pass on a test day.
    #[command(after_help = ACTIVITY_HELP_DISTURBANCE)]
    Disturbance(ActivityDisturbanceArgs),
}

pub(super) const ACTIVITY_HELP_FIT: &str = "\
Example (the bundled ATC grid; t is the hour bin, 12 recorded hours a day from 09:00, so t = 123
is 12:00 and t = 129 is 18:00 of the day after the ten training days):
  chronomap activity fit --train data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz \\
      -o atc.cmcopa
  chronomap activity predict --model atc.cmcopa --t 123,129 \\
      --map data/atc_copa_map_grid/atc_map.yaml --plot atc_copa.png -o atc_copa.csv

Times (--t) are in the units of the training t (for the ATC grid the hour-bin index), not wall-clock
times; repeat the flag or separate them by commas.";

/// `chronomap activity fit`.
#[derive(Debug, Args)]
pub struct ActivityFitArgs {
    /// Training rates, CSV `x1,x2,t,y`.
    #[arg(long)]
    pub train: PathBuf,
    /// Where to write the model.
    #[arg(short, long)]
    pub output: PathBuf,
    /// The model to fit: CoPA-Map (copa) or Log-AM (log-additive).
    #[arg(long, value_enum, default_value_t = FitModel::Copa)]
    pub model: FitModel,
    /// Length of a day in units of t (12: the ATC grid's 12 recorded hours).
    #[arg(long, default_value_t = 12.0, value_parser = parse_positive)]
    pub period: f64,
    /// Inducing points (CoPA-Map).
    #[arg(long, default_value_t = 200)]
    pub inducing: usize,
    /// Training iterations (CoPA-Map).
    #[arg(long, default_value_t = 300)]
    pub iterations: usize,
    /// Model the rates themselves or ln(1 + rate) (CoPA-Map).
    #[arg(long, value_enum, default_value_t = CopaScale::Rate)]
    pub scale: CopaScale,
    /// Seed of the minibatches and of the k-means of the inducing points.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `chronomap activity predict`.
#[derive(Debug, Args)]
pub struct ActivityPredictArgs {
    /// A model written by `chronomap activity fit` (CoPA-Map or Log-AM).
    #[arg(long)]
    pub model: PathBuf,
    /// Times to predict, in the units of the training t (numbers, not dates); repeat the flag
    /// or separate them by commas.
    #[arg(
        long = "t",
        required = true,
        value_delimiter = ',',
        num_args = 1..,
        allow_negative_numbers = true
    )]
    pub times: Vec<f64>,
    /// Region `x_min,y_min,x_max,y_max` in metres (default: the model's training square).
    #[arg(
        long,
        value_delimiter = ',',
        num_args = 4,
        allow_negative_numbers = true
    )]
    pub region: Option<Vec<f64>>,
    /// Side of a cell in metres.
    #[arg(long, default_value_t = 0.5, value_parser = parse_positive)]
    pub cell: f64,
    /// A ROS map (YAML) whose occupied cells are left out (drawn as obstacles).
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// Write the predictions as CSV `x1,x2,t,mean,std` here (else they are printed, unless
    /// --plot is given). `--csv` is an old spelling.
    #[arg(short, long, alias = "csv")]
    pub output: Option<PathBuf>,
    /// Draw the predicted mean and standard deviation at every time as a PNG (`--png` is an
    /// old spelling).
    #[arg(long, alias = "png")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object with every prediction.
    #[arg(long)]
    pub json: bool,
}

pub(super) const ACTIVITY_HELP_TRUTH: &str = "\
Example (the bundled ATC day 2012-10-24 as a test day after the ten days of the training grid;
bins 1,2,4..10 are the hours 10:00..20:00 that the tracks cover in full, 12:00 is missing):
  chronomap activity truth --tracks data/atc_20121024_1hz/atc-1024-*_train.csv.xz \\
      --cells data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz \\
      --t0 1351036800 --bins 1,2,4,5,6,7,8,9,10 --t-offset 120 -o atc_20121024_truth.csv
  chronomap activity eval --train data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz \\
      --test atc_20121024_truth.csv --model copa

Tracks are CSV `t,person,x,y,speed,heading` (plain, .xz or .gz). A cell's count is the number of
distinct person ids detected in it during the bin; rates are people per hour (count / bin length
in hours). The output's t is the bin index plus --t-offset.";

/// `chronomap activity truth`.
#[derive(Debug, Args)]
pub struct ActivityTruthArgs {
    /// Pedestrian track files, CSV `t,person,x,y,speed,heading`: several after the flag,
    /// the flag repeated, or separated by commas.
    #[arg(long, num_args = 1.., value_delimiter = ',', required = true)]
    pub tracks: Vec<PathBuf>,
    /// The grid whose cells get a ground truth (CSV `x1,x2,t,y`; its distinct cells are used).
    #[arg(long)]
    pub cells: PathBuf,
    /// Start of bin 0 in the tracks' time: unix seconds or ISO 8601 (2012-10-24T09:00+09:00).
    #[arg(long, value_parser = parse_time)]
    pub t0: f64,
    /// Length of a bin in seconds.
    #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
    pub bin_seconds: f64,
    /// Bin indices to count: comma-separated or the flag repeated.
    #[arg(
        long,
        value_delimiter = ',',
        required = true,
        allow_negative_numbers = true
    )]
    pub bins: Vec<i64>,
    /// Added to the bin index to give the output's t.
    #[arg(long, default_value_t = 0.0)]
    pub t_offset: f64,
    /// Side of a cell in metres (cells are aligned to multiples of it).
    #[arg(long, default_value_t = 0.5, value_parser = parse_positive)]
    pub cell: f64,
    /// Output CSV `x1,x2,t,y`.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub(super) const ACTIVITY_HELP_EXTRACT: &str = "\
Examples (the bundled ATC day, 2012-10-24; bin 0 = 09:00 JST):
  chronomap activity extract --tracks data/atc_20121024_1hz/*.csv.xz \\
      --map data/atc_copa_map_grid/atc_map.yaml --paths data/atc_20121024_1hz/robot_paths.csv \\
      -o atc-1024-train.csv
  chronomap activity eval --train atc-1024-train.csv --split-at 7 --model copa
  # the ground truth of §4.3.2 in the cells the robots saw: every cell, every bin, duration = bin
  chronomap activity extract --tracks data/atc_20121024_1hz/*.csv.xz \\
      --map data/atc_copa_map_grid/atc_map.yaml --paths data/atc_20121024_1hz/robot_paths.csv \\
      --ground-truth -o atc-1024-truth.csv

The robots (all paths of --paths, or those named by --robot) loop along their paths from --t0
on at --speed and observe together. Every --step seconds, a cell (--cell metres, aligned to
multiples of it) is visible when its centre is within --fov metres of a robot and the
Bresenham line to it crosses no occupied map cell. A visible cell adds the step to its observed
duration and counts the detections of that step inside it; y = count / duration in detections
per hour of observation (detections, not distinct people: the bundled tracks are 1 Hz with 90 %
kept). t is the bin index (t0 + t * bin seconds); --t0 defaults to the start of the bin of the
first detection (a multiple of --bin since 1970), --bins to every bin with a detection (an
hour missing from the data is not read as an empty hour). --ground-truth writes, for every bin and every cell the robots saw (or the cells
of --cells-from), the detections in the cell during the whole bin, ignoring the map.";

/// Which model gives the top-level scores of `chronomap activity eval`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ActivityModel {
    /// The baseline of the least NRMSE on a chronological hold-out of the training data
    /// (global mean, ML, ML-log, Fr-AAM or Log-AM; GP-Hom and WHyTe are too slow to be tried).
    Auto,
    /// The mean of all training rates.
    GlobalMean,
    /// The per-cell mean of the training rates (maximum likelihood, §4.3.2).
    Ml,
    /// The per-cell mean of ln(1 + rate), predicting exp(mean) − 1: robust to the huge rates
    /// of briefly observed cells.
    MlLog,
    /// Per-cell FreMEn Poisson-spectral model with a Gamma prior (§4.3.2).
    FrAam,
    /// GP-Hom: a log-Gaussian Cox process, CoPA-Map's kernel with a Poisson likelihood
    /// (§4.3.2); trained with --inducing and --iterations.
    GpHom,
    /// WHyTe (Warped Hypertime, [Krajník 2019]): a Gaussian mixture of people over space and the
    /// circles of the periods found in its error (day/1 .. day/6 of --period), divided by the
    /// same mixture weighted by observation time; periods and components (4, 8, 16, 32)
    /// chosen on a hold-out of the last 20 % of the training times.
    Whyte,
    /// CoPA-Map: the heteroscedastic sparse variational GP of §4.2 (eqs. 4.7–4.16).
    Copa,
    /// Log-AM (default): ln(1 + rate) as a level per cell plus a profile of the day (--period in
    /// 12 phase bins) and their interaction, shrunk by a κ, the days weighed by a memory τ, both
    /// chosen on the last 20 % of the training times; predicts exp(mean) − 1 (docs/activity.md).
    LogAdditive,
}

/// The models `chronomap activity fit` saves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FitModel {
    /// CoPA-Map, the heteroscedastic sparse variational GP of §4.2.
    Copa,
    /// Log-AM: ln(1 + rate) as a level per cell, a profile of the day and their shrunken
    /// interaction.
    LogAdditive,
}

/// The scale CoPA-Map models rates on (`chronomap_activity::RateScale`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CopaScale {
    /// The rates themselves, as §4.2 writes the model.
    Rate,
    /// ln(1 + rate); predictions are the predictive median.
    Log1p,
}

/// `chronomap activity extract`.
#[derive(Debug, Args)]
pub struct ActivityExtractArgs {
    /// Pedestrian track files `t,person,x,y,speed,heading` (plain, .xz or .gz): several
    /// after the flag, the flag repeated, or separated by commas.
    #[arg(long, required = true, num_args = 1.., value_delimiter = ',')]
    pub tracks: Vec<PathBuf>,
    /// ROS map YAML file (map_server / Nav2) of the environment.
    #[arg(long, required_unless_present = "cells_from")]
    pub map: Option<PathBuf>,
    /// Robot path file, CSV `path,x,y,stop_s`.
    #[arg(long, visible_alias = "path", required_unless_present = "cells_from")]
    pub paths: Option<PathBuf>,
    /// Only the paths of these names (repeat the flag or separate them by commas; default
    /// all).
    #[arg(long = "robot", value_name = "NAME", value_delimiter = ',')]
    pub robots: Vec<String>,
    /// Robot speed, m/s.
    #[arg(long, default_value_t = 0.5, value_parser = parse_positive)]
    pub speed: f64,
    /// Field-of-view radius, metres.
    #[arg(long, default_value_t = 3.5, value_parser = parse_positive)]
    pub fov: f64,
    /// Cell side, metres.
    #[arg(long, default_value_t = 0.5, value_parser = parse_positive)]
    pub cell: f64,
    /// Time-bin length, seconds.
    #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
    pub bin: f64,
    /// Simulation step, seconds (the bin length must be a whole multiple of it).
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    pub step: f64,
    /// Start of bin 0 and of the robots' loops: unix seconds or ISO 8601
    /// (2012-10-24T09:00+09:00).
    #[arg(long, value_parser = parse_time)]
    pub t0: Option<f64>,
    /// Bins to extract (indices from --t0, comma-separated or the flag repeated; default:
    /// every bin with a detection).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true)]
    pub bins: Vec<i64>,
    /// Map cells with at least this occupancy (percent) block sight.
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(i8).range(0..=100))]
    pub min_occupancy: i8,
    /// Write the ground truth of §4.3.2 instead (duration = bin, map ignored).
    #[arg(long)]
    pub ground_truth: bool,
    /// With --ground-truth: the cells of this rate file (x1,x2 of its rows) instead of the
    /// cells the robots saw.
    #[arg(long, requires = "ground_truth", value_name = "FILE")]
    pub cells_from: Option<PathBuf>,
    /// Rate written where nobody was seen (the bundled ATC grid writes 1e-6).
    #[arg(long, default_value_t = 0.0, value_parser = parse_non_negative)]
    pub zero_rate: f64,
    /// Output CSV x1,x2,t,y,count,duration_s.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print the summary as one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Where CoPA-Map's periods start (`chronomap activity eval --init`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum CopaInit {
    /// The day (`--period`) and its first harmonic.
    Day,
    /// Algorithm 4.1 ([Stüde 2024] §4.2.4): periods and variances from a NUDFT of sampled regions.
    Spectral,
}

/// `chronomap activity eval`.
#[derive(Debug, Args)]
pub struct ActivityEvalArgs {
    /// Training rates, CSV `x1,x2,t,y`.
    #[arg(long)]
    pub train: PathBuf,
    /// Test rates, CSV `x1,x2,t,y` (later than the training data).
    #[arg(
        long,
        conflicts_with = "split_at",
        required_unless_present = "split_at"
    )]
    pub test: Option<PathBuf>,
    /// Split --train chronologically instead: train on t < T, test on t >= T.
    #[arg(long, value_name = "T")]
    pub split_at: Option<f64>,
    /// The model of the top-level scores (default: Log-AM; every baseline is scored too).
    #[arg(long, value_enum, default_value_t = ActivityModel::LogAdditive)]
    pub model: ActivityModel,
    /// Fr-AAM and WHyTe: the base period in units of t (12: a day of the ATC grid's 12 recorded
    /// hours); candidate periods are period/1 .. period/6.
    #[arg(long, default_value_t = 12.0, value_parser = parse_positive)]
    pub period: f64,
    /// CoPA-Map and GP-Hom: inducing points.
    #[arg(long, default_value_t = 200)]
    pub inducing: usize,
    /// CoPA-Map and GP-Hom: training iterations.
    #[arg(long, default_value_t = 300)]
    pub iterations: usize,
    /// CoPA-Map: model the rates themselves (rate, as §4.2 does) or ln(1 + rate), predicting
    /// the median (log1p: follows typical activity rather than the spikes of brief glimpses).
    #[arg(long, value_enum, default_value_t = CopaScale::Rate)]
    pub scale: CopaScale,
    /// CoPA-Map: initial periods: the day and its first harmonic (`day`), or Algorithm 4.1's
    /// spectra of sampled 5 m regions (`spectral`; NRMSE 2.050 vs 2.028 on the ATC split).
    #[arg(long, value_enum, default_value_t = CopaInit::Day)]
    pub init: CopaInit,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Draw the calibration of the model's predictive intervals as a PNG: the share of test
    /// rates inside its intervals of whole hours and of one observation against their nominal
    /// coverage (10 % … 99 %), and their mean width (Log-AM and CoPA-Map; other models have
    /// none).
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
}

pub(super) const ACTIVITY_HELP_DISTURBANCE: &str = "\
Example (the bundled ATC grid for training, the bundled day 2012-10-24 for testing):
  chronomap activity disturbance \\
      --train data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz \\
      --tracks data/atc_20121024_1hz/atc-1024-*_train.csv.xz \\
      --map data/atc_copa_map_grid/atc_map.yaml \\
      --scenarios data/atc_20121024_1hz/disturbance_scenarios.csv --plot disturbance.png

Each scenario is a patrol A -> B -> C -> D (a CSV `scenario,waypoint,x,y`, see data/README.md),
started every 15 minutes of the test day whose whole slot lies in the tracked time. Paths are
planned by Dijkstra on the 8-connected 0.5 m cells of the training grid that are free on the map
(--clearance from obstacles); a cell costs its length times (predicted rate + --epsilon), the
`occupancy` baseline its length alone (the shortest route). Encounters are the person detections
within 1 m of the robot driving at 0.5 m/s; E(rho) of eq. (4.22) sums those of the cheapest
floor(n_nav rho) patrols (ties: the earlier first). Models: occupancy, global_mean, ml, ml_log,
fr_aam, gp_hom, whyte (WHyTe, about 5 s) and copa (CoPA-Map; about a minute with the defaults on
2 cores).";

/// `chronomap activity disturbance`.
#[derive(Debug, Args)]
pub struct ActivityDisturbanceArgs {
    /// Training rates, CSV `x1,x2,t,y` (the planning cells are its cells).
    #[arg(long)]
    pub train: PathBuf,
    /// Pedestrian track files of the test day (`t,person,x,y,speed,heading`): several after
    /// the flag, the flag repeated, or separated by commas.
    #[arg(long, num_args = 1.., value_delimiter = ',', required = true)]
    pub tracks: Vec<PathBuf>,
    /// ROS map YAML of the environment.
    #[arg(long)]
    pub map: PathBuf,
    /// Scenario file, CSV `scenario,waypoint,x,y`.
    #[arg(long)]
    pub scenarios: PathBuf,
    /// The scenario to run (a name in --scenarios), or `all`.
    #[arg(long, default_value = "all")]
    pub scenario: String,
    /// Start of the test day's first hour bin: unix seconds or ISO 8601
    /// (2012-10-24T09:00+09:00; UTC unless an offset is given). Default: the hour of the first
    /// detection.
    #[arg(long, value_parser = parse_time)]
    pub day_start: Option<f64>,
    /// The model time t of that first hour bin, in the units of the training t (default: the
    /// first whole day after the training data, a multiple of --period).
    #[arg(long, allow_negative_numbers = true)]
    pub t0: Option<f64>,
    /// Hour bins per day in the training grid (12 for the ATC grid, 09:00 to 21:00).
    #[arg(long, default_value_t = 12.0, value_parser = parse_positive)]
    pub period: f64,
    /// The robot keeps this many metres from obstacles at every cell centre.
    #[arg(long, default_value_t = 0.3, value_parser = parse_non_negative)]
    pub clearance: f64,
    /// Added to every predicted rate (people per hour) in the path cost.
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    pub epsilon: f64,
    /// CoPA-Map: inducing points.
    #[arg(long, default_value_t = 200)]
    pub inducing: usize,
    /// CoPA-Map: training iterations.
    #[arg(long, default_value_t = 300)]
    pub iterations: usize,
    /// Leave the two Gaussian-process models out, CoPA-Map and GP-Hom (the others take
    /// seconds).
    #[arg(long)]
    pub no_copa: bool,
    /// Write E(rho) per model, one panel per scenario, to this PNG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the map, CoPA-Map's (or --no-copa: ML's) cost map at the busiest hour and every
    /// model's path then, one panel per scenario, to this PNG.
    #[arg(long)]
    pub plot_paths: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

// ---------------------------------------------------------------------------------------------
// Behavior trees: `chronomap bt`
