//! scikit-learn cross-check of `chronomap_hypertime::mixture::fit_em_from`: from the same initial
//! mixture, with absolute regularisation, our EM must follow scikit-learn's
//! `GaussianMixture(covariance_type="full")` trajectory: the same iteration count and
//! convergence, and weights, means and covariances equal to 1e-8 (relative), on blobs, on
//! hypertime data (minutes of a week as cos/sin of the daily and weekly periods plus a noisy
//! 0/1 class column, [Krajník 2019] §III), on integer-weighted rows (scikit-learn gets the rows
//! repeated), on points on a circle and on a run stopped by `max_iter`.
//!
//! scikit-learn runs when `CHRONOMAP_SKLEARN_PYTHON` names a Python interpreter that imports
//! `sklearn` (`.ci/run` sets it up; `tests/oracle/sklearn_gmm.py` is the script). Without it
//! the test checks our own fits only and says how to enable the comparison, unless
//! `CHRONOMAP_REQUIRE_SKLEARN=1`, when it fails.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_hypertime::mixture::{
    EmConfig, EmFit, GaussianMixture, KMeansConfig, fit_em_from, kmeans, mixture_of_clusters,
};
use serde_json::{Value, json};

use crate::common::{oracle_python, run_oracle, scratch};

/// Relative tolerance of every comparison.
const TOLERANCE: f64 = 1e-8;

/// One case: data, initial mixture and EM settings.
struct Case {
    name: &'static str,
    dim: usize,
    data: Vec<f64>,
    weights: Option<Vec<f64>>,
    initial: GaussianMixture,
    reg_covar: f64,
    tol: f64,
    max_iter: usize,
}

impl Case {
    fn config(&self) -> EmConfig {
        EmConfig {
            components: self.initial.components(),
            max_iterations: self.max_iter,
            tolerance: self.tol,
            regularization: self.reg_covar,
            relative_regularization: false,
            ..EmConfig::default()
        }
    }

    fn fit(&self) -> EmFit {
        fit_em_from(
            &self.data,
            self.dim,
            self.weights.as_deref(),
            &self.initial,
            &self.config(),
        )
        .unwrap_or_else(|e| panic!("{}: {e}", self.name))
    }

    /// The case file of `sklearn_gmm.py`.
    fn json(&self) -> Value {
        let (d, m) = (self.dim, &self.initial);
        let rows: Vec<&[f64]> = self.data.chunks_exact(d).collect();
        let means: Vec<&[f64]> = (0..m.components()).map(|c| m.mean(c)).collect();
        let precisions: Vec<Vec<Vec<f64>>> = (0..m.components())
            .map(|c| {
                inverse(m.covariance(c), d)
                    .chunks_exact(d)
                    .map(<[f64]>::to_vec)
                    .collect()
            })
            .collect();
        json!({
            "data": rows,
            "weights": self.weights,
            "means_init": means,
            "weights_init": m.weights(),
            "precisions_init": precisions,
            "reg_covar": self.reg_covar,
            "tol": self.tol,
            "max_iter": self.max_iter,
        })
    }
}

/// The inverse of a symmetric positive definite matrix (Gauss–Jordan), symmetrised.
fn inverse(a: &[f64], d: usize) -> Vec<f64> {
    let mut m = a.to_vec();
    let mut inv: Vec<f64> = (0..d * d)
        .map(|i| f64::from(u8::from(i / d == i % d)))
        .collect();
    for col in 0..d {
        let p = m[col * d + col];
        for j in 0..d {
            m[col * d + j] /= p;
            inv[col * d + j] /= p;
        }
        for r in (0..d).filter(|&r| r != col) {
            let f = m[r * d + col];
            for j in 0..d {
                m[r * d + j] -= f * m[col * d + j];
                inv[r * d + j] -= f * inv[col * d + j];
            }
        }
    }
    for i in 0..d {
        for j in 0..i {
            let s = 0.5 * (inv[i * d + j] + inv[j * d + i]);
            inv[i * d + j] = s;
            inv[j * d + i] = s;
        }
    }
    inv
}

