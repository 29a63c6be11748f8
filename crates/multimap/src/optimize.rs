//! Pose-graph optimisation of the map poses after a loop closure ([Stüde 2024] §3.3.3, "Loop
//! Search and Graph Optimization", with the cost of eqs. (3.3)–(3.5)).
//!
//! The unknowns are the poses `xᵢ = ⁽⁰⁾pᵢ` of the maps in the frame of map 0 (held at the
//! identity). Every link point between maps `i` and `j` measures their relative pose
//! `zᵢⱼ = ⁽ⁱ⁾pⱼ` (eq. (3.10)) with covariance `Σᵢⱼ` (eq. (3.13)); the error
//! `eᵢⱼ = zᵢⱼ − ẑᵢⱼ(xᵢ, xⱼ)`, `ẑᵢⱼ = xᵢ⁻¹ ⊕ xⱼ`, heading wrapped (eq. (3.3)), and the cost
//! `F = Σ eᵢⱼᵀ Ωᵢⱼ eᵢⱼ` with `Ωᵢⱼ = Σᵢⱼ⁻¹` (eq. (3.4)) is minimised (eq. (3.5)) by
//! Levenberg–Marquardt on the dense normal equations (the Cholesky factorisation of
//! [`chronomap_geometry::linalg`]: map graphs are small). The text inverts "the covariance matrices `⁽⁰⁾Σᵢ`"; the relative
//! covariances are used here, which is what makes the measurements independent.
//!
//! ```
//! use chronomap_multimap::config::MapConfig;
//! use chronomap_multimap::graph::MapGraph;
//! use chronomap_multimap::optimize::{optimize, OptimizeParams};
//! use chronomap_multimap::se2::{Pose2, UncertainPose};
//!
//! // Two maps linked twice, by measurements 1.0 m and 1.2 m apart along x with equal
//! // covariance: the optimum is their mean.
//! let mut g = MapGraph::new();
//! let a = g.add_map(MapConfig::ShortRange, None)?;
//! let b = g.add_map(MapConfig::ShortRange, None)?;
//! let cov = [[0.01, 0.0, 0.0], [0.0, 0.01, 0.0], [0.0, 0.0, 0.01]];
//! let origin = UncertainPose::exact(Pose2::IDENTITY);
//! g.add_link(a, UncertainPose::new(Pose2::new(1.0, 0.0, 0.0)?, cov)?, b, origin)?;
//! g.add_link(a, UncertainPose::new(Pose2::new(1.2, 0.0, 0.0)?, cov)?, b, origin)?;
//! let result = optimize(&g, &OptimizeParams::default())?;
//! assert!((result.poses[1].x - 1.1).abs() < 1e-9);
//! // Two independent measurements halve the variance.
//! assert!((result.covariances[1][0][0] - 0.005).abs() < 1e-9);
//! # Ok::<(), chronomap_multimap::MultimapError>(())
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Leibniz Universität Hannover, 2024.

use serde::{Deserialize, Serialize};

use crate::MultimapError;
use crate::graph::{MapGraph, PathWeight};
use crate::se2::{Mat3, Pose2, ZERO3, inverse3, wrap_angle};
use chronomap_geometry::linalg::{self, Pivot, cholesky_solve};

/// The most maps [`optimize`] accepts (its dense normal equations are `3n × 3n`).
pub const MAX_OPT_MAPS: usize = 400;

/// The stopping rules of the optimiser.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptimizeParams {
    /// Most iterations; reaching them unconverged is an error. Default 100.
    pub max_iterations: usize,
    /// Stop when no update component exceeds this (m, rad). Default 1e-10.
    pub tolerance: f64,
    /// Initial Levenberg–Marquardt damping, relative to the diagonal. Default 1e-6.
    pub initial_damping: f64,
}

impl Default for OptimizeParams {
    fn default() -> Self {
        OptimizeParams {
            max_iterations: 100,
            tolerance: 1e-10,
            initial_damping: 1e-6,
        }
    }
}

/// The optimised map poses.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct OptimizedMaps {
    /// The pose of each map in the frame of map 0 (map 0 at the identity).
    pub poses: Vec<Pose2>,
    /// The marginal covariance of each pose (the 3×3 blocks of the inverse of the normal
    /// matrix at the optimum; zero for map 0).
    pub covariances: Vec<Mat3>,
    /// The cost `F` of eq. (3.4) at the initial guess (the compositions along the paths of
    /// fewest link points).
    pub initial_cost: f64,
    /// The cost at the optimum.
    pub final_cost: f64,
    /// Iterations made.
    pub iterations: usize,
}

