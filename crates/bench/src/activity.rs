//! The two performance goals of CoPA-Map's activity pipeline ([Stüde 2024] chapter 4), each timed
//! against a baseline in the same run.
//!
//! * **Training-data extraction** (§4.2.2, [`chronomap_activity::extract::extract`]): patrol
//!   robots on a map over a set of detections (`chronomap bench activity` gives the bundled
//!   ATC day, the setup of `activity extract`). Baseline: one bare pass over the same
//!   detections that only bins each into its (cell, hour), the memory scan every extraction
//!   needs ([`bare_scan`]). Apart: the field-of-view cache, against ray casting the field of
//!   view at every robot step with the public `visible_cells` (the ray casts alone, without
//!   the counting: [`uncached_fov`]).
//! * **CoPA-Map training** (eqs. 4.12–4.16, `CopaMap::fit` with the default `CopaConfig` on all
//!   threads, as `activity fit` runs it). Goal: ≤ 3 minutes on 2 cores
//!   ([`COPA_GOAL_SECONDS`]). Baseline: the bare faer products of one training iteration in
//!   their shapes (see [`DenseWork`]), times the iterations; apart, one thread against all
//!   threads.

use std::collections::HashSet;
use std::hint::black_box;
use std::time::Instant;

use chronomap_activity::extract::{
    ExtractConfig, ExtractError, ObstacleGrid, RobotPath, extract, visible_cells,
};
use chronomap_activity::gp::GpError;
use chronomap_activity::{CopaConfig, CopaMap, RateSamples};
use chronomap_core::Parallelism;
use chronomap_core::progress::Progress;
use chronomap_hypertime::events::Event;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Accum, Mat, MatRef, Par};
use serde::Serialize;
use thiserror::Error;

use crate::median;

/// The goal for the default CoPA-Map fit on 2 cores (s).
pub const COPA_GOAL_SECONDS: f64 = 180.0;

/// Products of the bare baseline per training iteration (see [`DenseWork`]).
pub const PRODUCTS_PER_ITERATION: usize = 16;

/// How often each part of the benchmark runs.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ActivityBenchConfig {
    /// The short form (`--quick`), from which the defaults below came.
    pub quick: bool,
    /// Timed extractions after a warm-up, ten bare scans each (the medians are reported).
    pub repeats: usize,
    /// Timed CoPA-Map fits (the median is reported).
    pub fit_repeats: usize,
    /// Timed fits of 0 iterations (the setup: scaling, k-means inducing points).
    pub setup_repeats: usize,
    /// An untimed fit of 0 iterations before those.
    pub setup_warm_up: bool,
    /// CoPA-Map training iterations.
    pub iterations: usize,
    /// Iterations of the one-thread vs all-threads comparison (0 leaves it out); the timed
    /// fits serve as its all-threads side when they run as many.
    pub sequential_iterations: usize,
    /// Timed rounds of the bare dense work (after a warm-up round).
    pub dense_repeats: usize,
}

impl ActivityBenchConfig {
    /// The full run (`quick == false`: 5 extractions, 3 setups after a warm-up, the default
    /// 300 iterations, 30 on one thread) or the smoke test (`quick`: 2 extractions, one setup
    /// without warm-up, 12 iterations, 12 on one thread).
    pub fn new(quick: bool) -> Self {
        ActivityBenchConfig {
            quick,
            repeats: if quick { 2 } else { 5 },
            fit_repeats: 1,
            setup_repeats: if quick { 1 } else { 3 },
            setup_warm_up: !quick,
            iterations: if quick {
                12
            } else {
                CopaConfig::default().iterations
            },
            sequential_iterations: if quick { 12 } else { 30 },
            dense_repeats: if quick { 3 } else { 10 },
        }
    }
}

