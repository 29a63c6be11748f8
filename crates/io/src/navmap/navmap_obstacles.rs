//! A ROS map read and gridded for the path planners of the service-disturbance benchmark
//! ([Stüde 2024] §4.3.5) and the person search (§5.4): the files are this crate's, the grid
//! [`MapPlanningGrid::of_map`] of `chronomap-activity`.

use chronomap_activity::planning::MapPlanningGrid;

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
    let map = crate::navmap::load_map(yaml, crate::navmap::LoadSemantics::Nav2)?;
    MapPlanningGrid::of_map(&map, occupied_percent, cell, clearance).map_err(|e| {
        PlanningMapError::Unusable {
            path: yaml.display().to_string(),
            reason: e.to_string(),
        }
    })
}
