//! The time axis of the bundled ATC grid of CoPA-Map (`data/atc_copa_map_grid`, see
//! data/README.md): `t` counts hour bins from 2012-10-24 09:00 JST (unix 1351036800), 12
//! recorded hours (09:00–21:00 JST) a day, the nights removed. A model trained on that grid
//! answers in these units, so a wall-clock time must be mapped onto them first.
//!
//! ```
//! use chronomap_activity::atc::model_time;
//!
//! // 2012-10-24 14:30 JST (05:30 UTC) is 5.5 hours into the first recorded day.
//! assert_eq!(model_time(1_351_056_600.0), Some(5.5));
//! // 09:00 JST the next day: 12 recorded hours later.
//! assert_eq!(model_time(1_351_036_800.0 + 86_400.0), Some(12.0));
//! // 22:00 JST: the grid has no night.
//! assert_eq!(model_time(1_351_036_800.0 + 13.0 * 3600.0), None);
//! ```

/// Unix time of `t = 0`: 2012-10-24 09:00 JST.
pub const T0: f64 = 1_351_036_800.0;

/// Recorded hours a day (09:00–21:00 JST).
pub const HOURS_PER_DAY: f64 = 12.0;

/// The model time of the unix time `time` on the ATC grid's axis: `12·d + h` on day `d` at
/// `h` hours after 09:00 JST; `None` outside 09:00–21:00 JST (the model has no night).
pub fn model_time(time: f64) -> Option<f64> {
    let since = time - T0;
    let day = (since / 86_400.0).floor();
    let hours = (since - day * 86_400.0) / 3600.0;
    (hours < HOURS_PER_DAY).then_some(HOURS_PER_DAY * day + hours)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recorded_hours_map_onto_consecutive_bins() {
        // 20:30 JST on the third day, and 10:00 JST the day before the grid starts.
        assert_eq!(model_time(T0 + 2.0 * 86_400.0 + 11.5 * 3600.0), Some(35.5));
        assert_eq!(model_time(T0 - 86_400.0 + 3600.0), Some(-11.0));
        // 21:00 JST sharp is the first hour of the night.
        assert_eq!(model_time(T0 + 12.0 * 3600.0), None);
    }
}
