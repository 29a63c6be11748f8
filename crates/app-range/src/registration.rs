//! Scan and cloud registration without an initial guess as jobs with reports ([Stüde 2024]
//! §3.2.2): two PLY clouds registered with FPFH, RANSAC and ICP (against a true transform when
//! one is given), and the loop pairs of a keyframe log registered against their SLAM relative
//! poses (the registration-vs-SLAM study). The reports render as the text of
//! `chronomap lidar register` and serialise as its `--json`.

use std::fmt::Write as _;
use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::progress::Progress;
use chronomap_geometry::GeometryError;
use chronomap_io::DataError;
use chronomap_io::ply::{PlyError, PlyErrorKind, read_ply_at_most};
use chronomap_registration::rigid::Rigid;
use chronomap_registration::{
    Cloud, MAX_FEATURE_POINTS, MAX_ICP_POINTS, MAX_INPUT_POINTS, RegistrationError, register,
};
use serde::Serialize;

use crate::laser_log::LaserLog;
use crate::lidar_study::{
    LoopStudyError, PairRegistration, RegistrationSummary, cloud_params, loop_pairs,
    register_pairs, within_range,
};

/// A registration job that cannot run: a file, or clouds the pipeline refuses. The messages
/// name the settings by the command line's flags (`--voxel`, `--fine-voxel`, `--max-range`).
#[derive(Debug, thiserror::Error)]
pub enum RegistrationJobError {
    /// A PLY file that cannot be read.
    #[error(transparent)]
    Ply(#[from] PlyError),
    /// A PLY file announcing more than [`MAX_INPUT_POINTS`] points.
    #[error(
        "{file}: line {line}: element vertex: {count} points, {purpose} takes at most \
         {MAX_INPUT_POINTS} a cloud (24 bytes each): thin the cloud first"
    )]
    TooManyPoints {
        /// The file.
        file: String,
        /// The header line of the vertex element.
        line: usize,
        /// The points it announces.
        count: u64,
        /// What the cloud is read for.
        purpose: String,
    },
    /// Too few points of a cloud within range of its sensor.
    #[error(
        "{file}: {within} of its {points} points lie within --max-range {max_range} m of the \
         sensor (the origin), at least 9 are needed; its nearest point is {nearest:.1} m away: \
         give a larger --max-range"
    )]
    OutOfRange {
        /// The file.
        file: String,
        /// Points within range.
        within: usize,
        /// Points of the cloud.
        points: usize,
        /// The range (m).
        max_range: f64,
        /// The distance of its nearest point (m).
        nearest: f64,
    },
    /// More points than [`MAX_FEATURE_POINTS`] on the coarse grid.
    #[error(
        "{file}: more than {MAX_FEATURE_POINTS} points remain on the --voxel {voxel} m grid, \
         at most {MAX_FEATURE_POINTS} enter feature computation (FPFH keeps about 2 KB \
         a point; counted in the first {seen} of the {points} points left after \
         --fine-voxel and --max-range): give a larger --voxel (about {larger:.2} m)"
    )]
    TooManyFeaturePoints {
        /// The file.
        file: String,
        /// The coarse leaf (m).
        voxel: f64,
        /// Points read when the grid stopped.
        seen: usize,
        /// Filtered points.
        points: usize,
        /// A leaf that would do (m).
        larger: f64,
    },
    /// More points than [`MAX_ICP_POINTS`] on the fine grid.
    #[error(
        "{file}: more than {MAX_ICP_POINTS} points remain on the --fine-voxel {fine_voxel} m \
         grid within --max-range {max_range} m, at most {MAX_ICP_POINTS} enter ICP (counted in \
         the first {seen} of its {points} points): give a larger --fine-voxel (about {larger:.2} m)"
    )]
    TooManyIcpPoints {
        /// The file.
        file: String,
        /// The fine leaf (m).
        fine_voxel: f64,
        /// The range (m).
        max_range: f64,
        /// Points read when the step stopped.
        seen: usize,
        /// Points of the cloud.
        points: usize,
        /// A leaf that would do (m).
        larger: f64,
    },
    /// Too few points left after the filters.
    #[error(
        "{file}: {got} points left after the --fine-voxel {fine_voxel} m grid and --max-range \
         {max_range} m, at least {need} needed"
    )]
    TooFewFiltered {
        /// The file.
        file: String,
        /// Points left.
        got: usize,
        /// Points needed.
        need: usize,
        /// The fine leaf (m).
        fine_voxel: f64,
        /// The range (m).
        max_range: f64,
    },
    /// Any other refusal of the pipeline.
    #[error("cannot register {source_file} to {target_file}")]
    Register {
        /// The source file.
        source_file: String,
        /// The target file.
        target_file: String,
        /// Why.
        #[source]
        source: RegistrationError,
    },
    /// A transform file that cannot be opened.
    #[error(transparent)]
    Open(#[from] DataError),
    /// A transform file that cannot be read.
    #[error("cannot read {file}")]
    Read {
        /// The file.
        file: String,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A transform file that is not text.
    #[error("{0}: not a text file of numbers")]
    NotText(String),
    /// A field of a transform file that is not a number.
    #[error("{file}:{line}: {field:?} is not a number")]
    NotANumber {
        /// The file.
        file: String,
        /// The 1-based line.
        line: usize,
        /// The field.
        field: String,
    },
    /// A transform file without 16 numbers.
    #[error("{file}: a 4×4 transform has 16 numbers, this file has {count}")]
    NotSixteen {
        /// The file.
        file: String,
        /// The numbers it has.
        count: usize,
    },
    /// A 4×4 matrix that is no rigid transform.
    #[error("{file}: not a rigid transform")]
    NotRigid {
        /// The file.
        file: String,
        /// Why.
        #[source]
        source: GeometryError,
    },
}

/// A PLY cloud for `purpose` (registration, a descriptor): at most [`MAX_INPUT_POINTS`],
/// checked from its header before any vertex is read, so that a compressed cloud announcing
/// 10^8 points is refused before it is decompressed.
///
/// # Errors
/// The file cannot be read or announces too many points.
pub fn read_cloud(path: &Path, purpose: &str) -> Result<Cloud<3>, RegistrationJobError> {
    read_ply_at_most(path, MAX_INPUT_POINTS as u64).map_err(|e| match e.kind {
        PlyErrorKind::TooManyVertices { line, count, .. } => RegistrationJobError::TooManyPoints {
            file: path.display().to_string(),
            line,
            count,
            purpose: purpose.to_string(),
        },
        _ => e.into(),
    })
}

/// Reads a 4×4 rigid transform: 16 numbers, row-major, whitespace-separated (at most 64 KiB).
///
/// # Errors
/// The file cannot be read, is not text, has a field that is not a number, not 16 numbers, or
/// no rigid transform.
pub fn read_transform(path: &Path) -> Result<Rigid<3>, RegistrationJobError> {
    let file = || path.display().to_string();
    let mut bytes = Vec::new();
    chronomap_io::open_data_file(path)?
        .take(1 << 16)
        .read_to_end(&mut bytes)
        .map_err(|source| RegistrationJobError::Read {
            file: file(),
            source,
        })?;
    let text = String::from_utf8(bytes).map_err(|_| RegistrationJobError::NotText(file()))?;
    let mut values = Vec::with_capacity(16);
    for (line_no, line) in text.lines().enumerate() {
        for field in line.split_whitespace() {
            let v: f64 = field
                .parse()
                .map_err(|_| RegistrationJobError::NotANumber {
                    file: file(),
                    line: line_no + 1,
                    field: field.to_string(),
                })?;
            values.push(v);
        }
    }
    if values.len() != 16 {
        return Err(RegistrationJobError::NotSixteen {
            file: file(),
            count: values.len(),
        });
    }
    let mut m = [[0.0; 4]; 4];
    for (i, v) in values.iter().enumerate() {
        m[i / 4][i % 4] = *v;
    }
    Rigid::from_matrix4(&m).map_err(|source| RegistrationJobError::NotRigid {
        file: file(),
        source,
    })
}

/// A 4×4 row-major matrix as four lines of text, 9 decimals.
pub fn matrix_text(m: &[[f64; 4]; 4]) -> String {
    m.iter()
        .map(|row| {
            row.iter()
                .map(|v| format!("{v:.9}"))
                .collect::<Vec<_>>()
                .join(" ")
                + "\n"
        })
        .collect()
}

/// How two clouds are registered ([`cloud_params`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CloudSettings {
    /// Leaf of the grid features and RANSAC work on (m).
    pub voxel: f64,
    /// Leaf of the grid ICP works on (m).
    pub fine_voxel: f64,
    /// Points farther from the sensor are dropped (m).
    pub max_range: f64,
    /// RANSAC's seed, if not the default.
    pub seed: Option<u64>,
}

