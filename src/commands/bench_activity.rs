//! `chronomap bench activity`: the two performance goals of CoPA-Map's activity pipeline (seed
//! 002 chapter 4) on the bundled ATC data, each timed against a baseline in the same run.
//!
//! * **Training-data extraction** (§4.2.2, `activity::extract::extract`): the bundled patrol
//!   robots on the real map over the tracks of 2012-10-24 (the whole day; one hour with
//!   `--quick`), the setup of `activity extract`. Baseline: one bare pass over the same
//!   detections that only bins each into its (cell, hour), the memory scan every extraction
//!   needs. Apart: the field-of-view cache, against ray casting the field of view at every
//!   robot step with the public `visible_cells` (the ray casts alone, without the counting).
//! * **CoPA-Map training** (eqs. 4.12–4.16, `CopaMap::fit` with the default `CopaConfig` on all
//!   threads, as `activity fit` runs it) on the bundled ATC grid. Goal: ≤ 3 minutes on 2
//!   cores. Baseline: the bare faer products of one training iteration in their shapes (see
//!   [`DenseWork`]), times the iterations; apart, one thread against all threads.

use std::collections::HashSet;
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result, anyhow, bail};
use chronomap_activity::extract::{ExtractConfig, ObstacleGrid, RobotPath, extract, visible_cells};
use chronomap_activity::{CopaConfig, CopaMap, RateSamples};
use chronomap_core::Parallelism;
use chronomap_hypertime::events::Event;
use chronomap_io::{read_rate_samples, read_track_files};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::{Accum, Mat, MatRef, Par};
use serde_json::{Value, json};

use super::activity_extract::{detection_bins, robots_on_map};
use super::bench_plan::median;
use crate::cli::BenchActivityArgs;
use crate::format::Table;

/// The bundled tracks of 2012-10-24 (one file per hour).
const TRACK_DIR: &str = "data/atc_20121024_1hz";
/// The hour of `--quick`.
const QUICK_TRACKS: &str = "atc-1024-10_train.csv.xz";
/// The goal for the default fit on 2 cores.
const GOAL_SECONDS: f64 = 180.0;
/// Map cells of at least this occupancy (percent) block sight (`activity extract`'s default).
const MIN_OCCUPANCY: i8 = 50;

/// The run's sizes: full, or `--quick`.
struct Plan {
    tracks: Vec<PathBuf>,
    repeats: usize,
    fit_repeats: usize,
    setup_repeats: usize,
    iterations: usize,
    sequential_iterations: usize,
    dense_repeats: usize,
}

impl Plan {
    fn of(args: &BenchActivityArgs) -> Result<Self> {
        let quick = args.quick;
        let tracks = if !args.tracks.is_empty() {
            args.tracks.clone()
        } else if quick {
            vec![Path::new(TRACK_DIR).join(QUICK_TRACKS)]
        } else {
            day_tracks(Path::new(TRACK_DIR))?
        };
        Ok(Plan {
            tracks,
            repeats: args
                .repeats
                .map_or(if quick { 2 } else { 5 }, |n| n as usize),
            fit_repeats: args.fit_repeats as usize,
            // (--quick: no warm-up before the one timed setup)
            setup_repeats: if quick { 1 } else { 3 },
            iterations: args.iterations.map_or(
                if quick {
                    12
                } else {
                    CopaConfig::default().iterations
                },
                |n| n as usize,
            ),
            sequential_iterations: args
                .sequential_iterations
                .map_or(if quick { 12 } else { 30 }, |n| n as usize),
            dense_repeats: if quick { 3 } else { 10 },
        })
    }
}

/// Every `atc-1024-*_train.csv.xz` of `dir`, sorted by name.
fn day_tracks(dir: &Path) -> Result<Vec<PathBuf>> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| {
            format!(
                "cannot list {} (run from the repository root, or give --tracks)",
                dir.display()
            )
        })?
        .filter_map(|entry| entry.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .is_some_and(|n| n.starts_with("atc-1024-") && n.ends_with("_train.csv.xz"))
        })
        .collect();
    files.sort();
    if files.is_empty() {
        bail!("no atc-1024-*_train.csv.xz in {}", dir.display());
    }
    Ok(files)
}

