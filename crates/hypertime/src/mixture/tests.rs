//! Tests of the mixtures: EM's monotonicity on ordinary and degenerate data, determinism,
//! weights as duplicated rows, k-means' inertia, known answers, densities against naive
//! formulas, marginals/conditionals/moments against hand-computed Gaussians, errors.

use super::*;
use chronomap_core::rng::Xoshiro256StarStar;

/// A standard normal draw.
fn normal(rng: &mut Xoshiro256StarStar) -> f64 {
    rng.standard_normal()
}

/// `n` rows in `dim` dimensions from `k` random Gaussian blobs.
fn blobs(seed: u64, n: usize, dim: usize, k: usize) -> Vec<f64> {
    let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
    let centres: Vec<f64> = (0..k * dim).map(|_| rng.uniform(-5.0, 5.0)).collect();
    let scales: Vec<f64> = (0..k * dim).map(|_| rng.uniform(0.2, 1.5)).collect();
    let mut data = Vec::with_capacity(n * dim);
    for _ in 0..n {
        let c = rng.int_in(0, k as u64 - 1) as usize;
        let shear = normal(&mut rng);
        for j in 0..dim {
            // Correlated coordinates: a shared term plus an independent one.
            data.push(
                centres[c * dim + j] + scales[c * dim + j] * (normal(&mut rng) + 0.5 * shear),
            );
        }
    }
    data
}

/// Points on the unit circle `(cos, sin)` at `n` times of day rounded to the hour: many
/// exact duplicates, all on a curve.
fn circle(seed: u64, n: usize) -> Vec<f64> {
    let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
    (0..n)
        .flat_map(|_| {
            let hour = rng.int_in(0, 23) as f64;
            let a = 2.0 * std::f64::consts::PI * hour / 24.0;
            [a.cos(), a.sin()]
        })
        .collect()
}

/// The degenerate data sets of the module doc, each `(name, data, dim)`.
fn degenerate_sets() -> Vec<(&'static str, Vec<f64>, usize)> {
    let mut sets = Vec::new();
    sets.push(("circle", circle(1, 500), 2));
    // Many duplicates: 400 copies of 5 points.
    let five = blobs(2, 5, 3, 2);
    sets.push(("duplicates", five.repeat(80), 3));
    // One far outlier.
    let mut outlier = blobs(3, 300, 2, 2);
    outlier.extend([1e6, -1e6]);
    sets.push(("outlier", outlier, 2));
    // Two dimensions exactly collinear: (x, 2x + 1, y).
    let base = blobs(4, 300, 2, 3);
    let collinear: Vec<f64> = base
        .chunks_exact(2)
        .flat_map(|r| [r[0], 2.0 * r[0] + 1.0, r[1]])
        .collect();
    sets.push(("collinear", collinear, 3));
    // Scales differing by 1e6.
    let scaled: Vec<f64> = blobs(5, 300, 2, 3)
        .chunks_exact(2)
        .flat_map(|r| [1e6 * r[0], 1e-6 * r[1]])
        .collect();
    sets.push(("scales", scaled, 2));
    // Hypertime-like: daily circle plus a 0/1 class column.
    let mut rng = Xoshiro256StarStar::seed_from_u64(6);
    let hyper: Vec<f64> = circle(7, 400)
        .chunks_exact(2)
        .flat_map(|r| [r[0], r[1], f64::from(rng.bernoulli(0.3 + 0.4 * r[1]))])
        .collect();
    sets.push(("circle+class", hyper, 3));
    sets
}

fn config(k: usize, seed: u64) -> EmConfig {
    EmConfig {
        components: k,
        seed,
        ..EmConfig::default()
    }
}

/// Every number of a mixture is finite; weights sum to 1.
fn assert_finite(m: &GaussianMixture, what: &str) {
    assert!(
        m.weights
            .iter()
            .chain(&m.means)
            .chain(&m.covariances)
            .chain(&m.cholesky)
            .chain(&m.log_normalisers)
            .all(|v| v.is_finite() || *v == f64::NEG_INFINITY),
        "{what}: a value is not finite: {m:?}"
    );
    let sum: f64 = m.weights.iter().sum();
    assert!((sum - 1.0).abs() < 1e-12, "{what}: weights sum to {sum}");
}

/// The trace of EM never decreases by more than `1e-9` relative.
fn assert_monotone(trace: &[f64], what: &str) {
    for (i, w) in trace.windows(2).enumerate() {
        let allowed = 1e-9 * w[0].abs().max(1.0);
        assert!(
            w[1] >= w[0] - allowed,
            "{what}: trace decreased at {i}: {} -> {} ({:e})",
            w[0],
            w[1],
            w[1] - w[0]
        );
    }
}

