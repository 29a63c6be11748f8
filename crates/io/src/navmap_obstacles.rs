//! What a robot that plans paths needs of a ROS map: the cells it must not enter (unknown
//! ones included), and which points of the plane lie on occupied cells.
//!
//! [`OccupancyMap::obstacle_grid`] is the map as the sight lines of training-sample extraction
//! see it (unknown cells do not block sight, the resolution is the shortest decimal of the
//! `f32`); [`OccupancyMap::planning_obstacles`] is the map as the path planners of the
//! service-disturbance benchmark ([Stüde 2024] §4.3.5) and of the person search (§5.4) see it:
//! unknown cells block too, and the resolution is the `f32` widened exactly
//! (`f64::from(0.05f32)` = 0.05000000074505806), as those benchmarks measured their numbers
//! with.

use chronomap_spatial::ObstacleGrid;

use crate::navmap::{NavMapErrorKind, OccupancyMap};

/// The occupancy (percent) from which a map cell is a wall for predictions drawn over the map:
/// `chronomap activity predict --map` and the service's `--activity-map` leave out the cells
/// whose centres lie on such a cell ([`OccupancyMap::is_occupied_at`]).
pub const WALL_PERCENT: i8 = 51;

impl OccupancyMap {
    /// The cells a path planner must avoid: at least `min_occupancy` percent occupied, or
    /// unknown (`-1`). Metres per cell are `f64::from(resolution)`.
    ///
    /// ```
    /// use chronomap_io::OccupancyMap;
    ///
    /// let mut map = OccupancyMap::new(4, 2, 0.05, [-1.0, 2.0, 0.0]);
    /// map.data = vec![0, 100, -1, 30, 0, 0, 0, 65];
    /// let grid = map.planning_obstacles(50)?;
    /// assert_eq!(grid.resolution(), f64::from(0.05f32));
    /// // Occupied (100, 65) and unknown (-1) cells block; 0 and 30 do not.
    /// assert!(grid.is_blocked(1, 0) && grid.is_blocked(2, 0) && grid.is_blocked(3, 1));
    /// assert!(!grid.is_blocked(0, 0) && !grid.is_blocked(3, 0));
    /// # Ok::<(), chronomap_io::NavMapErrorKind>(())
    /// ```
    ///
    /// # Errors
    /// [`NavMapErrorKind::InvalidMap`] for a rotated map (yaw ≠ 0), or a map whose size,
    /// resolution or origin no grid can have.
    pub fn planning_obstacles(&self, min_occupancy: i8) -> Result<ObstacleGrid, NavMapErrorKind> {
        if self.origin[2] != 0.0 {
            return Err(NavMapErrorKind::InvalidMap {
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
        .map_err(|e| NavMapErrorKind::InvalidMap {
            reason: e.to_string(),
        })
    }

    /// Whether the point `p` (metres, map frame) lies on a cell at least `min_occupancy`
    /// percent occupied; unknown cells and points outside the map are not occupied.
    ///
    /// ```
    /// use chronomap_io::OccupancyMap;
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
    /// use chronomap_io::OccupancyMap;
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
            Err(NavMapErrorKind::InvalidMap { .. })
        ));
    }
}

/// A ROS map as a grid of planning cells ([`chronomap_activity::planning::map_grid`]), with the
/// map's lower-left corner and size: what the service-disturbance benchmark and the person
/// search plan on.
#[cfg(feature = "activity")]
#[derive(Clone, Debug)]
pub struct MapPlanningGrid {
    /// Free planning cells of side `cell`, those nearer than `clearance` to an obstacle blocked.
    pub grid: chronomap_spatial::PlanningGrid,
    /// Lower-left corner of the map (m).
    pub origin: [f64; 2],
    /// Width and height of the map (m).
    pub size: [f64; 2],
}

/// Why [`load_planning_grid`] failed.
#[cfg(feature = "activity")]
#[derive(Debug, thiserror::Error)]
pub enum PlanningMapError {
    /// The map files could not be read.
    #[error(transparent)]
    Map(#[from] crate::navmap::NavMapError),
    /// The map cannot be planned on (rotated, or no free cell at this clearance).
    #[error("{path}: {reason}")]
    Unusable {
        /// The map's YAML file.
        path: String,
        /// What is wrong.
        reason: String,
    },
}

/// Reads a ROS map (YAML + image, Nav2 semantics) and grids it for planning: cells at least
/// `occupied_percent` occupied, or unknown, are obstacles; planning cells of `cell` metres keep
/// `clearance` metres from them.
///
/// # Errors
/// [`PlanningMapError`] naming the map.
#[cfg(feature = "activity")]
pub fn load_planning_grid(
    yaml: &std::path::Path,
    occupied_percent: i8,
    cell: f64,
    clearance: f64,
) -> Result<MapPlanningGrid, PlanningMapError> {
    use chronomap_activity::planning::{map_grid, map_size};
    let unusable = |reason: String| PlanningMapError::Unusable {
        path: yaml.display().to_string(),
        reason,
    };
    let map = crate::navmap::load_map(yaml, crate::navmap::LoadSemantics::Nav2)?;
    let obstacles = map
        .planning_obstacles(occupied_percent)
        .map_err(|e| unusable(e.to_string()))?;
    let grid = map_grid(&obstacles, cell, clearance).map_err(|e| unusable(e.to_string()))?;
    Ok(MapPlanningGrid {
        grid,
        origin: obstacles.origin(),
        size: map_size(&obstacles),
    })
}
