//! Flags of `chronomap features`, `chronomap hypertime` and `chronomap events`.

#[allow(unused_imports)]
use super::*;
use chronomap_hypertime::hypertime::Components;

pub(super) const FEATURES_HELP: &str = "\
Example (111 image features at one place of the Brayford office, one week in 10-minute slots,
each written on 10 lines; train on the first 6 days, test on the 7th):
  chronomap features --matrix data/brayford_week/features_0.txt.xz --lines-per-slot 10 \\
      --train-days 6 --n 5,10,20,50 --models mean,hist:24,fremen:auto,hyt-em:auto,hyt-km

A matrix file has one line per time slot with one 0/1 field per feature (1 = visible); slot k
starts at k × --slot-secs. Every model is fitted per feature on the training slots only; at every
test slot the n features with the highest predicted visibility are picked.";

/// `chronomap features`.
#[derive(Debug, Args)]
pub struct FeaturesArgs {
    /// State matrix: one line per slot, one 0/1 per feature.
    #[arg(long)]
    pub matrix: PathBuf,
    /// Length of a slot in seconds.
    #[arg(long, default_value_t = 600.0, value_parser = parse_positive)]
    pub slot_secs: f64,
    /// Lines per slot (the rows of a slot are repeated; the first is used).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub lines_per_slot: u32,
    /// Days of slots to train on; the rest is the test.
    #[arg(long, default_value_t = 6.0, value_parser = parse_positive)]
    pub train_days: f64,
    /// Numbers of features to pick (comma-separated or repeated).
    #[arg(long, value_delimiter = ',', default_value = "5,10,20,50")]
    pub n: Vec<usize>,
    /// Models (comma-separated or repeated).
    #[arg(long, value_parser = parse_models, default_value = "mean,hist:24,fremen:auto,hyt-em:auto,hyt-km")]
    pub models: Vec<ModelList>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub(super) const HYPERTIME_HELP: &str = "\
Example (people in the Lincoln corridors; Wednesday and Thursday, maps for Friday 10:00 and 16:30):
  chronomap hypertime \\
      --train data/lincoln_pedestrians_2017/whytes/wednesday_thursday_days_nights_only_ones.txt.xz \\
      --at 2017-05-26T10:00Z,2017-05-26T16:30Z --plot docs/img/pedestrians_hypertime.png

The model is a Gaussian mixture over [x, y, cos(2πt/T), sin(2πt/T), ...] with the periods T found
in the error of the predicted number of detections over time, kept while they lower the error on
the last training day (or the last quarter of a single day); components likewise (--components).
The map shows the expected detections per m² per hour; all maps share one colour scale (black =
the largest value).";

/// `chronomap hypertime`.
#[derive(Debug, Args)]
pub struct HypertimeArgs {
    /// Training event files (`t x y ...` lines; comma-separated or repeated).
    #[arg(long, value_delimiter = ',', required = true)]
    pub train: Vec<PathBuf>,
    /// Use only detections before this time: unix seconds or ISO 8601 (UTC unless an offset is
    /// given).
    #[arg(long, value_parser = parse_time)]
    pub train_before: Option<f64>,
    /// Times to draw the predicted density at: unix seconds or ISO 8601 such as
    /// 2017-05-26T10:00Z (UTC unless an offset is given); comma-separated, space-separated or
    /// repeated.
    #[arg(long, num_args = 1.., value_delimiter = ',', action = clap::ArgAction::Append, value_parser = parse_time)]
    pub at: Vec<f64>,
    /// Mixture components: a number >= 1 or `auto`.
    #[arg(long, default_value = "auto", value_parser = parse_components)]
    pub components: Components,
    /// Cell size of the maps in metres.
    #[arg(long, default_value_t = 0.25, value_parser = parse_positive)]
    pub cell: f64,
    /// Detections further apart than this many seconds start a new window of observation.
    #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
    pub gap: f64,
    /// Draw the maps at --at into this PNG.
    #[arg(long, requires = "at")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

fn parse_components(text: &str) -> Result<Components, String> {
    match text {
        "auto" => Ok(Components::Auto),
        k => match k.parse::<usize>() {
            Ok(k) if k >= 1 => Ok(Components::Fixed(k)),
            _ => Err(format!("{k:?}: give a whole number >= 1 or auto")),
        },
    }
}

pub(super) const EVENTS_HELP_EVAL: &str = "\
Examples (the bundled Lincoln pedestrian data, see docs/pedestrians.md):
  # train on Wednesday, test on Thursday (one file, one processing)
  chronomap events eval \\
      --train data/lincoln_pedestrians_2017/whytes/wednesday_thursday_days_nights_only_ones.txt.xz \\
      --train-before 2017-05-25 \\
      --test data/lincoln_pedestrians_2017/whytes/wednesday_thursday_days_nights_only_ones.txt.xz \\
      --test-from 2017-05-25 --cells 0.5,1,2 --bins 600,1800,3600
  # train on Wednesday and Thursday, test on Friday
  chronomap events eval \\
      --train data/lincoln_pedestrians_2017/whytes/wednesday_thursday_days_nights_only_ones.txt.xz \\
      --test data/lincoln_pedestrians_2017/raw_days/2017_05_26.txt.xz --json

Event files have lines `t x y` (further fields ignored), plain, .xz or .gz; see data/README.md.
The test grid covers the test detections: their bounding box in whole cells (edges at multiples
of the cell size) and their time span in whole bins aligned to the clock. Training time is the
windows of observation the detections reveal (a gap longer than --gap, such as a night while the
robot recharged, is not observed). Every model chooses its parameters on a chronological hold-out
of the training data (the last training day, or the last quarter of a single day), never on the
test. Reductions and p-values (paired t-test of per-cell squared errors) are against the static
map; a positive reduction means a smaller error.";

/// `chronomap events ...`.
#[derive(Debug, Subcommand)]
pub enum EventsCommand {
    /// Fit the event models on training detections and score them on a later day: mean
    /// squared error per cell of the counts, reduction against the static map, p-value.
    #[command(after_help = EVENTS_HELP_EVAL)]
    Eval(EventsEvalArgs),
}

/// `chronomap events eval`.
#[derive(Debug, Args)]
pub struct EventsEvalArgs {
    /// Training event files, merged in time order (comma-separated or repeated).
    #[arg(long, value_delimiter = ',', required = true)]
    pub train: Vec<PathBuf>,
    /// Use only training detections before this time: unix seconds or ISO 8601 such as
    /// 2017-05-25T00:00Z (UTC unless an offset is given).
    #[arg(long, value_parser = parse_time)]
    pub train_before: Option<f64>,
    /// Test event file (a later day).
    #[arg(long)]
    pub test: PathBuf,
    /// Use only test detections at or after this time: unix seconds or ISO 8601 (UTC unless
    /// an offset is given).
    #[arg(long, value_parser = parse_time)]
    pub test_from: Option<f64>,
    /// Cell sizes in metres (comma-separated or repeated).
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2", value_parser = parse_positive)]
    pub cells: Vec<f64>,
    /// Bin lengths in seconds (comma-separated or repeated).
    #[arg(long, value_delimiter = ',', default_value = "600,1800,3600", value_parser = parse_positive)]
    pub bins: Vec<f64>,
    /// Detections further apart than this many seconds start a new window of observation.
    #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
    pub gap: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}