/// Why the benchmark could not run.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ActivityBenchError {
    /// The extraction failed.
    #[error("extraction")]
    Extraction(#[source] ExtractError),
    /// A field of view could not be ray cast.
    #[error("field of view")]
    FieldOfView(#[source] ExtractError),
    /// CoPA-Map could not be fitted.
    #[error("CoPA-Map")]
    Fit(#[source] GpError),
}

/// What the extraction is timed on: the setup of `activity extract`.
#[derive(Clone, Copy, Debug)]
pub struct ExtractionInput<'a> {
    /// The files the detections were read from (for the report).
    pub track_files: &'a [String],
    /// The detections.
    pub detections: &'a [Event],
    /// The map: cells that block sight.
    pub grid: &'a ObstacleGrid,
    /// The robots, by name.
    pub robots: &'a [(String, RobotPath)],
    /// The time bins to extract (those with a detection).
    pub bins: &'a [i64],
    /// Field of view, cells, bins and steps.
    pub config: &'a ExtractConfig,
}

/// The extraction's measurements.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ExtractionBench {
    /// The files the detections were read from.
    pub track_files: Vec<String>,
    /// Detections.
    pub detections: usize,
    /// The time bins extracted.
    pub bins: Vec<i64>,
    /// The robots' names.
    pub robots: Vec<String>,
    /// Robot steps: bins × steps per bin × robots.
    pub robot_steps: u64,
    /// Samples extracted.
    pub samples: usize,
    /// Distinct cells of the samples.
    pub cells: usize,
    /// Detections counted in the samples.
    pub total_count: u64,
    /// Median seconds of an extraction.
    pub seconds: f64,
    /// Seconds of every timed extraction.
    pub runs: Vec<f64>,
    /// `detections / seconds`.
    pub detections_per_second: f64,
    /// `robot_steps / seconds`.
    pub robot_steps_per_second: f64,
    /// Median seconds of the bare (cell, bin) binning pass ([`bare_scan`]).
    pub bare_scan_seconds: f64,
    /// Detections the bare scan found outside the map or the bins' span.
    pub bare_scan_outside: u64,
    /// `seconds / bare_scan_seconds`.
    pub ratio_to_bare_scan: f64,
    /// Distinct robot map cells: the ray casts the cached extraction does.
    #[serde(rename = "fov_cached_ray_casts")]
    pub cached_ray_casts: usize,
    /// Ray casts without the cache: one per robot step.
    #[serde(rename = "fov_uncached_ray_casts")]
    pub uncached_ray_casts: u64,
    /// Seconds of those ray casts ([`uncached_fov`], once).
    #[serde(rename = "fov_uncached_seconds")]
    pub uncached_seconds: f64,
    /// `uncached_seconds / seconds`.
    pub ratio_uncached_fov_to_extraction: f64,
}

/// Seconds of `f`, with its result kept from the optimiser.
fn timed<T, E>(f: impl FnOnce() -> Result<T, E>) -> Result<(f64, T), E> {
    let started = Instant::now();
    let value = black_box(f()?);
    Ok((started.elapsed().as_secs_f64(), value))
}

/// The baseline of the extraction: one pass over the detections that bins each into its
/// (cell, bin), counting in a dense array over the map's cells and the bins' span — what any
/// extraction has to do with every detection. Returns the detections that fell outside (all
/// of them for no bins).
pub fn bare_scan(
    detections: &[Event],
    grid: &ObstacleGrid,
    config: &ExtractConfig,
    bins: &[i64],
) -> u64 {
    let (Some(&first), Some(&last)) = (bins.first(), bins.last()) else {
        return detections.len() as u64;
    };
    let cell = config.cell_size;
    let [x0, y0] = grid.origin();
    let (x1, y1) = (
        x0 + grid.width() as f64 * grid.resolution(),
        y0 + grid.height() as f64 * grid.resolution(),
    );
    let (i0, j0) = ((x0 / cell).floor() as i64, (y0 / cell).floor() as i64);
    let nx = ((x1 / cell).floor() as i64 - i0 + 1) as usize;
    let ny = ((y1 / cell).floor() as i64 - j0 + 1) as usize;
    let nb = (last - first + 1) as usize;
    let mut counts = vec![0u32; nx * ny * nb];
    let mut outside = 0;
    for d in detections {
        let i = (d.x / cell).floor() as i64 - i0;
        let j = (d.y / cell).floor() as i64 - j0;
        let k = ((d.t - config.t0) / config.bin_seconds).floor() as i64 - first;
        if (0..nx as i64).contains(&i) && (0..ny as i64).contains(&j) && (0..nb as i64).contains(&k)
        {
            counts[(k as usize * ny + j as usize) * nx + i as usize] += 1;
        } else {
            outside += 1;
        }
    }
    black_box(&counts);
    outside
}