#[test]
fn em_trace_is_non_decreasing_on_random_data() {
    for seed in 0..6 {
        let dim = 1 + seed as usize % 5;
        let data = blobs(100 + seed, 600, dim, 3);
        for k in [1, 2, 3, 5] {
            let what = format!("seed {seed}, dim {dim}, k {k}");
            let fit = fit_em(&data, dim, None, &config(k, seed)).unwrap();
            assert_monotone(&fit.trace, &what);
            assert_finite(&fit.mixture, &what);
            assert_eq!(fit.trace.len(), fit.iterations, "{what}");
            assert_eq!(fit.log_likelihood, *fit.trace.last().unwrap(), "{what}");
            assert_eq!(
                fit.mixture
                    .mean_log_likelihood(&data, None, Parallelism::Sequential)
                    .unwrap(),
                fit.log_likelihood,
                "{what}: the reported likelihood is the mixture's"
            );
            if k <= 3 {
                assert!(fit.converged, "{what}: {} iterations", fit.iterations);
            }
            assert!(!fit.diagonal, "{what}");
        }
    }
}

#[test]
fn em_is_monotone_and_finite_on_degenerate_data() {
    for (name, data, dim) in degenerate_sets() {
        for k in [1, 2, 4, 5] {
            let what = format!("{name}, k {k}");
            let fit = fit_em(&data, dim, None, &config(k, 9)).unwrap();
            assert_monotone(&fit.trace, &what);
            assert_finite(&fit.mixture, &what);
            assert!(fit.log_likelihood.is_finite(), "{what}");
            for c in 0..k {
                assert!(
                    fit.mixture.weights()[c] > 0.0,
                    "{what}: empty component {c}"
                );
            }
        }
    }
}

#[test]
fn em_without_regularisation_on_collinear_data_falls_back_to_diagonal() {
    let (_, data, dim) = degenerate_sets()
        .into_iter()
        .find(|s| s.0 == "collinear")
        .unwrap();
    let cfg = EmConfig {
        regularization: 0.0,
        ..config(3, 1)
    };
    let fit = fit_em(&data, dim, None, &cfg).unwrap();
    assert!(fit.diagonal);
    assert_eq!(fit.numerical_restarts, cfg.starts * NUMERICAL_RESTARTS);
    assert_finite(&fit.mixture, "collinear, diagonal");
    for c in 0..3 {
        let cov = fit.mixture.covariance(c);
        assert_eq!(cov[1], 0.0);
        assert!(cov[0] > 0.0 && cov[4] > 0.0 && cov[8] > 0.0);
    }
    assert_monotone(&fit.trace, "collinear, diagonal");

    // From a given mixture the first failing M-step switches to diagonal covariances.
    let initial = GaussianMixture::new(
        3,
        vec![0.5, 0.5],
        vec![-1.0, -1.0, 0.0, 1.0, 3.0, 0.0],
        [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0].repeat(2),
    )
    .unwrap();
    let cfg = EmConfig {
        regularization: 0.0,
        relative_regularization: false,
        ..config(2, 0)
    };
    let fit = fit_em_from(&data, dim, None, &initial, &cfg).unwrap();
    assert!(fit.diagonal);
    assert_eq!(fit.numerical_restarts, 0);
    assert_finite(&fit.mixture, "collinear from a mixture");
}

#[test]
fn identical_seeds_give_identical_bits_on_any_thread_pool() {
    // More rows than one chunk, so that the pool is used.
    let data = blobs(11, 5000, 4, 3);
    let fit = |threads: usize, seed: u64| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| fit_em(&data, 4, None, &config(3, seed)).unwrap())
    };
    let bits = |f: &EmFit| {
        let m = &f.mixture;
        m.weights
            .iter()
            .chain(&m.means)
            .chain(&m.covariances)
            .chain(&f.trace)
            .map(|v| v.to_bits())
            .collect::<Vec<_>>()
    };
    let a = fit(1, 5);
    let b = fit(4, 5);
    let c = fit(3, 5);
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(bits(&a), bits(&c));
    // The same bits on the calling thread alone.
    let sequential = EmConfig {
        parallelism: Parallelism::Sequential,
        ..config(3, 5)
    };
    assert_eq!(
        bits(&a),
        bits(&fit_em(&data, 4, None, &sequential).unwrap())
    );
    assert_eq!(
        a.mixture
            .mean_log_likelihood(&data, None, Parallelism::Sequential)
            .unwrap()
            .to_bits(),
        a.mixture
            .mean_log_likelihood(&data, None, Parallelism::Rayon(3))
            .unwrap()
            .to_bits()
    );
    assert_eq!(a, b);
    let other = fit(2, 6);
    assert_ne!(bits(&a), bits(&other), "the seed matters");

    let km = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                kmeans(
                    &data,
                    4,
                    None,
                    &KMeansConfig {
                        clusters: 4,
                        ..KMeansConfig::default()
                    },
                )
                .unwrap()
            })
    };
    assert_eq!(km(1), km(4));
}

/// Relative difference of two slices.
fn max_relative(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / x.abs().max(y.abs()).max(1e-300))
        .fold(0.0, f64::max)
}

