//! A ROS map read and gridded for the path planners of the service-disturbance benchmark
//! ([Stüde 2024] §4.3.5) and the person search (§5.4): the files are this crate's, the
//! obstacles [`OccupancyMap::planning_obstacles`](chronomap_spatial::OccupancyMap::planning_obstacles)
//! of `chronomap-spatial`, the grid `chronomap-activity`'s.

/// A ROS map as a grid of planning cells ([`chronomap_activity::planning::map_grid`]), with the
/// map's lower-left corner and size: what the service-disturbance benchmark and the person
/// search plan on.
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