fn normal(rng: &mut Xoshiro256StarStar) -> f64 {
    let u = 1.0 - rng.next_f64();
    (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * rng.next_f64()).cos()
}

/// `n` rows from `k` correlated Gaussian blobs in `dim` dimensions.
fn blobs(seed: u64, n: usize, dim: usize, k: usize, spread: f64) -> Vec<f64> {
    let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
    let centres: Vec<f64> = (0..k * dim).map(|_| rng.uniform(-spread, spread)).collect();
    let mut data = Vec::with_capacity(n * dim);
    for _ in 0..n {
        let c = rng.int_in(0, k as u64 - 1) as usize;
        let shared = normal(&mut rng);
        for j in 0..dim {
            data.push(centres[c * dim + j] + 0.7 * normal(&mut rng) + 0.4 * shared);
        }
    }
    data
}

/// Hypertime rows `(cos, sin)` of the daily and weekly periods of minute `t` of a week, and a
/// 0/1 class: an office door open on weekdays 8:00–18:00, observations wrong 10 % of the time.
fn hypertime_week(step_minutes: usize) -> Vec<f64> {
    let mut rng = Xoshiro256StarStar::seed_from_u64(7);
    let tau = 2.0 * std::f64::consts::PI;
    (0..7 * 1440)
        .step_by(step_minutes)
        .flat_map(|t| {
            let (day, minute) = (t / 1440, t % 1440);
            let open = day < 5 && (8 * 60..18 * 60).contains(&minute);
            let observed = open != rng.bernoulli(0.1);
            let (a, b) = (
                tau * minute as f64 / 1440.0,
                tau * t as f64 / (7.0 * 1440.0),
            );
            [
                a.cos(),
                a.sin(),
                b.cos(),
                b.sin(),
                f64::from(u8::from(observed)),
            ]
        })
        .collect()
}

/// The mixture of the clusters of our k-means, regularised by `reg`.
fn kmeans_mixture(
    data: &[f64],
    dim: usize,
    weights: Option<&[f64]>,
    k: usize,
    reg: f64,
) -> GaussianMixture {
    let config = KMeansConfig {
        clusters: k,
        seed: 3,
        ..KMeansConfig::default()
    };
    let fit = kmeans(data, dim, weights, &config).unwrap();
    mixture_of_clusters(data, dim, weights, &fit.labels, k, reg).unwrap()
}

/// A case on the rows `(dim, data, weights)` with the EM settings `(reg_covar, tol, max_iter)`,
/// started from the `k` clusters of our k-means (regularised by `reg_covar` too).
fn kmeans_case(
    name: &'static str,
    (dim, data, weights): (usize, Vec<f64>, Option<Vec<f64>>),
    k: usize,
    (reg_covar, tol, max_iter): (f64, f64, usize),
) -> Case {
    Case {
        name,
        dim,
        initial: kmeans_mixture(&data, dim, weights.as_deref(), k, reg_covar),
        data,
        weights,
        reg_covar,
        tol,
        max_iter,
    }
}