/// ICP's part of a registration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IcpSummary {
    /// Iterations run.
    pub iterations: usize,
    /// Whether it converged.
    pub converged: bool,
    /// Share of source points with a correspondence.
    pub fitness: f64,
    /// RMSE of the correspondences (m).
    pub rmse_m: f64,
}

/// The information matrix `I / σ̂²` of a registration.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct InformationSummary {
    /// `σ̂` (m).
    pub sigma_m: f64,
    /// Degrees of freedom.
    pub dof: usize,
    /// Residuals it was estimated from.
    pub correspondences: usize,
}

/// Two clouds registered without an initial guess ([Stüde 2024] §3.2.2), as
/// `chronomap lidar register SOURCE TARGET` reports it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CloudRegistrationReport {
    /// The source cloud's file.
    pub source: PathBuf,
    /// The target cloud's file.
    pub target: PathBuf,
    /// Points of source and target.
    pub points: [usize; 2],
    /// Target ← source, row-major.
    pub transform: [[f64; 4]; 4],
    /// RANSAC's transform ICP started from.
    pub coarse_transform: [[f64; 4]; 4],
    /// Feature correspondences.
    pub correspondences: usize,
    /// RANSAC inliers.
    pub inliers: usize,
    /// RANSAC samples drawn.
    pub ransac_iterations: usize,
    /// ICP.
    pub icp: IcpSummary,
    /// The information matrix.
    pub information: InformationSummary,
    /// Rotation error against the truth (degrees), if given.
    pub rotation_error_deg: Option<f64>,
    /// Translation error against the truth (m), if given.
    pub translation_error_m: Option<f64>,
    /// RANSAC's rotation error (degrees), if a truth is given.
    pub coarse_rotation_error_deg: Option<f64>,
    /// RANSAC's translation error (m), if a truth is given.
    pub coarse_translation_error_m: Option<f64>,
    /// Wall time of the registration (s; the job times itself on purpose).
    pub seconds: f64,
}

