//! Flags of `chronomap topo` and `chronomap plan`.

#[allow(unused_imports)]
use super::*;

pub(super) const TOPO_HELP_FIT: &str = "\
Example:
  chronomap topo fit --edges data/witham_topological_nav/edges -o witham.cmt

Edge files are `<From>_<To>.data` (plain, .xz or .gz) with lines `t duration_s success(0|1)`.";

pub(super) const TOPO_HELP_EVAL: &str = "\
Example (the last two weeks of the bundled Witham Wharf data):
  chronomap topo split --edges data/witham_topological_nav/edges --at 2014-08-20 \\
      --before witham-train --after witham-test
  chronomap topo eval --train witham-train --test witham-test --json

Protocols: `online` (default) predicts every test attempt from everything before it, as a robot
that keeps learning does, and learns it afterwards (the static baseline is the running per-edge
rate); `frozen` predicts all test attempts with the models as fitted on the training data.";

pub(super) const TOPO_HELP_OBSERVE: &str = "\
Example (fit on the weeks before 2014-08-20, then learn the weeks after):
  chronomap topo split --edges data/witham_topological_nav/edges --at 2014-08-20 \\
      --before witham-train --after witham-later
  chronomap topo fit --edges witham-train -o witham.cmt
  chronomap topo observe witham.cmt --edges witham-later -o witham.cmt

Every attempt must be later than what its edge learned last. Edges the models do not have are
added, modelled from their priors; an edge that joins other nodes than in the models is an
error. Nothing is learned or written when an attempt is at fault.";

pub(super) const PLAN_HELP: &str = "\
Examples:
  chronomap topo fit --edges data/witham_topological_nav/edges -o witham.cmt
  chronomap plan --model witham.cmt --from Station --task \"F Kitchen\" --time 2014-09-04T10:00Z
  chronomap plan --model witham.cmt --from Station --task \"F Kitchen\" --day-table --plot kitchen.png
  chronomap plan --model witham.cmt --from Station --task \"!Ramp1 U Kitchen\" --time 2014-09-04T10:00Z \\
      --prism witham.nm --drn witham.drn
  chronomap plan --model witham.cmt --from Kitchen --task \"F Station\" --time 2014-09-04T14:00Z \\
      --deadline 100 --confidence 0.5 --plot kitchen-deadline.png

Tasks are co-safe LTL over node names: ! & | -> X F U ( ) true false; e.g. \"F Kitchen\",
\"F (Printer & F Kitchen)\" (visit in order), \"!Ramp1 U Kitchen\" (avoid Ramp1 until Kitchen).

--deadline D plans for the greatest probability of fulfilling the task within D seconds (every
edge succeeds and the durations, drawn from each edge's duration quantiles, sum to at most D),
rounding durations up to buckets of --bucket-secs: the probability is a lower bound.";

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
    /// Teach fitted edge models later attempts, as a robot that keeps travelling learns them:
    /// success models, static rates and the online adaptation of the duration intervals.
    #[command(after_help = TOPO_HELP_OBSERVE)]
    Observe(TopoObserveArgs),
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
    /// Fix the order of every success model instead of choosing it per edge ([Fentanes 2015]:
    /// "typically, m = 2").
    #[arg(long)]
    pub success_order: Option<usize>,
    /// Most recent fraction of each edge's history held back to choose its orders.
    #[arg(long, default_value_t = 0.25, value_parser = parse_fraction)]
    pub holdout: f64,
}

