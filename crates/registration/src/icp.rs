//! Fine registration by the iterative closest point algorithm — point-to-point [Besl & McKay
//! 1992] and point-to-plane [Chen & Medioni 1992] (point-to-line in 2-D) — and the information
//! matrix of the result ([Stüde 2024] §3.2.2).

use crate::RegistrationError;
use crate::kdtree::KdTree;
use crate::rigid::{Rigid, assert_dim, kabsch};
use chronomap_geometry::linalg::{dot, solve_spd, sub};

/// The error ICP minimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IcpMethod {
    /// `Σ ‖R pᵢ + t − qᵢ‖²`, solved in closed form by [`kabsch`] each iteration [Besl & McKay 1992].
    PointToPoint,
    /// `Σ ((R pᵢ + t − qᵢ) · nᵢ)²` with the target normals `nᵢ` (the tangent plane in 3-D, the
    /// tangent line in 2-D), linearised about the current estimate and solved by Gauss–Newton
    /// [Chen & Medioni 1992].
    PointToPlane,
    /// `Σ ((R pᵢ + t − qᵢ) · (R n_pᵢ + n_qᵢ))²`, the symmetric objective of Rusinkiewicz
    /// ("A symmetric objective function for ICP", SIGGRAPH 2019) with the same linearisation:
    /// both clouds' normals, which tolerates the ring structure of spinning lidars better.
    Symmetric,
}

/// ICP parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct IcpParams {
    /// Point-to-point or point-to-plane.
    pub method: IcpMethod,
    /// Pairs farther apart than this are not correspondences (m).
    pub max_correspondence_distance: f64,
    /// Most iterations.
    pub max_iterations: usize,
    /// Converged when an update translates less than this (m) …
    pub translation_tolerance: f64,
    /// … and rotates less than this (rad).
    pub rotation_tolerance: f64,
}

impl IcpParams {
    /// Point-to-plane with 60 iterations and tolerances of 1e-6 m and 1e-6 rad.
    pub fn point_to_plane(max_correspondence_distance: f64) -> IcpParams {
        IcpParams {
            method: IcpMethod::PointToPlane,
            max_correspondence_distance,
            max_iterations: 60,
            translation_tolerance: 1e-6,
            rotation_tolerance: 1e-6,
        }
    }
}

/// The outcome of [`icp`].
#[derive(Clone, Debug, PartialEq)]
pub struct IcpResult<const D: usize> {
    /// The transform mapping source points into the target frame.
    pub transform: Rigid<D>,
    /// Iterations run.
    pub iterations: usize,
    /// Whether the last update was within the tolerances.
    pub converged: bool,
    /// Correspondences used in the last iteration.
    pub correspondences: usize,
    /// Their fraction of the source points.
    pub fitness: f64,
    /// Root mean square of their point distances (m), before the last update.
    pub rmse: f64,
}

