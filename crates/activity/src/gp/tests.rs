#![allow(clippy::needless_range_loop)] // index loops mirror the matrix formulas being checked

use faer::Mat;

use super::kernel::{cross, cross_grad, gram, gram_grad};
use super::svgp::{chol, mm, solve_l, solve_lt};
use super::*;
use chronomap_core::par::Parallelism;
use chronomap_core::rng::Xoshiro256StarStar;

const SEQ: Parallelism = Parallelism::Sequential;

/// The batch `(x, y)` whose expected log-likelihood is scaled by `scale`.
fn batch<'a>(x: &'a [Point], y: &'a [f64], scale: f64) -> Batch<'a> {
    Batch { x, y, scale }
}

/// A uniform input of `[0, 1]² × [0, t_max]`.
fn random_input(rng: &mut Xoshiro256StarStar, t_max: f64) -> Point {
    [
        rng.uniform(0.0, 1.0),
        rng.uniform(0.0, 1.0),
        rng.uniform(0.0, t_max),
    ]
}

fn random_points(rng: &mut Xoshiro256StarStar, n: usize) -> Vec<Point> {
    (0..n).map(|_| random_input(rng, 30.0)).collect()
}

/// An activity kernel of variance `variance` with one daily component.
fn daily_kernel(variance: f64) -> ActivityKernel {
    ActivityKernel::new(
        variance,
        [0.5, 0.5],
        &[PeriodicComponent {
            variance: 1.0,
            lengthscale: 0.6,
            period: 24.0,
        }],
    )
}

fn activity_kernel() -> ActivityKernel {
    ActivityKernel::new(
        0.7,
        [0.3, 0.45],
        &[
            PeriodicComponent {
                variance: 0.8,
                lengthscale: 0.6,
                period: 24.0,
            },
            PeriodicComponent {
                variance: 0.3,
                lengthscale: 0.4,
                period: 7.3,
            },
        ],
    )
}

fn rbf_kernel() -> RbfKernel {
    RbfKernel::new(0.5, [0.25, 0.35, 6.0])
}

/// Relative error `|a − b| / max(|a|, |b|, floor)`.
fn rel(a: f64, b: f64, floor: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs()).max(floor)
}

/// Central finite difference of `f` at `p[i]`.
fn fd<F: Fn(&[f64]) -> f64>(f: F, p: &[f64], i: usize, h: f64) -> f64 {
    let mut q = p.to_vec();
    q[i] = p[i] + h;
    let up = f(&q);
    q[i] = p[i] - h;
    let down = f(&q);
    (up - down) / (2.0 * h)
}

/// [`fd`] of `f(kernel)` in the kernel's log-parameter `i` (step `1e-6`).
fn fd_kernel<K: Kernel + Clone>(k: &K, i: usize, f: impl Fn(&K) -> f64) -> f64 {
    fd(
        |q| {
            let mut kk = k.clone();
            kk.params_mut().copy_from_slice(q);
            f(&kk)
        },
        k.params(),
        i,
        1e-6,
    )
}

/// [`fd`] of `f(points)` in coordinate `d` of `points[j]` (step `1e-6`).
fn fd_point(points: &[Point], j: usize, d: usize, f: impl Fn(&[Point]) -> f64) -> f64 {
    fd(
        |q| {
            let mut moved = points.to_vec();
            moved[j][d] = q[0];
            f(&moved)
        },
        &[points[j][d]],
        0,
        1e-6,
    )
}

// ------------------------------------------------------------------ quadrature

#[test]
fn gauss_hermite_matches_known_rules() {
    let (x, w) = gauss_hermite(2);
    let sp = std::f64::consts::PI.sqrt();
    assert!((x[0] - 0.5f64.sqrt()).abs() < 1e-15 && (x[1] + 0.5f64.sqrt()).abs() < 1e-15);
    assert!((w[0] - sp / 2.0).abs() < 1e-15 && (w[1] - sp / 2.0).abs() < 1e-15);
    let (x, w) = gauss_hermite(20);
    // Largest node of the 20-point rule (Abramowitz & Stegun table 25.10).
    assert!((x[0] - 5.387_480_890_011_233).abs() < 1e-13, "{}", x[0]);
    assert!((w.iter().sum::<f64>() - sp).abs() < 1e-13);
    // Exact up to degree 39: ∫ x³⁸ e^{−x²} dx = Γ(19.5) = 37!!/2¹⁹ √π.
    let dfact: f64 = (1..=37).step_by(2).map(|k| k as f64).product();
    let exact = dfact / 2f64.powi(19) * sp;
    let quad: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(38)).sum();
    assert!(rel(quad, exact, 0.0) < 1e-12, "{quad} vs {exact}");
    let odd: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(7)).sum();
    assert!(odd.abs() < 1e-10);
}

