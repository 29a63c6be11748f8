//! Flags of the temporal-model commands (`demo`, `eval`, `fit`, `predict`, `inspect`, `anomalies`, `compress`).

#[allow(unused_imports)]
use super::*;

pub(super) const EVAL_HELP: &str = "\
Models: mean, hist:N[:PERIOD], fremen:K, fremen:auto, persistence[:K|auto], stm,
pergam:K[:PERIOD], pergam:auto, fft:L|auto (uniform binary data), hyt-em:K|auto, hyt-km
(Warped Hypertime), auto.

Example:
  chronomap eval --train data/door_greg_2016/training_data.txt.xz \\
    --test data/door_greg_2016/test_times_1.txt.xz,data/door_greg_2016/test_data_1.txt.xz \\
    --test data/door_greg_2016/test_times_2.txt.xz,data/door_greg_2016/test_data_2.txt.xz \\
    --models mean,hist:24,fremen:2,fremen:4,fremen:auto,pergam:2,stm,auto --json
  # One file split in time: train before the first time, test between the times and after
  chronomap eval --train data/witham_topological_nav/labdoor_velocity/training_data.txt.xz \
    --split-at 2014-08-20,2014-08-27 --models mean,hist:24,fremen:auto,hyt-em:auto,hyt-km";

pub(super) const COMPRESS_HELP: &str = "\
Example (the door week of the FreMEn paper, 604,800 one-second samples):
  chronomap compress --series data/door_tom_2013/sec/test_times_0.txt.xz,data/door_tom_2013/sec/test_data_0.txt.xz \\
    --order auto --test data/door_tom_2013/sec/test_times_1.txt.xz,data/door_tom_2013/sec/test_data_1.txt.xz -o door.cmm";

/// `chronomap demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Folder the plots are written to.
    #[arg(long, default_value = "chronomap-demo")]
    pub out: PathBuf,
    /// Skip writing plots.
    #[arg(long)]
    pub no_plots: bool,
}

/// `chronomap eval`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Training data: `t value` lines.
    #[arg(long)]
    pub train: PathBuf,
    /// A test set as TIMES,VALUES (two line-aligned files); repeat for more test sets.
    #[arg(long = "test", value_parser = parse_file_pair, required_unless_present = "split_at")]
    pub tests: Vec<(PathBuf, PathBuf)>,
    /// Instead of --test: split the training file at these times (seconds or ISO 8601,
    /// increasing): train on what comes before the first, test on each following interval.
    #[arg(long, value_delimiter = ',', value_parser = parse_time, conflicts_with = "tests")]
    pub split_at: Vec<f64>,
    /// Comma-separated models to evaluate.
    #[arg(long, value_parser = parse_models, default_value = "mean,hist:24,fremen:2,fremen:4,fremen:auto,pergam:2,stm,auto")]
    pub models: ModelList,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Significance level of the paired t-tests.
    #[arg(long, default_value_t = 0.05, value_parser = parse_fraction)]
    pub alpha: f64,
    /// Fitting options.
    #[command(flatten)]
    pub fit: FitFlags,
}

/// `chronomap fit`.
#[derive(Debug, Args)]
pub struct FitArgs {
    /// Training data: `t value` lines.
    #[arg(long)]
    pub train: PathBuf,
    /// The model, e.g. fremen:4, fremen:auto, hist:24, auto.
    #[arg(long, value_parser = parse_model)]
    pub model: ModelSpec,
    /// Model file to write.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Fitting options.
    #[command(flatten)]
    pub fit: FitFlags,
}

/// `chronomap predict`.
#[derive(Debug, Args)]
pub struct PredictArgs {
    /// Model file written by `chronomap fit` or `chronomap compress`.
    pub model: PathBuf,
    /// Times to predict, one per line.
    #[arg(long, conflicts_with = "at", required_unless_present = "at")]
    pub times: Option<PathBuf>,
    /// Times to predict (seconds).
    #[arg(long, num_args = 1.., value_parser = parse_time)]
    pub at: Vec<f64>,
    /// Use this order instead of the stored one (FreMEn-family models).
    #[arg(long)]
    pub order: Option<usize>,
}

/// `chronomap inspect`.
#[derive(Debug, Args)]
pub struct InspectArgs {
    /// Model file.
    pub model: PathBuf,
    /// Print the whole spectrum, not only the components in use.
    #[arg(long)]
    pub spectrum: bool,
}

/// `chronomap anomalies`.
#[derive(Debug, Args)]
pub struct AnomaliesArgs {
    /// Model file.
    pub model: PathBuf,
    /// Observations as TIMES,VALUES (two line-aligned files) or one `t value` file.
    #[arg(long, value_parser = parse_series_source)]
    pub test: SeriesSource,
    /// Confidence level c in [0.5, 1]: anomalous if observed 0 while p >= c, or 1 while
    /// p < 1 - c.
    #[arg(long, default_value_t = 0.99)]
    pub confidence: f64,
}

/// `chronomap compress`.
#[derive(Debug, Args)]
pub struct CompressArgs {
    /// The series: TIMES,VALUES (two line-aligned files) or one `t value` file; uniformly
    /// sampled 0/1 values.
    #[arg(long, value_parser = parse_series_source)]
    pub series: SeriesSource,
    /// Number of spectral components, or `auto` (chosen by prediction error on the last 25 %).
    #[arg(long, default_value = "auto")]
    pub order: String,
    /// Shortest period considered, in seconds (`none`: the whole spectrum up to Nyquist).
    #[arg(long, default_value = "7200")]
    pub shortest_period: String,
    /// Measurements that follow the series (same sampling), added by eq. (8) to measure the
    /// prediction error.
    #[arg(long, value_parser = parse_series_source)]
    pub test: Option<SeriesSource>,
    /// Write the model file here.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}