#[test]
fn integer_weights_equal_duplicated_rows() {
    let base = blobs(21, 400, 3, 3);
    let mut rng = Xoshiro256StarStar::seed_from_u64(22);
    let weights: Vec<f64> = (0..400).map(|_| rng.int_in(0, 4) as f64).collect();
    let mut duplicated = Vec::new();
    for (row, &w) in base.chunks_exact(3).zip(&weights) {
        for _ in 0..w as usize {
            duplicated.extend_from_slice(row);
        }
    }
    let weighted = fit_em(&base, 3, Some(&weights), &config(3, 4)).unwrap();
    let plain = fit_em(&duplicated, 3, None, &config(3, 4)).unwrap();
    assert_eq!(weighted.iterations, plain.iterations);
    let (a, b) = (&weighted.mixture, &plain.mixture);
    for (x, y) in [
        (&a.weights, &b.weights),
        (&a.means, &b.means),
        (&a.covariances, &b.covariances),
        (&weighted.trace, &plain.trace),
    ] {
        let r = max_relative(x, y);
        assert!(r < 1e-12, "relative difference {r:e}");
    }

    // k-means too, and the mixture of its clusters.
    let cfg = KMeansConfig {
        clusters: 3,
        ..KMeansConfig::default()
    };
    let kw = kmeans(&base, 3, Some(&weights), &cfg).unwrap();
    let kd = kmeans(&duplicated, 3, None, &cfg).unwrap();
    assert!(max_relative(&kw.centres, &kd.centres) < 1e-12);
    assert!(max_relative(&[kw.inertia], &[kd.inertia]) < 1e-12);
}

#[test]
fn kmeans_inertia_never_increases() {
    let mut sets: Vec<(String, Vec<f64>, usize)> = (0..5)
        .map(|s| {
            (
                format!("blobs {s}"),
                blobs(30 + s, 1000, 2 + s as usize, 4),
                2 + s as usize,
            )
        })
        .collect();
    sets.extend(
        degenerate_sets()
            .into_iter()
            .map(|(n, d, dim)| (n.to_string(), d, dim)),
    );
    for (name, data, dim) in sets {
        let rows = Rows::new(&data, dim, None).unwrap();
        for k in [2, 3, 5] {
            let mut rng = Xoshiro256StarStar::seed_from_u64(k as u64);
            let centres = kmeans::plus_plus(&rows, k, &mut rng);
            let mut trace = Vec::new();
            let fit = kmeans::lloyd(&rows, centres, 100, Some(&mut trace));
            assert!(trace.len() >= 2, "{name}: {trace:?}");
            // Rounding of the means may leave 1e-12 of the data's sum of squares.
            let slack = 1e-12 * data.iter().map(|x| x * x).sum::<f64>();
            for w in trace.windows(2) {
                assert!(
                    w[1] <= w[0] + slack,
                    "{name}, k {k}: inertia rose {} -> {}",
                    w[0],
                    w[1]
                );
            }
            assert_eq!(fit.inertia, *trace.last().unwrap());
            // Every cluster keeps a row; the inertia is that of the labels.
            let mut counts = vec![0; k];
            let mut inertia = 0.0;
            for (i, &l) in fit.labels.iter().enumerate() {
                counts[l] += 1;
                let x = &data[i * dim..(i + 1) * dim];
                let c = &fit.centres[l * dim..(l + 1) * dim];
                inertia += x.iter().zip(c).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
            }
            assert!(counts.iter().all(|&c| c > 0), "{name}: {counts:?}");
            assert!((inertia - fit.inertia).abs() <= 1e-9 * inertia.max(1e-300));
        }
    }
}

#[test]
fn kmeans_finds_well_separated_clusters() {
    // Three tight clusters of different sizes; k-means++ with 3 starts finds them.
    let mut rng = Xoshiro256StarStar::seed_from_u64(40);
    let centres = [[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]];
    let mut data = Vec::new();
    for (c, n) in centres.iter().zip([100, 200, 300]) {
        for _ in 0..n {
            data.push(c[0] + 0.1 * normal(&mut rng));
            data.push(c[1] + 0.1 * normal(&mut rng));
        }
    }
    let fit = kmeans(
        &data,
        2,
        None,
        &KMeansConfig {
            clusters: 3,
            ..KMeansConfig::default()
        },
    )
    .unwrap();
    for c in centres {
        let found = fit
            .centres
            .chunks_exact(2)
            .any(|f| (f[0] - c[0]).abs() < 0.05 && (f[1] - c[1]).abs() < 0.05);
        assert!(found, "{c:?} not among {:?}", fit.centres);
    }
    assert!(fit.inertia < 600.0 * 2.0 * 0.01 * 1.3, "{}", fit.inertia);
}