#[test]
fn expected_log_lik_matches_brute_force_2d_quadrature() {
    let lik = HeteroGaussian::new(20);
    let (xs, ws) = gauss_hermite(60);
    let sp = std::f64::consts::PI.sqrt();
    for &(y, mf, vf, mg, vg) in &[
        (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64),
        (1.3, 0.7, 0.2, -0.5, 0.3),
        (-0.4, 0.1, 0.05, 0.8, 0.6),
        (2.0, 2.1, 1.0, 0.0, 0.01),
    ] {
        // Brute force: 60 × 60 Gauss–Hermite over (f, g) of ln N(y | f, softplus(g)²).
        let mut brute = 0.0;
        for (xf, wf) in xs.iter().zip(&ws) {
            for (xg, wg) in xs.iter().zip(&ws) {
                let f = mf + (2.0 * vf).sqrt() * xf;
                let s = softplus(mg + (2.0 * vg).sqrt() * xg);
                let lp = -0.5 * (2.0 * std::f64::consts::PI * s * s).ln()
                    - (y - f) * (y - f) / (2.0 * s * s);
                brute += wf * wg / (sp * sp) * lp;
            }
        }
        let e = lik.expected_log_lik(y, mf, vf, mg, vg);
        assert!(rel(e.value, brute, 1.0) < 1e-6, "{} vs {brute}", e.value);
    }
}

/// The half-width of the predictive law of an observation: the normal's `z √(v_f + ζ(m_g)²)`
/// when `g` is certain; otherwise the probability of the mixture within it is `coverage` by a
/// brute-force midpoint rule over `g` (to the accuracy of the model's 20-node rule), and it lies between the normals of the least and the greatest noise.
#[test]
fn central_half_width_solves_the_mixture_of_normals() {
    use statrs::distribution::{Continuous, ContinuousCDF, Normal};
    let lik = HeteroGaussian::new(20);
    let normal = Normal::standard();
    let normal_pdf = |u: f64| normal.pdf(u);
    for coverage in [0.1, 0.5, 0.9, 0.99, 0.999] {
        let z = normal.inverse_cdf(0.5 + coverage / 2.0);
        for &(vf, mg) in &[(0.0f64, 0.0f64), (0.3, -1.0), (2.0, 1.5)] {
            let exact = z * (vf + softplus(mg).powi(2)).sqrt();
            let h = lik.central_half_width(vf, mg, 0.0, coverage);
            assert!(rel(h, exact, 0.0) < 1e-12, "{h} vs {exact}");
        }
        for &(vf, mg, vg) in &[
            (0.1f64, -0.5f64, 0.8f64),
            (0.0, 0.5, 1.0),
            (0.01, 1.0, 0.5),
            (1.0, -2.0, 0.3),
        ] {
            let h = lik.central_half_width(vf, mg, vg, coverage);
            // The midpoint rule over g in m_g ± 10 sd, 20,000 steps.
            let steps = 20_000;
            let du = 20.0 / f64::from(steps);
            let p: f64 = (0..steps)
                .map(|k| {
                    let u = -10.0 + (f64::from(k) + 0.5) * du;
                    let s = (vf + softplus(mg + vg.sqrt() * u).powi(2)).sqrt();
                    du * normal_pdf(u) * (2.0 * normal.cdf(h / s) - 1.0)
                })
                .sum();
            // The 20-node rule is exact to 1e-7 here but where the noise dominates and g is
            // uncertain (v_f = 0, v_g = 1: 1.2e-5 at 90 %).
            assert!((p - coverage).abs() < 1e-4, "{p} vs {coverage}");
            let variance = vf + lik.expected_noise_variance(mg, vg);
            assert!(h > 0.0 && h.is_finite());
            let lo = z * (vf + softplus(mg - 6.0 * vg.sqrt()).powi(2)).sqrt();
            let hi = z * (vf + softplus(mg + 6.0 * vg.sqrt()).powi(2)).sqrt();
            assert!(
                lo < h && h < hi,
                "{lo} {h} {hi} (normal {})",
                z * variance.sqrt()
            );
        }
    }
    assert!(lik.central_half_width(1.0, 0.0, 0.0, 1.0).is_nan());
    assert!(lik.central_half_width(f64::NAN, 0.0, 0.0, 0.9).is_nan());
}

