//! Occupancy maps: what a `nav_msgs/OccupancyGrid` message and a ROS map file hold, and the
//! obstacles a robot derives from them.
//!
//! [`OccupancyMap`] holds what a `nav_msgs/OccupancyGrid` message holds: `data` is row-major,
//! row 0 is the **bottom** row (cell (0, 0) has its lower-left corner at `origin`), values
//! `0..=100` are occupancy probabilities in percent and `-1` is unknown; `resolution` is the
//! cell size in metres (an `f32`, as in the message) and `origin` is `[x, y, yaw]` (metres,
//! metres, radians). Reading and writing the map files (YAML + PGM/PNG) is `chronomap-io`'s.
//!
//! [`OccupancyMap::obstacle_grid`] is the map as the sight lines of training-sample extraction
//! see it (unknown cells do not block sight, the resolution is the shortest decimal of the
//! `f32`); [`OccupancyMap::planning_obstacles`] is the map as the path planners of the
//! service-disturbance benchmark ([Stüde 2024] §4.3.5) and of the person search (§5.4) see it:
//! unknown cells block too, and the resolution is the `f32` widened exactly
//! (`f64::from(0.05f32)` = 0.05000000074505806), as those benchmarks measured their numbers
//! with.

use thiserror::Error;

use crate::ObstacleGrid;

/// Cell value of a free cell.
pub const FREE: i8 = 0;
/// Cell value of an occupied cell.
pub const OCCUPIED: i8 = 100;
/// Cell value of an unknown cell.
pub const UNKNOWN: i8 = -1;

/// The occupancy (percent) from which a map cell is a wall for predictions drawn over the map:
/// `chronomap activity predict --map` and the service's `--activity-map` leave out the cells
/// whose centres lie on such a cell ([`OccupancyMap::is_occupied_at`]).
pub const WALL_PERCENT: i8 = 51;

/// Why a map cannot be used: empty, `data` not `width · height` cells, a resolution or origin
/// that is not a finite (positive) number, or a rotated map where only aligned ones are
/// supported.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[error("invalid map: {reason}")]
pub struct InvalidMap {
    /// What is wrong.
    pub reason: String,
}

/// A 2-D occupancy map with `nav_msgs/OccupancyGrid` semantics (see the
/// [module docs](self)).
#[derive(Clone, Debug, PartialEq)]
pub struct OccupancyMap {
    /// Number of cells per row.
    pub width: u32,
    /// Number of rows.
    pub height: u32,
    /// Cell size in metres.
    pub resolution: f32,
    /// `[x, y, yaw]` of the lower-left corner of cell (0, 0): metres, metres, radians.
    pub origin: [f64; 3],
    /// Row-major cells, row 0 at the bottom: `0..=100` occupancy in percent, `-1` unknown.
    pub data: Vec<i8>,
}

impl OccupancyMap {
    /// A map of `width × height` unknown cells.
    ///
    /// # Panics
    /// If `width · height` does not fit in memory (`usize`).
    pub fn new(width: u32, height: u32, resolution: f32, origin: [f64; 3]) -> Self {
        let cells = (width as usize)
            .checked_mul(height as usize)
            .expect("width * height overflows usize");
        OccupancyMap {
            width,
            height,
            resolution,
            origin,
            data: vec![UNKNOWN; cells],
        }
    }

    /// A map of occupancy probabilities (`width × height` values in `[0, 1]`, row 0 at the
    /// bottom, NaN for unknown), each cell `round(100·p)` or −1.
    ///
    /// # Panics
    /// If `probabilities` does not have `width · height` values.
    pub fn from_probabilities(
        width: u32,
        height: u32,
        resolution: f32,
        origin: [f64; 3],
        probabilities: &[f32],
    ) -> Self {
        assert_eq!(
            probabilities.len(),
            width as usize * height as usize,
            "map size"
        );
        let data = probabilities
            .iter()
            .map(|&p| {
                if p.is_nan() {
                    UNKNOWN
                } else {
                    (100.0 * p.clamp(0.0, 1.0)).round() as i8
                }
            })
            .collect();
        OccupancyMap {
            width,
            height,
            resolution,
            origin,
            data,
        }
    }

    /// Index in `data` of cell (`x`, `y`) (`y = 0` is the bottom row), if it is in the map.
    pub fn index(&self, x: u32, y: u32) -> Option<usize> {
        (x < self.width && y < self.height).then(|| y as usize * self.width as usize + x as usize)
    }

    /// Value of cell (`x`, `y`), if it is in the map (and `data` is long enough).
    pub fn cell(&self, x: u32, y: u32) -> Option<i8> {
        self.index(x, y).and_then(|i| self.data.get(i).copied())
    }

