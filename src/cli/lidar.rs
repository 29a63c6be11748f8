//! Flags of `chronomap lidar` and `chronomap maps`.

#[allow(unused_imports)]
use super::*;

pub(super) const LIDAR_HELP: &str = "\
Examples (the bundled Málaga 2006 loop):
  chronomap lidar eval --keyframes data/malaga_laser_2006/keyframes_slam.txt.xz --plot roc.png
  chronomap lidar train --keyframes data/malaga_laser_2006/keyframes_slam.txt.xz -o malaga.cml
  chronomap lidar detect --classifier malaga.cml --sensor-offset 0.78,0 --plot loops.png \\
      --bag data/malaga_laser_2006/rosbag2/malaga_2006_bag
  chronomap lidar register --keyframes data/malaga_laser_2006/keyframes_slam.txt.xz
  chronomap lidar register data/registration_small_gicp/source.ply.xz \\
      data/registration_small_gicp/target.ply.xz \\
      --truth data/registration_small_gicp/T_target_source.txt

Scans: the text format of the bundled log (one scan a line; keyframe files start each line
with the SLAM pose `x y yaw`), or a rosbag2 bag with sensor_msgs/msg/LaserScan and
nav_msgs/msg/Odometry. Clouds: PLY (ascii or binary) with vertex x, y, z.";

pub(super) const MAPS_HELP: &str = "\
Example (the bundled Málaga 2006 loop):
  chronomap maps build --scans data/malaga_laser_2006/scans.txt.xz \\
      --odometry data/malaga_laser_2006/odometry.txt.xz --plot maps.png

