//! Point clouds and the pre-registration filters of [Stüde 2024] §3.2.2: voxel grid, height,
//! intensity, range and random downsampling, "executed consecutively" ([`Filters::apply`]).

use std::collections::HashMap;

use chronomap_rng::Xoshiro256StarStar;

use crate::RegistrationError;
use crate::rigid::{Rigid, assert_dim};

/// The most points a cloud may have (10⁸, as the PLY reader).
pub const MAX_POINTS: usize = 100_000_000;

/// A point cloud in `D` = 2 or 3 dimensions, in its sensor's frame (the sensor at the origin),
/// with an optional intensity per point. Coordinates and intensities are finite.
#[derive(Clone, Debug, PartialEq)]
pub struct Cloud<const D: usize> {
    points: Vec<[f64; D]>,
    intensity: Option<Vec<f64>>,
}

impl<const D: usize> Cloud<D> {
    /// A checked cloud: at most [`MAX_POINTS`] points, all coordinates finite, and if given,
    /// one finite intensity per point.
    pub fn new(
        points: Vec<[f64; D]>,
        intensity: Option<Vec<f64>>,
    ) -> Result<Cloud<D>, RegistrationError> {
        const { assert_dim::<D>() };
        if points.len() > MAX_POINTS {
            return Err(RegistrationError::TooManyPoints(points.len()));
        }
        for (index, p) in points.iter().enumerate() {
            if let Some(axis) = p.iter().position(|x| !x.is_finite()) {
                return Err(RegistrationError::NonFinitePoint {
                    index,
                    axis,
                    value: p[axis],
                });
            }
        }
        if let Some(values) = &intensity {
            if values.len() != points.len() {
                return Err(RegistrationError::IntensityLength {
                    got: values.len(),
                    points: points.len(),
                });
            }
            if let Some(index) = values.iter().position(|x| !x.is_finite()) {
                return Err(RegistrationError::NonFiniteIntensity {
                    index,
                    value: values[index],
                });
            }
        }
        Ok(Cloud { points, intensity })
    }

    /// A checked cloud without intensity.
    pub fn from_points(points: Vec<[f64; D]>) -> Result<Cloud<D>, RegistrationError> {
        Cloud::new(points, None)
    }

    /// The points.
    pub fn points(&self) -> &[[f64; D]] {
        &self.points
    }