fn cases() -> Vec<Case> {
    let mut cases = vec![
        kmeans_case(
            "blobs_2d",
            (2, blobs(1, 900, 2, 3, 4.0), None),
            3,
            (1e-6, 1e-3, 100),
        ),
        kmeans_case(
            "hypertime_week",
            (5, hypertime_week(5), None),
            4,
            (1e-6, 1e-6, 300),
        ),
    ];

    // The daily part of the hypertime data aggregated: every (10-minute slot, class) once,
    // weighted by how often it was observed.
    let week = hypertime_week(10);
    let mut unique: Vec<[f64; 3]> = Vec::new();
    let mut counts: Vec<f64> = Vec::new();
    for r in week.chunks_exact(5) {
        let row = [r[0], r[1], r[4]];
        match unique.iter().position(|u| *u == row) {
            Some(i) => counts[i] += 1.0,
            None => {
                unique.push(row);
                counts.push(1.0);
            }
        }
    }
    cases.push(kmeans_case(
        "hypertime_daily_weighted",
        (3, unique.concat(), Some(counts)),
        3,
        (1e-4, 1e-6, 500),
    ));

    // Points on a circle (hours of the day, many duplicates) from a poor start: a long run.
    let mut rng = Xoshiro256StarStar::seed_from_u64(11);
    let data: Vec<f64> = (0..1500)
        .flat_map(|_| {
            let a = std::f64::consts::PI * rng.int_in(0, 23) as f64 / 12.0;
            [a.cos(), a.sin()]
        })
        .collect();
    cases.push(Case {
        name: "circle_poor_start",
        dim: 2,
        initial: GaussianMixture::new(
            2,
            vec![0.5, 0.3, 0.2],
            vec![0.1, 0.0, -0.1, 0.05, 0.0, -0.2],
            [1.0, 0.0, 0.0, 1.0].repeat(3),
        )
        .unwrap(),
        data,
        weights: None,
        reg_covar: 1e-6,
        tol: 1e-9,
        max_iter: 500,
    });

    cases.push(kmeans_case(
        "max_iter_4d",
        (4, blobs(2, 700, 4, 3, 1.5), None),
        3,
        (1e-3, 1e-12, 4),
    ));

    let data = blobs(3, 400, 1, 2, 3.0);
    cases.push(Case {
        name: "one_d",
        dim: 1,
        initial: GaussianMixture::new(1, vec![0.5, 0.5], vec![-1.0, 1.0], vec![1.0, 1.0]).unwrap(),
        data,
        weights: None,
        reg_covar: 1e-6,
        tol: 1e-6,
        max_iter: 300,
    });
    cases
}

/// Runs `sklearn_gmm.py` on the case files; returns its JSON output (file name -> result).
fn run_sklearn(python: &str, files: &[PathBuf]) -> Value {
    let args: Vec<&OsStr> = files.iter().map(|f| f.as_os_str()).collect();
    run_oracle(
        python,
        "CHRONOMAP_SKLEARN_PYTHON",
        "sklearn_gmm.py",
        &args,
        "sklearn_gmm.py",
    )
}

/// Flattens a JSON array of arrays of numbers.
fn numbers(v: &Value) -> Vec<f64> {
    match v {
        Value::Array(items) => items.iter().flat_map(numbers).collect(),
        v => vec![v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))],
    }
}

/// Largest `|a − b| / scale` over paired values.
fn worst(a: &[f64], b: &[f64], scale: impl Fn(usize) -> f64) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .enumerate()
        .map(|(i, (x, y))| (x - y).abs() / scale(i))
        .fold(0.0, f64::max)
}

/// Relative differences of our fit and scikit-learn's.
struct Agreement {
    weights: f64,
    means: f64,
    covariances: f64,
    likelihood: f64,
}

fn compare(case: &Case, ours: &EmFit, sk: &Value) -> Agreement {
    let (d, m) = (case.dim, &ours.mixture);
    let k = m.components();
    let sk_weights = numbers(&sk["weights_"]);
    let sk_means = numbers(&sk["means_"]);
    let sk_cov = numbers(&sk["covariances_"]);
    let our_means: Vec<f64> = (0..k).flat_map(|c| m.mean(c).to_vec()).collect();
    let our_cov: Vec<f64> = (0..k).flat_map(|c| m.covariance(c).to_vec()).collect();
    // Means relative to the component's spread in that dimension (a mean near 0 has no
    // relative precision of its own); covariances relative to √(Σ_aa Σ_bb).
    let spread = |c: usize, a: usize| sk_cov[c * d * d + a * d + a].sqrt();
    let weights = worst(m.weights(), &sk_weights, |i| {
        sk_weights[i].abs().max(1e-300)
    });
    let means = worst(&our_means, &sk_means, |i| {
        sk_means[i].abs().max(spread(i / d, i % d))
    });
    let covariances = worst(&our_cov, &sk_cov, |i| {
        let (c, a, b) = (i / (d * d), i % (d * d) / d, i % d);
        spread(c, a) * spread(c, b)
    });
    // scikit-learn's lower bounds are the E-step log-likelihoods of the mixtures entering
    // each iteration: ours of the initial mixture, then our trace without its last value.
    let mut bounds = vec![
        case.initial
            .mean_log_likelihood(
                &case.data,
                case.weights.as_deref(),
                chronomap_core::Parallelism::Sequential,
            )
            .unwrap(),
    ];
    bounds.extend(&ours.trace[..ours.trace.len().saturating_sub(1)]);
    let sk_bounds = numbers(&sk["lower_bounds_"]);
    let mut likelihood = worst(
        &[ours.log_likelihood],
        &[sk["score"].as_f64().unwrap()],
        |_| 1.0f64.max(ours.log_likelihood.abs()),
    );
    if !sk_bounds.is_empty() {
        likelihood = likelihood.max(worst(&bounds, &sk_bounds, |i| 1.0f64.max(bounds[i].abs())));
    }
    Agreement {
        weights,
        means,
        covariances,
        likelihood,
    }
}