impl CloudRegistrationReport {
    /// The report as `chronomap lidar register` prints it.
    pub fn text(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{} ({} points) onto {} ({} points) in {:.2} s",
            self.source.display(),
            self.points[0],
            self.target.display(),
            self.points[1],
            self.seconds
        );
        let _ = writeln!(
            out,
            "coarse (FPFH + RANSAC): {} correspondences, {} inliers, {} samples; fine (ICP): {} iterations, fitness {:.3}, RMSE {:.3} m",
            self.correspondences,
            self.inliers,
            self.ransac_iterations,
            self.icp.iterations,
            self.icp.fitness,
            self.icp.rmse_m
        );
        let _ = writeln!(
            out,
            "information matrix: I / σ̂² with σ̂ = {:.4} m (median absolute deviation of {} residuals)",
            self.information.sigma_m, self.information.correspondences
        );
        let _ = writeln!(
            out,
            "transform (target ← source):\n{}",
            matrix_text(&self.transform).trim_end()
        );
        if let (Some(r), Some(t), Some(cr), Some(ct)) = (
            self.rotation_error_deg,
            self.translation_error_m,
            self.coarse_rotation_error_deg,
            self.coarse_translation_error_m,
        ) {
            let _ = writeln!(
                out,
                "error against the truth: rotation {r:.4}°, translation {:.2} cm (coarse: {cr:.3}°, {:.2} cm)",
                t * 100.0,
                ct * 100.0
            );
        }
        out
    }
}