/// The baseline of the extraction's field-of-view cache: the field of view ray cast afresh at
/// every robot step of `bins` with the public `visible_cells` (what the extraction would cost
/// without its cache, counting nothing). Returns the visible cells found, and the casts.
///
/// # Errors
/// As `visible_cells`.
pub fn uncached_fov(
    grid: &ObstacleGrid,
    robots: &[RobotPath],
    bins: &[i64],
    config: &ExtractConfig,
    steps: usize,
) -> Result<(usize, u64), ExtractError> {
    let (mut cells, mut casts) = (0, 0);
    for &bin in bins {
        for step in 0..steps {
            // The pose in the middle of the step, as `extract` takes it.
            let elapsed =
                bin as f64 * config.bin_seconds + (step as f64 + 0.5) * config.step_seconds;
            for robot in robots {
                cells += visible_cells(grid, robot.pose_at(elapsed), config)?.len();
                casts += 1;
            }
        }
    }
    Ok((cells, casts))
}

/// The distinct map cells the robots occupy over `bins`: the ray casts of the cached extraction.
fn robot_cells(
    grid: &ObstacleGrid,
    robots: &[RobotPath],
    bins: &[i64],
    config: &ExtractConfig,
    steps: usize,
) -> usize {
    let mut cells = HashSet::new();
    for &bin in bins {
        for step in 0..steps {
            let elapsed =
                bin as f64 * config.bin_seconds + (step as f64 + 0.5) * config.step_seconds;
            cells.extend(
                robots
                    .iter()
                    .filter_map(|r| grid.cell_of(r.pose_at(elapsed))),
            );
        }
    }
    cells.len()
}

/// Times the extraction (a warm-up, then `config.repeats` runs, ten bare scans after each),
/// then the uncached field of view once.
///
/// # Errors
/// The extraction or a field of view fails (no robots, no bins, a bad configuration).
pub fn extraction(
    input: &ExtractionInput<'_>,
    config: &ActivityBenchConfig,
    progress: &dyn Progress,
) -> Result<ExtractionBench, ActivityBenchError> {
    let ExtractionInput {
        track_files,
        detections,
        grid,
        robots: named,
        bins,
        config: extract_config,
    } = *input;
    let robots: Vec<RobotPath> = named.iter().map(|(_, p)| p.clone()).collect();
    let steps = (extract_config.bin_seconds / extract_config.step_seconds).round() as usize;
    let robot_steps = (bins.len() * steps * robots.len()) as u64;
    progress.stage(
        &format!(
            "extraction: {} detections from {} files, {} bins, {} robots; {} timed runs after a warm-up",
            detections.len(),
            track_files.len(),
            bins.len(),
            robots.len(),
            config.repeats
        ),
        config.repeats as u64,
    );
    let run = || {
        extract(grid, &robots, detections, bins, extract_config)
            .map_err(ActivityBenchError::Extraction)
    };
    let result = run()?;
    let scan = || -> Result<u64, ActivityBenchError> {
        Ok(bare_scan(detections, grid, extract_config, bins))
    };
    let scan_outside = scan()?;
    let (mut runs, mut scan_runs) = (Vec::new(), Vec::new());
    for _ in 0..config.repeats {
        runs.push(timed(run)?.0);
        // The scan takes milliseconds: ten of them per extraction, for a steadier median.
        for _ in 0..10 {
            scan_runs.push(timed(scan)?.0);
        }
        progress.advance(1);
    }
    progress.stage(
        "field of view: ray cast at every robot step (once, no cache)",
        0,
    );
    let (uncached_seconds, (_, uncached_ray_casts)) = timed(|| {
        uncached_fov(grid, &robots, bins, extract_config, steps)
            .map_err(ActivityBenchError::FieldOfView)
    })?;
    let seconds = median(&runs);
    let bare_scan_seconds = median(&scan_runs);
    Ok(ExtractionBench {
        track_files: track_files.to_vec(),
        detections: detections.len(),
        bins: bins.to_vec(),
        robots: named.iter().map(|(name, _)| name.clone()).collect(),
        robot_steps,
        samples: result.len(),
        cells: result.cells().len(),
        total_count: result.total_count(),
        seconds,
        runs,
        detections_per_second: detections.len() as f64 / seconds,
        robot_steps_per_second: robot_steps as f64 / seconds,
        bare_scan_seconds,
        bare_scan_outside: scan_outside,
        ratio_to_bare_scan: seconds / bare_scan_seconds,
        cached_ray_casts: robot_cells(grid, &robots, bins, extract_config, steps),
        uncached_ray_casts,
        uncached_seconds,
        ratio_uncached_fov_to_extraction: uncached_seconds / seconds,
    })
}