#[test]
fn em_recovers_two_well_separated_blobs() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(50);
    let n = 4000;
    let mut data = Vec::with_capacity(2 * n);
    let mut labels = Vec::with_capacity(n);
    for _ in 0..n {
        let (a, b) = (normal(&mut rng), normal(&mut rng));
        if rng.bernoulli(0.3) {
            data.extend([a, 0.5 * a + b]); // Σ = [[1, .5], [.5, 1.25]]
            labels.push(0);
        } else {
            data.extend([20.0 + 2.0 * a, 5.0 + 0.5 * b]); // Σ = [[4, 0], [0, .25]]
            labels.push(1);
        }
    }
    let fit = fit_em(&data, 2, None, &config(2, 0)).unwrap();
    assert!(fit.converged);
    let m = &fit.mixture;
    let order = if m.mean(0)[0] < m.mean(1)[0] {
        [0, 1]
    } else {
        [1, 0]
    };
    // The blobs are 8 standard deviations apart: EM's answer is each blob's sample
    // statistics (what `mixture_of_clusters` computes from the true labels).
    let truth = mixture_of_clusters(&data, 2, None, &labels, 2, 0.0).unwrap();
    let close = |a: &[f64], b: &[f64], tol: f64| a.iter().zip(b).all(|(x, y)| (x - y).abs() < tol);
    for (t, &c) in order.iter().enumerate() {
        assert!((m.weights()[c] - truth.weights()[t]).abs() < 1e-6);
        assert!(close(m.mean(c), truth.mean(t), 1e-4), "{:?}", m.mean(c));
        assert!(close(m.covariance(c), truth.covariance(t), 1e-4));
    }
    // And close to the parameters the data were drawn from.
    let [small, large] = order;
    assert!((m.weights()[small] - 0.3).abs() < 0.03, "{:?}", m.weights());
    assert!(
        close(m.mean(small), &[0.0, 0.0], 0.1),
        "{:?}",
        m.mean(small)
    );
    assert!(
        close(m.mean(large), &[20.0, 5.0], 0.1),
        "{:?}",
        m.mean(large)
    );
    assert!(close(m.covariance(small), &[1.0, 0.5, 0.5, 1.25], 0.2));
    assert!(close(m.covariance(large), &[4.0, 0.0, 0.0, 0.25], 0.25));
}

#[test]
fn one_component_is_the_weighted_sample_mean_and_covariance() {
    let data = blobs(60, 300, 3, 2);
    let mut rng = Xoshiro256StarStar::seed_from_u64(61);
    let weights: Vec<f64> = (0..300).map(|_| rng.uniform(0.0, 2.0)).collect();
    let total: f64 = weights.iter().sum();
    let mut mean = [0.0; 3];
    for (row, w) in data.chunks_exact(3).zip(&weights) {
        for j in 0..3 {
            mean[j] += w * row[j] / total;
        }
    }
    let mut cov = [0.0; 9];
    for (row, w) in data.chunks_exact(3).zip(&weights) {
        for a in 0..3 {
            for b in 0..3 {
                cov[a * 3 + b] += w * (row[a] - mean[a]) * (row[b] - mean[b]) / total;
            }
        }
    }
    let mean_variance = (cov[0] + cov[4] + cov[8]) / 3.0;
    for relative in [true, false] {
        let cfg = EmConfig {
            regularization: 1e-3,
            relative_regularization: relative,
            ..config(1, 0)
        };
        let reg = if relative { 1e-3 * mean_variance } else { 1e-3 };
        let fit = fit_em(&data, 3, Some(&weights), &cfg).unwrap();
        let m = &fit.mixture;
        assert_eq!(m.weights(), [1.0]);
        assert!(
            max_relative(m.mean(0), &mean) < 1e-12,
            "{:?} {mean:?}",
            m.mean(0)
        );
        let mut expected = cov;
        for a in 0..3 {
            expected[a * 4] += reg;
        }
        let r = max_relative(m.covariance(0), &expected);
        assert!(r < 1e-12, "relative {relative}: {r:e}");
        // The first M-step is already the answer; the second E-step sees no change.
        assert_eq!(fit.iterations, 2);
    }
}

/// Determinant and inverse by Gauss–Jordan elimination with partial pivoting.
fn naive_inverse_and_determinant(a: &[f64], d: usize) -> (Vec<f64>, f64) {
    let mut m: Vec<f64> = a.to_vec();
    let mut inv: Vec<f64> = (0..d * d)
        .map(|i| if i / d == i % d { 1.0 } else { 0.0 })
        .collect();
    let mut det = 1.0;
    for col in 0..d {
        let pivot = (col..d)
            .max_by(|&x, &y| m[x * d + col].abs().total_cmp(&m[y * d + col].abs()))
            .unwrap();
        if pivot != col {
            for j in 0..d {
                m.swap(pivot * d + j, col * d + j);
                inv.swap(pivot * d + j, col * d + j);
            }
            det = -det;
        }
        let p = m[col * d + col];
        det *= p;
        for j in 0..d {
            m[col * d + j] /= p;
            inv[col * d + j] /= p;
        }
        for r in 0..d {
            if r != col {
                let f = m[r * d + col];
                for j in 0..d {
                    m[r * d + j] -= f * m[col * d + j];
                    inv[r * d + j] -= f * inv[col * d + j];
                }
            }
        }
    }
    (inv, det)
}

/// A random symmetric positive definite matrix `AAᵀ + 0.1 I`.
fn random_spd(rng: &mut Xoshiro256StarStar, d: usize) -> Vec<f64> {
    let a: Vec<f64> = (0..d * d).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let mut s = vec![0.0; d * d];
    for i in 0..d {
        for j in 0..d {
            s[i * d + j] = (0..d).map(|l| a[i * d + l] * a[j * d + l]).sum::<f64>()
                + if i == j { 0.1 } else { 0.0 };
        }
    }
    s
}

