//! Command-line flags. Only parsing and validation of single flags happen here; the commands
//! turn them into models and readers.

use std::path::PathBuf;

use chronomap_core::PeriodSet;
use chronomap_core::select::Criterion;
use chronomap_core::spec::{FitOptions, ModelSpec};
use clap::{Args, Parser, Subcommand, ValueEnum};

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
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Evaluate models on the bundled real door data and write plots (the main job).
    #[command(after_help = "Example:\n  chronomap demo --out chronomap-demo")]
    Demo(DemoArgs),
    /// Train models on a training file and score them on test sets (Brier score, binary
    /// error, paired t-tests).
    #[command(after_help = EVAL_HELP)]
    Eval(EvalArgs),
    /// Train one model and save it to a model file.
    #[command(
        after_help = "Example:\n  chronomap fit --train data/door_greg_2016/training_data.txt.xz --model fremen:auto -o door.cmm"
    )]
    Fit(FitArgs),
    /// Predict with a saved model: probability and entropy at given times.
    #[command(
        after_help = "Examples:\n  chronomap predict door.cmm --at 1458561600 1458565200\n  chronomap predict door.cmm --times test_times_1.txt"
    )]
    Predict(PredictArgs),
    /// Show what a saved model contains.
    #[command(after_help = "Example:\n  chronomap inspect door.cmm")]
    Inspect(InspectArgs),
    /// List observations that a saved model finds anomalous at a confidence level
    /// (FreMEn paper §V).
    #[command(
        after_help = "Example:\n  chronomap anomalies door.cmm --test test_times_1.txt,test_data_1.txt --confidence 0.99"
    )]
    Anomalies(AnomaliesArgs),
    /// Compress a uniformly sampled binary series with FFT FreMEn and its outlier set
    /// (lossless), and report errors and compression ratios (FreMEn paper §III-B, §IV).
    #[command(after_help = COMPRESS_HELP)]
    Compress(CompressArgs),
    /// Spatio-temporal occupancy grids: build from frames, predict maps Nav2 can load.
    #[command(subcommand)]
    Grid(GridCommand),
    /// Benchmarks at paper scale, timed against a baseline in the same run.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Lifelong spatio-temporal exploration (seed 000): every strategy with every temporal
    /// model on a real dataset, beside the paper's table.
    #[command(after_help = EXPLORE_HELP)]
    Explore(ExploreArgs),
    /// Topological maps whose edges know time: fit, evaluate and inspect the models of
    /// navigation success and duration (seed 003).
    #[command(subcommand)]
    Topo(TopoCommand),
    /// Now or later? Plan a co-safe LTL task on a topological map for a time, or for every
    /// hour of a week (seed 003 §V, Table III).
    #[command(after_help = PLAN_HELP)]
    Plan(PlanArgs),
    /// Events in space and time (people detected by a robot): score models of how many
    /// happen in each cell and time bin (seed 004 §V-D).
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
    /// Warped Hypertime for 2-D events (seed 004): fit the intensity of detections over space
    /// and time, print the periodicities found, draw the predicted density at chosen times.
    #[command(after_help = HYPERTIME_HELP)]
    Hypertime(HypertimeArgs),
    /// Which features will be visible? Pick the n most likely at every test slot and count the
    /// visible ones (seed 001 §VII Table I, seed 004 §V-B).
    #[command(after_help = FEATURES_HELP)]
    Features(FeaturesArgs),
    /// Run the world-model service: an HTTP/JSON API over durable models (add observations,
    /// predict, forecast), with an OpenAPI description at /openapi.json.
    #[command(after_help = SERVE_HELP)]
    Serve(ServeArgs),
    /// Talk to a running service: add observations, predict, forecast, view, list, remove.
    Client(ClientArgs),
    /// Behavior trees in BehaviorTree.CPP 4 XML: check a file, or tick a tree whose leaves
    /// follow a script (seed 002 §5.2-5.3).
    #[command(subcommand)]
    Bt(BtCommand),
    /// System monitoring of seed 002 §5.3: a fault-injection simulation of monitors feeding a
    /// behavior-tree arbiter that blocks the patrol and runs the recoveries of Table 5.1.
    #[command(subcommand)]
    Monitor(MonitorCommand),
}

const SERVE_HELP: &str = "\
Examples:
  chronomap serve --data chronomap-data
  chronomap serve --data chronomap-data --topo witham=witham.cmt
  chronomap serve --data chronomap-data --postgres 'host=127.0.0.1 user=robot dbname=lab'

Writes (add, addvalues, observations, create, remove) need `Authorization: Bearer TOKEN`; the token
is read from --token-file (default DATA/token), which is created with a random token if it does not
exist. Reads (predict, forecast, view, ...) need no token. Every acknowledged observation is durable:
a restart (also after a crash or SIGKILL) restores every model exactly.";

/// `chronomap serve`.
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// Directory of the embedded store (`chronomap.redb`) and of the default token file.
    #[arg(long)]
    pub data: PathBuf,
    /// Address to listen on (loopback by default; port 0 picks a free port).
    #[arg(long, default_value = "127.0.0.1:8470")]
    pub listen: std::net::SocketAddr,
    /// File holding the bearer token for writes (created with a random token if missing);
    /// default DATA/token.
    #[arg(long, conflicts_with = "no_token")]
    pub token_file: Option<PathBuf>,
    /// Accept writes without a token (only sensible on a loopback address of a one-user machine).
    #[arg(long)]
    pub no_token: bool,
    /// Keep the log and snapshots in PostgreSQL instead of DATA/chronomap.redb: a libpq
    /// connection string (`host=127.0.0.1 user=robot dbname=lab`) or postgresql:// URL.
    #[arg(long)]
    pub postgres: Option<String>,
    /// PostgreSQL schema of the tables (created if missing).
    #[arg(long, default_value = "chronomap", requires = "postgres")]
    pub postgres_schema: String,
    /// Largest request body in bytes (larger ones get 413).
    #[arg(long, default_value_t = 32 << 20)]
    pub max_body_bytes: usize,
    /// Snapshot changed models after this many observations (recovery replays fewer).
    #[arg(long, default_value_t = 1_000_000)]
    pub snapshot_every: u64,
    /// ... or after this many seconds with changes.
    #[arg(long, default_value_t = 60.0, value_parser = parse_positive)]
    pub snapshot_secs: f64,
    /// Serve a topological map with edge models (from `chronomap topo fit`) as NAME=FILE:
    /// edge predictions and now-or-later plans at /v1/topo/NAME/. Repeatable.
    #[arg(long, value_parser = parse_named_file)]
    pub topo: Vec<(String, PathBuf)>,
    /// Serve an occupancy grid file (from `chronomap grid build`) as NAME=FILE: predicted maps
    /// at /v1/grid/NAME/predict. Repeatable.
    #[arg(long, value_parser = parse_named_file)]
    pub grid: Vec<(String, PathBuf)>,
}

fn parse_named_file(text: &str) -> Result<(String, PathBuf), String> {
    match text.split_once('=') {
        Some((name, file))
            if !name.is_empty()
                && !file.is_empty()
                && name
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b)) =>
        {
            Ok((name.to_owned(), PathBuf::from(file)))
        }
        _ => Err(format!(
            "{text:?} is not NAME=FILE (NAME of letters, digits, '-', '_' or '.')"
        )),
    }
}