struct Edge {
    i: usize,
    j: usize,
    z: Pose2,
    omega: Mat3,
}

/// `e = z − ẑ(xᵢ, xⱼ)` and its Jacobians `∂e/∂xᵢ`, `∂e/∂xⱼ`.
fn error_and_jacobians(xi: &Pose2, xj: &Pose2, z: &Pose2) -> ([f64; 3], Mat3, Mat3) {
    let (s, c) = xi.theta.sin_cos();
    let (dx, dy) = (xj.x - xi.x, xj.y - xi.y);
    let zhat = [
        c * dx + s * dy,
        -s * dx + c * dy,
        wrap_angle(xj.theta - xi.theta),
    ];
    let e = [z.x - zhat[0], z.y - zhat[1], wrap_angle(z.theta - zhat[2])];
    // ∂ẑ/∂xᵢ and ∂ẑ/∂xⱼ; e = z − ẑ flips their signs.
    let a = [
        [c, s, s * dx - c * dy],
        [-s, c, c * dx + s * dy],
        [0.0, 0.0, 1.0],
    ];
    let b = [[-c, -s, 0.0], [s, -c, 0.0], [0.0, 0.0, -1.0]];
    (e, a, b)
}

fn cost(edges: &[Edge], x: &[Pose2]) -> f64 {
    edges
        .iter()
        .map(|ed| {
            let (e, _, _) = error_and_jacobians(&x[ed.i], &x[ed.j], &ed.z);
            (0..3)
                .map(|r| (0..3).map(|k| e[r] * ed.omega[r][k] * e[k]).sum::<f64>())
                .sum::<f64>()
        })
        .sum()
}

/// The normal equations `H Δ = −b` over maps `1..n` (map 0 fixed): `H` dense, row-major.
fn normal_equations(edges: &[Edge], x: &[Pose2]) -> (Vec<f64>, Vec<f64>) {
    let dim = 3 * (x.len() - 1);
    let mut h = vec![0.0; dim * dim];
    let mut g = vec![0.0; dim];
    for ed in edges {
        let (e, ji, jj) = error_and_jacobians(&x[ed.i], &x[ed.j], &ed.z);
        let blocks = [(ed.i, ji), (ed.j, jj)];
        for &(u, ju) in &blocks {
            if u == 0 {
                continue;
            }
            // Jᵤᵀ Ω
            let mut jt_omega = ZERO3;
            for r in 0..3 {
                for k in 0..3 {
                    jt_omega[r][k] = (0..3).map(|m| ju[m][r] * ed.omega[m][k]).sum();
                }
            }
            for r in 0..3 {
                g[3 * (u - 1) + r] += (0..3).map(|k| jt_omega[r][k] * e[k]).sum::<f64>();
            }
            for &(v, jv) in &blocks {
                if v == 0 {
                    continue;
                }
                for r in 0..3 {
                    for k in 0..3 {
                        let val: f64 = (0..3).map(|m| jt_omega[r][m] * jv[m][k]).sum();
                        h[(3 * (u - 1) + r) * dim + 3 * (v - 1) + k] += val;
                    }
                }
            }
        }
    }
    (h, g)
}

/// The Cholesky factorisation of the normal equations: each pivot against its own diagonal
/// entry (`1e-13` relative), the blocks of different maps having unrelated scales.
fn cholesky(a: &mut [f64], n: usize) -> Result<(), usize> {
    linalg::cholesky(a, n, Pivot::Diagonal(1e-13))
}