/// Registers the PLY cloud `source` onto `target` ([Stüde 2024] §3.2.2: FPFH, RANSAC, ICP on
/// [`cloud_params`]), against the transform of the file `truth` if given. Reports one stage.
///
/// # Errors
/// A file that cannot be read, a cloud without 9 points within range, clouds the pipeline
/// refuses (too many points on a grid: with the leaf that would do).
pub fn register_cloud_files(
    source_path: &Path,
    target_path: &Path,
    truth: Option<&Path>,
    settings: &CloudSettings,
    progress: &dyn Progress,
) -> Result<CloudRegistrationReport, RegistrationJobError> {
    let source = read_cloud(source_path, "registration")?;
    let target = read_cloud(target_path, "registration")?;
    let truth = truth.map(read_transform).transpose()?;
    let mut params = cloud_params(settings.voxel, settings.fine_voxel, settings.max_range);
    if let Some(seed) = settings.seed {
        params.ransac.seed = seed;
    }
    for (path, cloud) in [(source_path, &source), (target_path, &target)] {
        let (within, nearest) = within_range(cloud, settings.max_range);
        // The 9 points `register` needs at least (3 per dimension).
        if within < 9 {
            return Err(RegistrationJobError::OutOfRange {
                file: path.display().to_string(),
                within,
                points: cloud.len(),
                max_range: settings.max_range,
                nearest,
            });
        }
    }
    progress.stage("registering", 0);
    let start = Instant::now();
    let result = register(&source, &target, &params)
        .map_err(|e| registration_error(e, source_path, target_path, settings))?;
    let seconds = start.elapsed().as_secs_f64();
    let errors = truth.map(|t| result.transform.error_to(&t));
    let coarse_errors = truth.map(|t| result.coarse.error_to(&t));
    Ok(CloudRegistrationReport {
        source: source_path.to_path_buf(),
        target: target_path.to_path_buf(),
        points: [source.len(), target.len()],
        transform: result.transform.to_matrix4(),
        coarse_transform: result.coarse.to_matrix4(),
        correspondences: result.correspondences,
        inliers: result.inliers,
        ransac_iterations: result.ransac_iterations,
        icp: IcpSummary {
            iterations: result.icp.iterations,
            converged: result.icp.converged,
            fitness: result.icp.fitness,
            rmse_m: result.icp.rmse,
        },
        information: InformationSummary {
            sigma_m: result.information.sigma,
            dof: result.information.dof,
            correspondences: result.information.correspondences,
        },
        rotation_error_deg: errors.map(|e| e.0.to_degrees()),
        translation_error_m: errors.map(|e| e.1),
        coarse_rotation_error_deg: coarse_errors.map(|e| e.0.to_degrees()),
        coarse_translation_error_m: coarse_errors.map(|e| e.1),
        seconds,
    })
}

/// The pipeline's refusal naming the file and, for too many points, the leaf that would do.
fn registration_error(
    e: RegistrationError,
    source_path: &Path,
    target_path: &Path,
    settings: &CloudSettings,
) -> RegistrationJobError {
    let file = |what: &str| {
        if what.ends_with("source") {
            source_path.display().to_string()
        } else {
            target_path.display().to_string()
        }
    };
    // A grid that stopped after `seen` of `points` points with `max` cells: about
    // max·points/seen cells in all, for points spread evenly; on a surface the cells go as
    // 1/leaf², so a leaf larger by the square root of the excess (and a margin).
    let larger = |leaf: f64, max: usize, seen: usize, points: usize| {
        leaf * (points as f64 / seen.max(1) as f64).sqrt()
            * 1.2
            * ((max + 1) as f64 / max as f64).sqrt()
    };
    match e {
        RegistrationError::TooManyFeaturePoints {
            what,
            voxel,
            seen,
            points,
        } => RegistrationJobError::TooManyFeaturePoints {
            file: file(what),
            voxel,
            seen,
            points,
            larger: larger(voxel, MAX_FEATURE_POINTS, seen, points),
        },
        RegistrationError::TooManyIcpPoints {
            what, seen, points, ..
        } => RegistrationJobError::TooManyIcpPoints {
            file: file(what),
            fine_voxel: settings.fine_voxel,
            max_range: settings.max_range,
            seen,
            points,
            larger: larger(settings.fine_voxel, MAX_ICP_POINTS, seen, points),
        },
        RegistrationError::TooFewPoints { what, got, need } if what.starts_with("filtered") => {
            RegistrationJobError::TooFewFiltered {
                file: file(what),
                got,
                need,
                fine_voxel: settings.fine_voxel,
                max_range: settings.max_range,
            }
        }
        source => RegistrationJobError::Register {
            source_file: source_path.display().to_string(),
            target_file: target_path.display().to_string(),
            source,
        },
    }
}