/// `chronomap client`.
#[derive(Debug, Args)]
pub struct ClientArgs {
    /// Service address.
    #[arg(long, default_value = "http://127.0.0.1:8470", env = "CHRONOMAP_URL")]
    pub url: String,
    /// File holding the bearer token for writes (as printed by `chronomap serve`).
    #[arg(long, env = "CHRONOMAP_TOKEN_FILE")]
    pub token_file: Option<PathBuf>,
    /// What to ask.
    #[command(subcommand)]
    pub command: ClientCommand,
}

/// `chronomap client` subcommands.
#[derive(Debug, Subcommand)]
pub enum ClientCommand {
    /// Service health.
    Health,
    /// All models.
    List,
    /// A model's parameters.
    View {
        /// Model id.
        id: String,
    },
    /// Create a model.
    Create {
        /// Model id.
        id: String,
        /// Model spec (fremen:K, persistence:K, hist:N, pergam:K, stm, mean).
        #[arg(long, default_value = "fremen:2")]
        model: String,
        /// Value range LO,HI of continuous states.
        #[arg(long, value_delimiter = ',', num_args = 2)]
        range: Option<Vec<f64>>,
    },
    /// Remove a model.
    Remove {
        /// Model id.
        id: String,
    },
    /// Add observations from a `t value` file (or TIMES,VALUES files), in batches.
    #[command(
        after_help = "Example:\n  chronomap client add lab-door --file data/door_greg_2016/training_data.txt.xz --model fremen:2"
    )]
    Add {
        /// Model id.
        id: String,
        /// Observations: one `t value` file, or TIMES,VALUES (two line-aligned files).
        #[arg(long, value_parser = parse_series_source)]
        file: SeriesSource,
        /// Spec of the model to create if it does not exist.
        #[arg(long)]
        model: Option<String>,
        /// Observations per request.
        #[arg(long, default_value_t = 100_000)]
        batch: usize,
    },
    /// Predict p(t): at given times, or from --from to --to every --step seconds.
    #[command(
        after_help = "Example:\n  chronomap client predict lab-door --from 2016-03-21T00:00Z --to 2016-03-22T00:00Z --step 3600"
    )]
    Predict {
        /// Model id.
        id: String,
        /// Times (seconds or ISO 8601).
        #[arg(long, num_args = 1.., value_parser = parse_time, conflicts_with_all = ["from", "to"])]
        at: Vec<f64>,
        /// First time of a range.
        #[arg(long, value_parser = parse_time, requires = "to")]
        from: Option<f64>,
        /// Last time of a range.
        #[arg(long, value_parser = parse_time, requires = "from")]
        to: Option<f64>,
        /// Step of a range (s).
        #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
        step: f64,
        /// Order to predict with.
        #[arg(long)]
        order: Option<usize>,
    },
    /// p(t) of many models at one time.
    Forecast {
        /// Model ids, comma-separated.
        #[arg(long, value_delimiter = ',', required = true)]
        ids: Vec<String>,
        /// The time (seconds or ISO 8601).
        #[arg(long, value_parser = parse_time)]
        at: f64,
        /// Order for every model.
        #[arg(long)]
        order: Option<usize>,
    },
    /// Errors per order on a `t value` file.
    Evaluate {
        /// Model id.
        id: String,
        /// Observations.
        #[arg(long, value_parser = parse_series_source)]
        file: SeriesSource,
        /// Largest order.
        #[arg(long)]
        max_order: Option<usize>,
    },
}

const FEATURES_HELP: &str = "\
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
    #[arg(long, default_value_t = 1)]
    pub lines_per_slot: usize,
    /// Days of slots to train on; the rest is the test.
    #[arg(long, default_value_t = 6.0, value_parser = parse_positive)]
    pub train_days: f64,
    /// Numbers of features to pick, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "5,10,20,50")]
    pub n: Vec<usize>,
    /// Models, comma-separated.
    #[arg(long, value_parser = parse_models, default_value = "mean,hist:24,fremen:auto,hyt-em:auto,hyt-km")]
    pub models: ModelList,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

const HYPERTIME_HELP: &str = "\
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
    /// Training event files (`t x y ...` lines), comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
    pub train: Vec<PathBuf>,
    /// Use only detections before this time: seconds or ISO 8601.
    #[arg(long, value_parser = parse_time)]
    pub train_before: Option<f64>,
    /// Times to draw the predicted density at (seconds or ISO 8601), comma-separated.
    #[arg(long, value_delimiter = ',', value_parser = parse_time)]
    pub at: Vec<f64>,
    /// Mixture components: a number or `auto`.
    #[arg(long, default_value = "auto")]
    pub components: String,
    /// Cell size of the maps in metres.
    #[arg(long, default_value_t = 0.25, value_parser = parse_positive)]
    pub cell: f64,
    /// Detections further apart than this many seconds start a new window of observation.
    #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
    pub gap: f64,
    /// Write the maps at --at as one PNG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

const EVENTS_HELP_EVAL: &str = "\
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
    /// Training event files, comma-separated (merged in time order).
    #[arg(long, value_delimiter = ',', required = true)]
    pub train: Vec<PathBuf>,
    /// Use only training detections before this time: seconds or ISO 8601 (UTC unless an
    /// offset is given).
    #[arg(long, value_parser = parse_time)]
    pub train_before: Option<f64>,
    /// Test event file (a later day).
    #[arg(long)]
    pub test: PathBuf,
    /// Use only test detections at or after this time: seconds or ISO 8601.
    #[arg(long, value_parser = parse_time)]
    pub test_from: Option<f64>,
    /// Cell sizes in metres, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "0.5,1,2", value_parser = parse_positive)]
    pub cells: Vec<f64>,
    /// Bin lengths in seconds, comma-separated.
    #[arg(long, value_delimiter = ',', default_value = "600,1800,3600", value_parser = parse_positive)]
    pub bins: Vec<f64>,
    /// Detections further apart than this many seconds start a new window of observation.
    #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
    pub gap: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

const ACTIVITY_HELP_EVAL: &str = "\
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
scored; the top-level nrmse/chi2 are those of --model. `auto` (default) picks the baseline of the
least NRMSE on the last 20 % of the training times (never on the test). `copa` is CoPA-Map, the
heteroscedastic sparse variational GP (about a minute with the defaults on 2 cores; --inducing and
--iterations trade time for accuracy; --init spectral starts its periods from Algorithm 4.1
instead of the day); it is not part of `auto`. Fr-AAM treats each row as one hour of observation: the grid
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
    /// Fit CoPA-Map to training rates and save it as a model file (versioned, checksummed).
    #[command(after_help = ACTIVITY_HELP_FIT)]
    Fit(ActivityFitArgs),
    /// Predict the rate of people (mean and standard deviation) with a saved CoPA-Map over a
    /// grid of cells at chosen times; write CSV and/or a PNG of mean and std per time.
    #[command(after_help = ACTIVITY_HELP_FIT)]
    Predict(ActivityPredictArgs),
    /// The service-disturbance benchmark (eq. 4.22): patrols planned on each model's predicted
    /// rates, and the people they pass on a test day.
    #[command(after_help = ACTIVITY_HELP_DISTURBANCE)]
    Disturbance(ActivityDisturbanceArgs),
}

const ACTIVITY_HELP_FIT: &str = "\
Example (the bundled ATC grid; t is the hour bin, 12 recorded hours a day from 09:00, so t = 123
is 12:00 and t = 129 is 18:00 of the day after the ten training days):
  chronomap activity fit --train data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz \\
      -o atc.cmcopa
  chronomap activity predict --model atc.cmcopa --t 123 --t 129 \\
      --map data/atc_copa_map_grid/atc_map.yaml --png atc_copa.png --csv atc_copa.csv";