    /// The intensities, if the cloud has them.
    pub fn intensity(&self) -> Option<&[f64]> {
        self.intensity.as_deref()
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the cloud has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Points and intensities.
    pub fn into_parts(self) -> (Vec<[f64; D]>, Option<Vec<f64>>) {
        (self.points, self.intensity)
    }

    /// The cloud moved by `transform` (intensities kept).
    pub fn transformed(&self, transform: &Rigid<D>) -> Cloud<D> {
        Cloud {
            points: self.points.iter().map(|p| transform.apply(p)).collect(),
            intensity: self.intensity.clone(),
        }
    }

    /// The points at `keep` (in that order).
    fn select(&self, keep: &[usize]) -> Cloud<D> {
        Cloud {
            points: keep.iter().map(|&i| self.points[i]).collect(),
            intensity: self
                .intensity
                .as_ref()
                .map(|v| keep.iter().map(|&i| v[i]).collect()),
        }
    }

    fn retain(&self, keep: impl Fn(usize) -> bool) -> Cloud<D> {
        let kept: Vec<usize> = (0..self.len()).filter(|&i| keep(i)).collect();
        self.select(&kept)
    }

    /// Voxel-grid filter ([Stüde 2024] §3.2.2, filter 1): the points in each cube of edge `leaf`
    /// (cells `⌊p / leaf⌋`) are replaced by their centroid (and mean intensity). Voxels appear in
    /// the order of their first point, so the result does not depend on hashing.
    pub fn voxel_grid(&self, leaf: f64) -> Result<Cloud<D>, RegistrationError> {
        self.voxel_cells(leaf, usize::MAX, &|_| true)
    }

    /// [`Cloud::voxel_grid`] holding at most `max_voxels` occupied cells: the grid stops at the
    /// first point that would occupy one more, with [`RegistrationError::PointLimit`] (its
    /// `seen`: the points read up to and including that one). Memory is bounded by `max_voxels`
    /// cells (about 70 bytes each in 3-D), not by the size of the cloud.
    pub fn voxel_grid_at_most(
        &self,
        leaf: f64,
        max_voxels: usize,
    ) -> Result<Cloud<D>, RegistrationError> {
        self.voxel_cells(leaf, max_voxels, &|_| true)
    }

    /// The voxel grid of the cells `keep_cell` accepts (the others are dropped with their
    /// points), at most `max` of them.
    fn voxel_cells(
        &self,
        leaf: f64,
        max: usize,
        keep_cell: &dyn Fn(&[i64; D]) -> bool,
    ) -> Result<Cloud<D>, RegistrationError> {
        positive("voxel leaf", leaf)?;
        // Slots are u32: a cloud has at most MAX_POINTS (10⁸ < 2³²) points, so at most as
        // many cells.
        let mut slot_of: HashMap<[i64; D], u32> = HashMap::new();
        let mut sums: Vec<([f64; D], f64, u32)> = Vec::new();
        for (index, p) in self.points.iter().enumerate() {
            let mut key = [0i64; D];
            for a in 0..D {
                let cell = (p[a] / leaf).floor();
                if cell.abs() > 4.0e18 {
                    return Err(RegistrationError::VoxelOverflow { index });
                }
                key[a] = cell as i64;
            }
            let slot = match slot_of.get(&key) {
                Some(&slot) => slot as usize,
                None => {
                    if !keep_cell(&key) {
                        continue;
                    }
                    if sums.len() >= max {
                        return Err(RegistrationError::PointLimit {
                            max,
                            counted: sums.len() + 1,
                            seen: index + 1,
                            points: self.len(),
                        });
                    }
                    slot_of.insert(key, sums.len() as u32);
                    sums.push(([0.0; D], 0.0, 0));
                    sums.len() - 1
                }
            };
            let s = &mut sums[slot];
            for a in 0..D {
                s.0[a] += p[a];
            }
            s.1 += self.intensity.as_ref().map_or(0.0, |v| v[index]);
            s.2 += 1;
        }
        Ok(Cloud {
            points: sums
                .iter()
                .map(|(s, _, n)| std::array::from_fn(|a| s[a] / f64::from(*n)))
                .collect(),
            intensity: self
                .intensity
                .as_ref()
                .map(|_| sums.iter().map(|(_, i, n)| i / f64::from(*n)).collect()),
        })
    }

    /// Range filter (filter 4): keeps points whose distance from the sensor origin is in
    /// `[min, max]`.
    pub fn range_band(&self, min: f64, max: f64) -> Result<Cloud<D>, RegistrationError> {
        band("range", min, max)?;
        Ok(self.retain(|i| {
            let r = self.points[i].iter().map(|x| x * x).sum::<f64>().sqrt();
            r >= min && r <= max
        }))
    }

    /// Intensity filter (filter 3): keeps points whose intensity is in `[min, max]`, e.g. to drop
    /// the weak returns of multi-reflections on glass. A cloud without intensity is an error.
    pub fn intensity_band(&self, min: f64, max: f64) -> Result<Cloud<D>, RegistrationError> {
        band("intensity", min, max)?;
        let values = self
            .intensity
            .as_ref()
            .ok_or(RegistrationError::NoIntensity("intensity band"))?;
        Ok(self.retain(|i| values[i] >= min && values[i] <= max))
    }

    /// Random downsampling (filter 5): at most `max_points` points, drawn uniformly without
    /// replacement with the seeded `Xoshiro256StarStar`, kept in their original order.
    pub fn random_downsample(&self, max_points: usize, seed: u64) -> Cloud<D> {
        if self.len() <= max_points {
            return self.clone();
        }
        let mut rng = Xoshiro256StarStar::seed_from_u64(seed);
        let mut order: Vec<usize> = (0..self.len()).collect();
        // Partial Fisher–Yates: the first `max_points` slots are a uniform sample.
        for i in 0..max_points {
            let j = rng.int_in(i as u64, self.len() as u64 - 1) as usize;
            order.swap(i, j);
        }
        let mut keep = order[..max_points].to_vec();
        keep.sort_unstable();
        self.select(&keep)
    }
}

impl Cloud<3> {
    /// Height filter (filter 2): keeps points whose `z` is in `[min, max]` (the floor below
    /// `min`, e.g. `z_lim` = 0.3 m of [Stüde 2024] appendix A, is uninformative).
    pub fn height_band(&self, min: f64, max: f64) -> Result<Cloud<3>, RegistrationError> {
        band("height", min, max)?;
        Ok(self.retain(|i| self.points[i][2] >= min && self.points[i][2] <= max))
    }
}

/// The filters of [Stüde 2024] §3.2.2 in their order; `None` skips one. The height band applies
/// to 3-D clouds only (the last coordinate is height); on 2-D clouds it must be `None`.
#[derive(Clone, Debug, PartialEq)]
pub struct Filters {
    /// 1. Voxel-grid leaf (m); appendix A: 0.03 m indoors, 0.2 m on KITTI.
    pub voxel: Option<f64>,
    /// 2. Height band `[min, max]` (m); appendix A: `z ≥ 0.3 m` indoors.
    pub height: Option<(f64, f64)>,
    /// 3. Intensity band; appendix A: `i ≥ 5` indoors.
    pub intensity: Option<(f64, f64)>,
    /// 4. Range band (m); appendix A: `r ≤ 30 m`.
    pub range: Option<(f64, f64)>,
    /// 5. Random downsampling to at most this many points (appendix A: 7,000), and its seed.
    pub max_points: Option<(usize, u64)>,
}

impl Filters {
    /// Applies the filters in order.
    pub fn apply<const D: usize>(&self, cloud: &Cloud<D>) -> Result<Cloud<D>, RegistrationError> {
        self.apply_at_most(cloud, usize::MAX)
    }

