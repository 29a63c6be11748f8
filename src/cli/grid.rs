//! Flags of `chronomap grid`.

#[allow(unused_imports)]
use super::*;

/// `chronomap grid ...`.
#[derive(Debug, Subcommand)]
pub enum GridCommand {
    /// Build a grid from frames (ROS/Nav2 maps, per-cell series, or the synthetic office) and
    /// save it; optionally report the estimation errors of [Krajník 2017] §VI.
    #[command(after_help = GRID_BUILD_HELP)]
    Build(GridBuildArgs),
    /// Predict the map at a time and write it as a ROS map_server / Nav2 map (YAML + image).
    #[command(after_help = GRID_PREDICT_HELP)]
    Predict(GridPredictArgs),
    /// Show what a grid file holds: size, changing cells, compression ratio (eq. 16).
    #[command(after_help = "Example:\n  chronomap grid stats office.cmg --json")]
    Stats(GridStatsArgs),
    /// Draw the maps predicted for several times side by side.
    #[command(after_help = GRID_PLOT_HELP)]
    Plot(GridPlotArgs),
}

pub(super) const GRID_BUILD_HELP: &str = "\
Examples:
  chronomap grid build --synthetic --days 14 --cells 32000 -o office.cmg --errors
  chronomap grid build --frames frames.txt -o corridor.cmg   # lines: <unix time> <map.yaml>
  chronomap grid build --bag maps_bag --topic /map -o corridor.cmg   # nav_msgs/msg/OccupancyGrid
  chronomap grid build --cell-series data/aruba_rooms_1min/presence_minutes_0.txt.xz,... -o flat.cmg --json";

pub(super) const GRID_PREDICT_HELP: &str = "\
The time is unix seconds or ISO 8601 (2016-04-26T09:00:00Z; UTC unless an offset is given).

Examples:
  chronomap grid predict office.cmg --time 1461661200 -o predicted/map.yaml
  (writes predicted/map.yaml and predicted/map.pgm)
  chronomap grid predict office.cmg --time 2016-04-26T09:00:00Z -o mask --mode scale --json";

pub(super) const GRID_PLOT_HELP: &str = "\
Times are unix seconds or ISO 8601 (2016-04-26T02:00:00Z; UTC unless an offset is given).

Example:
  chronomap grid plot office.cmg --time 1461636000,1461672000 --plot maps.png";

/// Where `grid build` gets its frames.
#[derive(Debug, Args)]
#[group(required = true, multiple = false)]
pub struct GridSource {
    /// The synthetic office (see --cells, --days, --seed).
    #[arg(long)]
    pub synthetic: bool,
    /// A list of frames, one per line: `<time> <map.yaml>` (times in unix seconds; ROS
    /// map_server / Nav2 maps, paths relative to the list).
    #[arg(long)]
    pub frames: Option<PathBuf>,
    /// One `t value` file per cell (a symbolic map), all with the same times; comma-separated
    /// or repeated.
    #[arg(long, value_delimiter = ',')]
    pub cell_series: Vec<PathBuf>,
    /// A ROS 2 bag (rosbag2 folder or .mcap file) whose --topic carries
    /// nav_msgs/msg/OccupancyGrid maps, one frame each.
    #[arg(long, requires = "topic")]
    pub bag: Option<PathBuf>,
}

/// `chronomap grid build`.
#[derive(Debug, Args)]
pub struct GridBuildArgs {
    /// The frames.
    #[command(flatten)]
    pub source: GridSource,
    /// With --bag: the topic of the maps.
    #[arg(long, requires = "bag")]
    pub topic: Option<String>,
    /// With --bag: where a map's time comes from (header.stamp by default).
    #[arg(long, value_enum, default_value_t = TimeArg::Auto, requires = "bag")]
    pub time: TimeArg,
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
    #[arg(long, default_value = "2", value_parser = parse_order)]
    pub order: OrderArg,
    /// Candidate periods of every cell's FreMEn model.
    #[arg(long, default_value = "week", value_parser = parse_periods)]
    pub periods: PeriodSet,
    /// Report the estimation and prediction errors of [Krajník 2017] §VI for static, orders 1-5 and
    /// auto, with the lossy and lossless file sizes.
    #[arg(long)]
    pub errors: bool,
    /// Fraction of the frames (the most recent) held back to choose orders and measure
    /// prediction errors.
    #[arg(long, default_value_t = 0.25, value_parser = parse_fraction)]
    pub holdout: f64,
    /// Threads for the synthetic office (default: all).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub threads: Option<u32>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
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
    /// Time to predict: unix seconds or ISO 8601 (UTC unless an offset is given).
    #[arg(long, value_parser = parse_time)]
    pub time: f64,
    /// The map's YAML file (`map.yaml`, or `map` without extension): the image is written beside
    /// it (`map.pgm`, or `map.png` with --mode scale).
    #[arg(short, long, alias = "out")]
    pub output: PathBuf,
    /// Map mode: trinary (free/occupied/unknown, like map_saver) or scale (a costmap filter
    /// mask).
    #[arg(long, value_enum, default_value_t = MapModeArg::Trinary)]
    pub mode: MapModeArg,
    /// Order of the prediction (learning-state files only; default: the configured one).
    #[arg(long)]
    pub order: Option<usize>,
    /// For 3-D grids: the layers (z indices, `a..b`) projected onto the 2-D map; a column is as
    /// occupied as its most occupied known cell (default: all layers).
    #[arg(long, value_parser = parse_layers)]
    pub layers: Option<Layers>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `--layers a..b`: z indices `a` (inclusive) to `b` (exclusive).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Layers(pub u32, pub u32);

fn parse_layers(text: &str) -> Result<Layers, String> {
    let bad = || format!("{text:?} is not a..b (first and last + 1 layer, a < b)");
    let (a, b) = text.split_once("..").ok_or_else(bad)?;
    let (a, b): (u32, u32) = (
        a.trim().parse().map_err(|_| bad())?,
        b.trim().parse().map_err(|_| bad())?,
    );
    if a >= b {
        return Err(bad());
    }
    Ok(Layers(a, b))
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
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `chronomap grid plot`.
#[derive(Debug, Args)]
pub struct GridPlotArgs {
    /// Grid file.
    pub grid: PathBuf,
    /// Times to predict: unix seconds or ISO 8601 (UTC unless an offset is given);
    /// comma-separated or repeated (default: 3:00 and 14:00 on the day after the data).
    #[arg(long = "time", value_delimiter = ',', value_parser = parse_time)]
    pub times: Vec<f64>,
    /// Order of the prediction (learning-state files only).
    #[arg(long)]
    pub order: Option<usize>,
    /// Layers of a 3-D grid to project (`a..b`).
    #[arg(long, value_parser = parse_layers)]
    pub layers: Option<Layers>,
    /// PNG to write.
    #[arg(long, short_alias = 'o', alias = "output")]
    pub plot: PathBuf,
}