#[test]
fn log_density_equals_the_naive_formula() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(70);
    for d in [1, 2, 3, 5, 8] {
        let k = 3;
        let weights: Vec<f64> = (0..k).map(|_| rng.uniform(0.1, 1.0)).collect();
        let means: Vec<f64> = (0..k * d).map(|_| rng.uniform(-2.0, 2.0)).collect();
        let covs: Vec<f64> = (0..k).flat_map(|_| random_spd(&mut rng, d)).collect();
        let m = GaussianMixture::new(d, weights.clone(), means.clone(), covs.clone()).unwrap();
        let total: f64 = weights.iter().sum();
        for _ in 0..20 {
            let x: Vec<f64> = (0..d).map(|_| rng.uniform(-3.0, 3.0)).collect();
            let mut p = 0.0;
            let mut each = vec![0.0; k];
            for c in 0..k {
                let (inv, det) =
                    naive_inverse_and_determinant(&covs[c * d * d..(c + 1) * d * d], d);
                let diff: Vec<f64> = (0..d).map(|j| x[j] - means[c * d + j]).collect();
                let q: f64 = (0..d)
                    .map(|i| {
                        (0..d)
                            .map(|j| diff[i] * inv[i * d + j] * diff[j])
                            .sum::<f64>()
                    })
                    .sum();
                let pc = weights[c] / total
                    * (2.0 * std::f64::consts::PI).powf(-(d as f64) / 2.0)
                    * det.powf(-0.5)
                    * (-0.5 * q).exp();
                each[c] = pc.ln();
                p += pc;
            }
            let got = m.log_density(&x);
            assert!((got - p.ln()).abs() < 1e-10, "d {d}: {got} vs {}", p.ln());
            let mut out = vec![0.0; k];
            m.component_log_densities(&x, &mut out);
            for c in 0..k {
                assert!((out[c] - each[c]).abs() < 1e-10, "d {d}, c {c}");
            }
        }
    }
    // Far away the density underflows in linear space but not here.
    let m = GaussianMixture::new(1, vec![1.0], vec![0.0], vec![1.0]).unwrap();
    let far = m.log_density(&[100.0]);
    assert!((far - (-0.5 * (2.0 * std::f64::consts::PI).ln() - 5000.0)).abs() < 1e-9);
}

#[test]
fn mean_log_likelihood_weights_rows() {
    let m = GaussianMixture::new(1, vec![1.0], vec![0.0], vec![1.0]).unwrap();
    let data = [0.0, 1.0, 2.0];
    let weights = [1.0, 0.0, 3.0];
    let expected = (m.log_density(&[0.0]) + 3.0 * m.log_density(&[2.0])) / 4.0;
    let got = m
        .mean_log_likelihood(&data, Some(&weights), Parallelism::Sequential)
        .unwrap();
    assert!((got - expected).abs() < 1e-14);
    assert_eq!(
        m.mean_log_likelihood(&data, Some(&[0.0; 3]), Parallelism::Rayon(2)),
        Err(MixtureError::EmptyData)
    );
}