impl EdgeModelFlags {
    /// The core configuration these flags describe.
    pub fn config(&self) -> chronomap_topo::edges::EdgeModelConfig {
        chronomap_topo::edges::EdgeModelConfig {
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
    /// Model file to write (`--out` is an old spelling).
    #[arg(short, long, alias = "out")]
    pub output: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Model options.
    #[command(flatten)]
    pub model: EdgeModelFlags,
}

/// `chronomap topo observe`.
#[derive(Debug, Args)]
pub struct TopoObserveArgs {
    /// Edge model file (from `chronomap topo fit`).
    pub model: PathBuf,
    /// Directory of edge files with the later attempts.
    #[arg(long)]
    pub edges: PathBuf,
    /// Model file to write (may be the one read: it is replaced atomically).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
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
    /// Draw the calibration as a PNG: the reliability diagram of the success probabilities
    /// (edge models and static rates, the chosen protocol) and the share of successful
    /// durations inside their intervals against the nominal coverage (10 % … 99 %).
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
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
    /// Split time: unix seconds or ISO 8601 (2014-08-20; UTC unless an offset is given).
    #[arg(long, value_parser = parse_time)]
    pub at: f64,
    /// Directory for the attempts before the split (created; must not hold edge files).
    #[arg(long)]
    pub before: PathBuf,
    /// Directory for the attempts at or after the split.
    #[arg(long)]
    pub after: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `chronomap topo predict`.
#[derive(Debug, Args)]
pub struct TopoPredictArgs {
    /// Edge-model file (`topo fit`).
    pub model: PathBuf,
    /// Time: unix seconds or ISO 8601 (2014-09-04T08:00Z; UTC unless an offset is given).
    #[arg(long, value_parser = parse_time)]
    pub time: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write the map as a Nav2 route-server graph (GeoJSON) with the predictions.
    ///
    /// Each edge's metadata holds flat numbers: success_probability, abs_time_taken (expected
    /// seconds) and the 90 % interval of the duration, abs_time_taken_lower,
    /// abs_time_taken_upper and abs_time_taken_coverage (0.9; none of the three for models
    /// written before intervals existed), e.g. {"name": "LabDoor1_LabDoor2",
    /// "success_probability": 0.49, "abs_time_taken": 8.9, "abs_time_taken_lower": 5.7,
    /// "abs_time_taken_upper": 13.9, "abs_time_taken_coverage": 0.9}.
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
    /// Plan for this start time: unix seconds or ISO 8601 (2014-09-04T10:00Z; UTC unless an
    /// offset is given).
    #[arg(long, value_parser = parse_time)]
    pub time: Option<f64>,
    /// The now-or-later table: every hour (see --step-mins) of a week (see --week-of); with
    /// --deadline, of the plans most likely to arrive in time.
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
    /// Any time in the first day of the table: unix seconds or ISO 8601 (2014-09-05; UTC
    /// unless an offset is given). Default: the day after the model's data.
    #[arg(long, value_parser = parse_time, conflicts_with = "time")]
    pub week_of: Option<f64>,
    /// Days in the table.
    #[arg(
        long,
        default_value_t = 7,
        value_parser = clap::value_parser!(u32).range(1..=28),
        conflicts_with = "time"
    )]
    pub days: u32,
    /// Minutes between the table's start times.
    #[arg(
        long,
        default_value_t = 60,
        value_parser = clap::value_parser!(u32).range(5..=720),
        conflicts_with = "time"
    )]
    pub step_mins: u32,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Write a PNG: the table as a heat map (with --day-table; of the probabilities within
    /// the deadline with --deadline), or the probability of fulfilling the task within d
    /// seconds for every d up to the deadline (with --time and --deadline).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Plan for the greatest probability of fulfilling the task within this many seconds of
    /// --time ("arrive by T"), or of every start time of --day-table (when to leave to be
    /// there in time): a finite number > 0.
    #[arg(long, value_parser = parse_positive)]
    pub deadline: Option<f64>,
    /// With --time and --deadline: the probability asked for; the report says whether the
    /// plan reaches it and within how many seconds it could [default: 0.95].
    #[arg(
        long,
        value_parser = parse_probability,
        requires = "deadline",
        conflicts_with = "day_table"
    )]
    pub confidence: Option<f64>,
    /// With --deadline: the width of the time buckets durations are rounded up to, seconds
    /// [default: the deadline / 600, at least 1].
    #[arg(long, value_parser = parse_positive, requires = "deadline")]
    pub bucket_secs: Option<f64>,
    /// Write the Navigation MDP at --time in the PRISM language (STRANDS layout) and its
    /// property next to it (`.props`).
    #[arg(long, conflicts_with = "day_table")]
    pub prism: Option<PathBuf>,
    /// Write the product MDP at --time in Storm's explicit DRN format.
    #[arg(long, conflicts_with = "day_table")]
    pub drn: Option<PathBuf>,
}
