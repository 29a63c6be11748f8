//! ROS times (`builtin_interfaces/msg/Time`, MCAP nanoseconds) as the `f64` unix seconds every
//! chronomap model takes.
//!
//! The conversion is exact: the result is the `f64` nearest to `sec + nanosec / 10⁹` (the
//! decimal is formed and parsed, so there is one rounding, not two). A time written as
//! `sec = floor(t)`, `nanosec = round((t − sec)·10⁹)` from an `f64` unix time `t` therefore
//! reads back as `t` itself: near 2·10⁹ s the spacing of `f64` is 238 ns, far more than the
//! nanosecond lost.
//!
//! ```
//! use chronomap_rosbag::time::{stamp_seconds, nanos_seconds};
//!
//! assert_eq!(stamp_seconds(1_351_040_401, 900_000_095), Some(1_351_040_401.9));
//! assert_eq!(nanos_seconds(1_451_865_600_000_000_000), 1_451_865_600.0);
//! assert_eq!(stamp_seconds(-1, 0), None); // before 1970: not a time chronomap takes
//! assert_eq!(stamp_seconds(0, 1_000_000_000), None); // nanosec must be below 10⁹
//! ```

/// Seconds of a `builtin_interfaces/msg/Time` (`sec`, `nanosec`), if `sec >= 0` and
/// `nanosec < 10⁹`.
pub fn stamp_seconds(sec: i64, nanosec: u64) -> Option<f64> {
    if sec < 0 || nanosec >= 1_000_000_000 {
        return None;
    }
    decimal(sec as u64, nanosec)
}

/// Seconds of a time in nanoseconds (MCAP's log and publish times).
pub fn nanos_seconds(nanos: u64) -> f64 {
    decimal(nanos / 1_000_000_000, nanos % 1_000_000_000).unwrap_or(f64::NAN)
}

fn decimal(sec: u64, nanosec: u64) -> Option<f64> {
    if nanosec == 0 {
        // Exact whenever `sec` is (below 2⁵³); saves the formatting for whole seconds.
        if sec < (1 << 53) {
            return Some(sec as f64);
        }
    }
    format!("{sec}.{nanosec:09}").parse().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimal_times_survive_the_round_trip() {
        // Times of the bundled ATC tracks and greg door: written as sec + round(frac * 1e9).
        for t in [
            1_351_040_401.9f64,
            1_351_040_402.3,
            1_451_865_600.0,
            1_458_565_200.5,
            0.1,
        ] {
            let sec = t.floor();
            let nanosec = ((t - sec) * 1e9).round() as u64;
            assert_eq!(stamp_seconds(sec as i64, nanosec), Some(t), "{t}");
        }
        let expected: f64 = "1137834225.713386112".parse().unwrap();
        assert_eq!(nanos_seconds(1_137_834_225_713_386_112), expected);
    }
}