#[test]
fn marginal_and_conditional_of_hand_computed_gaussians() {
    // 2-D, one component: μ = (1, 2), Σ = [[4, 1.2], [1.2, 1]].
    let g = GaussianMixture::new(2, vec![1.0], vec![1.0, 2.0], vec![4.0, 1.2, 1.2, 1.0]).unwrap();
    let c = g.conditional(&[1], &[3.0]);
    assert_eq!(c.dim(), 1);
    // μ = 1 + 1.2/1·(3 − 2) = 2.2, σ² = 4 − 1.2²/1 = 2.56.
    assert!((c.mean(0)[0] - 2.2).abs() < 1e-14);
    assert!((c.covariance(0)[0] - 2.56).abs() < 1e-14);
    let c0 = g.conditional(&[0], &[-1.0]);
    // μ = 2 + 1.2/4·(−1 − 1) = 1.4, σ² = 1 − 1.44/4 = 0.64.
    assert!((c0.mean(0)[0] - 1.4).abs() < 1e-14);
    assert!((c0.covariance(0)[0] - 0.64).abs() < 1e-14);
    let mg = g.marginal(&[1]);
    assert_eq!((mg.mean(0), mg.covariance(0)), (&[2.0][..], &[1.0][..]));

    // Two components: the weights are re-weighted by N(x_b; μ_b, Σ_bb).
    let g = GaussianMixture::new(
        2,
        vec![0.25, 0.75],
        vec![1.0, 2.0, -1.0, 0.0],
        vec![4.0, 1.2, 1.2, 1.0, 1.0, -0.3, -0.3, 0.25],
    )
    .unwrap();
    let y = 0.5;
    let n1 = |x: f64, m: f64, v: f64| {
        (-(x - m) * (x - m) / (2.0 * v)).exp() / (2.0 * std::f64::consts::PI * v).sqrt()
    };
    let (a, b) = (0.25 * n1(y, 2.0, 1.0), 0.75 * n1(y, 0.0, 0.25));
    let c = g.conditional(&[1], &[y]);
    assert!((c.weights()[0] - a / (a + b)).abs() < 1e-14);
    assert!((c.weights()[1] - b / (a + b)).abs() < 1e-14);
    assert!((c.mean(1)[0] - (-1.0 + (-0.3 / 0.25) * (y - 0.0))).abs() < 1e-14);
    assert!((c.covariance(1)[0] - (1.0 - 0.09 / 0.25)).abs() < 1e-14);
    // Far away in the given dimension: the log domain keeps the weights finite.
    let c = g.conditional(&[1], &[1e3]);
    assert_finite(&c, "far conditional");
    assert!(c.weights()[0] > 0.999_999);

    // 3-D: condition on dims 0 and 2 (a 2 × 2 block inverted by hand).
    let s = [
        2.0, 0.3, 0.5, //
        0.3, 1.5, -0.4, //
        0.5, -0.4, 1.0,
    ];
    let mu = [0.5, -1.0, 2.0];
    let g = GaussianMixture::new(3, vec![1.0], mu.to_vec(), s.to_vec()).unwrap();
    let x = [1.0, 1.0]; // x0 = 1, x2 = 1
    // Σ_bb = [[2, .5], [.5, 1]], det = 1.75, inverse = [[1, −.5], [−.5, 2]] / 1.75.
    let inv = [1.0 / 1.75, -0.5 / 1.75, -0.5 / 1.75, 2.0 / 1.75];
    let s_ab = [0.3, -0.4]; // Σ_1,(0,2)
    let db = [x[0] - mu[0], x[1] - mu[2]];
    let k0 = s_ab[0] * inv[0] + s_ab[1] * inv[2];
    let k1 = s_ab[0] * inv[1] + s_ab[1] * inv[3];
    let mean = mu[1] + k0 * db[0] + k1 * db[1];
    let var = s[4] - (k0 * s_ab[0] + k1 * s_ab[1]);
    let c = g.conditional(&[2, 0], &[x[1], x[0]]);
    assert!(
        (c.mean(0)[0] - mean).abs() < 1e-14,
        "{} vs {mean}",
        c.mean(0)[0]
    );
    assert!((c.covariance(0)[0] - var).abs() < 1e-14);
    // Conditioning on one dimension leaves a 2-D Gaussian with the Schur complement.
    let c = g.conditional(&[1], &[0.0]);
    assert_eq!(c.dim(), 2);
    let expected = [
        2.0 - 0.3 * 0.3 / 1.5,
        0.5 - 0.3 * -0.4 / 1.5,
        0.5 - 0.3 * -0.4 / 1.5,
        1.0 - 0.16 / 1.5,
    ];
    assert!(max_relative(c.covariance(0), &expected) < 1e-14);
    let expected_mean = [0.5 + 0.3 / 1.5 * 1.0, 2.0 - 0.4 / 1.5 * 1.0];
    assert!(max_relative(c.mean(0), &expected_mean) < 1e-14);
    // Marginal over dims (2, 0) reorders.
    let mg = g.marginal(&[2, 0]);
    assert_eq!(mg.mean(0), [2.0, 0.5]);
    assert_eq!(mg.covariance(0), [1.0, 0.5, 0.5, 2.0]);
    assert!(
        (mg.log_density(&[2.0, 0.5]) - (-(2.0 * std::f64::consts::PI).ln() - 0.5 * 1.75f64.ln()))
            .abs()
            < 1e-14
    );
}

#[test]
fn moments_follow_the_law_of_total_variance() {
    let g = GaussianMixture::new(
        2,
        vec![0.2, 0.3, 0.5],
        vec![0.0, 1.0, 2.0, -1.0, 4.0, 0.5],
        vec![
            1.0, 0.1, 0.1, 2.0, //
            0.5, 0.0, 0.0, 0.5, //
            2.0, -0.3, -0.3, 1.0,
        ],
    )
    .unwrap();
    let (mean, var) = g.moments(0);
    let m: f64 = 0.2 * 0.0 + 0.3 * 2.0 + 0.5 * 4.0;
    let second = 0.2 * (1.0 + 0.0) + 0.3 * (0.5 + 4.0) + 0.5 * (2.0 + 16.0);
    assert!((mean - m).abs() < 1e-14);
    assert!((var - (second - m * m)).abs() < 1e-13);
    let (mean, var) = g.moments(1);
    let m = 0.2 * 1.0 - 0.3 + 0.5 * 0.5;
    let second = 0.2 * (2.0 + 1.0) + 0.3 * (0.5 + 1.0) + 0.5 * (1.0 + 0.25);
    assert!((mean - m).abs() < 1e-14);
    assert!((var - (second - m * m)).abs() < 1e-13);
}