// ---------------------------------------------------------------- CoPA-Map training

/// The baseline of CoPA-Map training: the dense linear algebra of one training iteration
/// (`HeteroSvgp::train_step` in `crates/activity/src/gp/svgp.rs`), with `M` inducing points
/// and a batch of `B`, on fixed matrices of the same shapes, bare: faer on one thread
/// (`Par::Seq`, as svgp.rs calls it), outputs allocated once. Per latent GP — `f` and `g`, so
/// everything twice per iteration:
///
/// | where | work | shape |
/// |---|---|---|
/// | `marginals` | `L = chol(K(Z, Z))` | Cholesky `M×M` |
/// | | `A = L⁻¹ K(Z, X)` | triangular solve `M×M`, `B` columns |
/// | | `L_Sᵀ A` | product `(M×M)ᵀ · (M×B)` |
/// | `natgrad_update` | `G = (A diag dv) Aᵀ` | product `(M×B) · (B×M)` |
/// | | `L_S⁻¹` | triangular solve `M×M`, `M` columns |
/// | | `S⁻¹ = L_S⁻ᵀ L_S⁻¹` | product `(M×M)ᵀ · (M×M)` |
/// | | `chol(new S⁻¹)`, its inverse `W` | Cholesky `M×M`, triangular solve `M×M`, `M` columns |
/// | | `S = Wᵀ W`, `chol(S)` | product `(M×M)ᵀ · (M×M)`, Cholesky `M×M` |
/// | `refresh` | `L_Sᵀ A` for the new `q` | product `(M×M)ᵀ · (M×B)` |
/// | `marginals_backward` | `L_S (L_Sᵀ A)` | product `(M×M) · (M×B)` |
/// | | `K̄(Z, X) = L⁻ᵀ Ā` | triangular solve `M×M`, `B` columns |
/// | | `L̄ = −K̄(Z, X) Aᵀ` | product `(M×B) · (B×M)` |
/// | | `Φ = Lᵀ L̄` | product `(M×M)ᵀ · (M×M)` |
/// | | `K̄(Z, Z) = L⁻ᵀ Φ L⁻¹` | 2 triangular solves `M×M`, `M` columns |
///
/// So **8 products per latent GP, 16 per iteration**: 6 of `(M×M)·(M×B)`, 4 of
/// `(M×B)·(B×M)` (each `2·M²·B` flops) and 6 of `(M×M)·(M×M)` (`2·M³`); with `M = 200`,
/// `B = 1000`: 8.96·10⁸ flops, 11.2 times one 1000×200 by 200×200 product. The rest of the
/// dense work: 12 triangular solves (4 with `B` columns, 8 with `M`) and 6 Cholesky
/// factorisations. Matrix-vector products (`O(M·B)`), the kernel matrices and their
/// gradients, the quadrature of the likelihood and Adam are not dense linear algebra and are
/// what the ratio to this baseline measures on top; a natural-gradient step that is retried
/// with half the step size (not positive definite) repeats its part.
pub struct DenseWork {
    /// `A`, `M×B`.
    a: Mat<f64>,
    /// A lower Cholesky factor, `M×M`.
    l: Mat<f64>,
    /// A symmetric positive definite matrix, `M×M`.
    spd: Mat<f64>,
    /// Outputs and work space.
    mb: Mat<f64>,
    mm: Mat<f64>,
    solve_mb: Mat<f64>,
    solve_mm: Mat<f64>,
    factor: Mat<f64>,
    scratch: MemBuffer,
}

