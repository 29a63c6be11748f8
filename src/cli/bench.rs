//! Flags of `chronomap bench`.

#[allow(unused_imports)]
use super::*;

/// `chronomap bench ...`.
#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// The 4-D office grid of [Krajník 2017] §VI (213,000 cells x 17,280 frames/day x 112 days),
    /// streamed from the synthetic generator into FreMEn grids, against a bare scan of the same
    /// frames.
    Grid(BenchGridArgs),
    /// Memory and grid-file bytes per changing cell of FreMEn grids of 10^4 to 4*10^6 cells whose
    /// every cell changes, against the representation of grid-state format 1 in the same run.
    #[command(name = "grid-memory", after_help = BENCH_GRID_MEMORY_HELP)]
    GridMemory(BenchGridMemoryArgs),
    /// Planning on the Witham map ([Fentanes 2015] §V), 24 hours x 3 tasks, end to end, against
    /// Storm (stormpy) on the same cases in the same run.
    #[command(after_help = BENCH_PLAN_HELP)]
    Plan(BenchPlanArgs),
    /// The service on loopback (redb store, token): latency of predict and forecast from
    /// concurrent clients, and durable observations/s of batched adds, against the same work
    /// done in-process (and straight into redb) in the same run.
    #[cfg(feature = "serve")]
    #[command(after_help = BENCH_SERVE_HELP)]
    Serve(BenchServeArgs),
    /// A fleet (`serve --fleet`) of 1, 2 and 3 nodes on loopback over one PostgreSQL server:
    /// durable observations/s and p99 predict latency under that load, against a batched INSERT
    /// and a COPY of the same rows in the same run; and a new node's catch-up over 10^7 logged
    /// observations.
    #[cfg(feature = "serve")]
    #[command(after_help = BENCH_FLEET_HELP)]
    Fleet(BenchFleetArgs),
    /// CoPA-Map's activity pipeline ([Stüde 2024] chapter 4) on the bundled ATC data: training-data
    /// extraction (§4.2.2) against a bare binning pass over the same detections, and CoPA-Map
    /// training (eqs. 4.12–4.16) against the bare faer matrix products of its iterations.
    #[command(after_help = BENCH_ACTIVITY_HELP)]
    Activity(BenchActivityArgs),
    /// Person search tree synthesis (dissertation §5.4) for 6 and 10 places on the bundled ATC
    /// day, against the dense-generator reference and a per-tree solve in the same run.
    #[command(after_help = BENCH_PSBT_HELP)]
    Psbt(BenchPsbtArgs),
    /// Reading and checking BehaviorTree.CPP 4 XML (`chronomap bt check`) on generated trees:
    /// 20,000 and 100,000 siblings, 100 trees 1,000 levels deep, 2,000 nodes of 50 attributes on
    /// one line, against parsing the same text with roxmltree alone in the same run.
    #[command(after_help = BENCH_BT_HELP)]
    Bt(BenchBtArgs),
    /// Bag ingestion (`chronomap ingest`): messages/s and MB/s of reading, decoding and taking out
    /// the records of a rosbag2 MCAP bag, against a bare read of the same file in the same run.
    #[command(after_help = BENCH_INGEST_HELP)]
    Ingest(BenchIngestArgs),
    /// Registration of two 3-D clouds without an initial guess (dissertation §3.2.2: FPFH,
    /// RANSAC, ICP) against a bare nearest-neighbour pass over the same clouds in the same run,
    /// with the errors against their known transform.
    #[command(after_help = BENCH_REGISTRATION_HELP)]
    Registration(BenchRegistrationArgs),
    /// The ROS 2 node's predicted maps (1 MB and 4 MB OccupancyGrid, one per second) to an
    /// rclpy subscriber with Nav2's map QoS: delivery delay and losses, against an rclpy
    /// publisher (Fast DDS to Fast DDS) to the same subscriber in the same run.
    #[cfg(feature = "ros2")]
    #[command(after_help = BENCH_ROS2_HELP)]
    Ros2(BenchRos2Args),
}

#[cfg(feature = "ros2")]
pub(super) const BENCH_ROS2_HELP: &str = "\
It runs the node (this binary's `ros2`) and the Python driver tests/ros2/bench_maps.py in a
private network namespace that it makes (`unshare -n` as root, `unshare -rn` otherwise). The
Python needs rclpy (Fast DDS) and nav_msgs; .ci/run makes one in target/ros-venv.