/// Seconds of `f`, with its result kept from the optimiser.
fn timed<T>(f: impl FnOnce() -> Result<T>) -> Result<(f64, T)> {
    let started = Instant::now();
    let value = black_box(f()?);
    Ok((started.elapsed().as_secs_f64(), value))
}

// ---------------------------------------------------------------- extraction

/// The extraction's measurements.
struct ExtractionBench {
    detections: usize,
    bins: Vec<i64>,
    robots: Vec<String>,
    robot_steps: u64,
    samples: usize,
    cells: usize,
    total_count: u64,
    runs: Vec<f64>,
    scan_runs: Vec<f64>,
    /// Detections the bare scan found outside the map or the bins' span.
    scan_outside: u64,
    /// Distinct robot map cells: the ray casts the cached extraction does.
    cached_casts: usize,
    uncached_casts: u64,
    uncached_seconds: f64,
}

impl ExtractionBench {
    fn seconds(&self) -> f64 {
        median(self.runs.clone())
    }

    fn scan_seconds(&self) -> f64 {
        median(self.scan_runs.clone())
    }
}

/// The baseline of the extraction: one pass over the detections that bins each into its
/// (cell, bin), counting in a dense array over the map's cells and the bins' span — what any
/// extraction has to do with every detection. Returns the detections that fell outside.
fn bare_scan(
    detections: &[Event],
    grid: &ObstacleGrid,
    config: &ExtractConfig,
    bins: &[i64],
) -> u64 {
    let cell = config.cell_size;
    let [x0, y0] = grid.origin();
    let (x1, y1) = (
        x0 + grid.width() as f64 * grid.resolution(),
        y0 + grid.height() as f64 * grid.resolution(),
    );
    let (i0, j0) = ((x0 / cell).floor() as i64, (y0 / cell).floor() as i64);
    let nx = ((x1 / cell).floor() as i64 - i0 + 1) as usize;
    let ny = ((y1 / cell).floor() as i64 - j0 + 1) as usize;
    let (first, last) = (bins[0], bins[bins.len() - 1]);
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

/// The field of view ray cast afresh at every robot step of `bins` (what the extraction would
/// cost without its cache, counting nothing): the visible cells found, and the casts.
fn uncached_fov(
    grid: &ObstacleGrid,
    robots: &[RobotPath],
    bins: &[i64],
    config: &ExtractConfig,
    steps: usize,
) -> Result<(usize, u64)> {
    let (mut cells, mut casts) = (0, 0);
    for &bin in bins {
        for step in 0..steps {
            // The pose in the middle of the step, as `extract` takes it.
            let elapsed =
                bin as f64 * config.bin_seconds + (step as f64 + 0.5) * config.step_seconds;
            for robot in robots {
                cells += visible_cells(grid, robot.pose_at(elapsed), config)
                    .map_err(|e| anyhow!("field of view: {e}"))?
                    .len();
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

fn bench_extraction(args: &BenchActivityArgs, plan: &Plan) -> Result<ExtractionBench> {
    let detections = read_track_files(&plan.tracks).context("cannot read the tracks")?;
    let Some(first) = detections.first().map(|d| d.t) else {
        bail!("the track files have no detection");
    };
    let (grid, named) = robots_on_map(
        &args.map,
        &args.paths,
        RobotPath::DEFAULT_SPEED,
        MIN_OCCUPANCY,
        &[],
    )?;
    let robots: Vec<RobotPath> = named.iter().map(|(_, p)| p.clone()).collect();
    // `activity extract`'s defaults: 3.5 m, 0.5 m cells, hour bins from the first detection's
    // hour, 1 s steps, every bin with a detection.
    let defaults = ExtractConfig::default();
    let t0 = (first / defaults.bin_seconds).floor() * defaults.bin_seconds;
    let config = ExtractConfig { t0, ..defaults };
    let bins = detection_bins(&detections, t0, config.bin_seconds);
    let steps = (config.bin_seconds / config.step_seconds).round() as usize;
    let robot_steps = (bins.len() * steps * robots.len()) as u64;
    eprintln!(
        "extraction: {} detections from {} files, {} bins, {} robots; {} timed runs after a warm-up...",
        detections.len(),
        plan.tracks.len(),
        bins.len(),
        robots.len(),
        plan.repeats
    );

    let run = || {
        extract(&grid, &robots, &detections, &bins, &config).map_err(|e| anyhow!("extraction: {e}"))
    };
    let extraction = run()?;
    let scan = || -> Result<u64> { Ok(bare_scan(&detections, &grid, &config, &bins)) };
    let scan_outside = scan()?;
    let (mut runs, mut scan_runs) = (Vec::new(), Vec::new());
    for _ in 0..plan.repeats {
        runs.push(timed(run)?.0);
        // The scan takes milliseconds: ten of them per extraction, for a steadier median.
        for _ in 0..10 {
            scan_runs.push(timed(scan)?.0);
        }
    }
    eprintln!("field of view: ray cast at every robot step (once, no cache)...");
    let (uncached_seconds, (_, uncached_casts)) =
        timed(|| uncached_fov(&grid, &robots, &bins, &config, steps))?;
    Ok(ExtractionBench {
        detections: detections.len(),
        robots: named.into_iter().map(|(name, _)| name).collect(),
        robot_steps,
        samples: extraction.len(),
        cells: extraction.cells().len(),
        total_count: extraction.total_count(),
        runs,
        scan_runs,
        scan_outside,
        cached_casts: robot_cells(&grid, &robots, &bins, &config, steps),
        uncached_casts,
        uncached_seconds,
        bins,
    })
}

// ---------------------------------------------------------------- CoPA-Map training

/// The dense linear algebra of one training iteration of CoPA-Map
/// (`HeteroSvgp::train_step` in `crates/core/src/gp/svgp.rs`), with `M` inducing points and
/// a batch of `B`, on fixed matrices of the same shapes, bare: faer on one thread (`Par::Seq`,
/// as svgp.rs calls it), outputs allocated once. Per latent GP — `f` and `g`, so everything
/// twice per iteration:
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
struct DenseWork {
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
    fn new(m: usize, b: usize) -> Self {
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
    fn products(&mut self) {
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
    fn solves(&mut self) {
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
/// GPs), after a warm-up.
fn bare_dense(m: usize, b: usize, repeats: usize) -> (f64, f64) {
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
    (median(products), median(all))
}

/// Flops of the 16 products of one iteration.
fn product_flops(m: usize, b: usize) -> f64 {
    let (m, b) = (m as f64, b as f64);
    2.0 * (5.0 * 2.0 * m * m * b + 3.0 * 2.0 * m * m * m)
}

/// CoPA-Map's measurements.
struct TrainingBench {
    samples: usize,
    cells: usize,
    inducing: usize,
    batch: usize,
    iterations: usize,
    threads: usize,
    runs: Vec<f64>,
    setup_runs: Vec<f64>,
    final_elbo: f64,
    gemm_seconds: f64,
    dense_seconds: f64,
    /// (iterations, one thread s, all threads s) of fits of the same iterations.
    sequential: Option<(usize, f64, f64)>,
}

impl TrainingBench {
    fn seconds(&self) -> f64 {
        median(self.runs.clone())
    }

    fn setup_seconds(&self) -> f64 {
        median(self.setup_runs.clone())
    }

    /// Training seconds per iteration: the fit less its setup (scaling and k-means inducing
    /// points, a fit of 0 iterations), over the iterations.
    fn per_iteration(&self, seconds: f64, iterations: usize) -> f64 {
        (seconds - self.setup_seconds()).max(0.0) / iterations as f64
    }

    fn iteration_seconds(&self) -> f64 {
        self.per_iteration(self.seconds(), self.iterations)
    }
}

fn fit(train: &RateSamples, iterations: usize, parallelism: Parallelism) -> Result<(f64, f64)> {
    let config = CopaConfig {
        iterations,
        parallelism,
        ..CopaConfig::default()
    };
    let (seconds, model) =
        timed(|| CopaMap::fit(train, &config).map_err(|e| anyhow!("CoPA-Map: {e}")))?;
    Ok((seconds, model.trace.last().copied().unwrap_or(f64::NAN)))
}

fn bench_training(args: &BenchActivityArgs, plan: &Plan) -> Result<TrainingBench> {
    let name = args.train.display().to_string();
    let train = read_rate_samples(&args.train).context("cannot read the training rates")?;
    let defaults = CopaConfig::default();
    let (m, b) = (defaults.inducing, defaults.batch_size.min(train.len()));
    let all = Parallelism::Rayon(0);
    eprintln!(
        "CoPA-Map: {} samples of {name}, {m} inducing points, batch {b}; setup (0 iterations), warm-up and {} timed...",
        train.len(),
        plan.setup_repeats
    );
    if !args.quick {
        fit(&train, 0, all)?;
    }
    let mut setup_runs = Vec::new();
    for _ in 0..plan.setup_repeats {
        setup_runs.push(fit(&train, 0, all)?.0);
    }
    let (mut runs, mut final_elbo) = (Vec::new(), f64::NAN);
    for r in 0..plan.fit_repeats {
        eprintln!(
            "CoPA-Map: fit {}/{} ({} iterations, all threads)...",
            r + 1,
            plan.fit_repeats,
            plan.iterations
        );
        let (seconds, elbo) = fit(&train, plan.iterations, all)?;
        runs.push(seconds);
        final_elbo = elbo;
    }
    let sequential = if plan.sequential_iterations > 0 {
        let n = plan.sequential_iterations;
        eprintln!("CoPA-Map: {n} iterations on one thread...");
        let one = fit(&train, n, Parallelism::Sequential)?.0;
        // The same iterations on all threads: the fits above when they ran as many.
        let every = if n == plan.iterations {
            median(runs.clone())
        } else {
            eprintln!("CoPA-Map: {n} iterations on all threads...");
            fit(&train, n, all)?.0
        };
        Some((n, one, every))
    } else {
        None
    };
    eprintln!("bare faer products of an iteration ({m} x {b})...");
    let (gemm_seconds, dense_seconds) = bare_dense(m, b, plan.dense_repeats);
    Ok(TrainingBench {
        samples: train.len(),
        cells: train.cell_count(),
        inducing: m,
        batch: b,
        iterations: plan.iterations,
        threads: all.tasks(),
        runs,
        setup_runs,
        final_elbo,
        gemm_seconds,
        dense_seconds,
        sequential,
    })
}

// ---------------------------------------------------------------- report

pub fn activity(args: &BenchActivityArgs) -> Result<()> {
    let plan = Plan::of(args)?;
    let ex = bench_extraction(args, &plan)?;
    let tr = bench_training(args, &plan)?;
    if args.json {
        println!("{}", report_json(args, &plan, &ex, &tr));
    } else {
        print_table(&plan, &ex, &tr);
    }
    Ok(())
}

fn report_json(
    args: &BenchActivityArgs,
    plan: &Plan,
    ex: &ExtractionBench,
    tr: &TrainingBench,
) -> Value {
    let seconds = ex.seconds();
    let scan = ex.scan_seconds();
    let fit = tr.seconds();
    let per_iteration = tr.iteration_seconds();
    let sequential = tr.sequential.map(|(n, one, every)| {
        let (one, every) = (tr.per_iteration(one, n), tr.per_iteration(every, n));
        json!({
            "iterations": n,
            "one_thread_seconds_per_iteration": one,
            "all_threads_seconds_per_iteration": every,
            "speedup": one / every,
        })
    });
    json!({
        "quick": args.quick,
        "threads": tr.threads,
        "extraction": {
            "track_files": plan.tracks.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "detections": ex.detections,
            "bins": ex.bins,
            "robots": ex.robots,
            "robot_steps": ex.robot_steps,
            "samples": ex.samples,
            "cells": ex.cells,
            "total_count": ex.total_count,
            "seconds": seconds,
            "runs": ex.runs,
            "detections_per_second": ex.detections as f64 / seconds,
            "robot_steps_per_second": ex.robot_steps as f64 / seconds,
            "bare_scan_seconds": scan,
            "bare_scan_outside": ex.scan_outside,
            "ratio_to_bare_scan": seconds / scan,
            "fov_cached_ray_casts": ex.cached_casts,
            "fov_uncached_ray_casts": ex.uncached_casts,
            "fov_uncached_seconds": ex.uncached_seconds,
            "ratio_uncached_fov_to_extraction": ex.uncached_seconds / seconds,
        },
        "copa": {
            "train": args.train.display().to_string(),
            "samples": tr.samples,
            "cells": tr.cells,
            "inducing": tr.inducing,
            "batch": tr.batch,
            "iterations": tr.iterations,
            "seconds": fit,
            "runs": tr.runs,
            "setup_seconds": tr.setup_seconds(),
            "seconds_per_iteration": per_iteration,
            "final_elbo": tr.final_elbo,
            "goal_seconds": GOAL_SECONDS,
            "goal_met": fit <= GOAL_SECONDS,
            "bare_gemm_products_per_iteration": 16,
            "bare_gemm_flops_per_iteration": product_flops(tr.inducing, tr.batch),
            "bare_gemm_seconds_per_iteration": tr.gemm_seconds,
            "ratio_iteration_to_bare_gemm": per_iteration / tr.gemm_seconds,
            "ratio_fit_to_bare_gemm": fit / (tr.gemm_seconds * tr.iterations as f64),
            "bare_dense_seconds_per_iteration": tr.dense_seconds,
            "ratio_iteration_to_bare_dense": per_iteration / tr.dense_seconds,
            "sequential": sequential,
        },
    })
}

fn print_table(plan: &Plan, ex: &ExtractionBench, tr: &TrainingBench) {
    let seconds = ex.seconds();
    let scan = ex.scan_seconds();
    let fit = tr.seconds();
    let per_iteration = tr.iteration_seconds();
    let bare_fit = tr.gemm_seconds * tr.iterations as f64;
    println!(
        "extraction (§4.2.2): ATC 2012-10-24, {} detections from {} track files, {} hour bins; \
         robots {} ({} robot steps of 1 s); {} samples over {} cells",
        ex.detections,
        plan.tracks.len(),
        ex.bins.len(),
        ex.robots.join(", "),
        ex.robot_steps,
        ex.samples,
        ex.cells
    );
    println!(
        "  {:.3e} detections/s, {:.3e} robot steps/s; field of view ray cast {} times (once per robot \
         map cell) instead of {} (once per robot step)",
        ex.detections as f64 / seconds,
        ex.robot_steps as f64 / seconds,
        ex.cached_casts,
        ex.uncached_casts
    );
    println!(
        "CoPA-Map (eqs. 4.12–4.16): {} samples over {} cells, {} inducing points, batch {}, {} \
         iterations, {} threads; setup (scaling, k-means inducing points) {:.2} s of the fit",
        tr.samples,
        tr.cells,
        tr.inducing,
        tr.batch,
        tr.iterations,
        tr.threads,
        tr.setup_seconds()
    );
    println!(
        "  bare baseline: the 16 faer products of an iteration ({:.2e} flops), one thread",
        product_flops(tr.inducing, tr.batch)
    );
    let mut table = Table::new(["goal", "measured", "baseline (same run)", "ratio"]);
    table.row([
        format!("extraction, median of {}", ex.runs.len()),
        format!("{seconds:.3} s"),
        format!("bare (cell, hour) binning {:.2} ms", scan * 1e3),
        format!("{:.0}", seconds / scan),
    ]);
    table.row([
        "extraction with its field-of-view cache".to_string(),
        format!("{seconds:.3} s"),
        format!("ray casts at every step {:.2} s", ex.uncached_seconds),
        format!("{:.3}", seconds / ex.uncached_seconds),
    ]);
    table.row([
        format!(
            "CoPA-Map fit <= {GOAL_SECONDS:.0} s, median of {}",
            tr.runs.len()
        ),
        format!(
            "{fit:.1} s ({})",
            if fit <= GOAL_SECONDS { "met" } else { "missed" }
        ),
        format!("{} x bare products {bare_fit:.2} s", tr.iterations),
        format!("{:.2}", fit / bare_fit),
    ]);
    table.row([
        "  one iteration".to_string(),
        format!("{:.1} ms", per_iteration * 1e3),
        format!("bare products {:.1} ms", tr.gemm_seconds * 1e3),
        format!("{:.2}", per_iteration / tr.gemm_seconds),
    ]);
    table.row([
        "  one iteration".to_string(),
        format!("{:.1} ms", per_iteration * 1e3),
        format!("+ solves, Cholesky {:.1} ms", tr.dense_seconds * 1e3),
        format!("{:.2}", per_iteration / tr.dense_seconds),
    ]);
    if let Some((n, one, every)) = tr.sequential {
        let (one, every) = (tr.per_iteration(one, n), tr.per_iteration(every, n));
        table.row([
            format!("  one thread vs {} ({n} iterations)", tr.threads),
            format!("{:.1} ms", one * 1e3),
            format!("{:.1} ms", every * 1e3),
            format!("{:.2}", one / every),
        ]);
    }
    println!("{}", table.render());
}
