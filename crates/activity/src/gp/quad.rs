//! Gauss–Hermite quadrature and the expected log-likelihood of the heteroscedastic Gaussian
//! likelihood `y ~ N(f, ζ(g)²)`, `ζ` = softplus ([Stüde 2024] eq. 4.7 and the first term of the
//! bound eq. 4.12).
//!
//! The dissertation writes the noise *variance* as `ζ(g)`; the original implementation (GPflow,
//! `tfp.distributions.Normal(f, softplus(g))`) uses `ζ(g)` as the *standard deviation*, and
//! so does this module.

/// Nodes `x_k` and weights `w_k` of the `n`-point Gauss–Hermite rule
/// `∫ e^{−x²} h(x) dx ≈ Σ_k w_k h(x_k)` (exact for polynomials of degree `< 2n`), nodes in
/// decreasing order. Computed by Newton's method on the normalised Hermite recurrence.
pub fn gauss_hermite(n: usize) -> (Vec<f64>, Vec<f64>) {
    assert!(n >= 1, "gauss_hermite needs at least one node");
    let pim4 = std::f64::consts::PI.powf(-0.25);
    let mut x = vec![0.0; n];
    let mut w = vec![0.0; n];
    let nf = n as f64;
    let mut z = 0.0f64;
    for i in 0..n.div_ceil(2) {
        z = match i {
            0 => (2.0 * nf + 1.0).sqrt() - 1.85575 * (2.0 * nf + 1.0).powf(-1.0 / 6.0),
            1 => z - 1.14 * nf.powf(0.426) / z,
            2 => 1.86 * z - 0.86 * x[0],
            3 => 1.91 * z - 0.91 * x[1],
            _ => 2.0 * z - x[i - 2],
        };
        let mut pp = 0.0;
        for _ in 0..100 {
            let (mut p1, mut p2) = (pim4, 0.0);
            for j in 1..=n {
                let jf = j as f64;
                let p3 = p2;
                p2 = p1;
                p1 = z * (2.0 / jf).sqrt() * p2 - ((jf - 1.0) / jf).sqrt() * p3;
            }
            pp = (2.0 * nf).sqrt() * p2;
            let z1 = z;
            z = z1 - p1 / pp;
            if (z - z1).abs() <= 1e-15 * z.abs().max(1.0) {
                break;
            }
        }
        x[i] = z;
        x[n - 1 - i] = -z;
        w[i] = 2.0 / (pp * pp);
        w[n - 1 - i] = w[i];
    }
    (x, w)
}

/// `ζ(g) = ln(1 + eᵍ)`, computed without overflow.
pub fn softplus(g: f64) -> f64 {
    g.max(0.0) + (-g.abs()).exp().ln_1p()
}

/// The logistic function `σ(g) = ζ'(g)`.
fn logistic(g: f64) -> f64 {
    if g >= 0.0 {
        1.0 / (1.0 + (-g).exp())
    } else {
        let e = g.exp();
        e / (1.0 + e)
    }
}

/// The expected log-likelihood `E_{q(f)q(g)}[ln N(y | f, ζ(g)²)]` for Gaussian marginals
/// `f ~ N(m_f, v_f)`, `g ~ N(m_g, v_g)` and its gradient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExpectedLogLik {
    /// The value.
    pub value: f64,
    /// `∂/∂m_f`.
    pub d_mf: f64,
    /// `∂/∂v_f`.
    pub d_vf: f64,
    /// `∂/∂m_g`.
    pub d_mg: f64,
    /// `∂/∂v_g`.
    pub d_vg: f64,
}

/// The heteroscedastic Gaussian likelihood `y ~ N(f, ζ(g)²)` with a Gauss–Hermite rule for
/// the expectation over `g`.
#[derive(Clone, Debug, PartialEq)]
pub struct HeteroGaussian {
    nodes: Vec<f64>,
    /// Weights divided by `√π` (they sum to one).
    weights: Vec<f64>,
}

impl Default for HeteroGaussian {
    fn default() -> Self {
        Self::new(20)
    }
}

impl HeteroGaussian {
    /// The likelihood with an `n`-point Gauss–Hermite rule over `g`.
    pub fn new(n: usize) -> Self {
        let (nodes, w) = gauss_hermite(n);
        let s = std::f64::consts::PI.sqrt();
        HeteroGaussian {
            nodes,
            weights: w.into_iter().map(|w| w / s).collect(),
        }
    }

