//! Flags of the temporal-model commands (`demo`, `eval`, `fit`, `predict`, `inspect`, `anomalies`, `compress`).

#[allow(unused_imports)]
use super::*;

pub(super) const EVAL_HELP: &str = "\
Models: mean, hist:N[:PERIOD], recent:N[:PERIOD[:CYCLES]], fremen:K, fremen:auto,
persistence[:K|auto], stm, pergam:K[:PERIOD], pergam:auto, fft:L|auto (uniform binary data),
hyt-em:K|auto, hyt-km (Warped Hypertime), auto.

Example:
  chronomap eval --train data/door_greg_2016/training_data.txt.xz \\
    --test data/door_greg_2016/test_times_1.txt.xz,data/door_greg_2016/test_data_1.txt.xz \\
    --test data/door_greg_2016/test_times_2.txt.xz,data/door_greg_2016/test_data_2.txt.xz \\
    --models mean,hist:24,fremen:2,fremen:4,fremen:auto,pergam:2,stm,auto --json
  # Calibration: the reliability diagram, and the bank holidays predicted as Sundays
  chronomap eval --train data/door_greg_2016/training_data.txt.xz \\
    --test data/door_greg_2016/test_times_1.txt.xz,data/door_greg_2016/test_data_1.txt.xz \\
    --models fremen:4,auto --plot reliability.png --days-off data/calendars/england_wales_2016.txt
  # One file split in time: train before the first time, test between the times and after
  chronomap eval --train data/witham_topological_nav/labdoor_velocity/training_data.txt.xz \
    --split-at 2014-08-20,2014-08-27 --models mean,hist:24,fremen:auto,hyt-em:auto,hyt-km";

pub(super) const COMPRESS_HELP: &str = "\
Example (the door week of the FreMEn paper, 604,800 one-second samples):
  chronomap compress --series data/door_tom_2013/sec/test_times_0.txt.xz,data/door_tom_2013/sec/test_data_0.txt.xz \\
    --order auto --test data/door_tom_2013/sec/test_times_1.txt.xz,data/door_tom_2013/sec/test_data_1.txt.xz -o door.cmm
  chronomap compress --series week.txt --order 5 --json";

pub(super) const DEMO_HELP: &str = "\
Example:
  chronomap demo -o chronomap-demo     # tables on stdout, plots and Nav2 maps in chronomap-demo/
  chronomap demo --no-plots";

pub(super) const FIT_HELP: &str = "\
Examples:
  chronomap fit --train data/door_greg_2016/training_data.txt.xz --model fremen:auto -o door.cmm
  chronomap fit --train training_data.txt --model auto -o door.cmm --json";

pub(super) const PREDICT_HELP: &str = "\
Times are unix seconds (or seconds from the start of relative data) or ISO 8601 date-times such
as 2016-03-21T13:00:00Z (UTC unless an offset is given: 2016-03-21T14:00+01:00).

Examples:
  chronomap predict door.cmm --at 1458561600,1458565200
  chronomap predict door.cmm --at 2016-03-21T13:00:00Z --at 2016-03-21T14:00:00Z --json
  chronomap predict door.cmm --times test_times_1.txt";

pub(super) const INSPECT_HELP: &str = "\
Examples:
  chronomap inspect door.cmm
  chronomap inspect door.cmm --spectrum --json";

pub(super) const ANOMALIES_HELP: &str = "\
Example:
  chronomap anomalies door.cmm --test test_times_1.txt,test_data_1.txt --confidence 0.99 --json";