/// One keyframe pair of [`KeyframeRegistrationReport`] as `--json` shows it: the registered
/// pose and its errors, or why the registration failed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairRow {
    /// Keyframes `[i, j]`: `j`'s scan moved onto `i`'s.
    pub pair: [usize; 2],
    /// The registered pose of `j`'s laser in `i`'s frame (`x, y, yaw`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pose: Option<[f64; 3]>,
    /// The SLAM relative pose.
    pub slam_pose: [f64; 3],
    /// Rotation error against SLAM (degrees).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rotation_error_deg: Option<f64>,
    /// Translation error against SLAM (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub translation_error_m: Option<f64>,
    /// RANSAC inliers.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub inliers: Option<usize>,
    /// `σ̂` of the information matrix (m).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_m: Option<f64>,
    /// Why the registration failed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

impl From<&PairRegistration> for PairRow {
    fn from(row: &PairRegistration) -> PairRow {
        let ok = row.result.as_ref().ok();
        PairRow {
            pair: row.pair,
            pose: ok.map(|x| x.pose),
            slam_pose: row.slam_pose,
            rotation_error_deg: ok.map(|x| x.rotation_error_deg),
            translation_error_m: ok.map(|x| x.translation_error_m),
            inliers: ok.map(|x| x.inliers),
            sigma_m: ok.map(|x| x.sigma_m),
            error: row.result.as_ref().err().cloned(),
        }
    }
}

/// Keyframe pairs of a laser log registered without an initial guess against their SLAM
/// relative poses ([Stüde 2024] §3.2.2), as `chronomap lidar register --keyframes` reports it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KeyframeRegistrationReport {
    /// The keyframe file.
    pub keyframes: String,
    /// Every pair.
    pub pairs: Vec<PairRow>,
    /// Pairs within 2° and 20 cm.
    pub within_2_deg_and_20_cm: usize,
    /// Pairs whose registration failed.
    pub failed: usize,
    /// Median rotation error over all pairs (degrees; a failure counts as unbounded).
    pub median_rotation_error_deg: f64,
    /// Median translation error over all pairs (m).
    pub median_translation_error_m: f64,
    /// Median rotation error of the pairs within 2° and 20 cm (degrees).
    pub median_rotation_error_deg_within: f64,
    /// Median translation error of those (m).
    pub median_translation_error_m_within: f64,
    /// Wall time per pair (s; the job times itself on purpose).
    pub seconds_per_pair: f64,
    /// The loop distance the pairs were chosen by (m).
    #[serde(skip)]
    pub near: f64,
    /// The least keyframe separation of a pair.
    #[serde(skip)]
    pub min_separation: usize,
    /// The registrations.
    #[serde(skip)]
    pub rows: Vec<PairRegistration>,
}