    /// Number of quadrature nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// `E_{q(f)q(g)}[ln N(y | f, ζ(g)²)]` and its gradient ([Stüde 2024] eq. 4.12, one term of the
    /// sum). The `f`-expectation is closed form,
    /// `E_f[ln N(y|f, s²)] = −½ ln(2π s²) − ((y − m_f)² + v_f)/(2 s²)`; the `g`-expectations
    /// `E[ln ζ(g)]` and `E[ζ(g)⁻²]` use the Gauss–Hermite rule with `g_k = m_g + √(2 v_g) x_k`.
    /// `∂/∂v_g` is the exact derivative of the quadrature value.
    pub fn expected_log_lik(&self, y: f64, mf: f64, vf: f64, mg: f64, vg: f64) -> ExpectedLogLik {
        let sd = (2.0 * vg.max(0.0)).sqrt();
        let (mut e1, mut e2, mut e1m, mut e2m, mut e1v, mut e2v) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for (&x, &w) in self.nodes.iter().zip(&self.weights) {
            let g = mg + sd * x;
            let s = softplus(g);
            let sig = logistic(g);
            let inv2 = 1.0 / (s * s);
            // h1 = ln s, h2 = s⁻²; first and second derivatives in g.
            let h1p = sig / s;
            let h2p = -2.0 * sig * inv2 / s;
            e1 += w * s.ln();
            e2 += w * inv2;
            e1m += w * h1p;
            e2m += w * h2p;
            if sd > 1e-7 {
                e1v += w * h1p * x;
                e2v += w * h2p * x;
            } else {
                // Price's theorem (limit v_g → 0): ∂E[h]/∂v = ½ E[h''].
                let sp = sig * (1.0 - sig);
                let h1pp = (sp * s - sig * sig) * inv2;
                let h2pp = -2.0 * sp * inv2 / s + 6.0 * sig * sig * inv2 * inv2;
                e1v += w * 0.5 * h1pp;
                e2v += w * 0.5 * h2pp;
            }
        }
        if sd > 1e-7 {
            // ∂g_k/∂v_g = x_k / √(2 v_g)
            e1v /= sd;
            e2v /= sd;
        }
        let r = (y - mf) * (y - mf) + vf;
        let value = -0.5 * (2.0 * std::f64::consts::PI).ln() - e1 - 0.5 * r * e2;
        ExpectedLogLik {
            value,
            d_mf: (y - mf) * e2,
            d_vf: -0.5 * e2,
            d_mg: -e1m - 0.5 * r * e2m,
            d_vg: -e1v - 0.5 * r * e2v,
        }
    }

    /// The half-width `h` of the central interval `m_f ± h` that holds a new observation
    /// `y = f + ζ(g) ε` with probability `coverage`, under the predictive law of
    /// [Stüde 2024] eq. 4.7 with the marginals `f ~ N(m_f, v_f)`, `g ~ N(m_g, v_g)` of
    /// eqs. 4.13–4.16 and `ε ~ N(0, 1)`.
    ///
    /// Given `g`, `y ~ N(m_f, v_f + ζ(g)²)`; over `q(g)` the law of `y` is a scale mixture of
    /// normals, symmetric about `m_f` but heavier-tailed than the normal of the same variance
    /// (eq. 4.19 gives only its moments, `m_f` and `v_f + E[ζ(g)²]`). Its CDF, with the
    /// Gauss–Hermite rule over `g` (`g_k = m_g + √(2 v_g) x_k`, the rule of the ELBO),
    ///
    /// ```text
    /// P(|y − m_f| ≤ h) = 2 Σ_k w_k Φ(h / s_k) − 1,   s_k = √(v_f + ζ(g_k)²),
    /// ```
    ///
    /// (accurate to about 1e-5 in probability even where the noise dominates and `v_g = 1`;
    /// to 1e-7 and better in milder cases) is solved for `P = coverage` by Newton's method kept inside the bracket
    /// `[z s_min, z s_max]` (`z` the standard normal quantile of `(1 + coverage) / 2`: every
    /// component's own half-width bounds the mixture's). `NaN` unless `coverage` is in
    /// `(0, 1)` and the marginals are finite.
    pub fn central_half_width(&self, vf: f64, mg: f64, vg: f64, coverage: f64) -> f64 {
        use statrs::distribution::{Continuous, ContinuousCDF, Normal};
        if !(coverage > 0.0 && coverage < 1.0 && vf.is_finite() && mg.is_finite()) {
            return f64::NAN;
        }
        let normal = Normal::standard();
        let target = 0.5 + coverage / 2.0;
        let z = normal.inverse_cdf(target);
        let sd = (2.0 * vg.max(0.0)).sqrt();
        let scales: Vec<(f64, f64)> = self
            .nodes
            .iter()
            .zip(&self.weights)
            .map(|(&x, &w)| (w, (vf.max(0.0) + softplus(mg + sd * x).powi(2)).sqrt()))
            .collect();
        let s_min = scales.iter().map(|s| s.1).fold(f64::INFINITY, f64::min);
        let s_max = scales.iter().map(|s| s.1).fold(0.0, f64::max);
        let (mut lo, mut hi) = (z * s_min, z * s_max);
        // Start from the normal of the mixture's variance.
        let mut h = z * scales.iter().map(|(w, s)| w * s * s).sum::<f64>().sqrt();
        for _ in 0..100 {
            if !(h > lo && h < hi) {
                h = 0.5 * (lo + hi);
            }
            let (mut cdf, mut pdf) = (0.0, 0.0);
            for &(w, s) in &scales {
                cdf += w * normal.cdf(h / s);
                pdf += w * normal.pdf(h / s) / s;
            }
            let excess = cdf - target;
            if excess > 0.0 {
                hi = h;
            } else {
                lo = h;
            }
            let step = excess / pdf;
            h -= step;
            if step.abs() <= 1e-13 * h.abs() || hi - lo <= 1e-13 * hi {
                break;
            }
        }
        h.clamp(lo, hi)
    }

    /// `E_{q(g)}[ζ(g)²]`, the expected noise variance (for predictions).
    pub fn expected_noise_variance(&self, mg: f64, vg: f64) -> f64 {
        let sd = (2.0 * vg.max(0.0)).sqrt();
        self.nodes
            .iter()
            .zip(&self.weights)
            .map(|(&x, &w)| w * softplus(mg + sd * x).powi(2))
            .sum()
    }
}