Examples:
  chronomap bench ros2 --python target/ros-venv/bin/python
  chronomap bench ros2 --python target/ros-venv/bin/python --sides 1000,2000,3000 --maps 20 --json";

/// `chronomap bench ros2`.
#[cfg(feature = "ros2")]
#[derive(Debug, Args)]
pub struct BenchRos2Args {
    /// A Python with rclpy (Fast DDS) and nav_msgs.
    #[arg(long, env = "CHRONOMAP_ROS_PYTHON")]
    pub python: PathBuf,
    /// Map sides in cells (1000: a 1 MB map, 2000: 4 MB).
    #[arg(long, value_delimiter = ',', num_args = 1.., default_value = "1000,2000",
          value_parser = clap::value_parser!(u32).range(1..=20_000))]
    pub sides: Vec<u32>,
    /// Maps measured per size and publisher (after two warm-up maps).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub maps: u32,
    /// Seconds between maps (the node's `map_period`).
    #[arg(long, default_value_t = 1.0, value_parser = parse_map_period)]
    pub period: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

#[cfg(feature = "ros2")]
fn parse_map_period(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(p) if p.is_finite() && (0.05..=3600.0).contains(&p) => Ok(p),
        _ => Err(format!(
            "{text:?} is not a number of seconds in [0.05, 3600]"
        )),
    }
}

pub(super) const BENCH_REGISTRATION_HELP: &str = "\
Without arguments: the bundled small_gicp pair of real 3-D lidar scans (69,792 and 69,088
points) and its transform.

Examples:
  chronomap bench registration
  chronomap bench registration --repeats 9 --json";

/// `chronomap bench registration`.
#[derive(Debug, Args)]
pub struct BenchRegistrationArgs {
    /// The cloud to move (PLY).
    #[arg(long, default_value = "data/registration_small_gicp/source.ply.xz")]
    pub source: PathBuf,
    /// The cloud to move it onto (PLY).
    #[arg(long, default_value = "data/registration_small_gicp/target.ply.xz")]
    pub target: PathBuf,
    /// Their true 4×4 transform (text, row-major).
    #[arg(
        long,
        default_value = "data/registration_small_gicp/T_target_source.txt"
    )]
    pub truth: PathBuf,
    /// Timed runs of each part (the median is reported).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeats: u32,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub(super) const BENCH_INGEST_HELP: &str = "\
Without --bag: the greg door training data written as a bag of 96,480 std_msgs/msg/Bool
messages in zstd chunks (as `ros2 bag record` writes them, into a temporary file), and the
bundled Málaga laser bag's /scan.

Examples:
  chronomap bench ingest --json
  chronomap bench ingest --bag my_bag --topic /map --repeats 3";