/// `chronomap activity fit`.
#[derive(Debug, Args)]
pub struct ActivityFitArgs {
    /// Training rates, CSV `x1,x2,t,y`.
    #[arg(long)]
    pub train: PathBuf,
    /// Where to write the model.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Length of a day in units of t (12: the ATC grid's 12 recorded hours).
    #[arg(long, default_value_t = 12.0, value_parser = parse_positive)]
    pub period: f64,
    /// Inducing points.
    #[arg(long, default_value_t = 200)]
    pub inducing: usize,
    /// Training iterations.
    #[arg(long, default_value_t = 300)]
    pub iterations: usize,
    /// Model the rates themselves or ln(1 + rate).
    #[arg(long, value_enum, default_value_t = CopaScale::Rate)]
    pub scale: CopaScale,
    /// Seed of the minibatches and of the k-means of the inducing points.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
}

/// `chronomap activity predict`.
#[derive(Debug, Args)]
pub struct ActivityPredictArgs {
    /// A model written by `chronomap activity fit`.
    #[arg(long)]
    pub model: PathBuf,
    /// Times to predict (repeat the flag), in the units of the training t.
    #[arg(long = "t", required = true)]
    pub times: Vec<f64>,
    /// Region `x_min,y_min,x_max,y_max` in metres (default: the model's training square).
    #[arg(long, value_delimiter = ',', num_args = 4)]
    pub region: Option<Vec<f64>>,
    /// Side of a cell in metres.
    #[arg(long, default_value_t = 0.5, value_parser = parse_positive)]
    pub cell: f64,
    /// A ROS map (YAML) whose occupied cells are left out (drawn as obstacles).
    #[arg(long)]
    pub map: Option<PathBuf>,
    /// Write `x1,x2,t,mean,std` here.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Draw the predicted mean and standard deviation at every time as a PNG.
    #[arg(long)]
    pub png: Option<PathBuf>,
}

const ACTIVITY_HELP_TRUTH: &str = "\
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
    /// Pedestrian track files, CSV `t,person,x,y,speed,heading`.
    #[arg(long, num_args = 1.., required = true)]
    pub tracks: Vec<PathBuf>,
    /// The grid whose cells get a ground truth (CSV `x1,x2,t,y`; its distinct cells are used).
    #[arg(long)]
    pub cells: PathBuf,
    /// Start of bin 0 in the tracks' time unit (unix seconds).
    #[arg(long)]
    pub t0: f64,
    /// Length of a bin in seconds.
    #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
    pub bin_seconds: f64,
    /// Bin indices to count, comma-separated.
    #[arg(long, value_delimiter = ',', required = true)]
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
}

const ACTIVITY_HELP_EXTRACT: &str = "\
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
    /// (global mean, ML, ML-log or Fr-AAM; GP-Hom and WHyTe are too slow to be tried).
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
    /// WHyTe (Warped Hypertime, seed 004): a Gaussian mixture of people over space and the
    /// circles of the periods found in its error (day/1 .. day/6 of --period), divided by the
    /// same mixture weighted by observation time; periods and components (4, 8, 16, 32)
    /// chosen on a hold-out of the last 20 % of the training times.
    Whyte,
    /// CoPA-Map: the heteroscedastic sparse variational GP of §4.2 (eqs. 4.7–4.16).
    Copa,
}

/// The scale CoPA-Map models rates on (`chronomap_core::activity::RateScale`).
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
    /// Pedestrian track files `t,person,x,y,speed,heading` (plain, .xz or .gz).
    #[arg(long, required = true, num_args = 1..)]
    pub tracks: Vec<PathBuf>,
    /// ROS map YAML file (map_server / Nav2) of the environment.
    #[arg(long, required_unless_present = "cells_from")]
    pub map: Option<PathBuf>,
    /// Robot path file, CSV `path,x,y,stop_s`.
    #[arg(long, visible_alias = "path", required_unless_present = "cells_from")]
    pub paths: Option<PathBuf>,
    /// Only the paths of these names (repeatable; default all).
    #[arg(long = "robot", value_name = "NAME")]
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
    /// Start of bin 0 and of the robots' loops, unix seconds.
    #[arg(long)]
    pub t0: Option<f64>,
    /// Bins to extract (indices from --t0, comma-separated; default: every bin with a
    /// detection).
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
    /// Algorithm 4.1 (seed 002 §4.2.4): periods and variances from a NUDFT of sampled regions.
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
    /// The model of the top-level scores (default: CoPA-Map; every baseline is scored too).
    #[arg(long, value_enum, default_value_t = ActivityModel::Copa)]
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
}

const TOPO_HELP_FIT: &str = "\
Example:
  chronomap topo fit --edges data/witham_topological_nav/edges -o witham.cmt

Edge files are `<From>_<To>.data` (plain, .xz or .gz) with lines `t duration_s success(0|1)`.";

const TOPO_HELP_EVAL: &str = "\
Example (the last two weeks of the bundled Witham Wharf data):
  chronomap topo split --edges data/witham_topological_nav/edges --at 2014-08-20 \\
      --before witham-train --after witham-test
  chronomap topo eval --train witham-train --test witham-test --json

Protocols: `online` (default) predicts every test attempt from everything before it, as a robot
that keeps learning does, and learns it afterwards (the static baseline is the running per-edge
rate); `frozen` predicts all test attempts with the models as fitted on the training data.";

const PLAN_HELP: &str = "\
Examples:
  chronomap topo fit --edges data/witham_topological_nav/edges -o witham.cmt
  chronomap plan --model witham.cmt --from Station --task \"F Kitchen\" --time 2014-09-04T10:00Z
  chronomap plan --model witham.cmt --from Station --task \"F Kitchen\" --day-table --plot kitchen.png
  chronomap plan --model witham.cmt --from Station --task \"!Ramp1 U Kitchen\" --time 2014-09-04T10:00Z \\
      --prism witham.nm --drn witham.drn

Tasks are co-safe LTL over node names: ! & | -> X F U ( ) true false; e.g. \"F Kitchen\",
\"F (Printer & F Kitchen)\" (visit in order), \"!Ramp1 U Kitchen\" (avoid Ramp1 until Kitchen).";

/// `chronomap topo ...`.
#[derive(Debug, Subcommand)]
pub enum TopoCommand {
    /// Fit the success and duration models of every edge from a directory of edge files.
    #[command(after_help = TOPO_HELP_FIT)]
    Fit(TopoFitArgs),
    /// Fit on one directory of edge files and score on another (later) one against the
    /// static per-edge models.
    #[command(after_help = TOPO_HELP_EVAL)]
    Eval(TopoEvalArgs),
    /// Split a directory of edge files at a time into two directories (before, at-or-after).
    Split(TopoSplitArgs),
    /// Predict every edge at a time; optionally write the map with its predictions as a Nav2
    /// route graph (GeoJSON) or a tmap2 file.
    #[command(
        after_help = "Example:\n  chronomap topo predict witham.cmt --time 2014-09-04T08:00Z --geojson witham.geojson"
    )]
    Predict(TopoPredictArgs),
}