impl KeyframeRegistrationReport {
    /// The registered pose of the only pair as a homogeneous 3×3 transform (three lines of
    /// text, 9 decimals), if one pair was registered.
    pub fn single_matrix_text(&self) -> Option<String> {
        let [row] = self.rows.as_slice() else {
            return None;
        };
        let m = row.result.as_ref().ok()?.matrix();
        Some(format!(
            "{:.9} {:.9} {:.9}\n{:.9} {:.9} {:.9}\n0 0 1\n",
            m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2]
        ))
    }

    /// Why the only pair could not be registered (`keyframe j onto keyframe i: …`), if one
    /// pair was asked for and failed.
    pub fn single_failure(&self) -> Option<String> {
        match self.rows.as_slice() {
            [row] => row.result.as_ref().err().map(|e| {
                let [i, j] = row.pair;
                format!("keyframe {j} onto keyframe {i}: {e}")
            }),
            _ => None,
        }
    }

    /// The report as `chronomap lidar register --keyframes` prints it (one line for one pair).
    pub fn text(&self) -> String {
        if let [row] = self.rows.as_slice() {
            let ([i, j], t) = (row.pair, row.slam_pose);
            return match &row.result {
                Ok(x) => format!(
                    "keyframe {j} onto keyframe {i}: ({:.3} m, {:.3} m, {:.2}°); SLAM: ({:.3} m, {:.3} m, {:.2}°); error {:.3}°, {:.1} cm; {} inliers, σ̂ = {:.3} m\n",
                    x.pose[0],
                    x.pose[1],
                    x.pose[2].to_degrees(),
                    t[0],
                    t[1],
                    t[2].to_degrees(),
                    x.rotation_error_deg,
                    100.0 * x.translation_error_m,
                    x.inliers,
                    x.sigma_m
                ),
                Err(e) => format!("keyframe {j} onto keyframe {i}: {e}\n"),
            };
        }
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{}: {} loop pairs (laser origins closer than {} m, more than {} keyframes apart), registered without an initial guess (FPFH-2D, RANSAC, point-to-line ICP) in {:.1} ms per pair",
            self.keyframes,
            self.rows.len(),
            self.near,
            self.min_separation,
            1e3 * self.seconds_per_pair
        );
        let _ = writeln!(
            out,
            "against the SLAM relative poses: median error {:.3}° and {:.1} cm over all pairs; {} within 2° and 20 cm (median {:.3}°, {:.1} cm); {} failed",
            self.median_rotation_error_deg,
            100.0 * self.median_translation_error_m,
            self.within_2_deg_and_20_cm,
            self.median_rotation_error_deg_within,
            100.0 * self.median_translation_error_m_within,
            self.failed
        );
        out
    }
}

