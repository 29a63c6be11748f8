//! The grid Poisson model of eq. 5.7 learned from pedestrian tracks over a map's area, as
//! `chronomap psbt` builds it for the synthesis and the evaluation of §5.4.4 (1 m cells, 1 h
//! intervals).

use chronomap_activity::truth::TrackPoint;

use chronomap_core::num::count_of;

use super::{GammaPrior, GridPoisson, GridSpec, PsbtError};

/// The most columns, rows or intervals of the model (the whole grid is further limited to
/// 2²⁸ cells × intervals by [`GridPoisson::new`]).
pub const MAX_COUNT: usize = 1 << 28;

/// The grid Poisson model ([`GridPoisson::from_tracks`], default prior) over the area of
/// `size` metres from `origin` in cells of `cell` metres (the last ones may reach past the
/// area), with intervals of `interval` seconds from the start of the interval of the first
/// point to the one of the last, learned from the points (in time order) whose time `keep`
/// accepts. `None` when it accepts none.
///
/// ```
/// use chronomap_activity::truth::TrackPoint;
/// use chronomap_psbt::world::grid_poisson_from_tracks;
///
/// let points = [
///     TrackPoint { t: 3_600.5, person: 1, x: 2.5, y: 0.5 },
///     TrackPoint { t: 9_000.0, person: 2, x: 0.5, y: 0.5 },
/// ];
/// let model = grid_poisson_from_tracks(&points, [0.0, 0.0], [3.5, 1.0], 1.0, 3600.0, |_| true)?
///     .expect("points were kept");
/// let spec = model.spec();
/// assert_eq!((spec.cols, spec.rows), (4, 1));
/// assert_eq!((spec.t0, spec.intervals), (3600.0, 2));
/// assert!(grid_poisson_from_tracks(&points, [0.0, 0.0], [3.5, 1.0], 1.0, 3600.0, |t| t < 0.0)?
///     .is_none());
/// # Ok::<(), chronomap_psbt::PsbtError>(())
/// ```
///
/// # Errors
/// [`PsbtError::TooMany`] when `cell` or `interval` gives more than [`MAX_COUNT`] columns,
/// rows or intervals (or a first interval index beyond it); otherwise as
/// [`GridPoisson::from_tracks`].
pub fn grid_poisson_from_tracks(
    points: &[TrackPoint],
    origin: [f64; 2],
    size: [f64; 2],
    cell: f64,
    interval: f64,
    keep: impl Fn(f64) -> bool,
) -> Result<Option<GridPoisson>, PsbtError> {
    let points: Vec<TrackPoint> = points.iter().copied().filter(|p| keep(p.t)).collect();
    let (Some(first), Some(last)) = (points.first(), points.last()) else {
        return Ok(None);
    };
    let within = |limit, parameter, value: f64, what, count: f64| {
        count_of(count, limit).ok_or(PsbtError::TooMany {
            parameter,
            value,
            what,
            count,
            limit,
        })
    };
    let count = |parameter, value, what, count| within(MAX_COUNT, parameter, value, what, count);
    // The interval index of the first point must be an exact integer too (2^53), or t0 is
    // not a finite multiple of the interval.
    let index = (first.t / interval).abs().floor();
    within(
        1 << 53,
        "interval",
        interval,
        "intervals since time 0",
        index,
    )?;
    let t0 = (first.t / interval).floor() * interval;
    let intervals = count(
        "interval",
        interval,
        "intervals",
        ((last.t - t0) / interval).floor(),
    )?;
    let spec = GridSpec {
        origin,
        cell,
        cols: count("cell", cell, "columns", (size[0] / cell).ceil())?,
        rows: count("cell", cell, "rows", (size[1] / cell).ceil())?,
        t0,
        interval,
        intervals: count("interval", interval, "intervals", intervals as f64 + 1.0)?,
    };
    Ok(Some(GridPoisson::from_tracks(
        &points,
        spec,
        GammaPrior::default(),
    )?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::RateField;

    #[test]
    fn the_model_learns_from_the_kept_hour_only() {
        // Person 1 in cell (0, 0) in the first hour, person 2 in cell (1, 0) in the second.
        let points = [
            TrackPoint {
                t: 0.0,
                person: 1,
                x: 0.5,
                y: 0.5,
            },
            TrackPoint {
                t: 599.0,
                person: 1,
                x: 0.6,
                y: 0.5,
            },
            TrackPoint {
                t: 3_700.0,
                person: 2,
                x: 1.5,
                y: 0.5,
            },
        ];
        let first_hour = |t: f64| t < 3600.0;
        let model =
            grid_poisson_from_tracks(&points, [0.0, 0.0], [2.0, 1.0], 1.0, 3600.0, first_hour)
                .unwrap()
                .unwrap();
        assert_eq!(model.spec().intervals, 1);
        assert!(model.has_detections([0.5, 0.5]));
        assert!(!model.has_detections([1.5, 0.5]));
        // One person in 600 s of tracked time, with the prior: more in the seen cell.
        assert!(model.density([0.5, 0.5], 100.0) > model.density([1.5, 0.5], 100.0));
    }
}