#[test]
fn mixture_of_clusters_is_the_clusters_statistics() {
    let data = [0.0, 0.0, 2.0, 0.0, 10.0, 10.0, 10.0, 12.0, 11.0, 11.0];
    let labels = [0, 0, 2, 2, 2];
    let weights = [1.0, 3.0, 1.0, 1.0, 2.0];
    let m = mixture_of_clusters(&data, 2, Some(&weights), &labels, 3, 0.5).unwrap();
    assert_eq!(m.components(), 2, "the empty cluster 1 is dropped");
    assert_eq!(m.weights(), [0.5, 0.5]);
    assert_eq!(m.mean(0), [1.5, 0.0]);
    // Var x = (1·1.5² + 3·0.5²)/4 = 0.75.
    assert_eq!(m.covariance(0), [0.75 + 0.5, 0.0, 0.0, 0.5]);
    assert_eq!(m.mean(1), [10.5, 11.0]);
    // x: (1·.25 + 1·.25 + 2·.25)/4 = .25; y: (1 + 1 + 0)/4 = .5; xy: (.5 − .5 + 0)/4 = 0.
    assert_eq!(m.covariance(1), [0.25 + 0.5, 0.0, 0.0, 0.5 + 0.5]);
    assert_eq!(
        mixture_of_clusters(&data, 2, None, &labels, 2, 0.5),
        Err(MixtureError::DimensionMismatch(
            "label 2 is not below k = 2".into()
        ))
    );
    // Without regularisation two points are a singular cluster.
    let all = mixture_of_clusters(&data, 2, None, &[0; 5], 1, 0.0).unwrap();
    assert_eq!(all.components(), 1);
    assert_eq!(
        mixture_of_clusters(&data, 2, None, &[2, 2, 0, 0, 0], 3, 0.0),
        Err(MixtureError::NotPositiveDefinite { component: 1 })
    );
}

#[test]
fn empty_components_are_reseeded() {
    let data = blobs(80, 500, 2, 2);
    // A component far from every row: its responsibilities underflow to zero.
    let initial = GaussianMixture::new(
        2,
        vec![0.5, 0.5, 1e-30],
        vec![0.0, 0.0, 1.0, 1.0, 1e4, 1e4],
        [1.0, 0.0, 0.0, 1.0].repeat(3),
    )
    .unwrap();
    let fit = fit_em_from(&data, 2, None, &initial, &config(3, 0)).unwrap();
    assert_finite(&fit.mixture, "reseeded");
    assert!(
        fit.mixture.weights()[2] > 1e-6,
        "{:?}",
        fit.mixture.weights()
    );
    assert!(fit.mixture.mean(2)[0].abs() < 100.0);
}

#[test]
fn bad_input_gives_the_right_error() {
    let data = blobs(90, 20, 2, 2);
    let cfg = config(2, 0);
    let mut nan = data.clone();
    nan[7] = f64::NAN;
    assert!(matches!(
        fit_em(&nan, 2, None, &cfg),
        Err(MixtureError::NonFinite { row: 3, coordinate: 1, value }) if value.is_nan()
    ));
    let mut inf = data.clone();
    inf[0] = f64::INFINITY;
    assert!(matches!(
        kmeans(&inf, 2, None, &KMeansConfig::default()),
        Err(MixtureError::NonFinite {
            row: 0,
            coordinate: 0,
            ..
        })
    ));
    let mut w = vec![1.0; 20];
    w[5] = -1.0;
    assert_eq!(
        fit_em(&data, 2, Some(&w), &cfg),
        Err(MixtureError::InvalidWeight {
            row: 5,
            weight: -1.0
        })
    );
    w[5] = f64::NAN;
    assert!(matches!(
        fit_em(&data, 2, Some(&w), &cfg),
        Err(MixtureError::InvalidWeight { row: 5, .. })
    ));
    assert!(matches!(
        fit_em(&data, 3, None, &cfg),
        Err(MixtureError::DimensionMismatch(_))
    ));
    assert!(matches!(
        fit_em(&data, 2, Some(&[1.0; 19]), &cfg),
        Err(MixtureError::DimensionMismatch(_))
    ));
    assert!(matches!(
        fit_em(&data, 0, None, &cfg),
        Err(MixtureError::DimensionMismatch(_))
    ));
    assert_eq!(fit_em(&[], 2, None, &cfg), Err(MixtureError::EmptyData));
    assert_eq!(
        fit_em(&data, 2, Some(&[0.0; 20]), &cfg),
        Err(MixtureError::EmptyData)
    );
    // 3 distinct points (many duplicates, and a distinct one of weight 0) for 4 components.
    let few = [0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 2.0, 0.0, 1.0, 1.0, 5.0, 5.0];
    let fw = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0];
    assert_eq!(
        fit_em(&few, 2, Some(&fw), &config(4, 0)),
        Err(MixtureError::TooFewPoints {
            points: 3,
            components: 4
        })
    );
    assert!(fit_em(&few, 2, None, &config(4, 0)).is_ok());
    assert_eq!(
        fit_em(&few, 2, None, &config(usize::MAX, 0)),
        Err(MixtureError::TooFewPoints {
            points: 4,
            components: usize::MAX
        })
    );
    assert_eq!(
        kmeans(
            &few,
            2,
            Some(&fw),
            &KMeansConfig {
                clusters: 4,
                ..KMeansConfig::default()
            }
        ),
        Err(MixtureError::TooFewPoints {
            points: 3,
            components: 4
        })
    );
    assert!(matches!(
        fit_em(&data, 2, None, &config(0, 0)),
        Err(MixtureError::InvalidConfig(_))
    ));
    assert!(matches!(
        kmeans(
            &data,
            2,
            None,
            &KMeansConfig {
                clusters: 0,
                ..KMeansConfig::default()
            }
        ),
        Err(MixtureError::InvalidConfig(_))
    ));
    for bad in [
        EmConfig {
            starts: 0,
            ..cfg.clone()
        },
        EmConfig {
            tolerance: f64::NAN,
            ..cfg.clone()
        },
        EmConfig {
            regularization: -1.0,
            ..cfg.clone()
        },
    ] {
        assert!(matches!(
            fit_em(&data, 2, None, &bad),
            Err(MixtureError::InvalidConfig(_))
        ));
    }
    // Mixtures.
    assert_eq!(
        GaussianMixture::new(2, vec![1.0], vec![0.0, 0.0], vec![1.0, 2.0, 2.0, 1.0]),
        Err(MixtureError::NotPositiveDefinite { component: 0 })
    );
    assert_eq!(
        GaussianMixture::new(2, vec![1.0], vec![0.0, 0.0], vec![1.0, 0.5, 0.0, 1.0]),
        Err(MixtureError::NotPositiveDefinite { component: 0 })
    );
    assert!(matches!(
        GaussianMixture::new(2, vec![1.0], vec![0.0], vec![1.0, 0.0, 0.0, 1.0]),
        Err(MixtureError::DimensionMismatch(_))
    ));
    assert!(matches!(
        GaussianMixture::new(1, vec![-1.0, 2.0], vec![0.0, 1.0], vec![1.0, 1.0]),
        Err(MixtureError::InvalidConfig(_))
    ));
    assert!(matches!(
        GaussianMixture::new(1, vec![0.0], vec![0.0], vec![1.0]),
        Err(MixtureError::InvalidConfig(_))
    ));
    assert!(matches!(
        GaussianMixture::new(1, vec![1.0], vec![f64::NAN], vec![1.0]),
        Err(MixtureError::NonFinite {
            row: 0,
            coordinate: 0,
            ..
        })
    ));
    let one = GaussianMixture::new(2, vec![1.0], vec![0.0, 0.0], vec![1.0, 0.0, 0.0, 1.0]).unwrap();
    assert!(matches!(
        fit_em_from(&blobs(1, 10, 3, 1), 3, None, &one, &cfg),
        Err(MixtureError::DimensionMismatch(_))
    ));
    assert!(matches!(
        one.mean_log_likelihood(&[1.0, 2.0, 3.0], None, Parallelism::Sequential),
        Err(MixtureError::DimensionMismatch(_))
    ));
}