#[test]
fn expected_log_lik_gradients_match_finite_differences() {
    let lik = HeteroGaussian::new(20);
    let mut worst: f64 = 0.0;
    for &p in &[
        [1.3, 0.7, 0.2, -0.5, 0.3],
        [-0.4, 0.1, 0.05, 0.8, 0.6],
        [2.0, 2.1, 1.0, 0.0, 1e-16],
    ] {
        let e = lik.expected_log_lik(p[0], p[1], p[2], p[3], p[4]);
        let an = [e.d_mf, e.d_vf, e.d_mg, e.d_vg];
        let val = |q: &[f64]| lik.expected_log_lik(q[0], q[1], q[2], q[3], q[4]).value;
        for k in 0..4 {
            // v_g = 1e-16 uses the Price's-theorem branch: a one-sided difference there.
            let num = if k == 3 && p[4] < 1e-10 {
                let mut q = p.to_vec();
                q[4] = 1e-7;
                (val(&q) - val(&p)) / (1e-7 - p[4])
            } else {
                fd(val, &p, k + 1, 1e-6)
            };
            let r = rel(an[k], num, 1e-3);
            worst = worst.max(if k == 3 && p[4] < 1e-10 { 0.0 } else { r });
            let tol = if k == 3 && p[4] < 1e-10 { 1e-4 } else { 1e-7 };
            assert!(r < tol, "param {k} at {p:?}: {} vs {num}", an[k]);
        }
    }
    assert!(worst < 1e-7);
}

// ------------------------------------------------------------------ kernels

fn check_kernel_grads<K: Kernel + Clone>(k: &K, seed: u64) -> f64 {
    let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
    let pts = random_points(&mut rng, 12);
    let np = k.params().len();
    let mut worst: f64 = 0.0;
    for pair in pts.chunks_exact(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let mut dth = vec![0.0; np];
        let mut dx = [0.0; 3];
        let v = k.eval_grad(a, b, &mut dth, &mut dx);
        assert!(rel(v, k.eval(a, b), 1e-300) < 1e-14);
        for i in 0..np {
            let num = fd_kernel(k, i, |kk| kk.eval(a, b));
            let r = rel(dth[i], num, 1e-8);
            worst = worst.max(r);
            assert!(r < 1e-6, "param {i}: {} vs {num}", dth[i]);
        }
        for d in 0..3 {
            let num = fd(|q| k.eval(&[q[0], q[1], q[2]], b), a, d, 1e-6);
            let r = rel(dx[d], num, 1e-8);
            worst = worst.max(r);
            assert!(r < 1e-6, "dx {d}: {} vs {num}", dx[d]);
        }
    }
    // Diagonal.
    let mut dd = vec![0.0; np];
    k.diag_grad(&mut dd);
    assert!(rel(k.diag(), k.eval(&pts[0], &pts[0]), 0.0) < 1e-14);
    for i in 0..np {
        let num = fd_kernel(k, i, K::diag);
        assert!(
            (dd[i] - num).abs() < 1e-8,
            "diag param {i}: {} vs {num}",
            dd[i]
        );
    }
    worst
}

#[test]
fn kernel_gradients_match_finite_differences() {
    assert!(check_kernel_grads(&activity_kernel(), 1) < 1e-6);
    assert!(check_kernel_grads(&rbf_kernel(), 2) < 1e-6);
}

#[test]
fn kernels_have_the_seed_form() {
    let k = activity_kernel();
    let a = [0.2, 0.4, 3.0];
    // Shift by 0.1 in x1 only: Matérn-5/2 with l = 0.3 (eq. 4.9) times the temporal sum at 0.
    let r = 5f64.sqrt() * 0.1 / 0.3;
    let m = (1.0 + r + r * r / 3.0) * (-r).exp();
    let expect = 0.7 * m * (0.8 + 0.3);
    assert!(rel(k.eval(&a, &[0.3, 0.4, 3.0]), expect, 0.0) < 1e-14);
    // A shift of one period of the first component leaves that component at its maximum.
    let t_only = ActivityKernel::new(
        1.0,
        [1.0, 1.0],
        &[PeriodicComponent {
            variance: 2.0,
            lengthscale: 0.5,
            period: 24.0,
        }],
    );
    assert!(rel(t_only.eval(&a, &[0.2, 0.4, 27.0]), 2.0, 0.0) < 1e-14);
    // Half a period: exp(−½ sin²(π/2) / 0.25) = e^{−2}.
    assert!(
        rel(
            t_only.eval(&a, &[0.2, 0.4, 15.0]),
            2.0 * (-2.0f64).exp(),
            0.0
        ) < 1e-14
    );
    let g = rbf_kernel();
    let expect = 0.5 * (-0.5 * ((0.1f64 / 0.25).powi(2) + (3.0f64 / 6.0).powi(2))).exp();
    assert!(rel(g.eval(&a, &[0.3, 0.4, 6.0]), expect, 0.0) < 1e-14);
}