    /// The map as the [`ObstacleGrid`] of `chronomap-activity`'s training-sample extraction: a cell blocks
    /// sight when its occupancy is at least `min_occupancy` percent (in a trinary map, 100 for
    /// occupied cells); free and unknown (`-1`) cells do not. The resolution is the shortest
    /// decimal of the `f32` (0.05, not 0.0500000007).
    ///
    /// ```
    /// use chronomap_spatial::OccupancyMap;
    ///
    /// let mut map = OccupancyMap::new(4, 2, 0.05, [-1.0, 2.0, 0.0]);
    /// map.data = vec![0, 100, -1, 30, 0, 0, 0, 65];
    /// let grid = map.obstacle_grid(50)?;
    /// assert_eq!((grid.resolution(), grid.origin()), (0.05, [-1.0, 2.0]));
    /// assert!(grid.is_blocked(1, 0) && grid.is_blocked(3, 1));
    /// assert!(!grid.is_blocked(2, 0) && !grid.is_blocked(3, 0));
    /// # Ok::<(), chronomap_spatial::occupancy::InvalidMap>(())
    /// ```
    ///
    /// # Errors
    /// [`InvalidMap`] for an empty or inconsistent map, or a rotated one
    /// (yaw ≠ 0).
    pub fn obstacle_grid(&self, min_occupancy: i8) -> Result<ObstacleGrid, InvalidMap> {
        self.check()?;
        if self.origin[2] != 0.0 {
            return Err(InvalidMap {
                reason: format!(
                    "the origin's yaw is {} rad: rotated maps are not supported here",
                    self.origin[2]
                ),
            });
        }
        let resolution: f64 = self
            .resolution
            .to_string()
            .parse()
            .expect("an f32 prints as a decimal");
        let blocked = self
            .data
            .iter()
            .map(|&v| v >= min_occupancy && v >= 0)
            .collect();
        ObstacleGrid::new(
            self.width as usize,
            self.height as usize,
            resolution,
            [self.origin[0], self.origin[1]],
            blocked,
        )
        .map_err(|e| InvalidMap {
            reason: e.to_string(),
        })
    }

    /// Checks what a writer needs: a non-empty map whose `data` has `width · height` cells,
    /// a positive finite resolution and a finite origin.
    ///
    /// # Errors
    /// [`InvalidMap`] saying which of these fails.
    pub fn check(&self) -> Result<(), InvalidMap> {
        let invalid = |reason: String| Err(InvalidMap { reason });
        if self.width == 0 || self.height == 0 {
            return invalid(format!(
                "the map is empty ({} x {} cells)",
                self.width, self.height
            ));
        }
        let cells = u64::from(self.width) * u64::from(self.height);
        if self.data.len() as u64 != cells {
            return invalid(format!(
                "data has {} cells but width x height = {} x {} = {cells}",
                self.data.len(),
                self.width,
                self.height
            ));
        }
        if !(self.resolution.is_finite() && self.resolution > 0.0) {
            return invalid(format!(
                "resolution {} is not a positive number",
                self.resolution
            ));
        }
        if let Some(bad) = self.origin.iter().find(|v| !v.is_finite()) {
            return invalid(format!("origin contains {bad}, not a finite number"));
        }
        Ok(())
    }
}

impl OccupancyMap {
    /// The cells a path planner must avoid: at least `min_occupancy` percent occupied, or
    /// unknown (`-1`). Metres per cell are `f64::from(resolution)`.
    ///
    /// ```
    /// use chronomap_spatial::OccupancyMap;
    ///
    /// let mut map = OccupancyMap::new(4, 2, 0.05, [-1.0, 2.0, 0.0]);
    /// map.data = vec![0, 100, -1, 30, 0, 0, 0, 65];
    /// let grid = map.planning_obstacles(50)?;
    /// assert_eq!(grid.resolution(), f64::from(0.05f32));
    /// // Occupied (100, 65) and unknown (-1) cells block; 0 and 30 do not.
    /// assert!(grid.is_blocked(1, 0) && grid.is_blocked(2, 0) && grid.is_blocked(3, 1));
    /// assert!(!grid.is_blocked(0, 0) && !grid.is_blocked(3, 0));
    /// # Ok::<(), chronomap_spatial::occupancy::InvalidMap>(())
    /// ```
    ///
    /// # Errors
    /// [`InvalidMap`] for a rotated map (yaw ≠ 0), or a map whose size,
    /// resolution or origin no grid can have.
    pub fn planning_obstacles(&self, min_occupancy: i8) -> Result<ObstacleGrid, InvalidMap> {
        if self.origin[2] != 0.0 {
            return Err(InvalidMap {
                reason: format!(
                    "the map is rotated (yaw {}): only maps aligned with their frame are \
                     supported",
                    self.origin[2]
                ),
            });
        }
        let blocked = self
            .data
            .iter()
            .map(|&v| !(0..min_occupancy).contains(&v))
            .collect();
        ObstacleGrid::new(
            self.width as usize,
            self.height as usize,
            f64::from(self.resolution),
            [self.origin[0], self.origin[1]],
            blocked,
        )
        .map_err(|e| InvalidMap {
            reason: e.to_string(),
        })
    }