/// How edge models are fitted.
#[derive(Debug, Args)]
pub struct EdgeModelFlags {
    /// Static per-edge models only: no periodic (FreMEn) components.
    #[arg(long = "static")]
    pub static_only: bool,
    /// No persistence term (the outcome of the latest attempt does not carry over).
    #[arg(long)]
    pub no_persistence: bool,
    /// Edges with fewer attempts use their (shrunk) success rate only.
    #[arg(long, default_value_t = 10)]
    pub min_attempts: usize,
    /// Prior success probability of an edge.
    #[arg(long, default_value_t = 0.9, value_parser = parse_probability)]
    pub prior: f64,
    /// Weight of the prior, in attempts.
    #[arg(long, default_value_t = 2.0, value_parser = parse_non_negative)]
    pub prior_attempts: f64,
    /// Success probabilities never go below this.
    #[arg(long, default_value_t = 0.05, value_parser = parse_probability)]
    pub floor: f64,
    /// Largest FreMEn order tried per edge.
    #[arg(long, default_value_t = 10)]
    pub max_order: usize,
    /// Fix the order of every success model instead of choosing it per edge (seed 003:
    /// "typically, m = 2").
    #[arg(long)]
    pub success_order: Option<usize>,
    /// Most recent fraction of each edge's history held back to choose its orders.
    #[arg(long, default_value_t = 0.25, value_parser = parse_fraction)]
    pub holdout: f64,
}

impl EdgeModelFlags {
    /// The core configuration these flags describe.
    pub fn config(&self) -> chronomap_core::edges::EdgeModelConfig {
        chronomap_core::edges::EdgeModelConfig {
            min_attempts: self.min_attempts,
            prior_success: self.prior,
            prior_attempts: self.prior_attempts,
            floor: self.floor,
            periodic: !self.static_only,
            persistence: !self.no_persistence,
            holdout: self.holdout,
            max_order: self.max_order,
            success_order: self.success_order,
            default_duration_secs: None,
        }
    }
}

/// `chronomap topo fit`.
#[derive(Debug, Args)]
pub struct TopoFitArgs {
    /// Directory of edge files.
    #[arg(long)]
    pub edges: PathBuf,
    /// Model file to write.
    #[arg(short, long = "out")]
    pub output: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Model options.
    #[command(flatten)]
    pub model: EdgeModelFlags,
}

/// `--protocol` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ProtocolArg {
    /// Each test attempt is predicted, then learned.
    Online,
    /// The models stay as fitted on the training data.
    Frozen,
}

/// `chronomap topo eval`.
#[derive(Debug, Args)]
pub struct TopoEvalArgs {
    /// Directory of training edge files.
    #[arg(long)]
    pub train: PathBuf,
    /// Directory of test edge files (later attempts).
    #[arg(long)]
    pub test: PathBuf,
    /// How the test attempts are predicted.
    #[arg(long, value_enum, default_value_t = ProtocolArg::Online)]
    pub protocol: ProtocolArg,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Also show the scores of every edge.
    #[arg(long)]
    pub per_edge: bool,
    /// Model options.
    #[command(flatten)]
    pub model: EdgeModelFlags,
}

/// `chronomap topo split`.
#[derive(Debug, Args)]
pub struct TopoSplitArgs {
    /// Directory of edge files.
    #[arg(long)]
    pub edges: PathBuf,
    /// Split time: seconds or ISO 8601 (UTC unless an offset is given).
    #[arg(long, value_parser = parse_time)]
    pub at: f64,
    /// Directory for the attempts before the split (created; must not hold edge files).
    #[arg(long)]
    pub before: PathBuf,
    /// Directory for the attempts at or after the split.
    #[arg(long)]
    pub after: PathBuf,
}

/// `chronomap topo predict`.
#[derive(Debug, Args)]
pub struct TopoPredictArgs {
    /// Edge-model file (`topo fit`).
    pub model: PathBuf,
    /// Time: seconds or ISO 8601.
    #[arg(long, value_parser = parse_time)]
    pub time: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write the map as a Nav2 route-server graph (GeoJSON) with the predictions.
    #[arg(long)]
    pub geojson: Option<PathBuf>,
    /// Write the map as an LCAS tmap2 file.
    #[arg(long)]
    pub tmap2: Option<PathBuf>,
}

/// When `plan` plans.
#[derive(Debug, Args)]
#[group(required = true, multiple = false)]
pub struct PlanWhen {
    /// Plan for this start time: seconds or ISO 8601 (UTC unless an offset is given).
    #[arg(long, value_parser = parse_time)]
    pub time: Option<f64>,
    /// The now-or-later table: every hour (see --step-mins) of a week (see --week-of).
    #[arg(long)]
    pub day_table: bool,
}

/// `chronomap plan`.
#[derive(Debug, Args)]
pub struct PlanArgs {
    /// Edge-model file (`topo fit`).
    #[arg(long)]
    pub model: PathBuf,
    /// Start node.
    #[arg(long)]
    pub from: String,
    /// Co-safe LTL task over node names.
    #[arg(long)]
    pub task: String,
    /// When.
    #[command(flatten)]
    pub when: PlanWhen,
    /// Any time in the first day of the table (default: the day after the model's data).
    #[arg(long, value_parser = parse_time)]
    pub week_of: Option<f64>,
    /// Days in the table.
    #[arg(long, default_value_t = 7, value_parser = clap::value_parser!(u32).range(1..=28))]
    pub days: u32,
    /// Minutes between the table's start times.
    #[arg(long, default_value_t = 60, value_parser = clap::value_parser!(u32).range(5..=720))]
    pub step_mins: u32,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write the table as a PNG heat map.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Write the Navigation MDP at --time in the PRISM language (STRANDS layout) and its
    /// property next to it (`.props`).
    #[arg(long)]
    pub prism: Option<PathBuf>,
    /// Write the product MDP at --time in Storm's explicit DRN format.
    #[arg(long)]
    pub drn: Option<PathBuf>,
}

const EXPLORE_HELP: &str = "\
Examples:
  chronomap explore --dataset aruba --data data/aruba_rooms_1min --ratio 0.5
  chronomap explore --dataset brayford --data data/brayford_week --ratio 0.5 --json
  chronomap explore --dataset aruba --data data/aruba_rooms_1min \\
      --sweep docs/img/exploration_sweep.png --behaviour docs/img/exploration_behaviour.png";

/// Datasets `explore` reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DatasetArg {
    /// CASAS Aruba apartment: presence_minutes_R.txt[.xz] ("t value", one per minute).
    Aruba,
    /// Brayford office: presence_L.txt[.xz] (one value per 10-minute slot).
    Brayford,
}

/// `chronomap explore`.
#[derive(Debug, Args)]
pub struct ExploreArgs {
    /// Which dataset format the directory holds.
    #[arg(long, value_enum)]
    pub dataset: DatasetArg,
    /// The dataset's directory.
    #[arg(long)]
    pub data: PathBuf,
    /// Exploration ratio e: the fraction of 10-minute slots spent observing.
    #[arg(long, default_value_t = 0.5, value_parser = parse_ratio)]
    pub ratio: f64,
    /// Seed of every random choice (runs are repeatable).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Explore only the first N days.
    #[arg(long)]
    pub days: Option<usize>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Also write the exploration-ratio sweep (seed 000 Fig. 5) to this PNG.
    #[arg(long)]
    pub sweep: Option<PathBuf>,
    /// Also write the behaviour of the first days (seed 000 Fig. 6) to this PNG.
    #[arg(long)]
    pub behaviour: Option<PathBuf>,
}

fn parse_ratio(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(e) if e > 0.0 && e <= 1.0 => Ok(e),
        _ => Err(format!("{text:?} is not an exploration ratio in (0, 1]")),
    }
}