A new map starts where the robot passes a door (criteria C1–C3 of the dissertation's §3.3.2);
its configuration is chosen by the size of the room it enters.";

/// `chronomap lidar ...`.
#[derive(Debug, Subcommand)]
pub enum LidarCommand {
    /// Global descriptors of scans or of a 3-D cloud ([Granström 2009]): the 32 scalar
    /// features per scan, as CSV (or all 843 numbers with --json).
    Descriptors(LidarDescriptorsArgs),
    /// Cross-validate the loop classifier on keyframes with known poses: ROC, AUC and the
    /// true-positive rate at a false-positive rate below 1 % (dissertation §3.2.1).
    Eval(LidarEvalArgs),
    /// Train the loop classifier on keyframes with known poses, choose p_min by
    /// cross-validation, and save it.
    Train(LidarTrainArgs),
    /// Detect loops along a log of scans and odometry: search radius (eq. 3.8), classifier,
    /// verification.
    Detect(LidarDetectArgs),
    /// Register two clouds (or two scans) without an initial guess: FPFH, RANSAC and ICP
    /// (dissertation §3.2.2).
    Register(LidarRegisterArgs),
}

/// Where a log of 2-D scans comes from.
#[derive(Debug, Args)]
pub struct LaserSourceArgs {
    /// Keyframes with their SLAM poses (`x y yaw` then the scan, one a line).
    #[arg(long, value_name = "FILE")]
    pub keyframes: Option<PathBuf>,
    /// Scans, one a line (`t aperture right_to_left max_range sensor_x … n r… valid…`).
    #[arg(long, value_name = "FILE")]
    pub scans: Option<PathBuf>,
    /// Odometry increments `t dx dy dyaw` (robot frame) for --scans or --keyframes.
    #[arg(long, value_name = "FILE")]
    pub odometry: Option<PathBuf>,
    /// A rosbag2 bag (directory, .mcap or .db3) with LaserScan and Odometry topics.
    #[arg(long, value_name = "BAG")]
    pub bag: Option<PathBuf>,
    /// The bag's scan topic.
    #[arg(long, default_value = "/scan")]
    pub scan_topic: String,
    /// The bag's odometry topic.
    #[arg(long, default_value = "/odom")]
    pub odom_topic: String,
    /// The laser's position on the robot `x,y` (m) for bags (they carry no TF here).
    #[arg(long, value_name = "X,Y", default_value = "0,0", value_parser = parse_xy)]
    pub sensor_offset: [f64; 2],
}

/// `chronomap lidar descriptors`.
#[derive(Debug, Args)]
pub struct LidarDescriptorsArgs {
    /// The scans (or --cloud).
    #[command(flatten)]
    pub source: LaserSourceArgs,
    /// A 3-D point cloud (PLY) instead of scans.
    #[arg(long, value_name = "PLY", conflicts_with_all = ["keyframes", "scans", "bag"])]
    pub cloud: Option<PathBuf>,
    /// CSV file to write (default: stdout).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Print JSON (every descriptor, histograms included).
    #[arg(long)]
    pub json: bool,
}

/// How loop pairs are labelled and the classifier is trained.
#[derive(Debug, Args)]
pub struct LoopTrainingFlags {
    /// The dissertation's classifier (41 pair values, AdaBoost with stumps, balanced subsets)
    /// instead of ours (3 heading-tolerant range-profile values added, depth-2 trees, class
    /// weights).
    #[arg(long)]
    pub paper: bool,
    /// Keyframes closer than this (m) and --min-separation apart in the sequence are loops.
    #[arg(long, default_value_t = 3.0, value_parser = parse_positive)]
    pub near: f64,
    /// Keyframes farther apart than this (m) are not loops; pairs between are left out.
    #[arg(long, default_value_t = 10.0, value_parser = parse_positive)]
    pub far: f64,
    /// Loops must be more than this many keyframes apart.
    #[arg(long, default_value_t = 20)]
    pub min_separation: usize,
    /// AdaBoost rounds T.
    #[arg(long, default_value_t = 50)]
    pub rounds: usize,
    /// Largest false-positive rate allowed when choosing p_min.
    #[arg(long, default_value_t = 0.01, value_parser = parse_probability)]
    pub max_fpr: f64,
    /// Cross-validation folds (keyframes split by place).
    #[arg(long, default_value_t = 5)]
    pub folds: usize,
    /// Fold layouts (rotations of the places) averaged over.
    #[arg(long, default_value_t = 10)]
    pub layouts: usize,
}

/// `chronomap lidar eval`.
#[derive(Debug, Args)]
pub struct LidarEvalArgs {
    /// Keyframes with their SLAM poses.
    #[arg(long, value_name = "FILE")]
    pub keyframes: PathBuf,
    /// Odometry increments for the loop-detection run (default: the motion between the SLAM
    /// poses, i.e. perfect odometry).
    #[arg(long, value_name = "FILE")]
    pub odometry: Option<PathBuf>,
    /// Labels and training.
    #[command(flatten)]
    pub training: LoopTrainingFlags,
    /// Draw the ROC curves and the trajectory with the labelled loops.
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object (with the ROC points).
    #[arg(long)]
    pub json: bool,
}

/// `chronomap lidar train`.
#[derive(Debug, Args)]
pub struct LidarTrainArgs {
    /// Keyframes with their SLAM poses.
    #[arg(long, value_name = "FILE")]
    pub keyframes: PathBuf,
    /// Labels and training.
    #[command(flatten)]
    pub training: LoopTrainingFlags,
    /// Classifier file to write.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `chronomap lidar detect`.
#[derive(Debug, Args)]
pub struct LidarDetectArgs {
    /// A classifier file (`chronomap lidar train`).
    #[arg(long, value_name = "FILE")]
    pub classifier: PathBuf,
    /// The log.
    #[command(flatten)]
    pub source: LaserSourceArgs,
    /// Keyframes every this many metres of odometry (logs of scans and bags).
    #[arg(long, default_value_t = 0.75, value_parser = parse_positive)]
    pub keyframe_distance: f64,
    /// … or every this many radians of turning.
    #[arg(long, default_value_t = 0.35, value_parser = parse_positive)]
    pub keyframe_angle: f64,
    /// Override the classifier's threshold p_min.
    #[arg(long, value_parser = parse_probability)]
    pub p_min: Option<f64>,
    /// Loops must be more than this many keyframes apart.
    #[arg(long, default_value_t = 20)]
    pub min_separation: usize,
    /// Write the loops as CSV (`query,target,probability,radius_m,mode`).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Draw the trajectory with the loops found.
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `chronomap lidar register`.
#[derive(Debug, Args)]
pub struct LidarRegisterArgs {
    /// The cloud to move (PLY); or use --keyframes.
    #[arg(required_unless_present = "keyframes", requires = "target")]
    pub source: Option<PathBuf>,
    /// The cloud to move it onto (PLY).
    pub target: Option<PathBuf>,
    /// 2-D scans instead: keyframes with SLAM poses. Without --pair, every loop pair (closer
    /// than --near, more than --min-separation keyframes apart) is registered and compared
    /// with the SLAM relative pose.
    #[arg(long, value_name = "FILE", conflicts_with_all = ["source", "truth"])]
    pub keyframes: Option<PathBuf>,
    /// With --keyframes: register keyframe J onto keyframe I (0-based).
    #[arg(long, value_name = "I,J", requires = "keyframes", value_parser = parse_pair)]
    pub pair: Option<[usize; 2]>,
    /// With --keyframes: loop pairs are closer than this (m) …
    #[arg(long, default_value_t = 3.0, value_parser = parse_positive)]
    pub near: f64,
    /// … and more than this many keyframes apart.
    #[arg(long, default_value_t = 20)]
    pub min_separation: usize,
    /// The true 4×4 transform (text, row-major) to report errors against.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Voxel size (m) of the downsampled clouds for features and RANSAC (3-D clouds).
    #[arg(long, default_value_t = 0.25, value_parser = parse_positive)]
    pub voxel: f64,
    /// Voxel size (m) of the filtered clouds ICP refines on (3-D clouds).
    #[arg(long, default_value_t = 0.05, value_parser = parse_positive)]
    pub fine_voxel: f64,
    /// Points farther than this from the sensor (m) are dropped first (dissertation
    /// appendix A: 30 m; 3-D clouds).
    #[arg(long, default_value_t = 30.0, value_parser = parse_positive)]
    pub max_range: f64,
    /// Seed of RANSAC (default: the library's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Write the estimated transform (4×4, or 3×3 for scans; text, row-major).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `chronomap maps ...`.
#[derive(Debug, Subcommand)]
pub enum MapsCommand {
    /// Run the map manager along a log: door passages, one map per room, links, the robot's
    /// pose uncertainty (dissertation §3.3).
    #[command(after_help = MAPS_HELP)]
    Build(MapsBuildArgs),
}

/// `chronomap maps build`.
#[derive(Debug, Args)]
pub struct MapsBuildArgs {
    /// The log.
    #[command(flatten)]
    pub source: LaserSourceArgs,
    /// Write the map graph as JSON.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Draw the trajectory coloured by map, with door passages.
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `I,J` as two indices.
fn parse_pair(text: &str) -> Result<[usize; 2], String> {
    match text.split_once(',') {
        Some((i, j)) => match (i.trim().parse(), j.trim().parse()) {
            (Ok(i), Ok(j)) => Ok([i, j]),
            _ => Err(format!("{text:?} is not I,J (two keyframe indices)")),
        },
        None => Err(format!("{text:?} is not I,J (two keyframe indices)")),
    }
}

/// `X,Y` as two finite numbers of metres, each at most
/// [`MAX_LENGTH_M`](chronomap_io::laser_text::MAX_LENGTH_M) in magnitude (as offsets in the
/// text logs).
fn parse_xy(text: &str) -> Result<[f64; 2], String> {
    let parts: Vec<&str> = text.split(',').collect();
    let numbers: Vec<f64> = parts
        .iter()
        .filter_map(|p| p.trim().parse::<f64>().ok().filter(|x| x.is_finite()))
        .collect();
    let limit = chronomap_io::laser_text::MAX_LENGTH_M;
    match numbers[..] {
        [x, y] if parts.len() == 2 && x.abs() <= limit && y.abs() <= limit => Ok([x, y]),
        [_, _] if parts.len() == 2 => Err(format!(
            "{text:?}: an offset beyond ±{limit} m (the laser sits on the robot)"
        )),
        _ => Err(format!("{text:?} is not X,Y (two finite numbers)")),
    }
}