    /// Whether the point `p` (metres, map frame) lies on a cell at least `min_occupancy`
    /// percent occupied; unknown cells and points outside the map are not occupied.
    ///
    /// ```
    /// use chronomap_spatial::OccupancyMap;
    ///
    /// let mut map = OccupancyMap::new(2, 1, 0.5, [1.0, 0.0, 0.0]);
    /// map.data = vec![51, 50];
    /// assert!(map.is_occupied_at([1.2, 0.3], 51));
    /// assert!(!map.is_occupied_at([1.7, 0.3], 51) && map.is_occupied_at([1.7, 0.3], 50));
    /// assert!(!map.is_occupied_at([0.9, 0.3], 0));
    /// ```
    pub fn is_occupied_at(&self, p: [f64; 2], min_occupancy: i8) -> bool {
        let resolution = f64::from(self.resolution);
        let column = ((p[0] - self.origin[0]) / resolution).floor();
        let row = ((p[1] - self.origin[1]) / resolution).floor();
        if column < 0.0
            || row < 0.0
            || column >= f64::from(self.width)
            || row >= f64::from(self.height)
        {
            return false;
        }
        self.cell(column as u32, row as u32)
            .is_some_and(|v| v >= min_occupancy && v >= 0)
    }

    /// The centres of the cells at least `min_occupancy` percent occupied inside the box
    /// `[min, max)` (metres, map frame), row by row from the bottom: the walls to draw under a
    /// planner's paths.
    ///
    /// ```
    /// use chronomap_spatial::OccupancyMap;
    ///
    /// let mut map = OccupancyMap::new(3, 2, 1.0, [0.0, 0.0, 0.0]);
    /// map.data = vec![100, 0, 100, -1, 100, 100];
    /// assert_eq!(
    ///     map.occupied_centres(50, [0.0, 0.0], [2.0, 2.0]),
    ///     [[0.5, 0.5], [1.5, 1.5]]
    /// );
    /// ```
    pub fn occupied_centres(
        &self,
        min_occupancy: i8,
        min: [f64; 2],
        max: [f64; 2],
    ) -> Vec<[f64; 2]> {
        let resolution = f64::from(self.resolution);
        let width = self.width as usize;
        let mut points = Vec::new();
        for row in 0..self.height as usize {
            let y = self.origin[1] + (row as f64 + 0.5) * resolution;
            if y < min[1] || y >= max[1] {
                continue;
            }
            for column in 0..width {
                let x = self.origin[0] + (column as f64 + 0.5) * resolution;
                if x >= min[0]
                    && x < max[0]
                    && self
                        .data
                        .get(row * width + column)
                        .is_some_and(|&v| v >= min_occupancy && v >= 0)
                {
                    points.push([x, y]);
                }
            }
        }
        points
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planning_obstacles_differ_from_sight_obstacles_in_unknown_cells_and_resolution() {
        let mut map = OccupancyMap::new(3, 1, 0.05, [0.0, 0.0, 0.0]);
        map.data = vec![-1, 49, 50];
        let planning = map.planning_obstacles(50).unwrap();
        let sight = map.obstacle_grid(50).unwrap();
        assert_eq!(
            (0..3)
                .map(|c| planning.is_blocked(c, 0))
                .collect::<Vec<_>>(),
            [true, false, true]
        );
        assert_eq!(
            (0..3).map(|c| sight.is_blocked(c, 0)).collect::<Vec<_>>(),
            [false, false, true]
        );
        assert_eq!(planning.resolution(), 0.05000000074505806);
        assert_eq!(sight.resolution(), 0.05);
    }

    #[test]
    fn rotated_and_inconsistent_maps_are_refused() {
        let rotated = OccupancyMap::new(2, 2, 0.05, [0.0, 0.0, 0.1]);
        assert_eq!(
            rotated.planning_obstacles(50).unwrap_err().to_string(),
            "invalid map: the map is rotated (yaw 0.1): only maps aligned with their frame are \
             supported"
        );
        let mut short = OccupancyMap::new(2, 2, 0.05, [0.0, 0.0, 0.0]);
        short.data.pop();
        assert!(matches!(
            short.planning_obstacles(50),
            Err(InvalidMap { .. })
        ));
    }
}