/// `chronomap grid ...`.
#[derive(Debug, Subcommand)]
pub enum GridCommand {
    /// Build a grid from frames (ROS/Nav2 maps, per-cell series, or the synthetic office) and
    /// save it; optionally report the estimation errors of seed 001 §VI.
    #[command(after_help = GRID_BUILD_HELP)]
    Build(GridBuildArgs),
    /// Predict the map at a time and write it as a ROS map_server / Nav2 map (YAML + image).
    #[command(
        after_help = "Example:\n  chronomap grid predict office.cmg --time 1461661200 --out predicted/map.yaml\n  (writes predicted/map.yaml and predicted/map.pgm)"
    )]
    Predict(GridPredictArgs),
    /// Show what a grid file holds: size, changing cells, compression ratio (eq. 16).
    Stats(GridStatsArgs),
    /// Draw the maps predicted for several times side by side.
    #[command(
        after_help = "Example:\n  chronomap grid plot office.cmg --time 1461636000 --time 1461672000 -o maps.png"
    )]
    Plot(GridPlotArgs),
}

const GRID_BUILD_HELP: &str = "\
Examples:
  chronomap grid build --synthetic --days 14 --cells 32000 -o office.cmg --errors
  chronomap grid build --frames frames.txt -o corridor.cmg   # lines: <unix time> <map.yaml>
  chronomap grid build --cell-series data/aruba_rooms_1min/presence_minutes_0.txt.xz,... -o flat.cmg";

/// `chronomap bench ...`.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// The 4-D office grid of seed 001 §VI (213,000 cells x 17,280 frames/day x 112 days),
    /// streamed from the synthetic generator into FreMEn grids, against a bare scan of the same
    /// frames.
    Grid(BenchGridArgs),
    /// Planning on the Witham map (seed 003 §V), 24 hours x 3 tasks, end to end, against
    /// Storm (stormpy) on the same cases in the same run.
    #[command(after_help = BENCH_PLAN_HELP)]
    Plan(BenchPlanArgs),
    /// The service on loopback (redb store, token): latency of predict and forecast from
    /// concurrent clients, and durable observations/s of batched adds, against the same work
    /// done in-process (and straight into redb) in the same run.
    #[command(after_help = BENCH_SERVE_HELP)]
    Serve(BenchServeArgs),
    /// CoPA-Map's activity pipeline (seed 002 chapter 4) on the bundled ATC data: training-data
    /// extraction (§4.2.2) against a bare binning pass over the same detections, and CoPA-Map
    /// training (eqs. 4.12–4.16) against the bare faer matrix products of its iterations.
    #[command(after_help = BENCH_ACTIVITY_HELP)]
    Activity(BenchActivityArgs),
    /// Person search tree synthesis (dissertation §5.4) for 6 and 10 places on the bundled ATC
    /// day, against the dense-generator reference and a per-tree solve in the same run.
    #[command(after_help = BENCH_PSBT_HELP)]
    Psbt(BenchPsbtArgs),
}

const BENCH_PSBT_HELP: &str = "\
Example:
  chronomap bench psbt --json";

