//! Human-readable formatting of times, durations, periods and tables: the calendar is
//! `chronomap_core::time`, the tables and units `chronomap_app::report`, shared with the other faces.

/// Unix time of an ISO 8601 date-time ([`chronomap_core::time::parse_iso8601`]), the error
/// as the message clap shows.
pub fn parse_iso8601(text: &str) -> Result<f64, String> {
    chronomap_core::time::parse_iso8601(text).map_err(|e| e.to_string())
}

pub use chronomap_app::report::{Table, duration, time};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_known_times() {
        assert_eq!(time(1_451_865_600.0), "2016-01-04 00:00 UTC");
        assert_eq!(
            time(1_458_518_400.0 + 3600.0 * 13.5),
            "2016-03-21 13:30 UTC"
        );
        assert_eq!(time(691_200.0), "day 9 00:00 (+691200 s)");
    }

    #[test]
    fn times_parse_as_the_core_parses_them() {
        assert_eq!(parse_iso8601("2014-07-21T09:30:00Z"), Ok(1_405_935_000.0));
        let e = parse_iso8601("2014-02-30").unwrap_err();
        assert!(
            e.contains("ISO 8601") && e.contains("day out of range"),
            "{e}"
        );
    }
}