#[test]
fn gram_and_cross_gradients_match_finite_differences() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(7);
    let z = random_points(&mut rng, 5);
    let x = random_points(&mut rng, 4);
    let k = activity_kernel();
    let np = k.params().len();
    let wz = Mat::from_fn(5, 5, |_, _| rng.uniform(-1.0, 1.0));
    let wx = Mat::from_fn(5, 4, |_, _| rng.uniform(-1.0, 1.0));
    let objective = |kk: &ActivityKernel, zz: &[Point], xx: &[Point]| {
        let g = gram(kk, zz, 1e-6, SEQ);
        let c = cross(kk, zz, xx, SEQ);
        let mut s = 0.0;
        for i in 0..5 {
            for j in 0..5 {
                s += wz[(i, j)] * g[(i, j)];
            }
            for j in 0..4 {
                s += wx[(i, j)] * c[(i, j)];
            }
        }
        s
    };
    let mut dth = vec![0.0; np];
    let mut dz = vec![[0.0; 3]; 5];
    let mut dx = vec![[0.0; 3]; 4];
    gram_grad(&k, &z, wz.as_ref(), &mut dth, &mut dz, SEQ);
    cross_grad(
        &k,
        &z,
        &x,
        wx.as_ref(),
        &mut dth,
        Some(&mut dz),
        Some(&mut dx),
        Parallelism::Rayon(3),
    );
    for i in 0..np {
        let num = fd_kernel(&k, i, |kk| objective(kk, &z, &x));
        assert!(rel(dth[i], num, 1e-6) < 1e-6, "{i}: {} vs {num}", dth[i]);
    }
    for j in 0..5 {
        for d in 0..3 {
            let num = fd_point(&z, j, d, |zz| objective(&k, zz, &x));
            assert!(
                rel(dz[j][d], num, 1e-6) < 1e-6,
                "z {j},{d}: {} vs {num}",
                dz[j][d]
            );
        }
    }
    for j in 0..4 {
        for d in 0..3 {
            let num = fd_point(&x, j, d, |xx| objective(&k, &z, xx));
            assert!(
                rel(dx[j][d], num, 1e-6) < 1e-6,
                "x {j},{d}: {} vs {num}",
                dx[j][d]
            );
        }
    }
}

// ------------------------------------------------------------------ SVGP

/// A random (non-prior) `q(v)`.
fn random_q(rng: &mut Xoshiro256StarStar, m: usize) -> Variational {
    let mean = (0..m).map(|_| rng.uniform(-1.0, 1.0)).collect();
    let chol = Mat::from_fn(m, m, |i, j| {
        if i == j {
            rng.uniform(0.3, 1.0)
        } else if i > j {
            rng.uniform(-0.2, 0.2)
        } else {
            0.0
        }
    });
    Variational { mean, chol }
}

#[test]
fn whitened_marginals_equal_the_seed_equations() {
    // eqs. 4.13/4.14 with q(u) = N(L μ, L S Lᵀ).
    let mut rng = Xoshiro256StarStar::seed_from_u64(11);
    let z = random_points(&mut rng, 6);
    let x = random_points(&mut rng, 5);
    let mut gp = LatentGp::new(activity_kernel(), z.clone());
    gp.q = random_q(&mut rng, 6);
    let marg = gp.marginals(&x, 1e-6, SEQ).unwrap();
    let kzz = gram(&gp.kernel, &z, 1e-6, SEQ);
    let l = chol(kzz.as_ref()).unwrap();
    let mu_u = mm(l.as_ref(), Mat::from_fn(6, 1, |i, _| gp.q.mean[i]).as_ref());
    let s = gp.q.covariance();
    let s_u = mm(mm(l.as_ref(), s.as_ref()).as_ref(), l.as_ref().transpose());
    let kzx = cross(&gp.kernel, &z, &x, SEQ);
    // B = Kzz⁻¹ Kzx
    let mut b = kzx.clone();
    solve_l(&l, &mut b);
    solve_lt(&l, &mut b);
    let mean = mm(b.as_ref().transpose(), mu_u.as_ref());
    let diff = Mat::from_fn(6, 6, |i, j| s_u[(i, j)] - kzz[(i, j)]);
    let cov = mm(
        mm(b.as_ref().transpose(), diff.as_ref()).as_ref(),
        b.as_ref(),
    );
    for j in 0..5 {
        assert!((marg.mean[j] - mean[(j, 0)]).abs() < 1e-9);
        let v = gp.kernel.diag() + cov[(j, j)];
        assert!((marg.var[j] - v).abs() < 1e-9, "{} vs {v}", marg.var[j]);
    }
}

/// `n` random inputs over three days (seeded) and the target `y(rng, x)` of each.
fn sample(
    seed: u64,
    n: usize,
    mut y_of: impl FnMut(&mut Xoshiro256StarStar, &Point) -> f64,
) -> (Vec<Point>, Vec<f64>) {
    let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
    let mut x = Vec::with_capacity(n);
    let mut y = Vec::with_capacity(n);
    for _ in 0..n {
        let p = random_input(&mut rng, 72.0);
        y.push(y_of(&mut rng, &p));
        x.push(p);
    }
    (x, y)
}

/// Every `k`-th input: the initial inducing inputs.
fn inducing(x: &[Point], k: usize) -> Vec<Point> {
    x.iter().step_by(k).copied().collect()
}