#[test]
fn mixtures_serialise_round_trip() {
    let fit = fit_em(&blobs(95, 200, 2, 2), 2, None, &config(2, 0)).unwrap();
    let bytes = postcard::to_allocvec(&fit.mixture).unwrap();
    let back: GaussianMixture = postcard::from_bytes(&bytes).unwrap();
    assert_eq!(back, fit.mixture);
}

#[test]
fn small_degenerate_data_never_panic_or_give_nan() {
    // Few distinct points (on a grid, on a circle, identical but one), random integer
    // weights with zeros, every k up to the number of distinct points, both inits, with and
    // without regularisation.
    let mut rng = Xoshiro256StarStar::seed_from_u64(99);
    for case in 0..60 {
        let dim = 1 + case % 4;
        let n = 2 + rng.int_in(0, 30) as usize;
        let levels = 1 + rng.int_in(0, 3);
        let mut data: Vec<f64> = (0..n * dim)
            .map(|_| rng.int_in(0, levels) as f64 * 0.5)
            .collect();
        if case % 5 == 0 {
            data.iter_mut().for_each(|v| *v = 3.0);
            data[0] = 3.5;
        }
        let weights: Vec<f64> = (0..n).map(|_| rng.int_in(0, 3) as f64).collect();
        let weights = if weights.iter().all(|&w| w == 0.0) || case % 3 == 0 {
            None
        } else {
            Some(weights)
        };
        let rows = Rows::new(&data, dim, weights.as_deref()).unwrap();
        let distinct = rows.distinct_up_to(usize::MAX);
        for k in 1..=distinct.min(6) {
            for (init, reg) in [(EmInit::KMeans, 1e-6), (EmInit::KMeansPlusPlus, 0.0)] {
                let cfg = EmConfig {
                    components: k,
                    init,
                    regularization: reg,
                    starts: 2,
                    max_iterations: 50,
                    seed: case as u64,
                    ..EmConfig::default()
                };
                let what = format!("case {case}, dim {dim}, k {k}, {init:?}");
                let fit = fit_em(&data, dim, weights.as_deref(), &cfg)
                    .unwrap_or_else(|e| panic!("{what}: {e}"));
                assert_finite(&fit.mixture, &what);
                assert!(!fit.log_likelihood.is_nan(), "{what}");
                assert!(fit.trace.iter().all(|v| !v.is_nan()), "{what}");
                let km = kmeans(
                    &data,
                    dim,
                    weights.as_deref(),
                    &KMeansConfig {
                        clusters: k,
                        ..KMeansConfig::default()
                    },
                )
                .unwrap();
                assert!(km.inertia.is_finite() && km.centres.iter().all(|v| v.is_finite()));
            }
        }
        let too_many = distinct + 1;
        assert!(matches!(
            fit_em(&data, dim, weights.as_deref(), &config(too_many, 0)),
            Err(MixtureError::TooFewPoints { .. })
        ));
    }
}