#[test]
fn fit_em_from_follows_scikit_learns_trajectory() {
    let started = Instant::now();
    let cases = cases();
    let fits: Vec<EmFit> = cases.iter().map(Case::fit).collect();
    println!(
        "chronomap: {} fits in {:.2} s",
        cases.len(),
        started.elapsed().as_secs_f64()
    );
    // Our own sanity: nothing diagonalises, the runs end as set. (The likelihood trace is
    // compared with scikit-learn's below rather than checked for monotonicity: with a ridge
    // as large as `hypertime_daily_weighted`'s 1e-4 on a 0/1 column, the M-step maximises a
    // penalised expected log-likelihood and the likelihood can fall by ~1e-6, in both.)
    for (case, fit) in cases.iter().zip(&fits) {
        assert!(fit.log_likelihood.is_finite(), "{}", case.name);
        assert!(!fit.diagonal, "{}", case.name);
        assert_eq!(fit.numerical_restarts, 0);
        assert_eq!(
            fit.converged,
            fit.iterations < case.max_iter,
            "{}",
            case.name
        );
    }
    assert_eq!(fits[4].iterations, 4, "max_iter_4d stops at max_iter");

    let enable = "set CHRONOMAP_SKLEARN_PYTHON to a Python with scikit-learn \
                  (python3 -m venv sk-venv && sk-venv/bin/pip install scikit-learn==1.9.1), \
                  see tests/oracle/README.md";
    let Some(python) = oracle_python("SKLEARN", "sklearn_gmm", "scikit-learn", enable) else {
        return;
    };
    let dir = scratch("sklearn_gmm");
    let files: Vec<PathBuf> = cases
        .iter()
        .map(|case| {
            let path = dir.join(format!("{}.json", case.name));
            std::fs::write(&path, case.json().to_string()).unwrap();
            path
        })
        .collect();
    let results = run_sklearn(&python, &files);

    println!(
        "| case | rows | dim | k | iterations (ours / sklearn) | converged | max rel Δ weights | \
         means | covariances | log-likelihoods |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    let mut failures = Vec::new();
    for ((case, fit), file) in cases.iter().zip(&fits).zip(&files) {
        let name = Path::new(file).file_name().unwrap().to_str().unwrap();
        let sk = &results[name];
        let a = compare(case, fit, sk);
        let sk_iter = sk["n_iter_"].as_u64().unwrap() as usize;
        println!(
            "| {} | {} | {} | {} | {} / {} | {} | {:.1e} | {:.1e} | {:.1e} | {:.1e} |",
            case.name,
            sk["rows"],
            case.dim,
            case.initial.components(),
            fit.iterations,
            sk_iter,
            fit.converged,
            a.weights,
            a.means,
            a.covariances,
            a.likelihood
        );
        if fit.iterations != sk_iter || fit.converged != sk["converged_"].as_bool().unwrap() {
            failures.push(format!(
                "{}: {} iterations (converged {}), scikit-learn {sk_iter} ({})",
                case.name, fit.iterations, fit.converged, sk["converged_"]
            ));
        }
        let worst = a.weights.max(a.means).max(a.covariances).max(a.likelihood);
        if worst.is_nan() || worst > TOLERANCE {
            failures.push(format!("{}: relative difference {worst:e}", case.name));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
