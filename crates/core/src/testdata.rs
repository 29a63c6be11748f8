//! Synthetic series shared by the unit tests.

use crate::periods::cycle_fraction;

/// A door open 8:00–18:00 on weekdays, observed at irregular times (5–25 min apart, every
/// 97th instant observed twice) for three weeks from Monday 2016-01-04 00:00 UTC.
pub(crate) fn door_weeks() -> (Vec<f64>, Vec<f64>) {
    let start = 1_451_865_600.0;
    let (mut times, mut values) = (Vec::new(), Vec::new());
    let (mut t, mut i) = (start, 0u64);
    while t < start + 21.0 * 86_400.0 {
        let day = ((t - start) / 86_400.0) as u64 % 7;
        let hour = cycle_fraction(t, 86_400.0) * 24.0;
        let open = day < 5 && (8.0..18.0).contains(&hour);
        times.push(t);
        values.push(if open { 1.0 } else { 0.0 });
        i += 1;
        if i % 97 != 0 {
            t += 300.0 + ((i * 2_654_435_761) % 1200) as f64;
        }
    }
    (times, values)
}

/// A binary series sampled every 15 minutes for `days` days from time 0: 1 where `on(t)`.
pub(crate) fn quarter_hours(days: u32, on: impl Fn(f64) -> bool) -> (Vec<f64>, Vec<f64>) {
    let times: Vec<f64> = (0..days * 96).map(|i| 900.0 * f64::from(i)).collect();
    let values = times.iter().map(|&t| f64::from(u8::from(on(t)))).collect();
    (times, values)
}