impl DenseWork {
    /// Fixed matrices for `m` inducing points and a batch of `b`.
    pub fn new(m: usize, b: usize) -> Self {
        // Deterministic entries in [-0.5, 0.5); K = A Aᵀ / B + I is well conditioned, so
        // repeated solves neither blow up nor underflow.
        let a = Mat::from_fn(m, b, |i, j| {
            ((i * 7919 + j * 104_729) % 1000) as f64 / 1000.0 - 0.5
        });
        let mut spd = Mat::zeros(m, m);
        matmul(
            spd.as_mut(),
            Accum::Replace,
            a.as_ref(),
            a.as_ref().transpose(),
            1.0 / b as f64,
            Par::Seq,
        );
        for i in 0..m {
            spd[(i, i)] += 1.0;
        }
        let scratch = MemBuffer::new(cholesky_in_place_scratch::<f64>(
            m,
            Par::Seq,
            Default::default(),
        ));
        let mut work = DenseWork {
            l: Mat::zeros(m, m),
            mb: Mat::zeros(m, b),
            mm: Mat::zeros(m, m),
            solve_mb: Mat::zeros(m, b),
            solve_mm: Mat::zeros(m, m),
            factor: Mat::zeros(m, m),
            a,
            spd,
            scratch,
        };
        work.cholesky();
        work.l = Mat::from_fn(m, m, |i, j| if j <= i { work.factor[(i, j)] } else { 0.0 });
        work
    }

    fn product(dst: &mut Mat<f64>, lhs: MatRef<'_, f64>, rhs: MatRef<'_, f64>) {
        matmul(dst.as_mut(), Accum::Replace, lhs, rhs, 1.0, Par::Seq);
    }

    /// The 8 products of one latent GP.
    pub fn products(&mut self) {
        let (a, l) = (self.a.as_ref(), self.l.as_ref());
        // (M×M)ᵀ·(M×B): marginals, refresh; (M×M)·(M×B): backward.
        Self::product(&mut self.mb, l.transpose(), a);
        Self::product(&mut self.mb, l.transpose(), a);
        Self::product(&mut self.mb, l, a);
        // (M×B)·(B×M): G, L̄.
        Self::product(&mut self.mm, a, a.transpose());
        Self::product(&mut self.mm, a, a.transpose());
        // (M×M)ᵀ·(M×M): S⁻¹, S, Φ.
        for _ in 0..3 {
            Self::product(&mut self.mm, l.transpose(), l);
        }
    }

    fn cholesky(&mut self) {
        self.factor.copy_from(&self.spd);
        cholesky_in_place(
            self.factor.as_mut(),
            Default::default(),
            Par::Seq,
            MemStack::new(&mut self.scratch),
            Default::default(),
        )
        .expect("K = A Aᵀ / B + I is positive definite");
    }