fn synthetic(seed: u64, n: usize) -> (Vec<Point>, Vec<f64>) {
    // A daily rhythm whose amplitude grows with x1; noise std 0.05 left, 0.4 right.
    sample(seed, n, |rng, p| {
        let f = 1.0 + (0.5 + p[0]) * (2.0 * std::f64::consts::PI * p[2] / 24.0).sin();
        let sd = if p[0] < 0.5 { 0.05 } else { 0.4 };
        f + sd * rng.standard_normal()
    })
}

fn small_model(z: Vec<Point>) -> HeteroSvgp {
    let kg = RbfKernel::new(0.5, [0.4, 0.4, 20.0]);
    HeteroSvgp::new(daily_kernel(1.0), kg, z)
}

/// Checks the analytic ELBO gradient `an` of `model` (flattened with the inducing inputs)
/// against central differences of `elbo` in every hyperparameter; returns their number.
#[track_caller]
fn check_elbo_gradient<M: SvgpModel + Clone>(
    model: &M,
    an: &[f64],
    elbo: impl Fn(&M) -> f64,
) -> usize {
    let p0 = model.hyperparameters(true);
    assert_eq!(p0.len(), an.len());
    let mut worst: f64 = 0.0;
    for i in 0..p0.len() {
        let num = fd(
            |q| {
                let mut m = model.clone();
                m.set_hyperparameters(q, true);
                elbo(&m)
            },
            &p0,
            i,
            1e-5,
        );
        let r = rel(an[i], num, 1e-2);
        worst = worst.max(r);
        assert!(r < 1e-6, "param {i}: {} vs {num}", an[i]);
    }
    assert!(worst < 1e-6);
    p0.len()
}

/// 150 iterations on minibatches of 200, seeded with `seed` ([`check_training`]).
fn long_training(seed: u64) -> TrainConfig {
    TrainConfig {
        iterations: 150,
        batch_size: 200,
        seed,
        ..TrainConfig::default()
    }
}

/// Trains `model` on `(x, y)`: the full-data ELBO must grow by more than `gain` and the
/// minibatch ELBO of the last 20 of 150 iterations must beat that of the first 20.
#[track_caller]
fn check_training<M: SvgpModel>(
    model: &mut M,
    (x, y): (&[Point], &[f64]),
    config: &TrainConfig,
    gain: f64,
    elbo: impl Fn(&M) -> f64,
) {
    let before = elbo(model);
    let trace = train(model, x, y, config, SEQ).unwrap();
    let after = elbo(model);
    assert!(after > before + gain, "ELBO {before} -> {after}");
    let late: f64 = trace[130..].iter().sum::<f64>() / 20.0;
    let early: f64 = trace[..20].iter().sum::<f64>() / 20.0;
    assert!(late > early, "minibatch ELBO {early} -> {late}");
}

/// Trains three models of `make` alike (twice sequentially, once on 3 threads): traces and
/// models must be identical; another seed gives another trace.
#[track_caller]
fn check_determinism<M: SvgpModel + PartialEq + std::fmt::Debug>(
    make: impl Fn() -> M,
    x: &[Point],
    y: &[f64],
) {
    let config = TrainConfig {
        iterations: 10,
        batch_size: 50,
        seed: 9,
        ..TrainConfig::default()
    };
    let (mut a, mut b, mut c) = (make(), make(), make());
    let ta = train(&mut a, x, y, &config, SEQ).unwrap();
    let tb = train(&mut b, x, y, &config, SEQ).unwrap();
    let tc = train(&mut c, x, y, &config, Parallelism::Rayon(3)).unwrap();
    assert_eq!((&ta, &a), (&tb, &b));
    assert_eq!((&ta, &a), (&tc, &c));
    let mut d = make();
    let td = train(&mut d, x, y, &TrainConfig { seed: 10, ..config }, SEQ).unwrap();
    assert_ne!(ta[1..], td[1..]);
}

/// 5 iterations on minibatches of 50.
fn short_training() -> TrainConfig {
    TrainConfig {
        iterations: 5,
        batch_size: 50,
        ..TrainConfig::default()
    }
}

/// Trains `model` for 5 iterations; it must survive postcard bit-identically (predictions
/// included), and with one entry fewer in `q(v)`'s mean of `f` be refused.
#[track_caller]
fn check_round_trip<M>(model: &mut M, (x, y): (&[Point], &[f64]), shorten: impl Fn(&mut M))
where
    M: SvgpModel + Clone + PartialEq + std::fmt::Debug + Predict,
    M: serde::Serialize + serde::de::DeserializeOwned,
{
    let config = short_training();
    train(model, x, y, &config, SEQ).unwrap();
    let bytes = postcard::to_allocvec(&*model).unwrap();
    let back: M = postcard::from_bytes(&bytes).unwrap();
    assert_eq!(&back, &*model);
    assert_eq!(back.prediction(&x[..5]), model.prediction(&x[..5]));
    let mut bad = model.clone();
    shorten(&mut bad);
    let bytes = postcard::to_allocvec(&bad).unwrap();
    assert!(postcard::from_bytes::<M>(&bytes).is_err());
}