/// Iterative closest point from `initial`: each iteration pairs every transformed source point
/// with its nearest target point (k-d tree), drops pairs beyond the maximum correspondence
/// distance, and updates the transform by the chosen method, until an update is below both
/// tolerances or the iterations run out. Point-to-plane needs `target_normals` (zero normals
/// are skipped).
pub fn icp<const D: usize>(
    source: &[[f64; D]],
    source_normals: Option<&[[f64; D]]>,
    target: &[[f64; D]],
    target_tree: &KdTree<D>,
    target_normals: Option<&[[f64; D]]>,
    initial: Rigid<D>,
    params: &IcpParams,
) -> Result<IcpResult<D>, RegistrationError> {
    const { assert_dim::<D>() };
    crate::cloud::positive(
        "max_correspondence_distance",
        params.max_correspondence_distance,
    )?;
    for (field, value) in [
        ("translation_tolerance", params.translation_tolerance),
        ("rotation_tolerance", params.rotation_tolerance),
    ] {
        if !(value >= 0.0 && value.is_finite()) {
            return Err(RegistrationError::Parameter {
                field,
                value,
                why: "must be finite and ≥ 0",
            });
        }
    }
    if target_tree.len() != target.len() {
        return Err(RegistrationError::Degenerate(
            "icp: the k-d tree is not the target's",
        ));
    }
    let normals = match (params.method, target_normals) {
        (IcpMethod::PointToPoint, _) => None,
        (_, Some(n)) if n.len() == target.len() => Some(n),
        _ => {
            return Err(RegistrationError::Degenerate(
                "point-to-plane ICP needs one normal per target point",
            ));
        }
    };
    let source_normals = match (params.method, source_normals) {
        (IcpMethod::Symmetric, Some(n)) if n.len() == source.len() => Some(n),
        (IcpMethod::Symmetric, _) => {
            return Err(RegistrationError::Degenerate(
                "symmetric ICP needs one normal per source point",
            ));
        }
        _ => None,
    };
    let need = if D == 3 { 6 } else { 3 };
    let max2 = params.max_correspondence_distance.powi(2);
    let mut transform = initial;
    let mut result = IcpResult {
        transform,
        iterations: 0,
        converged: false,
        correspondences: 0,
        fitness: 0.0,
        rmse: 0.0,
    };
    for it in 1..=params.max_iterations {
        // (transformed source point, target index, squared distance, normal of the residual)
        let mut pairs: Vec<([f64; D], usize, f64, [f64; D])> = Vec::with_capacity(source.len());
        for (i, p) in source.iter().enumerate() {
            let tp = transform.apply(p);
            let Some((j, d2)) = target_tree.nearest(&tp) else {
                continue;
            };
            if d2 > max2 {
                continue;
            }
            let mut normal = [0.0; D];
            if let Some(n) = normals {
                if dot(&n[j], &n[j]) == 0.0 {
                    continue;
                }
                normal = n[j];
                if let Some(ns) = source_normals {
                    let np = transform.rotate(&ns[i]);
                    if dot(&np, &np) == 0.0 {
                        continue;
                    }
                    let sign = if dot(&np, &normal) < 0.0 { -1.0 } else { 1.0 };
                    normal = std::array::from_fn(|a| normal[a] + sign * np[a]);
                }
            }
            pairs.push((tp, j, d2, normal));
        }
        if pairs.len() < need {
            return Err(RegistrationError::TooFewPoints {
                what: "ICP correspondences",
                got: pairs.len(),
                need,
            });
        }
        result.correspondences = pairs.len();
        result.fitness = pairs.len() as f64 / source.len() as f64;
        result.rmse = (pairs.iter().map(|x| x.2).sum::<f64>() / pairs.len() as f64).sqrt();
        let update = match normals {
            None => {
                let (ps, qs): (Vec<[f64; D]>, Vec<[f64; D]>) =
                    pairs.iter().map(|&(p, j, _, _)| (p, target[j])).unzip();
                kabsch(&ps, &qs)?
            }
            Some(_) => {
                // r = (p − q)·n + ω·(p × n) + t·n (3-D); θ (p × n) + t·n with the scalar cross
                // product in 2-D. Normal equations JᵀJ x = −Jᵀr.
                let mut a = [[0.0; 6]; 6];
                let mut b = [0.0; 6];
                for &(p, j, _, nq) in &pairs {
                    let q = &target[j];
                    let nq = &nq;
                    let mut jac = [0.0; 6];
                    if D == 3 {
                        jac[0] = p[1] * nq[2] - p[2] * nq[1];
                        jac[1] = p[2] * nq[0] - p[0] * nq[2];
                        jac[2] = p[0] * nq[1] - p[1] * nq[0];
                        jac[3..6].copy_from_slice(&nq[..3]);
                    } else {
                        jac[0] = p[0] * nq[1] - p[1] * nq[0];
                        jac[1..3].copy_from_slice(&nq[..2]);
                    }
                    let r = dot(&sub(&p, q), nq);
                    for u in 0..need {
                        b[u] -= jac[u] * r;
                        for v in 0..need {
                            a[u][v] += jac[u] * jac[v];
                        }
                    }
                }
                let x = solve_spd(&a, &b, need).ok_or(RegistrationError::Degenerate(
                    "point-to-plane ICP: the correspondences do not constrain every direction (a plane or a corridor)",
                ))?;
                Rigid::from_twist(&x[..need])
            }
        };
        transform = update.compose(&transform);
        result.iterations = it;
        if update.translation_norm() <= params.translation_tolerance
            && update.angle() <= params.rotation_tolerance
        {
            result.converged = true;
            break;
        }
    }
    result.transform = transform;
    Ok(result)
}