/// `chronomap demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Folder the plots and predicted maps are written to.
    #[arg(short, long, alias = "out", default_value = "chronomap-demo")]
    pub output: PathBuf,
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
    /// A test set as TIMES,VALUES (two line-aligned files); repeat the flag for more test sets.
    #[arg(long = "test", value_parser = parse_file_pair, required_unless_present = "split_at")]
    pub tests: Vec<(PathBuf, PathBuf)>,
    /// Instead of --test: split the training file at these times (increasing; unix seconds or
    /// ISO 8601 such as 2014-08-20T00:00Z, UTC unless an offset is given; comma-separated or
    /// repeated): train on what comes before the first, test on each following interval.
    #[arg(long, value_delimiter = ',', value_parser = parse_time, conflicts_with = "tests")]
    pub split_at: Vec<f64>,
    /// Models to evaluate (comma-separated or repeated).
    #[arg(long, value_parser = parse_models, default_value = "mean,hist:24,fremen:2,fremen:4,fremen:auto,pergam:2,stm,auto")]
    pub models: Vec<ModelList>,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
    /// Significance level of the paired t-tests.
    #[arg(long, default_value_t = 0.05, value_parser = parse_fraction)]
    pub alpha: f64,
    /// Draw the reliability diagram of every model over all test sets (PNG).
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// A calendar of days off (one YYYY-MM-DD per line, UTC dates, optionally a name): training
    /// observations on them are left out, test times on them are predicted as the Sunday before.
    #[arg(long, value_name = "FILE")]
    pub days_off: Option<PathBuf>,
    /// Fitting options.
    #[command(flatten)]
    pub fit: FitFlags,
}

/// The models of repeated `--models` lists, in order.
pub fn model_specs(lists: &[ModelList]) -> Vec<ModelSpec> {
    lists.iter().flat_map(|l| l.0.iter().cloned()).collect()
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
    /// Print one JSON object (the model fitted, how it was chosen, the file written).
    #[arg(long)]
    pub json: bool,
    /// A calendar of days off (one YYYY-MM-DD per line, UTC dates, optionally a name): the
    /// model is fitted on the working days and saved with the calendar, so that whoever opens
    /// the file (`predict`, Python's `load`) predicts a day off as the Sunday before.
    #[arg(long, value_name = "FILE")]
    pub days_off: Option<PathBuf>,
    /// Fitting options.
    #[command(flatten)]
    pub fit: FitFlags,
}

/// `chronomap predict`.
#[derive(Debug, Args)]
pub struct PredictArgs {
    /// Model file written by `chronomap fit` or `chronomap compress`.
    pub model: PathBuf,
    /// Times to predict, one per line (seconds).
    #[arg(long, conflicts_with = "at", required_unless_present = "at")]
    pub times: Option<PathBuf>,
    /// Times to predict: unix seconds or ISO 8601 (2016-03-21T13:00:00Z; UTC unless an offset
    /// is given); comma-separated, space-separated or repeated.
    #[arg(long, num_args = 1.., value_delimiter = ',', action = clap::ArgAction::Append, value_parser = parse_time)]
    pub at: Vec<f64>,
    /// Use this order instead of the stored one (FreMEn-family models).
    #[arg(long)]
    pub order: Option<usize>,
    /// A calendar of days off (one YYYY-MM-DD per line, UTC dates): times on them are
    /// predicted as the same time on the Sunday before.
    #[arg(long, value_name = "FILE")]
    pub days_off: Option<PathBuf>,
    /// Print one JSON object: {"model", "predictions": [{"time", "p", "entropy_bits"}]}.
    #[arg(long)]
    pub json: bool,
}

/// `chronomap inspect`.
#[derive(Debug, Args)]
pub struct InspectArgs {
    /// Model file.
    pub model: PathBuf,
    /// Print the whole spectrum, not only the components in use.
    #[arg(long)]
    pub spectrum: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
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
    #[arg(long, default_value_t = 0.99, value_parser = parse_confidence)]
    pub confidence: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

fn parse_confidence(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(c) if (0.5..=1.0).contains(&c) => Ok(c),
        _ => Err(format!("{text:?} is not a confidence level in [0.5, 1]")),
    }
}

/// `chronomap compress --shortest-period`: seconds, or `none` (the whole spectrum).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShortestPeriod(pub Option<f64>);

