//! The choice of a map's SLAM configuration by the size of its room ([Stüde 2024] §3.3.2,
//! "Changing SLAM Configurations", with the bounding box of criterion (C3)).
//!
//! After a door passage, the bounding box `𝓑` of the low-pass-filtered scan in the map
//! frame gives the rough extent of the new room. "If the width and height of the bounding box
//! are over a specified threshold after door passing, the configuration for large rooms and
//! high distances applies"; otherwise the small-range one. The threshold depends on the
//! sensors (e.g. the useful range of an RGB-D camera); the text gives no number, the default
//! here (10 m) is the "less than 10 m" reach of infrared-stereo depth it quotes.
//!
//! ```
//! use chronomap_multimap::config::{choose_config, ConfigParams, MapConfig};
//! use chronomap_multimap::door::BoundingBox;
//!
//! let office = BoundingBox { min: [0.0, 0.0], max: [6.0, 4.0] };
//! let hall = BoundingBox { min: [-20.0, -5.0], max: [25.0, 30.0] };
//! let corridor = BoundingBox { min: [0.0, 0.0], max: [40.0, 2.5] };
//! let params = ConfigParams::default();
//! assert_eq!(choose_config(&office, &params), MapConfig::ShortRange);
//! assert_eq!(choose_config(&hall, &params), MapConfig::LongRange);
//! // Both sides must exceed the threshold: a long corridor stays short-range.
//! assert_eq!(choose_config(&corridor, &params), MapConfig::ShortRange);
//! ```
//!
//! [Stüde 2024]: M. Stüde, dissertation, Leibniz Universität Hannover, 2024.

use serde::{Deserialize, Serialize};

use crate::MultimapError;
use crate::door::BoundingBox;

/// The SLAM configuration of one map ([Stüde 2024] §3.3.2 and §3.3.4: small-range, e.g.
/// RGB-D depth, and long-range, e.g. lidar depth and a larger grid range).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum MapConfig {
    /// Small rooms: dense data near the robot, short-range sensors.
    ShortRange,
    /// Large rooms and outdoor areas: long-range sensors, larger maximum ranges.
    LongRange,
}

/// The threshold of the configuration choice.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ConfigParams {
    /// Width and height of the bounding box above which a room is large (m). Default 10 m.
    pub large_room_side: f64,
}

impl Default for ConfigParams {
    fn default() -> Self {
        ConfigParams {
            large_room_side: 10.0,
        }
    }
}

impl ConfigParams {
    /// Checks that the threshold is finite and positive.
    pub fn validate(&self) -> Result<(), MultimapError> {
        if !(self.large_room_side.is_finite() && self.large_room_side > 0.0) {
            return Err(MultimapError::Parameter {
                field: "large_room_side",
                value: self.large_room_side,
                why: "must be finite and positive",
            });
        }
        Ok(())
    }
}

/// The configuration for a room with bounding box `bbox`: [`MapConfig::LongRange`] if both
/// its width and its height exceed `params.large_room_side`, else [`MapConfig::ShortRange`].
pub fn choose_config(bbox: &BoundingBox, params: &ConfigParams) -> MapConfig {
    if bbox.width() > params.large_room_side && bbox.height() > params.large_room_side {
        MapConfig::LongRange
    } else {
        MapConfig::ShortRange
    }
}