/// The predictions of both SVGPs, for [`check_round_trip`].
trait Predict {
    fn prediction(&self, x: &[Point]) -> Prediction;
}

impl Predict for HeteroSvgp {
    fn prediction(&self, x: &[Point]) -> Prediction {
        self.predict(x, SEQ).unwrap()
    }
}

impl Predict for PoissonSvgp {
    fn prediction(&self, x: &[Point]) -> Prediction {
        self.predict(x, SEQ).unwrap()
    }
}

#[test]
fn elbo_gradient_matches_finite_differences() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(21);
    let (x, y) = synthetic(3, 15);
    let z = random_points(&mut rng, 6);
    let mut model = small_model(z);
    model.f.q = random_q(&mut rng, 6);
    model.g.q = random_q(&mut rng, 6);
    let scale = 2.5;
    let elbo = |m: &HeteroSvgp| m.elbo(&batch(&x, &y, scale), SEQ).unwrap();
    let grad = model.elbo_grad(&batch(&x, &y, scale), SEQ).unwrap();
    assert!(rel(grad.elbo, elbo(&model), 0.0) < 1e-14);
    check_elbo_gradient(&model, &grad.flatten(true), elbo);
}

#[test]
fn natural_gradient_step_of_one_is_the_titsias_optimum() {
    // Homoscedastic Gaussian likelihood y ~ N(f, σ²): the optimal q(u) (Titsias 2009) is
    // S_u = Kzz Σ⁻¹ Kzz, μ_u = σ⁻² Kzz Σ⁻¹ Kzx y with Σ = Kzz + σ⁻² Kzx Kxz; whitened,
    // S_v = Lᵀ Σ⁻¹ L and μ_v = σ⁻² Lᵀ Σ⁻¹ Kzx y.
    let mut rng = Xoshiro256StarStar::seed_from_u64(5);
    let (x, y) = synthetic(9, 40);
    let z = random_points(&mut rng, 8);
    let sigma2 = 0.09;
    let mut gp = LatentGp::new(rbf_kernel(), z.clone());
    gp.q = random_q(&mut rng, 8);
    let marg = gp.marginals(&x, 1e-6, SEQ).unwrap();
    let dm: Vec<f64> = (0..40).map(|i| (y[i] - marg.mean[i]) / sigma2).collect();
    let dv = vec![-0.5 / sigma2; 40];
    let q = gp.natgrad_update(&marg, &dm, &dv, 1.0).unwrap();

    let kzz = gram(&gp.kernel, &z, 1e-6, SEQ);
    let l = chol(kzz.as_ref()).unwrap();
    let kzx = cross(&gp.kernel, &z, &x, SEQ);
    let kk = mm(kzx.as_ref(), kzx.as_ref().transpose());
    let sig = Mat::from_fn(8, 8, |i, j| kzz[(i, j)] + kk[(i, j)] / sigma2);
    let ls = chol(sig.as_ref()).unwrap();
    let ycol = Mat::from_fn(40, 1, |i, _| y[i] / sigma2);
    let mut rhs = mm(kzx.as_ref(), ycol.as_ref());
    solve_l(&ls, &mut rhs);
    solve_lt(&ls, &mut rhs);
    let mu_v = mm(l.as_ref().transpose(), rhs.as_ref());
    let mut sl = l.clone();
    solve_l(&ls, &mut sl);
    solve_lt(&ls, &mut sl);
    let s_v = mm(l.as_ref().transpose(), sl.as_ref());
    let s_got = q.covariance();
    let mut worst: f64 = 0.0;
    for i in 0..8 {
        worst = worst.max((q.mean[i] - mu_v[(i, 0)]).abs());
        for j in 0..8 {
            worst = worst.max((s_got[(i, j)] - s_v[(i, j)]).abs());
        }
    }
    assert!(worst < 1e-8, "max deviation {worst}");
    // The optimum is a fixed point: a second step of any size changes nothing.
    gp.q = q.clone();
    let marg = gp.marginals(&x, 1e-6, SEQ).unwrap();
    let dm: Vec<f64> = (0..40).map(|i| (y[i] - marg.mean[i]) / sigma2).collect();
    let q2 = gp.natgrad_update(&marg, &dm, &dv, 0.3).unwrap();
    for i in 0..8 {
        assert!((q2.mean[i] - q.mean[i]).abs() < 1e-8);
    }
}