/// The information matrix of a registration, `Ω = I / σ̂²` ([Stüde 2024] §3.2.2), `dof × dof`
/// (6 in 3-D, 3 in 2-D).
#[derive(Clone, Debug, PartialEq)]
pub struct Information {
    /// `σ̂` (m): `1.4826 · median(dᵢ)`, the median absolute deviation about zero of the
    /// correspondence residuals (whose magnitudes are the distances `dᵢ`), scaled to be a
    /// consistent estimate of the standard deviation of normal residuals; at least `min_sigma`.
    pub sigma: f64,
    /// 6 in 3-D, 3 in 2-D.
    pub dof: usize,
    /// Correspondences the median was taken over.
    pub correspondences: usize,
}

impl Information {
    /// `σ̂²`.
    pub fn variance(&self) -> f64 {
        self.sigma * self.sigma
    }

    /// `Ω = I / σ̂²`, row by row.
    pub fn matrix(&self) -> Vec<Vec<f64>> {
        (0..self.dof)
            .map(|i| {
                (0..self.dof)
                    .map(|j| if i == j { 1.0 / self.variance() } else { 0.0 })
                    .collect()
            })
            .collect()
    }
}

/// The consistency constant of the MAD for normal data, `1 / Φ⁻¹(3/4)`.
pub const MAD_TO_SIGMA: f64 = 1.482_602_218_505_602;

/// [`Information`] of `transform`: nearest-neighbour correspondences between the transformed
/// source and the target within `max_distance` ([Stüde 2024] §3.2.2: "a nearest-neighbor
/// correspondence estimation is carried out between the aligned clouds"), `σ̂` from the median
/// of their distances, floored at `min_sigma` (a perfect synthetic fit would give Ω = ∞).
pub fn information<const D: usize>(
    source: &[[f64; D]],
    target_tree: &KdTree<D>,
    transform: &Rigid<D>,
    max_distance: f64,
    min_sigma: f64,
) -> Result<Information, RegistrationError> {
    const { assert_dim::<D>() };
    crate::cloud::positive("max_distance", max_distance)?;
    crate::cloud::positive("min_sigma", min_sigma)?;
    let mut d: Vec<f64> = source
        .iter()
        .filter_map(|p| target_tree.nearest(&transform.apply(p)))
        .filter(|&(_, d2)| d2 <= max_distance * max_distance)
        .map(|(_, d2)| d2.sqrt())
        .collect();
    if d.is_empty() {
        return Err(RegistrationError::TooFewPoints {
            what: "information correspondences",
            got: 0,
            need: 1,
        });
    }
    let mid = d.len() / 2;
    let (_, &mut upper, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    let median = if d.len() % 2 == 1 {
        upper
    } else {
        let lower = d[..mid].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lower + upper)
    };
    Ok(Information {
        sigma: (MAD_TO_SIGMA * median).max(min_sigma),
        dof: if D == 3 { 6 } else { 3 },
        correspondences: d.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn information_is_the_mad_of_the_residuals() {
        // Five pairs 10 m apart, residuals 1..5 cm: median 3 cm.
        let target: Vec<[f64; 3]> = (0..5).map(|i| [10.0 * f64::from(i), 0.0, 0.0]).collect();
        let source: Vec<[f64; 3]> = (0..5)
            .map(|i| [10.0 * f64::from(i), 0.01 * f64::from(i + 1), 0.0])
            .collect();
        let tree = KdTree::new(&target);
        let info = information(&source, &tree, &Rigid::identity(), 1.0, 1e-4).unwrap();
        assert!((info.sigma - MAD_TO_SIGMA * 0.03).abs() < 1e-12);
        assert_eq!((info.dof, info.correspondences), (6, 5));
        let omega = info.matrix();
        assert!(
            (omega[3][3] - 1.0 / (MAD_TO_SIGMA * 0.03).powi(2)).abs() < 1e-6 && omega[3][4] == 0.0
        );
        // Beyond 4.5 cm the 5 cm pair is no correspondence: the median of 1..4 cm is 2.5 cm.
        let info = information(&source, &tree, &Rigid::identity(), 0.045, 1e-4).unwrap();
        assert!((info.sigma - MAD_TO_SIGMA * 0.025).abs() < 1e-12);
        assert!(information(&source, &tree, &Rigid::identity(), 0.001, 1e-4).is_err());
        assert!(information(&source, &tree, &Rigid::identity(), f64::NAN, 1e-4).is_err());
    }
}