/// `chronomap bench psbt`.
#[derive(Debug, Args)]
pub struct BenchPsbtArgs {
    /// ROS map YAML.
    #[arg(long, default_value = "data/atc_copa_map_grid/atc_map.yaml")]
    pub map: PathBuf,
    /// Pedestrian track files (comma-separated).
    #[arg(long, value_delimiter = ',', num_args = 1.., default_value = "data/atc_20121024_1hz/atc-1024-13_train.csv.xz,data/atc_20121024_1hz/atc-1024-14_train.csv.xz")]
    pub activity: Vec<PathBuf>,
    /// Help location `x,y` (metres).
    #[arg(long, value_parser = parse_xy, allow_hyphen_values = true, default_value = "10,-3")]
    pub from: [f64; 2],
    /// Time of the request (unix seconds or ISO 8601).
    #[arg(long, value_parser = parse_time, default_value = "1351058400")]
    pub time: f64,
    /// Timed repetitions of each synthesis (the median is reported).
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// At most this many candidates are solved by the dense reference (a seeded sample; the
    /// time of the rest is extrapolated).
    #[arg(long, default_value_t = 1000)]
    pub reference_sample: usize,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `chronomap bench grid`.
#[derive(Debug, Args)]
pub struct BenchGridArgs {
    /// Days of 5-second frames.
    #[arg(long, default_value_t = 112)]
    pub days: u32,
    /// Number of cells.
    #[arg(long, default_value_t = 213_000)]
    pub cells: usize,
    /// Seed of the synthetic office.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Threads (default: all).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

const PSBT_HELP: &str = "\
Examples:
  chronomap psbt --map data/atc_copa_map_grid/atc_map.yaml \\
      --activity data/atc_20121024_1hz/atc-1024-13_train.csv.xz,data/atc_20121024_1hz/atc-1024-14_train.csv.xz \\
      --from 10,-3 --time 2012-10-24T05:30Z --json
  chronomap psbt eval --map data/atc_copa_map_grid/atc_map.yaml \\
      --activity data/atc_20121024_1hz/atc-1024-9_train.csv.xz,...,atc-1024-15_train.csv.xz \\
      --time 2012-10-24T06:30Z --starts 500 --seed 1 --plot psbt_atc.png

The activity model is the grid Poisson model of eq. 5.7 (1 m cells, 1 h intervals, distinct
people per cell and interval over the tracked time). Defaults are those of §5.4.4: r_D = 2 m,
p'_s = 0.9, dt = 1 s, l_fail = 100 m, v = 0.5 m/s, n_pl = 6, t_max = 200 s.";

/// `chronomap psbt`: synthesis, or `eval`.
#[derive(Debug, Args)]
pub struct PsbtArgs {
    /// `eval`: compare with the baselines from many random help locations.
    #[command(subcommand)]
    pub command: Option<PsbtCommand>,
    /// Synthesis.
    #[command(flatten)]
    pub synth: PsbtSynthArgs,
}

/// Subcommands of `chronomap psbt`.
#[derive(Debug, Subcommand)]
pub enum PsbtCommand {
    /// Fig. 5.11: PSBT and the baselines GM, GC, RND, W and PP from random help locations,
    /// p_s,T(t_k) every 20 s up to t_max and E[T|S], on the planning model and on a model of the
    /// evaluated hour itself.
    Eval(PsbtEvalArgs),
}

/// Where the robot is and what it knows of people.
#[derive(Debug, Args)]
pub struct PsbtWorldArgs {
    /// ROS map YAML (map_server / Nav2).
    #[arg(long)]
    pub map: PathBuf,
    /// Pedestrian track files, `t,person,x,y,speed,heading` (comma-separated; .xz/.gz read),
    /// or one CoPA-Map model file of `chronomap activity fit` (.cmcopa; synthesis only).
    #[arg(long, value_delimiter = ',', num_args = 1.., required = true)]
    pub activity: Vec<PathBuf>,
    /// Side of a cell of the activity model in metres.
    #[arg(long, default_value_t = 1.0, value_parser = parse_positive)]
    pub cell: f64,
    /// Length of a time interval of the activity model in seconds.
    #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
    pub interval: f64,
    /// Side of a planning cell in metres.
    #[arg(long, default_value_t = 0.5, value_parser = parse_positive)]
    pub planning_cell: f64,
    /// The robot keeps this many metres from obstacles at every planning-cell centre.
    #[arg(long, default_value_t = 0.3, value_parser = parse_non_negative)]
    pub clearance: f64,
    /// Number of places n_pl (at most 16).
    #[arg(long, default_value_t = 6)]
    pub places: usize,
}

/// `chronomap psbt`.
#[derive(Debug, Args)]
pub struct PsbtSynthArgs {
    /// Map and activity.
    #[command(flatten)]
    pub world: Option<PsbtWorldArgs>,
    /// Help location `x,y` in metres (map frame).
    #[arg(long, value_parser = parse_xy, allow_hyphen_values = true, required = true)]
    pub from: Option<[f64; 2]>,
    /// Time of the request: unix seconds or ISO 8601.
    #[arg(long, value_parser = parse_time, required = true)]
    pub time: Option<f64>,
    /// Seed of place sampling and of the TSP's genetic algorithm.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// With a CoPA-Map model: the model time to use (its own t units; default: --time on the
    /// ATC grid's axis, hours since 2012-10-24 09:00 JST with 12 recorded hours a day).
    #[arg(long)]
    pub model_t: Option<f64>,
    /// With a CoPA-Map model: side in metres of the cells whose rates it was trained on.
    #[arg(long, default_value_t = 0.5, value_parser = parse_positive)]
    pub model_cell: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `chronomap psbt eval`.
#[derive(Debug, Args)]
pub struct PsbtEvalArgs {
    /// Map and activity.
    #[command(flatten)]
    pub world: PsbtWorldArgs,
    /// Time of the requests (unix seconds or ISO 8601).
    #[arg(long, value_parser = parse_time)]
    pub time: f64,
    /// The planning model learns from tracks before this time (default: the start of the
    /// interval of --time); the scoring model from the tracks of that interval.
    #[arg(long, value_parser = parse_time)]
    pub train_until: Option<f64>,
    /// Number of random help locations.
    #[arg(long, default_value_t = 500)]
    pub starts: usize,
    /// Seed of the help locations and of every plan.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Write the mean p_s,T(t) per method (planning and scoring model) to this PNG.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// A point `x,y`.
fn parse_xy(text: &str) -> Result<[f64; 2], String> {
    let parts: Vec<&str> = text.split(',').collect();
    match parts[..] {
        [x, y] => match (x.trim().parse::<f64>(), y.trim().parse::<f64>()) {
            (Ok(x), Ok(y)) if x.is_finite() && y.is_finite() => Ok([x, y]),
            _ => Err(format!("{text:?} is not a point x,y of two finite numbers")),
        },
        _ => Err(format!(
            "{text:?} is not a point x,y (two numbers, one comma)"
        )),
    }
}

const BENCH_PLAN_HELP: &str = "\
Examples:
  chronomap bench plan                                   # chronomap only
  chronomap bench plan --storm-python storm-venv/bin/python --json
  (Storm: python3 -m venv storm-venv && storm-venv/bin/pip install stormpy==2.0.0)";

/// `chronomap bench plan`.
#[derive(Debug, Args)]
pub struct BenchPlanArgs {
    /// The Witham edge files (`<From>_<To>.data.xz`).
    #[arg(long, default_value = "data/witham_topological_nav/edges")]
    pub edges: PathBuf,
    /// A Python interpreter that imports stormpy 2.0: time Storm on the same cases.
    #[arg(long)]
    pub storm_python: Option<PathBuf>,
    /// Timed sweeps over the 72 cases after a warm-up (the median is reported).
    #[arg(long, default_value_t = 5)]
    pub repeat: usize,
    /// Also time Storm in exact (rational) arithmetic (slow).
    #[arg(long)]
    pub exact: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

const BENCH_SERVE_HELP: &str = "\
Examples:
  chronomap bench serve                          # about 10 s on 2 cores
  chronomap bench serve --models 1000 --clients 8 --json
  chronomap bench serve --observations 2000000 --batch 20000 --data bench-data   # keep the store";

/// `chronomap bench serve`.
#[derive(Debug, Args)]
pub struct BenchServeArgs {
    /// Models served (each is the training door, shifted by one hour per model).
    #[arg(long, default_value_t = 100)]
    pub models: usize,
    /// Spec of the models.
    #[arg(long, default_value = "fremen:2")]
    pub model: String,
    /// Training data of every model (`t value` lines; default: the bundled greg door, 96,480
    /// observations at one a minute).
    #[arg(long)]
    pub train: Option<PathBuf>,
    /// Observations added to each model through the API before the latency test (default:
    /// two weeks of the greg door).
    #[arg(long, default_value_t = 20_160)]
    pub preload: usize,
    /// Concurrent clients, each with its own connection.
    #[arg(long, default_value_t = 4)]
    pub clients: usize,
    /// Timed requests per client and kind of request (after 20 untimed ones).
    #[arg(long, default_value_t = 5_000)]
    pub requests: usize,
    /// Time limit per kind of request of the latency test (s).
    #[arg(long, default_value_t = 5.0)]
    pub latency_seconds: f64,
    /// Times per request of the second predict test (the next hours).
    #[arg(long, default_value_t = 24)]
    pub predict_times: usize,
    /// Models per forecast request (at most --models).
    #[arg(long, default_value_t = 100)]
    pub forecast_ids: usize,
    /// Observations of the durable-throughput test, in all.
    #[arg(long, default_value_t = 10_000_000)]
    pub observations: u64,
    /// Observations per request (`POST /v1/observations`, one durable commit).
    #[arg(long, default_value_t = 100_000)]
    pub batch: usize,
    /// Models per request (the batch is split evenly among them).
    #[arg(long, default_value_t = 10)]
    pub batch_ids: usize,
    /// Time limit of the durable-throughput test (s).
    #[arg(long, default_value_t = 30.0)]
    pub seconds: f64,
    /// Keep the service's store in this (new or empty) directory instead of a temporary one.
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

const BENCH_ACTIVITY_HELP: &str = "\
Examples:
  chronomap bench activity                     # the whole ATC day and the default fit (~1.5 min on 2 cores)
  chronomap bench activity --quick --json      # one hour of tracks, 12 iterations (smoke test)
  chronomap bench activity --iterations 50 --sequential-iterations 10";

/// `chronomap bench activity`.
#[derive(Debug, Args)]
pub struct BenchActivityArgs {
    /// Pedestrian track files (default: every `atc-1024-*_train.csv.xz` of
    /// data/atc_20121024_1hz, the whole day; with --quick only its 10:00 file).
    #[arg(long, num_args = 1..)]
    pub tracks: Vec<PathBuf>,
    /// ROS map YAML file of the environment.
    #[arg(long, default_value = "data/atc_copa_map_grid/atc_map.yaml")]
    pub map: PathBuf,
    /// Patrol paths of the simulated robots, CSV `path,x,y,stop_s` (all are used).
    #[arg(long, default_value = "data/atc_20121024_1hz/robot_paths.csv")]
    pub paths: PathBuf,
    /// Training rates of CoPA-Map, CSV `x1,x2,t,y`.
    #[arg(
        long,
        default_value = "data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz"
    )]
    pub train: PathBuf,
    /// Timed extractions after a warm-up, ten bare scans each (medians are reported; default
    /// 5, 2 with --quick).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeats: Option<u32>,
    /// Timed CoPA-Map fits (the median is reported; each takes about 40 s with the defaults).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub fit_repeats: u32,
    /// CoPA-Map training iterations (default: `CopaConfig`'s, 300; 12 with --quick).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub iterations: Option<u32>,
    /// Iterations of the one-thread vs all-threads comparison (0 leaves it out; default 30,
    /// 12 with --quick); the timed fits serve as its all-threads side when they run as many.
    #[arg(long)]
    pub sequential_iterations: Option<u32>,
    /// A run of under 20 s for smoke tests: one hour of tracks, 12 iterations, fewer repeats.
    #[arg(long)]
    pub quick: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Where `grid build` gets its frames.
#[derive(Debug, Args)]
#[group(required = true, multiple = false)]
pub struct GridSource {
    /// The synthetic office (see --cells, --days, --seed).
    #[arg(long)]
    pub synthetic: bool,
    /// A list of frames, one per line: `<time> <map.yaml>` (ROS map_server / Nav2 maps, paths
    /// relative to the list).
    #[arg(long)]
    pub frames: Option<PathBuf>,
    /// One `t value` file per cell (a symbolic map), all with the same times, comma-separated.
    #[arg(long, value_delimiter = ',')]
    pub cell_series: Vec<PathBuf>,
}

/// `chronomap grid build`.
#[derive(Debug, Args)]
pub struct GridBuildArgs {
    /// The frames.
    #[command(flatten)]
    pub source: GridSource,
    /// Synthetic office: number of cells.
    #[arg(long, default_value_t = 213_000)]
    pub cells: usize,
    /// Synthetic office: days of 5-second frames.
    #[arg(long, default_value_t = 112)]
    pub days: u32,
    /// Synthetic office: seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Map files: read them with ROS 1 instead of Nav2 semantics.
    #[arg(long)]
    pub ros1: bool,
    /// The grid file to write.
    #[arg(short, long)]
    pub output: PathBuf,
    /// What to store: the learning state (can be updated and predicts with any order), the
    /// compact model (lossy), or the compact model with outlier sets (lossless).
    #[arg(long, value_enum, default_value_t = StoreArg::State)]
    pub store: StoreArg,
    /// Order of the stored compact model: a number, or `auto` (chosen per cell on the held-back
    /// frames).
    #[arg(long, default_value = "2")]
    pub order: String,
    /// Candidate periods of every cell's FreMEn model.
    #[arg(long, default_value = "week", value_parser = parse_periods)]
    pub periods: PeriodSet,
    /// Report the estimation and prediction errors of seed 001 §VI for static, orders 1-5 and
    /// auto, with the lossy and lossless file sizes.
    #[arg(long)]
    pub errors: bool,
    /// Fraction of the frames (the most recent) held back to choose orders and measure
    /// prediction errors.
    #[arg(long, default_value_t = 0.25, value_parser = parse_fraction)]
    pub holdout: f64,
    /// Threads for the synthetic office (default: all).
    #[arg(long)]
    pub threads: Option<usize>,
}

/// `--store` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum StoreArg {
    /// The learning state.
    State,
    /// The compact model.
    Lossy,
    /// The compact model and outlier sets.
    Lossless,
}

/// `chronomap grid predict`.
#[derive(Debug, Args)]
pub struct GridPredictArgs {
    /// Grid file.
    pub grid: PathBuf,
    /// Time to predict (seconds).
    #[arg(long, value_parser = parse_time)]
    pub time: f64,
    /// The map's YAML file (`map.yaml`, or `map` without extension): the image is written beside
    /// it (`map.pgm`, or `map.png` with --mode scale).
    #[arg(long)]
    pub out: PathBuf,
    /// Map mode: trinary (free/occupied/unknown, like map_saver) or scale (a costmap filter
    /// mask).
    #[arg(long, value_enum, default_value_t = MapModeArg::Trinary)]
    pub mode: MapModeArg,
    /// Order of the prediction (learning-state files only; default: the configured one).
    #[arg(long)]
    pub order: Option<usize>,
    /// For 3-D grids: the layers (z indices, `a..b`) projected onto the 2-D map; a column is as
    /// occupied as its most occupied known cell (default: all layers).
    #[arg(long)]
    pub layers: Option<String>,
}

/// `--mode` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MapModeArg {
    /// 254 free, 0 occupied, 205 unknown (PGM).
    Trinary,
    /// Grey level by probability, unknown transparent (PNG).
    Scale,
}

/// `chronomap grid stats`.
#[derive(Debug, Args)]
pub struct GridStatsArgs {
    /// Grid file.
    pub grid: PathBuf,
}

/// `chronomap grid plot`.
#[derive(Debug, Args)]
pub struct GridPlotArgs {
    /// Grid file.
    pub grid: PathBuf,
    /// Times to predict (repeat; default: 3:00 and 14:00 on the day after the data).
    #[arg(long = "time", value_parser = parse_time)]
    pub times: Vec<f64>,
    /// Order of the prediction (learning-state files only).
    #[arg(long)]
    pub order: Option<usize>,
    /// Layers of a 3-D grid to project (`a..b`).
    #[arg(long)]
    pub layers: Option<String>,
    /// PNG to write.
    #[arg(short, long)]
    pub output: PathBuf,
}

const EVAL_HELP: &str = "\
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

const COMPRESS_HELP: &str = "\
Example (the door week of the FreMEn paper, 604,800 one-second samples):
  chronomap compress --series data/door_tom_2013/sec/test_times_0.txt.xz,data/door_tom_2013/sec/test_data_0.txt.xz \\
    --order auto --test data/door_tom_2013/sec/test_times_1.txt.xz,data/door_tom_2013/sec/test_data_1.txt.xz -o door.cmm";

/// Options shared by commands that fit models.
#[derive(Debug, Args)]
pub struct FitFlags {
    /// Candidate periods of FreMEn models: week (604800/84: one week to 2 h), day, year,
    /// BASE/COUNT (BASE/k for k = 1..COUNT) or a comma list of seconds.
    #[arg(long, default_value = "week", value_parser = parse_periods)]
    pub periods: PeriodSet,
    /// Most recent fraction of the training time span held back to choose orders and models.
    #[arg(long, default_value_t = 0.25, value_parser = parse_fraction)]
    pub holdout: f64,
    /// Largest FreMEn order that `auto` tries.
    #[arg(long, default_value_t = 10)]
    pub max_order: usize,
    /// Error measure used to choose orders and models on held-back data.
    #[arg(long, value_enum, default_value_t = CriterionArg::Brier)]
    pub criterion: CriterionArg,
}

impl FitFlags {
    /// The core options these flags describe.
    pub fn options(&self) -> FitOptions {
        FitOptions {
            periods: self.periods.clone(),
            holdout: self.holdout,
            max_order: self.max_order,
            criterion: self.criterion.into(),
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

/// A parsed `--models` list (a newtype so that clap treats it as one value).
#[derive(Debug, Clone)]
pub struct ModelList(pub Vec<ModelSpec>);

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
    chronomap_core::spec::parse_model_list(text)
        .map(ModelList)
        .map_err(|e| e.to_string())
}

fn parse_probability(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(p) if (0.0..=1.0).contains(&p) => Ok(p),
        _ => Err(format!("{text:?} is not a probability in [0, 1]")),
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

const ACTIVITY_HELP_DISTURBANCE: &str = "\
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
    /// Pedestrian track files of the test day (`t,person,x,y,speed,heading`).
    #[arg(long, num_args = 1.., required = true)]
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
    /// Start of the test day's first hour bin: unix seconds or ISO 8601 (default: the hour of
    /// the first detection).
    #[arg(long, value_parser = parse_time)]
    pub day_start: Option<f64>,
    /// The model time t of that first hour bin (default: the first whole day after the
    /// training data, a multiple of --period).
    #[arg(long)]
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

const BT_HELP_CHECK: &str = "\
Example:
  chronomap bt check tests/data/bt/door.xml

Reads BehaviorTree.CPP 4 XML (<root BTCPP_format=\"4\">): built-in controls and decorators,
<SubTree>, and leaves declared in <TreeNodesModel> or written as <Action ID=\"...\"/> /
<Condition ID=\"...\"/>. Prints the tree to execute with the uids that `bt run` and .btlog files
use (depth first, subtrees expanded). Errors name the file, line, column and attribute.";

const BT_HELP_RUN: &str = "\
Example:
  chronomap bt run tests/data/bt/door.xml --script tests/data/bt/door.script --btlog door.btlog

The script gives the outcome of leaves (by instance name: the name attribute, or the ID) per
tick; an outcome holds until changed:
  # comment
  tick 1: IsDoorClosed=success, OpenDoor=failure, PickLock=running
  tick 2: PickLock=failure
  tick 4 @ 1000: PickLock=success
Ticks run from 1 to the last tick of the script (one root tick each, as BehaviorTree.CPP's
tickExactlyOnce) and stop when the root succeeds or fails. `@ MS` sets a tick's time in
milliseconds; other ticks come --tick-ms after the previous one. The trace lists every status
change of every tick; --btlog writes them as a Groot2 log (times from 0).";

/// `chronomap bt ...`.
#[derive(Debug, Subcommand)]
pub enum BtCommand {
    /// Load and check a BehaviorTree.CPP 4 XML file and print the tree with node uids.
    #[command(after_help = BT_HELP_CHECK)]
    Check(BtCheckArgs),
    /// Tick a tree whose leaves follow a script of outcomes and print every status change.
    #[command(after_help = BT_HELP_RUN)]
    Run(BtRunArgs),
    /// Analyse a tree as a stochastic behavior tree: p_s,T(t), p_f,T(t) and mean times.
    #[command(after_help = BT_HELP_ANALYSE)]
    Analyse(BtAnalyseArgs),
}

const BT_HELP_ANALYSE: &str = "\
Example:
  chronomap bt analyse tests/data/bt/door.xml --params tests/data/bt/door_sbt.csv --t-max 120

Seed 002 §5.2.2: every action ends in success with probability p_s after an Exp(mu) time,
else in failure after an Exp(nu) time; a condition holds with probability p_s and takes no
time. The parameters file is CSV with a header, one row per leaf (instance name, or ID for
every instance of it); conditions leave mu and nu empty, p_f is optional (= 1 - p_s):
  node,p_s,p_f,mu,nu
  IsDoorClosed,0.7,,,
  OpenDoor,0.4,0.6,0.1,0.5
Supported: Sequence, SequenceWithMemory, Fallback, Inverter, ForceSuccess, ForceFailure,
RetryUntilSuccessful and Repeat with a literal count, SubTree, AlwaysSuccess, AlwaysFailure,
SetBlackboard. Prints p_s,T(t) and p_f,T(t) (eq. 5.1) at --steps times up to --t-max (default:
three times the longer mean time), the eventual probabilities and the exact mean times to
success and failure (1/mu_T, 1/nu_T).";

/// `chronomap bt analyse`.
#[derive(Debug, Args)]
pub struct BtAnalyseArgs {
    /// The XML file.
    pub file: PathBuf,
    /// The leaves' parameters: CSV `node,p_s,p_f,mu,nu` (see below).
    #[arg(long)]
    pub params: PathBuf,
    /// The tree to analyse (default: main_tree_to_execute, or the only tree).
    #[arg(long)]
    pub tree: Option<String>,
    /// Last time of the table, seconds after the tree starts.
    #[arg(long)]
    pub t_max: Option<f64>,
    /// Number of intervals of the time table.
    #[arg(long, default_value_t = 10)]
    pub steps: usize,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
    /// Draw p_s,T(t) and p_f,T(t) into a PNG file.
    #[arg(long)]
    pub plot: Option<PathBuf>,
}

/// `chronomap bt check`.
#[derive(Debug, Args)]
pub struct BtCheckArgs {
    /// The XML file.
    pub file: PathBuf,
    /// The tree to print (default: main_tree_to_execute, or the only tree).
    #[arg(long)]
    pub tree: Option<String>,
    /// Also write the file in the canonical BehaviorTree.CPP 4 form (compact nodes, node models).
    #[arg(long)]
    pub save: Option<PathBuf>,
}

/// `chronomap bt run`.
#[derive(Debug, Args)]
pub struct BtRunArgs {
    /// The XML file.
    pub file: PathBuf,
    /// The outcomes of the leaves, tick by tick (see below).
    #[arg(long)]
    pub script: PathBuf,
    /// The tree to run (default: main_tree_to_execute, or the only tree).
    #[arg(long)]
    pub tree: Option<String>,
    /// Milliseconds between ticks whose time the script does not give.
    #[arg(long, default_value_t = 100)]
    pub tick_ms: u64,
    /// Write the status changes as a Groot2 execution log (must end in .btlog).
    #[arg(long)]
    pub btlog: Option<PathBuf>,
}

const MONITOR_HELP_SIM: &str = "\
Examples:
  chronomap monitor sim --hours 8 --seed 1
  chronomap monitor sim --hours 1 --faults faults.txt --certain

A fault file has one fault a line: TIME KIND [TARGET] [fails=N] [for=SECONDS], TIME in seconds
or h:mm:ss, KIND node_crash (TARGET localization, move_base or camera), topic_slow (/scan),
cpu_overload, localization_lost, navigation_failure or stuck; fails=N makes the first N
recoveries on it fail, for= sets a CPU overload's length (120 s). Without --faults, faults are
drawn at random from the seed. A recovery counts as successful if no recovery of the same
category starts within one minute (seed 002 §5.3.2); TSL is the time between supervisor
interventions the robot did not request.";

/// `chronomap monitor ...`.
#[derive(Debug, Subcommand)]
pub enum MonitorCommand {
    /// Simulate a patrol with injected faults; print every recovery and the metrics of
    /// Tables 5.2 and 5.3.
    #[command(after_help = MONITOR_HELP_SIM)]
    Sim(MonitorSimArgs),
}

/// `chronomap monitor sim`.
#[derive(Debug, Args)]
pub struct MonitorSimArgs {
    /// Simulated hours.
    #[arg(long, default_value_t = 8.0)]
    pub hours: f64,
    /// Seed of the random faults and recovery outcomes.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Faults to inject instead of random ones (see below).
    #[arg(long)]
    pub faults: Option<PathBuf>,
    /// Every recovery fixes its fault (unless the fault says fails=N) instead of Table 5.3's
    /// success rates.
    #[arg(long)]
    pub certain: bool,
    /// The arbiter tree (BehaviorTree.CPP 4 XML with the simulation's leaves; default: the
    /// built-in one, tests/data/bt/monitor_arbiter.xml).
    #[arg(long)]
    pub arbiter: Option<PathBuf>,
    /// Print JSON instead of tables.
    #[arg(long)]
    pub json: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn eval_parses_the_acceptance_call() {
        let cli = Cli::try_parse_from([
            "chronomap",
            "eval",
            "--train",
            "training_data.txt",
            "--test",
            "test_times_1.txt,test_data_1.txt",
            "--test",
            "test_times_2.txt,test_data_2.txt",
            "--models",
            "mean,hist:24,fremen:2,fremen:4,fremen:auto,pergam:2,stm,auto",
            "--json",
        ])
        .unwrap();
        let Command::Eval(args) = cli.command else {
            panic!("not eval")
        };
        assert_eq!(args.tests.len(), 2);
        assert_eq!(args.models.0.len(), 8);
        assert!(args.json);
        assert!(Cli::try_parse_from(["chronomap", "eval", "--train", "a", "--test", "x"]).is_err());
        assert!(
            Cli::try_parse_from([
                "chronomap",
                "eval",
                "--train",
                "a",
                "--test",
                "x,y",
                "--models",
                "fremen:q"
            ])
            .is_err()
        );
    }
}