#[test]
fn training_increases_the_elbo_and_learns_the_noise() {
    let (x, y) = synthetic(1, 600);
    let mut model = small_model(inducing(&x, 20));
    let config = TrainConfig {
        natgrad_step: 0.2,
        learning_rate: 0.02,
        train_inducing: true,
        ..long_training(4)
    };
    check_training(&mut model, (&x, &y), &config, 100.0, |m| {
        m.elbo(&batch(&x, &y, 1.0), SEQ).unwrap()
    });
    // Heteroscedasticity: predicted std is larger where the noise is (x1 > 0.5).
    let quiet: Vec<Point> = (0..20).map(|i| [0.2, 0.5, i as f64 * 3.0]).collect();
    let loud: Vec<Point> = (0..20).map(|i| [0.8, 0.5, i as f64 * 3.0]).collect();
    let pq = model.predict(&quiet, SEQ).unwrap();
    let pl = model.predict(&loud, SEQ).unwrap();
    let mq = pq.std.iter().sum::<f64>() / 20.0;
    let ml = pl.std.iter().sum::<f64>() / 20.0;
    assert!(ml > 2.0 * mq, "std quiet {mq}, loud {ml}");
    // And the mean follows the rhythm.
    let err: f64 = quiet
        .iter()
        .zip(&pq.mean)
        .map(|(p, m)| {
            let f = 1.0 + 0.7 * (2.0 * std::f64::consts::PI * p[2] / 24.0).sin();
            (m - f).powi(2)
        })
        .sum::<f64>()
        / 20.0;
    assert!(err.sqrt() < 0.2, "rmse {}", err.sqrt());
}

#[test]
fn identical_seeds_give_identical_models_whatever_the_parallelism() {
    let (x, y) = synthetic(2, 200);
    check_determinism(|| small_model(inducing(&x, 10)), &x, &y);
    let (x, y) = poisson_toy(2, 200);
    check_determinism(|| poisson_model(inducing(&x, 10)), &x, &y);
}

#[test]
fn adam_minimises_a_quadratic() {
    let mut adam = Adam::new(0.1);
    let mut p = vec![3.0, -2.0];
    for _ in 0..500 {
        let g = vec![-2.0 * (p[0] - 1.0), -2.0 * (p[1] + 0.5)];
        adam.ascend(&mut p, &g);
    }
    assert!(
        (p[0] - 1.0).abs() < 1e-3 && (p[1] + 0.5).abs() < 1e-3,
        "{p:?}"
    );
}

