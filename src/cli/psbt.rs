//! Flags of `chronomap psbt`.

#[allow(unused_imports)]
use super::*;

pub(super) const PSBT_HELP: &str = "\
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
    /// Pedestrian track files, `t,person,x,y,speed,heading` (several after the flag, the flag
    /// repeated, or comma-separated; .xz/.gz read), or one CoPA-Map model file of `chronomap
    /// activity fit` (.cmcopa; synthesis only).
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
    /// Number of places n_pl (1 to 16).
    #[arg(long, default_value_t = 6,
          value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..=16))]
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
    /// Time of the request: unix seconds or ISO 8601 (2012-10-24T05:30Z; UTC unless an offset
    /// is given).
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
    /// Time of the requests: unix seconds or ISO 8601 (2012-10-24T06:30Z; UTC unless an
    /// offset is given).
    #[arg(long, value_parser = parse_time)]
    pub time: f64,
    /// The planning model learns from tracks before this time (unix seconds or ISO 8601;
    /// default: the start of the interval of --time); the scoring model from the tracks of
    /// that interval.
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
pub(super) fn parse_xy(text: &str) -> Result<[f64; 2], String> {
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