fn parse_shortest_period(text: &str) -> Result<ShortestPeriod, String> {
    match text {
        "none" => Ok(ShortestPeriod(None)),
        p => match p.parse::<f64>() {
            Ok(p) if p.is_finite() && p > 0.0 => Ok(ShortestPeriod(Some(p))),
            _ => Err(format!(
                "{p:?} is not a positive number of seconds or 'none'"
            )),
        },
    }
}

/// `chronomap compress`.
#[derive(Debug, Args)]
pub struct CompressArgs {
    /// The series: TIMES,VALUES (two line-aligned files) or one `t value` file; uniformly
    /// sampled 0/1 values.
    #[arg(long, value_parser = parse_series_source)]
    pub series: SeriesSource,
    /// Number of spectral components, or `auto` (chosen by prediction error on the last 25 %).
    #[arg(long, default_value = "auto", value_parser = parse_order)]
    pub order: OrderArg,
    /// Shortest period considered, in seconds (`none`: the whole spectrum up to Nyquist).
    #[arg(long, default_value = "7200", value_parser = parse_shortest_period)]
    pub shortest_period: ShortestPeriod,
    /// Measurements that follow the series (same sampling), added by eq. (8) to measure the
    /// prediction error.
    #[arg(long, value_parser = parse_series_source)]
    pub test: Option<SeriesSource>,
    /// Write the model file here.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

#[cfg(test)]
mod tests {
    use clap::{CommandFactory, Parser};

    use super::super::{Cli, Command};
    use super::*;

    #[test]
    fn the_flags_are_consistent_and_parse() {
        Cli::command().debug_assert();
        let parse = |args: &[&str]| Cli::try_parse_from(args).map(|c| c.command);
        let Ok(Command::Compress(c)) = parse(&["chronomap", "compress", "--series", "s.txt"])
        else {
            panic!("compress does not parse")
        };
        assert_eq!(c.order, OrderArg::Auto);
        assert_eq!(c.shortest_period, ShortestPeriod(Some(7200.0)));
        let Ok(Command::Compress(c)) = parse(&[
            "chronomap",
            "compress",
            "--series",
            "s.txt",
            "--order",
            "5",
            "--shortest-period",
            "none",
        ]) else {
            panic!("compress does not parse")
        };
        assert_eq!(
            (c.order, c.shortest_period),
            (OrderArg::Fixed(5), ShortestPeriod(None))
        );
        // One list syntax: comma-separated, space-separated or repeated, in order.
        for at in [
            &["--at", "1,2", "--at", "2016-03-21T13:00:00Z"][..],
            &["--at", "1", "2", "2016-03-21T13:00:00Z"],
            &["--at", "1", "--at", "2", "--at", "2016-03-21T13:00:00Z"],
        ] {
            let mut args = vec!["chronomap", "predict", "m.cmm"];
            args.extend(at);
            let Ok(Command::Predict(p)) = parse(&args) else {
                panic!("{at:?} does not parse")
            };
            assert_eq!(p.at, [1.0, 2.0, 1_458_565_200.0], "{at:?}");
        }
        let Ok(Command::Eval(e)) = parse(&[
            "chronomap",
            "eval",
            "--train",
            "t.txt",
            "--test",
            "a,b",
            "--models",
            "mean,fremen:2",
            "--models",
            "hist:24:86400",
        ]) else {
            panic!("eval does not parse")
        };
        let specs: Vec<String> = model_specs(&e.models)
            .iter()
            .map(|s| s.to_string())
            .collect();
        assert_eq!(specs, ["mean", "fremen:2", "hist:24:86400"]);
        let Ok(Command::Eval(e)) =
            parse(&["chronomap", "eval", "--train", "t.txt", "--test", "a,b"])
        else {
            panic!("eval does not parse")
        };
        assert_eq!(model_specs(&e.models).len(), 8);
        assert!(
            parse(&[
                "chronomap",
                "anomalies",
                "m",
                "--test",
                "t",
                "--confidence",
                "0.2"
            ])
            .is_err()
        );
    }
}