    /// The triangular solves and Cholesky factorisations of one latent GP.
    pub fn solves(&mut self) {
        let l = self.l.as_ref();
        // B columns: A = L⁻¹ K(Z, X) (lower), K̄ = L⁻ᵀ Ā (upper), each from fresh values.
        self.solve_mb.copy_from(&self.a);
        solve_lower_triangular_in_place(l, self.solve_mb.as_mut(), Par::Seq);
        self.solve_mb.copy_from(&self.a);
        solve_upper_triangular_in_place(l.transpose(), self.solve_mb.as_mut(), Par::Seq);
        // M columns: two inverses of lower factors, two solves with Lᵀ.
        for lower in [true, true, false, false] {
            self.solve_mm.copy_from(&self.spd);
            if lower {
                solve_lower_triangular_in_place(l, self.solve_mm.as_mut(), Par::Seq);
            } else {
                solve_upper_triangular_in_place(l.transpose(), self.solve_mm.as_mut(), Par::Seq);
            }
        }
        for _ in 0..3 {
            self.cholesky();
        }
    }
}

/// Median seconds of the products, and of all the dense work, of one iteration (both latent
/// GPs), after a warm-up round: the bare baseline of CoPA-Map training ([`DenseWork`]).
pub fn bare_dense(m: usize, b: usize, repeats: usize) -> (f64, f64) {
    let mut work = DenseWork::new(m, b);
    let (mut products, mut all) = (Vec::new(), Vec::new());
    for round in 0..repeats + 1 {
        let started = Instant::now();
        for _ in 0..2 {
            work.products();
        }
        let p = started.elapsed().as_secs_f64();
        for _ in 0..2 {
            work.solves();
        }
        let a = started.elapsed().as_secs_f64();
        if round > 0 {
            products.push(p);
            all.push(a);
        }
    }
    black_box(&work.mb);
    black_box(&work.mm);
    (median(&products), median(&all))
}

/// Flops of the 16 products of one iteration with `m` inducing points and a batch of `b`.
pub fn product_flops(m: usize, b: usize) -> f64 {
    let (m, b) = (m as f64, b as f64);
    2.0 * (5.0 * 2.0 * m * m * b + 3.0 * 2.0 * m * m * m)
}

/// What CoPA-Map is trained on.
#[derive(Clone, Copy, Debug)]
pub struct TrainingInput<'a> {
    /// The file the rates were read from (for the report).
    pub name: &'a str,
    /// The training rates.
    pub samples: &'a RateSamples,
}

/// The one-thread vs all-threads comparison.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SequentialBench {
    /// Iterations of both fits.
    pub iterations: usize,
    /// Training seconds per iteration on one thread.
    pub one_thread_seconds_per_iteration: f64,
    /// Training seconds per iteration on all threads.
    pub all_threads_seconds_per_iteration: f64,
    /// `one_thread / all_threads`.
    pub speedup: f64,
}

/// CoPA-Map's measurements.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TrainingBench {
    /// The file the rates were read from.
    pub train: String,
    /// Training samples.
    pub samples: usize,
    /// Distinct cells of the samples.
    pub cells: usize,
    /// Inducing points (`CopaConfig`'s default).
    pub inducing: usize,
    /// Batch size (`CopaConfig`'s default, at most the samples).
    pub batch: usize,
    /// Iterations of the timed fits.
    pub iterations: usize,
    /// Threads of "all threads" (text report and the top level of [`ActivityBench`]).
    #[serde(skip)]
    pub threads: usize,
    /// Median seconds of a fit.
    pub seconds: f64,
    /// Seconds of every timed fit.
    pub runs: Vec<f64>,
    /// Median seconds of the setup (a fit of 0 iterations: scaling, k-means inducing points).
    pub setup_seconds: f64,
    /// Training seconds per iteration: the fit less its setup, over the iterations.
    pub seconds_per_iteration: f64,
    /// The ELBO after the last timed fit.
    pub final_elbo: f64,
    /// [`COPA_GOAL_SECONDS`].
    pub goal_seconds: f64,
    /// `seconds <= goal_seconds`.
    pub goal_met: bool,
    /// [`PRODUCTS_PER_ITERATION`].
    pub bare_gemm_products_per_iteration: usize,
    /// Flops of those products ([`product_flops`]).
    pub bare_gemm_flops_per_iteration: f64,
    /// Median seconds of those products, bare, one thread ([`bare_dense`]).
    pub bare_gemm_seconds_per_iteration: f64,
    /// `seconds_per_iteration / bare_gemm_seconds_per_iteration`.
    pub ratio_iteration_to_bare_gemm: f64,
    /// `seconds / (bare_gemm_seconds_per_iteration × iterations)`.
    pub ratio_fit_to_bare_gemm: f64,
    /// Median seconds of all the dense work of an iteration (products, solves, Cholesky).
    pub bare_dense_seconds_per_iteration: f64,
    /// `seconds_per_iteration / bare_dense_seconds_per_iteration`.
    pub ratio_iteration_to_bare_dense: f64,
    /// One thread against all threads, unless left out.
    pub sequential: Option<SequentialBench>,
}

