//! Maps of the expected density of events at given times, and where events happened: what
//! `chronomap hypertime` draws and reports ([Krajník 2019], Fig. 6 style maps of people).

use serde::{Deserialize, Serialize};

use super::{Event, EventIntensity, SpatialGrid};

/// The expected events per m² per hour around one time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct DensityMap {
    /// The time (s).
    pub time: f64,
    /// Expected events per m² per hour in every cell of the map's grid (indexed
    /// `row · nx + column`, row 0 the smallest y).
    pub per_m2_hour: Vec<f64>,
}

impl DensityMap {
    /// Expected events per hour over the whole map: `Σ density · cell²`.
    pub fn total_per_hour(&self, space: &SpatialGrid) -> f64 {
        self.per_m2_hour.iter().sum::<f64>() * space.cell * space.cell
    }

    /// The largest density of a cell (0 for an empty map).
    pub fn max_per_m2_hour(&self) -> f64 {
        self.per_m2_hour.iter().copied().fold(0.0f64, f64::max)
    }
}

/// The expected events per m² per hour of `model` on the cells of `space` at each of `times`:
/// its expected count in the hour centred on the time (`[t − 30 min, t + 30 min)`) divided by
/// the cell's area.
pub fn hourly_density(
    model: &dyn EventIntensity,
    space: &SpatialGrid,
    times: &[f64],
) -> Vec<DensityMap> {
    let area = space.cell * space.cell;
    times
        .iter()
        .map(|&t| DensityMap {
            time: t,
            per_m2_hour: model
                .expected_counts(&space.with_bins(t - 1800.0, 3600.0, 1))
                .into_iter()
                .map(|c| c / area)
                .collect(),
        })
        .collect()
}

/// The smallest axis-aligned rectangle holding every event's position.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Extent {
    /// Smallest x (m).
    pub x_min: f64,
    /// Largest x (m).
    pub x_max: f64,
    /// Smallest y (m).
    pub y_min: f64,
    /// Largest y (m).
    pub y_max: f64,
}

impl Extent {
    /// The extent of `events`; `None` if there are none.
    pub fn of(events: &[Event]) -> Option<Extent> {
        let first = events.first()?;
        let mut e = Extent {
            x_min: first.x,
            x_max: first.x,
            y_min: first.y,
            y_max: first.y,
        };
        for ev in events {
            e.x_min = e.x_min.min(ev.x);
            e.x_max = e.x_max.max(ev.x);
            e.y_min = e.y_min.min(ev.y);
            e.y_max = e.y_max.max(ev.y);
        }
        Some(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::events::{StaticMap, TrainingData};

    #[test]
    fn densities_of_a_static_map_and_extents() {
        let e = |t, x, y| Event { t, x, y };
        // Four detections in 2 h of observation: three in the cell at the origin, one 3 m away.
        let train = [
            e(0.0, 0.2, 0.2),
            e(2400.0, 0.4, 0.1),
            e(4800.0, 3.2, -0.5),
            e(7200.0, 0.1, 0.3),
        ];
        let training = TrainingData::from_events(&train, 3600.0).unwrap();
        let space = SpatialGrid::covering(&train, 0.5).unwrap();
        let model = StaticMap::fit(&training, space);
        let maps = hourly_density(&model, &space, &[3600.0, 90_000.0]);
        assert_eq!(maps.len(), 2);
        assert_eq!(maps[1].time, 90_000.0);
        // 3 detections in 2 h = 1.5 per hour in a cell of 0.25 m²: 6 per m² per hour.
        let origin = space
            .cell_of(0.2, 0.2)
            .map(|(r, c)| space.index(r, c))
            .unwrap();
        assert!((maps[0].per_m2_hour[origin] - 6.0).abs() < 1e-9);
        assert!((maps[0].max_per_m2_hour() - 6.0).abs() < 1e-9);
        // Everything: 4 detections in 2 h.
        assert!((maps[0].total_per_hour(&space) - 2.0).abs() < 1e-9);
        assert_eq!(maps[0].per_m2_hour, maps[1].per_m2_hour);

        let extent = Extent::of(&train).unwrap();
        assert_eq!(
            (extent.x_min, extent.x_max, extent.y_min, extent.y_max),
            (0.1, 3.2, -0.5, 0.3)
        );
        assert_eq!(Extent::of(&[]), None);
    }
}