/// Keyframe pairs that cannot be registered.
#[derive(Debug, thiserror::Error)]
pub enum KeyframePairsError {
    /// The loop pairs cannot be labelled.
    #[error(transparent)]
    Study(#[from] LoopStudyError),
    /// No keyframes close enough and far enough apart.
    #[error("{name}: no keyframes are closer than {near} m and more than {min_separation} apart")]
    NoPairs {
        /// The log.
        name: String,
        /// The loop distance (m).
        near: f64,
        /// The least keyframe separation.
        min_separation: usize,
    },
}

/// The registration-vs-SLAM study ([Stüde 2024] §3.2.2): registers `pair` of the keyframe log,
/// or every loop pair (laser origins closer than `near`, more than `min_separation` keyframes
/// apart, as `lidar eval` labels loops) without an initial guess and compares each with the
/// SLAM relative pose ([`register_pairs`], [`RegistrationSummary`]).
///
/// # Errors
/// Positions that cannot be labelled; no loop pair.
///
/// # Panics
/// If `pair` names a keyframe the log does not have, or the log has no SLAM poses.
pub fn register_keyframes(
    log: &LaserLog,
    pair: Option<[usize; 2]>,
    near: f64,
    min_separation: usize,
    seed: Option<u64>,
    progress: &dyn Progress,
) -> Result<KeyframeRegistrationReport, KeyframePairsError> {
    let pairs = match pair {
        Some(pair) => vec![pair],
        None => loop_pairs(log, near, min_separation)?,
    };
    if pairs.is_empty() {
        return Err(KeyframePairsError::NoPairs {
            name: log.name.clone(),
            near,
            min_separation,
        });
    }
    let start = Instant::now();
    let rows = register_pairs(log, &pairs, seed, progress);
    let seconds = start.elapsed().as_secs_f64();
    let summary = RegistrationSummary::of(&rows);
    Ok(KeyframeRegistrationReport {
        keyframes: log.name.clone(),
        pairs: rows.iter().map(PairRow::from).collect(),
        within_2_deg_and_20_cm: summary.within,
        failed: summary.failed,
        median_rotation_error_deg: summary.median_rotation_deg,
        median_translation_error_m: summary.median_translation_m,
        median_rotation_error_deg_within: summary.median_rotation_within_deg,
        median_translation_error_m_within: summary.median_translation_within_m,
        seconds_per_pair: seconds / rows.len() as f64,
        near,
        min_separation,
        rows,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tmp(name: &str, text: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("chronomap-app-reg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    #[test]
    fn a_transform_file_is_read_row_major_and_refused_naming_line_and_field() {
        let path = tmp("t.txt", "0 -1 0 1\n1 0 0 2\n0 0 1 3\n0 0 0 1\n");
        let rigid = read_transform(&path).unwrap();
        assert_eq!(
            rigid.to_matrix4(),
            [
                [0.0, -1.0, 0.0, 1.0],
                [1.0, 0.0, 0.0, 2.0],
                [0.0, 0.0, 1.0, 3.0],
                [0.0, 0.0, 0.0, 1.0]
            ]
        );
        assert_eq!(
            matrix_text(&rigid.to_matrix4()).lines().next().unwrap(),
            "0.000000000 -1.000000000 0.000000000 1.000000000"
        );
        let bad = tmp("bad.txt", "1 0 0 0\n0 x 0 0\n");
        assert_eq!(
            read_transform(&bad).unwrap_err().to_string(),
            format!("{}:2: \"x\" is not a number", bad.display())
        );
        let short = tmp("short.txt", "1 0 0 0\n");
        assert_eq!(
            read_transform(&short).unwrap_err().to_string(),
            format!(
                "{}: a 4×4 transform has 16 numbers, this file has 4",
                short.display()
            )
        );
    }

    #[test]
    fn a_keyframe_report_renders_its_summary_and_json() {
        let row = |pair, result: Result<(f64, f64), &str>| PairRegistration {
            pair,
            slam_pose: [1.0, 0.0, 0.0],
            result: result
                .map(|(r, t)| crate::lidar_study::PairResult {
                    pose: [1.0, 0.0, 0.0],
                    rotation_error_deg: r,
                    translation_error_m: t,
                    inliers: 12,
                    sigma_m: 0.02,
                })
                .map_err(str::to_string),
        };
        let rows = vec![
            row([0, 30], Ok((0.5, 0.05))),
            row([2, 40], Err("too few points")),
        ];
        let s = RegistrationSummary::of(&rows);
        let report = KeyframeRegistrationReport {
            keyframes: "kf.txt".into(),
            pairs: rows.iter().map(PairRow::from).collect(),
            within_2_deg_and_20_cm: s.within,
            failed: s.failed,
            median_rotation_error_deg: s.median_rotation_deg,
            median_translation_error_m: s.median_translation_m,
            median_rotation_error_deg_within: s.median_rotation_within_deg,
            median_translation_error_m_within: s.median_translation_within_m,
            seconds_per_pair: 0.0125,
            near: 3.0,
            min_separation: 20,
            rows,
        };
        let text = report.text();
        assert_eq!(
            text.lines().next().unwrap(),
            "kf.txt: 2 loop pairs (laser origins closer than 3 m, more than 20 keyframes apart), registered without an initial guess (FPFH-2D, RANSAC, point-to-line ICP) in 12.5 ms per pair"
        );
        assert_eq!(
            text.lines().nth(1).unwrap(),
            "against the SLAM relative poses: median error inf° and inf cm over all pairs; 1 within 2° and 20 cm (median 0.500°, 5.0 cm); 1 failed"
        );
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["pairs"][0]["inliers"], 12);
        assert_eq!(json["pairs"][1]["error"], "too few points");
        assert!(json["pairs"][1].get("pose").is_none());
        assert_eq!(json["within_2_deg_and_20_cm"], 1);
        assert!(json.get("rows").is_none());
        assert_eq!(report.single_failure(), None);
    }
}