/// Seconds of a CoPA-Map fit of `iterations` and its final ELBO.
fn fit(
    train: &RateSamples,
    iterations: usize,
    parallelism: Parallelism,
) -> Result<(f64, f64), ActivityBenchError> {
    let config = CopaConfig {
        iterations,
        parallelism,
        ..CopaConfig::default()
    };
    let (seconds, model) = timed(|| CopaMap::fit(train, &config).map_err(ActivityBenchError::Fit))?;
    Ok((seconds, model.trace.last().copied().unwrap_or(f64::NAN)))
}

/// Times the setup, the fits and the one-thread comparison of CoPA-Map with its default
/// configuration, then the bare dense work of an iteration.
///
/// # Errors
/// A fit fails.
pub fn training(
    input: &TrainingInput<'_>,
    config: &ActivityBenchConfig,
    progress: &dyn Progress,
) -> Result<TrainingBench, ActivityBenchError> {
    let train = input.samples;
    let defaults = CopaConfig::default();
    let (m, b) = (defaults.inducing, defaults.batch_size.min(train.len()));
    let all = Parallelism::Rayon(0);
    progress.stage(
        &format!(
            "CoPA-Map: {} samples of {}, {m} inducing points, batch {b}; setup (0 iterations), warm-up and {} timed",
            train.len(),
            input.name,
            config.setup_repeats
        ),
        0,
    );
    if config.setup_warm_up {
        fit(train, 0, all)?;
    }
    let mut setup_runs = Vec::new();
    for _ in 0..config.setup_repeats {
        setup_runs.push(fit(train, 0, all)?.0);
    }
    let setup_seconds = median(&setup_runs);
    // Training seconds per iteration: the fit less its setup, over the iterations.
    let per_iteration =
        |seconds: f64, iterations: usize| (seconds - setup_seconds).max(0.0) / iterations as f64;
    let (mut runs, mut final_elbo) = (Vec::new(), f64::NAN);
    for r in 0..config.fit_repeats {
        progress.stage(
            &format!(
                "CoPA-Map: fit {}/{} ({} iterations, all threads)",
                r + 1,
                config.fit_repeats,
                config.iterations
            ),
            0,
        );
        let (seconds, elbo) = fit(train, config.iterations, all)?;
        runs.push(seconds);
        final_elbo = elbo;
    }
    let seconds = median(&runs);
    let sequential = if config.sequential_iterations > 0 {
        let n = config.sequential_iterations;
        progress.stage(&format!("CoPA-Map: {n} iterations on one thread"), 0);
        let one = fit(train, n, Parallelism::Sequential)?.0;
        // The same iterations on all threads: the fits above when they ran as many.
        let every = if n == config.iterations {
            seconds
        } else {
            progress.stage(&format!("CoPA-Map: {n} iterations on all threads"), 0);
            fit(train, n, all)?.0
        };
        let (one, every) = (per_iteration(one, n), per_iteration(every, n));
        Some(SequentialBench {
            iterations: n,
            one_thread_seconds_per_iteration: one,
            all_threads_seconds_per_iteration: every,
            speedup: one / every,
        })
    } else {
        None
    };
    progress.stage(
        &format!("bare faer products of an iteration ({m} x {b})"),
        0,
    );
    let (gemm_seconds, dense_seconds) = bare_dense(m, b, config.dense_repeats);
    let seconds_per_iteration = per_iteration(seconds, config.iterations);
    Ok(TrainingBench {
        train: input.name.to_string(),
        samples: train.len(),
        cells: train.cell_count(),
        inducing: m,
        batch: b,
        iterations: config.iterations,
        threads: all.tasks(),
        seconds,
        runs,
        setup_seconds,
        seconds_per_iteration,
        final_elbo,
        goal_seconds: COPA_GOAL_SECONDS,
        goal_met: seconds <= COPA_GOAL_SECONDS,
        bare_gemm_products_per_iteration: PRODUCTS_PER_ITERATION,
        bare_gemm_flops_per_iteration: product_flops(m, b),
        bare_gemm_seconds_per_iteration: gemm_seconds,
        ratio_iteration_to_bare_gemm: seconds_per_iteration / gemm_seconds,
        ratio_fit_to_bare_gemm: seconds / (gemm_seconds * config.iterations as f64),
        bare_dense_seconds_per_iteration: dense_seconds,
        ratio_iteration_to_bare_dense: seconds_per_iteration / dense_seconds,
        sequential,
    })
}