    /// [`Filters::apply`], refusing more than `max_points` filtered points with
    /// [`RegistrationError::PointLimit`]. With a voxel leaf and neither an intensity band nor
    /// random downsampling (which could still drop points afterwards), the voxel grid stops as
    /// soon as more than `max_points` cells are occupied, so memory stays bounded by
    /// `max_points`: cells that lie wholly outside the range or height band are left out of the
    /// grid (their centroids, inside the cell, would be dropped by those bands anyway, so the
    /// result is the one [`Filters::apply`] gives), and a cell reaching into a band counts even
    /// if its centroid ends up outside it. Otherwise the filtered points are counted at the end.
    pub fn apply_at_most<const D: usize>(
        &self,
        cloud: &Cloud<D>,
        max_points: usize,
    ) -> Result<Cloud<D>, RegistrationError> {
        if let Some((min, max)) = self.range {
            band("range", min, max)?;
        }
        if let Some((min, max)) = self.height {
            band("height", min, max)?;
        }
        let mut out = match self.voxel {
            Some(leaf) if self.intensity.is_none() && self.max_points.is_none() => {
                let range = self.range;
                let height = self.height.filter(|_| D == 3);
                cloud.voxel_cells(leaf, max_points, &|key| {
                    cell_may_pass(key, leaf, range, height)
                })?
            }
            Some(leaf) => cloud.voxel_grid(leaf)?,
            None => cloud.clone(),
        };
        if let Some((min, max)) = self.height {
            band("height", min, max)?;
            if D != 3 {
                return Err(RegistrationError::Parameter {
                    field: "height",
                    value: D as f64,
                    why: "a height band needs 3-D points",
                });
            }
            out = out.retain(|i| out.points[i][2] >= min && out.points[i][2] <= max);
        }
        if let Some((min, max)) = self.intensity {
            out = out.intensity_band(min, max)?;
        }
        if let Some((min, max)) = self.range {
            out = out.range_band(min, max)?;
        }
        if let Some((n, seed)) = self.max_points {
            out = out.random_downsample(n, seed);
        }
        if out.len() > max_points {
            return Err(RegistrationError::PointLimit {
                max: max_points,
                counted: out.len(),
                seen: cloud.len(),
                points: cloud.len(),
            });
        }
        Ok(out)
    }
}

/// Whether the voxel `key` (the cube `[k·leaf, (k+1)·leaf]` on each axis) may hold a centroid
/// that the `range` band (distance from the origin) and the `height` band (last coordinate)
/// keep: false only for a cell wholly outside one of them by more than 10⁻⁶ × (leaf + |bound|),
/// a margin that covers the rounding of `⌊p / leaf⌋` and of a centroid.
fn cell_may_pass<const D: usize>(
    key: &[i64; D],
    leaf: f64,
    range: Option<(f64, f64)>,
    height: Option<(f64, f64)>,
) -> bool {
    let bounds = |a: usize| (key[a] as f64 * leaf, (key[a] as f64 + 1.0) * leaf);
    let margin = |r: f64| 1e-6 * (leaf + r.abs());
    if let Some((min, max)) = range {
        let (mut near, mut far) = (0.0, 0.0);
        for a in 0..D {
            let (lo, hi) = bounds(a);
            let n = if lo > 0.0 {
                lo
            } else if hi < 0.0 {
                -hi
            } else {
                0.0
            };
            let f = lo.abs().max(hi.abs());
            near += n * n;
            far += f * f;
        }
        let (near, far) = (f64::sqrt(near), f64::sqrt(far));
        if near > max + margin(max) || far < min - margin(min) {
            return false;
        }
    }
    if let Some((min, max)) = height {
        let (lo, hi) = bounds(D - 1);
        if lo > max + margin(max) || hi < min - margin(min) {
            return false;
        }
    }
    true
}

/// A positive finite parameter.
pub(crate) fn positive(field: &'static str, value: f64) -> Result<(), RegistrationError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(RegistrationError::Parameter {
            field,
            value,
            why: "must be positive and finite",
        })
    }
}