/// `chronomap bench ingest`.
#[derive(Debug, Args)]
pub struct BenchIngestArgs {
    /// A bag to time (repeatable, each with a --topic; a folder needs its metadata.yaml).
    #[arg(long, requires = "topic")]
    pub bag: Vec<PathBuf>,
    /// The topic of each --bag, in order.
    #[arg(long)]
    pub topic: Vec<String>,
    /// Timed runs of each pass (the median is reported).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeats: u32,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub(super) const BENCH_BT_HELP: &str = "\
Examples:
  chronomap bench bt
  chronomap bench bt --repeats 9 --json";

/// `chronomap bench bt`.
#[derive(Debug, Args)]
pub struct BenchBtArgs {
    /// Timed runs of each case (the median is reported).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeats: u32,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub(super) const BENCH_PSBT_HELP: &str = "\
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

pub(super) const BENCH_GRID_MEMORY_HELP: &str = "\
Every cell changes: in frame 0 a quarter of the cells are unknown, then every cell flips each
frame (one a minute). A 4096-cell grid of the same frames is checked first: the baseline written
as a format-1 file and read back holds every cell's sums as the new grid does.

Examples:
  chronomap bench grid-memory
  chronomap bench grid-memory --periods day --json
  chronomap bench grid-memory --cells 10000,100000,1000000 --frames 40";

/// `chronomap bench grid-memory`.
#[derive(Debug, Args)]
pub struct BenchGridMemoryArgs {
    /// Cell counts of the grids (comma-separated).
    #[arg(long, value_delimiter = ',', num_args = 1.., default_value = "10000,100000,1000000,4000000", value_parser = clap::value_parser!(u64).range(1..=u64::from(u32::MAX)))]
    pub cells: Vec<u64>,
    /// Frames (every cell changes in each after the first).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: u32,
    /// Candidate periods of every cell: week, day, year, BASE/COUNT or a comma list of seconds.
    #[arg(long, default_value = "week", value_parser = parse_periods)]
    pub periods: PeriodSet,
    /// Model order (kept in the grid's configuration; memory does not depend on it).
    #[arg(long, default_value_t = 2)]
    pub order: usize,
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

pub(super) const BENCH_PLAN_HELP: &str = "\
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

#[cfg(feature = "serve")]
pub(super) const BENCH_SERVE_HELP: &str = "\
Examples:
  chronomap bench serve                          # about 10 s on 2 cores
  chronomap bench serve --models 1000 --clients 8 --json
  chronomap bench serve --observations 2000000 --batch 20000 --data bench-data   # keep the store";

/// `chronomap bench serve`.
#[cfg(feature = "serve")]
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
    /// Instead: grid maps asked for by --grid-clients clients, and health and door
    /// predictions beside them, against `chronomap serve` of this binary and of
    /// --baseline-bin, each in a process of its own, in turns.
    #[arg(long)]
    pub grid_load: bool,
    /// The `chronomap` binary to compare with in --grid-load (e.g. built from an earlier
    /// commit).
    #[arg(long, requires = "grid_load")]
    pub baseline_bin: Option<PathBuf>,
    /// Cells of the synthetic office grid of --grid-load.
    #[arg(long, default_value_t = 40_000, requires = "grid_load")]
    pub grid_cells: usize,
    /// Concurrent clients asking for the grid's map in --grid-load.
    #[arg(long, default_value_t = 20, requires = "grid_load")]
    pub grid_clients: usize,
    /// Seconds of each phase of --grid-load.
    #[arg(long, default_value_t = 3.0, requires = "grid_load")]
    pub grid_seconds: f64,
    /// Rounds of --grid-load (each service measured once a round).
    #[arg(long, default_value_t = 3, requires = "grid_load")]
    pub grid_rounds: usize,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub(super) const BENCH_FLEET_HELP: &str = "\
Needs a PostgreSQL server the role may create schemas on (each run makes its own and drops it).

Examples:
  chronomap bench fleet --postgres 'host=127.0.0.1 dbname=lab'     # about 1 min on 2 cores
  chronomap bench fleet --nodes 1,3 --seconds 2 --catch-up-observations 0 --json";

/// `chronomap bench fleet`.
#[cfg(feature = "serve")]
#[derive(Debug, Args)]
pub struct BenchFleetArgs {
    /// PostgreSQL: a libpq connection string or postgresql:// URL.
    #[arg(long, env = "CHRONOMAP_POSTGRES", hide_env_values = true)]
    pub postgres: String,
    /// Node counts to measure, each on a fresh schema.
    #[arg(long, value_delimiter = ',', default_value = "1,2,3")]
    pub nodes: Vec<usize>,
    /// Writing clients per node.
    #[arg(long, default_value_t = 2)]
    pub clients_per_node: usize,
    /// Models written.
    #[arg(long, default_value_t = 120)]
    pub models: usize,
    /// Spec of the models.
    #[arg(long, default_value = "fremen:2")]
    pub model: String,
    /// Observations per request (`POST /v1/observations`).
    #[arg(long, default_value_t = 1_000)]
    pub batch: usize,
    /// Models per request.
    #[arg(long, default_value_t = 10)]
    pub batch_ids: usize,
    /// Seconds of writing per node count.
    #[arg(long, default_value_t = 5.0)]
    pub seconds: f64,
    /// Observations of the catch-up log (0: skip the catch-up).
    #[arg(long, default_value_t = 10_000_000)]
    pub catch_up_observations: u64,
    /// Keep the schemas instead of dropping them.
    #[arg(long)]
    pub keep: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

pub(super) const BENCH_ACTIVITY_HELP: &str = "\
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