/// The whole report of `chronomap bench activity`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ActivityBench {
    /// Whether this was the short form.
    pub quick: bool,
    /// Threads of "all threads".
    pub threads: usize,
    /// The extraction's measurements.
    pub extraction: ExtractionBench,
    /// CoPA-Map's measurements.
    pub copa: TrainingBench,
}

impl ActivityBench {
    /// The report of one run.
    pub fn new(
        config: &ActivityBenchConfig,
        extraction: ExtractionBench,
        copa: TrainingBench,
    ) -> Self {
        ActivityBench {
            quick: config.quick,
            threads: copa.threads,
            extraction,
            copa,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bare_scan_counts_the_detections_outside_the_map_or_the_bins() {
        // A 4 m × 2 m map of 0.5 m map cells from the origin, 1 m extraction cells, hour bins.
        let grid = ObstacleGrid::free(8, 4, 0.5, [0.0, 0.0]).unwrap();
        let config = ExtractConfig {
            cell_size: 1.0,
            t0: 7200.0,
            ..ExtractConfig::default()
        };
        let at = |t: f64, x: f64, y: f64| Event { t, x, y };
        let detections = [
            at(7200.0, 0.5, 0.5),   // bin 0, inside
            at(10_799.0, 3.9, 1.9), // bin 0, inside
            at(11_000.0, 2.0, 1.0), // bin 1, inside
            at(7300.0, -1.5, 1.0),  // left of the map
            at(7300.0, 1.0, 9.0),   // above it
            at(18_000.0, 1.0, 1.0), // bin 3, after the bins
            at(3600.0, 1.0, 1.0),   // bin -1, before them
        ];
        assert_eq!(bare_scan(&detections, &grid, &config, &[0, 1]), 4);
        // The counts span the bins from the first to the last: bins 0 to 3 take in bins 1 and 3.
        assert_eq!(bare_scan(&detections, &grid, &config, &[0, 3]), 3);
        assert_eq!(bare_scan(&detections, &grid, &config, &[]), 7);
    }

    #[test]
    fn product_flops_of_the_default_shapes() {
        // The doc of `DenseWork`: 8.96·10⁸ flops for M = 200, B = 1000.
        assert_eq!(product_flops(200, 1000), 8.96e8);
        assert_eq!(product_flops(1, 1), 2.0 * (10.0 + 6.0));
    }

    #[test]
    fn the_quick_config_is_the_short_run() {
        let quick = ActivityBenchConfig::new(true);
        assert_eq!(
            (quick.repeats, quick.setup_repeats, quick.setup_warm_up),
            (2, 1, false)
        );
        assert_eq!((quick.iterations, quick.sequential_iterations), (12, 12));
        let full = ActivityBenchConfig::new(false);
        assert_eq!(full.iterations, CopaConfig::default().iterations);
        assert_eq!(
            (full.repeats, full.setup_warm_up, full.dense_repeats),
            (5, true, 10)
        );
    }
}