/// Optimises the poses of all maps of `graph` in the frame of map 0 given every link point's
/// relative-pose measurement (see the module documentation). Every map must be connected to
/// map 0; every link's relative covariance must be invertible.
///
/// # Errors
/// Bad parameters; [`MultimapError::TooLarge`] above [`MAX_OPT_MAPS`] maps; a singular
/// covariance or graph; [`MultimapError::NotConverged`] if `max_iterations` pass without the
/// stopping rule being met (no partial result is returned as if it were the optimum).
pub fn optimize(graph: &MapGraph, params: &OptimizeParams) -> Result<OptimizedMaps, MultimapError> {
    if !(params.tolerance.is_finite() && params.tolerance > 0.0) {
        return Err(MultimapError::Parameter {
            field: "tolerance",
            value: params.tolerance,
            why: "must be finite and positive",
        });
    }
    if !(params.initial_damping.is_finite() && params.initial_damping >= 0.0) {
        return Err(MultimapError::Parameter {
            field: "initial_damping",
            value: params.initial_damping,
            why: "must be finite and non-negative",
        });
    }
    let n = graph.maps().len();
    if n == 0 {
        return Err(MultimapError::UnknownMap(0));
    }
    if n > MAX_OPT_MAPS {
        return Err(MultimapError::TooLarge {
            what: "maps to optimise",
            n,
            max: MAX_OPT_MAPS,
        });
    }
    let mut edges = Vec::with_capacity(graph.links().len());
    for (k, l) in graph.links().iter().enumerate() {
        let z = graph.relative_pose(k, l.maps[0])?;
        let omega = inverse3(&z.cov).ok_or(MultimapError::SingularCovariance { link: k })?;
        edges.push(Edge {
            i: l.maps[0],
            j: l.maps[1],
            z: z.mean,
            omega,
        });
    }
    let mut x = Vec::with_capacity(n);
    for m in 0..n {
        match graph.map_path(0, m, PathWeight::Hops) {
            Ok(path) => x.push(graph.compose_path(&path)?.mean),
            Err(MultimapError::NoPath { .. }) => {
                return Err(MultimapError::SingularGraph { map: m });
            }
            Err(e) => return Err(e),
        }
    }
    let dim = 3 * (n - 1);
    let initial_cost = cost(&edges, &x);
    let mut current = initial_cost;
    let mut lambda = params.initial_damping;
    let mut iterations = 0;
    // With map 0 alone there is nothing to optimise.
    let mut converged = dim == 0;
    if dim > 0 {
        'outer: while iterations < params.max_iterations {
            iterations += 1;
            let (h, g) = normal_equations(&edges, &x);
            loop {
                let mut a = h.clone();
                for i in 0..dim {
                    a[i * dim + i] += lambda * h[i * dim + i].max(1e-12);
                }
                cholesky(&mut a, dim)
                    .map_err(|j| MultimapError::SingularGraph { map: j / 3 + 1 })?;
                let mut step: Vec<f64> = g.iter().map(|v| -v).collect();
                cholesky_solve(&a, dim, &mut step);
                let candidate: Vec<Pose2> = x
                    .iter()
                    .enumerate()
                    .map(|(m, p)| {
                        if m == 0 {
                            return *p;
                        }
                        let d = &step[3 * (m - 1)..3 * m];
                        Pose2 {
                            x: p.x + d[0],
                            y: p.y + d[1],
                            theta: wrap_angle(p.theta + d[2]),
                        }
                    })
                    .collect();
                let new_cost = cost(&edges, &candidate);
                let biggest = step.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
                if new_cost <= current {
                    x = candidate;
                    current = new_cost;
                    lambda = (lambda * 0.1).max(1e-12);
                    if biggest < params.tolerance {
                        converged = true;
                        break 'outer;
                    }
                    break;
                }
                // No step lowers the cost, not even a tiny one: a minimum to round-off.
                if biggest < params.tolerance || lambda > 1e12 {
                    converged = true;
                    break 'outer;
                }
                lambda = (lambda * 10.0).max(1e-9);
            }
        }
    }
    if !converged {
        return Err(MultimapError::NotConverged {
            iterations,
            cost: current,
        });
    }
    // Marginal covariances from the undamped normal matrix at the optimum.
    let mut covariances = vec![ZERO3; n];
    if dim > 0 {
        let (mut h, _) = normal_equations(&edges, &x);
        cholesky(&mut h, dim).map_err(|j| MultimapError::SingularGraph { map: j / 3 + 1 })?;
        for m in 1..n {
            for c in 0..3 {
                let mut col = vec![0.0; dim];
                col[3 * (m - 1) + c] = 1.0;
                cholesky_solve(&h, dim, &mut col);
                for r in 0..3 {
                    covariances[m][r][c] = col[3 * (m - 1) + r];
                }
            }
        }
    }
    Ok(OptimizedMaps {
        poses: x,
        covariances,
        initial_cost,
        final_cost: current,
        iterations,
    })
}