#[test]
fn invalid_inputs_are_rejected() {
    let model = small_model(vec![[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]);
    assert!(matches!(
        model.elbo(&batch(&[[0.0; 3]], &[1.0, 2.0], 1.0), SEQ),
        Err(GpError::InvalidInput(_))
    ));
    assert!(matches!(
        model.elbo(&batch(&[[0.0, f64::NAN, 0.0]], &[1.0], 1.0), SEQ),
        Err(GpError::InvalidInput(_))
    ));
    // Duplicate inducing inputs with no jitter: K(Z, Z) is singular.
    let mut m = small_model(vec![[0.5; 3], [0.5; 3]]);
    m.jitter = 0.0;
    assert!(matches!(
        m.elbo(&batch(&[[0.0; 3]], &[1.0], 1.0), SEQ),
        Err(GpError::NotPositiveDefinite { .. })
    ));
}

#[test]
fn models_round_trip_through_serde_and_bad_ones_are_rejected() {
    let (x, y) = synthetic(5, 100);
    let mut model = small_model(inducing(&x, 10));
    // A q(v) whose mean does not match the inducing inputs is refused.
    check_round_trip(&mut model, (&x, &y), |bad| {
        bad.f.q.mean.pop();
    });
    let (x, y) = poisson_toy(5, 100);
    let mut model = poisson_model(inducing(&x, 10));
    check_round_trip(&mut model, (&x, &y), |bad| {
        bad.f.q.mean.pop();
    });
}

#[test]
fn train_step_reuses_kernel_matrices_without_changing_results() {
    let (x, y) = synthetic(6, 80);
    let mut a = small_model(inducing(&x, 8));
    let mut rng = Xoshiro256StarStar::seed_from_u64(3);
    a.f.q = random_q(&mut rng, 10);
    let mut b = a.clone();
    let (elbo_a, grad_a) = a.train_step(&batch(&x, &y, 2.0), 0.3, SEQ).unwrap();
    let elbo_b = b.natgrad_step(&batch(&x, &y, 2.0), 0.3, SEQ).unwrap();
    let grad_b = b.elbo_grad(&batch(&x, &y, 2.0), SEQ).unwrap();
    assert_eq!(elbo_a, elbo_b);
    assert_eq!(a, b);
    assert_eq!(grad_a, grad_b);
    assert!(grad_a.elbo > elbo_a, "{} -> {}", elbo_a, grad_a.elbo);
}

// ------------------------------------------------------------------ Poisson SVGP (GP-Hom)

/// The log rate of the Poisson toy: a daily rhythm that grows with `x1`.
fn toy_log_rate(p: &Point) -> f64 {
    1.0 + (0.3 + 0.8 * p[0]) * (2.0 * std::f64::consts::PI * p[2] / 24.0).sin()
}

/// Poisson counts at random inputs (Knuth's sampler; rates stay below 10).
fn poisson_toy(seed: u64, n: usize) -> (Vec<Point>, Vec<f64>) {
    sample(seed, n, |rng, p| {
        let limit = (-toy_log_rate(p).exp()).exp();
        let (mut k, mut prod) = (0.0, rng.next_f64());
        while prod > limit {
            k += 1.0;
            prod *= rng.next_f64();
        }
        k
    })
}

fn poisson_model(z: Vec<Point>) -> PoissonSvgp {
    PoissonSvgp::new(daily_kernel(0.5), z, 0.8)
}

#[test]
fn expected_poisson_log_lik_matches_quadrature_and_finite_differences() {
    let (xs, ws) = gauss_hermite(60);
    let sp = std::f64::consts::PI.sqrt();
    for &(y, m, v) in &[
        (0.0f64, 0.3f64, 0.2f64),
        (3.0, 1.1, 0.5),
        (1e-6, -2.0, 1.5),
        (42.5, 3.7, 0.01),
    ] {
        // y f − eᶠ − ln Γ(y + 1) by Gauss–Hermite over f ~ N(m, v); ln Γ(4) = ln 6 by hand.
        let lg = statrs::function::gamma::ln_gamma(y + 1.0);
        if y == 3.0 {
            assert!((lg - 6f64.ln()).abs() < 1e-13);
        }
        let brute: f64 = xs
            .iter()
            .zip(&ws)
            .map(|(x, w)| {
                let f = m + (2.0 * v).sqrt() * x;
                w / sp * (y * f - f.exp() - lg)
            })
            .sum();
        let e = expected_poisson_log_lik(y, m, v);
        assert!(rel(e.value, brute, 1.0) < 1e-10, "{} vs {brute}", e.value);
        let dm = fd(
            |q| expected_poisson_log_lik(y, q[0], v).value,
            &[m],
            0,
            1e-6,
        );
        let dv = fd(
            |q| expected_poisson_log_lik(y, m, q[0]).value,
            &[v],
            0,
            1e-6,
        );
        assert!(rel(e.d_m, dm, 1e-3) < 1e-8, "{} vs {dm}", e.d_m);
        assert!(rel(e.d_v, dv, 1e-3) < 1e-8, "{} vs {dv}", e.d_v);
    }
}

#[test]
fn poisson_elbo_gradient_matches_finite_differences() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(31);
    let (x, y) = poisson_toy(3, 15);
    let mut model = poisson_model(random_points(&mut rng, 6));
    model.f.q = random_q(&mut rng, 6);
    let scale = 2.5;
    let elbo = |m: &PoissonSvgp| m.elbo(&batch(&x, &y, scale), SEQ).unwrap();
    let grad = model.elbo_grad(&batch(&x, &y, scale), SEQ).unwrap();
    assert!(rel(grad.elbo, elbo(&model), 0.0) < 1e-14);
    // 6 kernel log-parameters, the mean c, 6 × 3 inducing coordinates.
    assert_eq!(check_elbo_gradient(&model, &grad.flatten(true), elbo), 25);
}

#[test]
fn poisson_training_increases_the_elbo_and_recovers_the_rate() {
    let (x, y) = poisson_toy(1, 600);
    let mut model = poisson_model(inducing(&x, 20));
    // Measured: −1792 → −1136.
    check_training(&mut model, (&x, &y), &long_training(4), 500.0, |m| {
        m.elbo(&batch(&x, &y, 1.0), SEQ).unwrap()
    });
    // The predicted mean rate follows the true rate along a day at x1 = 0.8.
    let day: Vec<Point> = (0..24).map(|h| [0.8, 0.5, 24.0 + h as f64]).collect();
    let pred = model.predict(&day, SEQ).unwrap();
    let mut sq = 0.0;
    for (p, (m, s)) in day.iter().zip(pred.mean.iter().zip(&pred.std)) {
        assert!(*m > 0.0 && *s > 0.0);
        sq += (m - toy_log_rate(p).exp()).powi(2);
    }
    // Measured 0.127 (the training mean, 2.7, misses by 2.10).
    let rmse = (sq / 24.0).sqrt();
    assert!(rmse < 0.25, "rmse {rmse}");
}

#[test]
fn poisson_training_refuses_negative_rates_before_changing_anything() {
    let (x, y) = poisson_toy(5, 100);
    let mut model = poisson_model(inducing(&x, 10));
    let config = short_training();
    train(&mut model, &x, &y, &config, SEQ).unwrap();
    // A negative rate anywhere is refused before anything changes.
    let mut neg = y.clone();
    neg[77] = -1.0;
    let before = model.clone();
    let err = train(&mut model, &x, &neg, &config, SEQ).unwrap_err();
    assert_eq!(
        err,
        GpError::InvalidInput("rate -1 at row 77 is negative (a Poisson rate is >= 0)".into())
    );
    assert_eq!(model, before);
    assert!(model.predict(&[[0.0, f64::NAN, 0.0]], SEQ).is_err());
}