fn band(field: &'static str, min: f64, max: f64) -> Result<(), RegistrationError> {
    if min.is_nan() || max.is_nan() || min > max {
        return Err(RegistrationError::Parameter {
            field,
            value: min,
            why: "the band needs min ≤ max, not NaN",
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn voxel_grid_averages_each_cell() {
        let cloud = Cloud::new(
            vec![[0.1, 0.1], [0.3, 0.5], [1.5, 0.2], [-0.5, 0.0]],
            Some(vec![1.0, 3.0, 7.0, 9.0]),
        )
        .unwrap();
        let out = cloud.voxel_grid(1.0).unwrap();
        assert_eq!(out.points(), &[[0.2, 0.3], [1.5, 0.2], [-0.5, 0.0]]);
        assert_eq!(out.intensity().unwrap(), &[2.0, 7.0, 9.0]);
        assert!(cloud.voxel_grid(0.0).is_err());
        let far = Cloud::from_points(vec![[1e300, 0.0]]).unwrap();
        assert_eq!(
            far.voxel_grid(1e-3),
            Err(RegistrationError::VoxelOverflow { index: 0 })
        );
    }

    #[test]
    fn a_bounded_voxel_grid_stops_at_the_first_point_over_its_bound() {
        // Cells (0,0), (1,0), (0,0) again, (2,0), (3,0): the third cell is occupied by point 3.
        let cloud = Cloud::from_points(vec![
            [0.1, 0.1],
            [1.5, 0.2],
            [0.3, 0.5],
            [2.5, 0.0],
            [3.5, 0.0],
        ])
        .unwrap();
        assert_eq!(
            cloud.voxel_grid_at_most(1.0, 2),
            Err(RegistrationError::PointLimit {
                max: 2,
                counted: 3,
                seen: 4,
                points: 5
            })
        );
        assert_eq!(cloud.voxel_grid_at_most(1.0, 4), cloud.voxel_grid(1.0));
        assert_eq!(cloud.voxel_grid_at_most(1.0, 4).unwrap().len(), 4);
    }

    #[test]
    fn bounded_filters_leave_out_cells_outside_the_range_band() {
        // Range band [0, 5] m on a 1 m grid: two cells inside, 1,000 cells 100 m out (never
        // counted), and cell (4, 3), whose nearest corner is 5 m away but whose one point
        // (6.3 m) is not: it counts towards the bound, then the band drops its centroid.
        let mut points = vec![[0.5, 0.5], [2.5, 0.5]];
        points.extend((0..1000).map(|i| [100.5 + f64::from(i), 0.5]));
        points.push([4.9, 3.9]);
        let cloud = Cloud::from_points(points).unwrap();
        let filters = Filters {
            voxel: Some(1.0),
            height: None,
            intensity: None,
            range: Some((0.0, 5.0)),
            max_points: None,
        };
        let all = filters.apply(&cloud).unwrap();
        assert_eq!(all.points(), &[[0.5, 0.5], [2.5, 0.5]]);
        assert_eq!(filters.apply_at_most(&cloud, 3).unwrap(), all);
        assert_eq!(
            filters.apply_at_most(&cloud, 2),
            Err(RegistrationError::PointLimit {
                max: 2,
                counted: 3,
                seen: 1003,
                points: 1003
            })
        );
        // A height band [2, 3] m leaves out the cells wholly above or below it: of the 100
        // cells of this column, those of z in [1, 2], [2, 3] and [3, 4] touch it and count.
        let tall = Cloud::from_points(
            (0..100)
                .map(|i| [0.5, 0.5, f64::from(i) + 0.5])
                .collect::<Vec<_>>(),
        )
        .unwrap();
        let filters = Filters {
            height: Some((2.0, 3.0)),
            range: None,
            ..filters
        };
        let kept = filters.apply_at_most(&tall, 3).unwrap();
        assert_eq!(kept.points(), &[[0.5, 0.5, 2.5]]);
        assert_eq!(
            filters.apply_at_most(&tall, 2),
            Err(RegistrationError::PointLimit {
                max: 2,
                counted: 3,
                seen: 4,
                points: 100
            })
        );
        // Without a voxel grid, the filtered points are counted at the end.
        let bare = Filters {
            voxel: None,
            height: None,
            ..filters
        };
        assert_eq!(
            bare.apply_at_most(&tall, 10),
            Err(RegistrationError::PointLimit {
                max: 10,
                counted: 100,
                seen: 100,
                points: 100
            })
        );
    }

    #[test]
    fn bands_keep_what_is_inside() {
        let cloud = Cloud::new(
            vec![[1.0, 0.0, 0.1], [3.0, 4.0, 0.5], [0.0, 10.0, 1.0]],
            Some(vec![2.0, 6.0, 8.0]),
        )
        .unwrap();
        assert_eq!(cloud.range_band(0.0, 6.0).unwrap().len(), 2);
        assert_eq!(
            cloud.height_band(0.3, 2.0).unwrap().points()[0],
            [3.0, 4.0, 0.5]
        );
        assert_eq!(
            cloud
                .intensity_band(5.0, f64::INFINITY)
                .unwrap()
                .intensity()
                .unwrap(),
            &[6.0, 8.0]
        );
        let bare = Cloud::from_points(vec![[0.0, 0.0, 0.0]]).unwrap();
        assert_eq!(
            bare.intensity_band(0.0, 1.0),
            Err(RegistrationError::NoIntensity("intensity band"))
        );
        assert!(cloud.range_band(2.0, 1.0).is_err());
        let filters = Filters {
            voxel: None,
            height: Some((0.3, 2.0)),
            intensity: Some((7.0, 100.0)),
            range: Some((0.0, 20.0)),
            max_points: Some((10, 1)),
        };
        assert_eq!(filters.apply(&cloud).unwrap().points(), &[[0.0, 10.0, 1.0]]);
    }

    #[test]
    fn random_downsampling_is_seeded_uniform_and_ordered() {
        let cloud = Cloud::from_points((0..1000).map(|i| [f64::from(i), 0.0]).collect()).unwrap();
        let a = cloud.random_downsample(100, 5);
        assert_eq!(a, cloud.random_downsample(100, 5));
        assert_ne!(a, cloud.random_downsample(100, 6));
        assert_eq!(a.len(), 100);
        assert!(a.points().windows(2).all(|w| w[0][0] < w[1][0]));
        // Uniform: the mean index of the sample is near 499.5 (sd of the mean ≈ 27.4).
        let mean = a.points().iter().map(|p| p[0]).sum::<f64>() / 100.0;
        assert!((mean - 499.5).abs() < 4.0 * 27.4, "{mean}");
    }

    #[test]
    fn bad_clouds_are_refused_naming_the_point() {
        let e = Cloud::from_points(vec![[0.0, 0.0], [1.0, f64::NAN]]).unwrap_err();
        assert!(matches!(
            e,
            RegistrationError::NonFinitePoint {
                index: 1,
                axis: 1,
                ..
            }
        ));
        assert_eq!(e.to_string(), "point 1: coordinate 1 is NaN, not finite");
        let e = Cloud::new(vec![[0.0, 0.0]], Some(vec![])).unwrap_err();
        assert_eq!(e, RegistrationError::IntensityLength { got: 0, points: 1 });
    }
}
