//! The generating processes: a cell's occupied frames on a day, and its truth at a time.

use super::layout::{Cell, TAG_NOISE, TAG_PERIODIC};
use super::{DAY_SECS, OfficeWorkload, day_of, is_weekday};
use chronomap_core::rng::{Xoshiro256StarStar, derive_seed};

/// Longest noise burst, frames (bursts last 1 to this many frames, uniformly).
pub(crate) const MAX_BURST_FRAMES: u64 = 6;

/// Noise profiles: `(end hour, multiplier)` pieces covering 0–24 h.
const WEEKDAY_PROFILE: [(f64, f64); 5] = [
    (6.0, 0.01),
    (8.0, 0.2),
    (18.0, 1.0),
    (22.0, 0.2),
    (24.0, 0.01),
];
const WEEKEND_PROFILE: [(f64, f64); 4] = [(8.0, 0.01), (18.0, 0.1), (22.0, 0.05), (24.0, 0.01)];

fn profile(day: i64) -> &'static [(f64, f64)] {
    if is_weekday(day) {
        &WEEKDAY_PROFILE
    } else {
        &WEEKEND_PROFILE
    }
}

/// `∫_0^hours m`, in multiplier-weighted hours.
fn cumulative(profile: &[(f64, f64)], hours: f64) -> f64 {
    let mut acc = 0.0;
    let mut from = 0.0;
    for &(to, m) in profile {
        if hours <= from {
            break;
        }
        acc += m * (hours.min(to) - from);
        from = to;
    }
    acc
}

/// The hour `x` at which `cumulative(profile, x) = weighted` (24 beyond the day's total).
fn inverse_cumulative(profile: &[(f64, f64)], mut weighted: f64) -> f64 {
    let mut from = 0.0;
    for &(to, m) in profile {
        let piece = m * (to - from);
        if weighted < piece {
            return from + weighted / m;
        }
        weighted -= piece;
        from = to;
    }
    24.0
}

/// `P(J <= x)` for `J` uniform in `[−w, w]`.
#[inline]
fn jitter_cdf(x: f64, w: f64) -> f64 {
    ((x + w) / (2.0 * w)).clamp(0.0, 1.0)
}

/// Appends `[a, b)` to sorted intervals, merging it with the last one if they touch.
#[inline]
fn push_interval(out: &mut Vec<(u64, u64)>, a: u64, b: u64) {
    if a >= b {
        return;
    }
    if let Some(last) = out.last_mut()
        && a <= last.1
    {
        last.1 = last.1.max(b);
        return;
    }
    out.push((a, b));
}

impl OfficeWorkload {
    /// The occupied frames of dynamic cell `cell` on calendar day `day`, whose frames are
    /// `lo..hi`, as sorted, disjoint, non-touching intervals appended to `out` (cleared
    /// first). Depends only on the seed, the cell's descriptor and the day.
    pub(crate) fn day_intervals(
        &self,
        cell: usize,
        day: i64,
        lo: u64,
        hi: u64,
        out: &mut Vec<(u64, u64)>,
    ) {
        out.clear();
        let day0 = day as f64 * DAY_SECS;
        let clip = |f: u64| f.clamp(lo, hi);
        match self.layout.cells[cell] {
            Cell::Free | Cell::Occupied => {}
            Cell::Periodic {
                process,
                trim_start,
                trim_end,
            } => {
                let p = &self.layout.periodic[process as usize];
                let mut rng = Xoshiro256StarStar::seed_from_u64(derive_seed(
                    self.config.seed,
                    TAG_PERIODIC,
                    u64::from(process),
                    day as u64,
                ));
                let skipped = rng.bernoulli(p.skip);
                let jitter_start = rng.uniform(-p.jitter, p.jitter);
                let jitter_end = rng.uniform(-p.jitter, p.jitter);
                let happens = (!p.weekdays_only || is_weekday(day)) && !skipped;
                let a =
                    clip(self.frame_ceil(day0 + p.start + f64::from(trim_start) + jitter_start));
                let b = clip(self.frame_ceil(day0 + p.end - f64::from(trim_end) + jitter_end));
                match (p.inverted, happens) {
                    (false, true) => push_interval(out, a, b),
                    (false, false) => {}
                    (true, false) => push_interval(out, lo, hi),
                    (true, true) => {
                        push_interval(out, lo, a);
                        push_interval(out, b.max(a), hi);
                    }
                }
            }
            Cell::Noise { rate } => {
                let rate = f64::from(rate);
                let profile = profile(day);
                let expected = rate * cumulative(profile, 24.0);
                let mut rng = Xoshiro256StarStar::seed_from_u64(derive_seed(
                    self.config.seed,
                    TAG_NOISE,
                    cell as u64,
                    day as u64,
                ));
                // Arrivals of a unit-rate Poisson process in "expected bursts", mapped to
                // times through the inverse of the cumulative intensity: sorted times.
                let mut s = rng.exp1();
                while s < expected {
                    let hour = inverse_cumulative(profile, s / rate);
                    let a = clip(self.frame_ceil(day0 + hour * 3600.0));
                    let len = rng.int_in(1, MAX_BURST_FRAMES);
                    push_interval(out, a, clip(a + len));
                    s += rng.exp1();
                }
            }
            Cell::Persistent { step } => {
                let step = &self.layout.steps[step as usize];
                let k = clip(self.frame_ceil(step.time));
                if step.initially_occupied {
                    push_interval(out, lo, k);
                } else {
                    push_interval(out, k, hi);
                }
            }
        }
    }

    /// Ground truth of `cell` (which exists) at finite time `t`.
    pub(crate) fn truth(&self, cell: usize, t: f64) -> f64 {
        let day = day_of(t);
        let day0 = day as f64 * DAY_SECS;
        match self.layout.cells[cell] {
            Cell::Free => 0.0,
            Cell::Occupied => 1.0,
            Cell::Periodic {
                process,
                trim_start,
                trim_end,
            } => {
                let p = &self.layout.periodic[process as usize];
                let tod = t - day0;
                let inside = if !p.weekdays_only || is_weekday(day) {
                    (1.0 - p.skip)
                        * jitter_cdf(tod - p.start - f64::from(trim_start), p.jitter)
                        * (1.0 - jitter_cdf(tod - p.end + f64::from(trim_end), p.jitter))
                } else {
                    0.0
                };
                if p.inverted { 1.0 - inside } else { inside }
            }
            Cell::Noise { rate } => {
                let rate = f64::from(rate);
                let profile = profile(day);
                let fs = self.config.frame_secs;
                let mut expected = 0.0;
                for k in 0..MAX_BURST_FRAMES {
                    let to = t - k as f64 * fs;
                    if to <= day0 {
                        break;
                    }
                    let from = (to - fs).max(day0);
                    let bursts = rate
                        * (cumulative(profile, (to - day0) / 3600.0)
                            - cumulative(profile, (from - day0) / 3600.0));
                    expected += bursts * (MAX_BURST_FRAMES - k) as f64 / MAX_BURST_FRAMES as f64;
                }
                1.0 - (-expected).exp()
            }
            Cell::Persistent { step } => {
                let step = &self.layout.steps[step as usize];
                if (t < step.time) == step.initially_occupied {
                    1.0
                } else {
                    0.0
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_cumulative_and_inverse_agree() {
        assert!((cumulative(&WEEKDAY_PROFILE, 24.0) - 11.28).abs() < 1e-12);
        assert!((cumulative(&WEEKEND_PROFILE, 24.0) - 1.3).abs() < 1e-12);
        for p in [&WEEKDAY_PROFILE[..], &WEEKEND_PROFILE[..]] {
            for i in 0..=240 {
                let h = f64::from(i) * 0.1;
                let back = inverse_cumulative(p, cumulative(p, h));
                assert!((back - h).abs() < 1e-9 || h >= 24.0, "{h} -> {back}");
            }
        }
    }

    #[test]
    fn intervals_merge() {
        let mut v = Vec::new();
        push_interval(&mut v, 3, 5);
        push_interval(&mut v, 5, 7);
        push_interval(&mut v, 6, 6);
        push_interval(&mut v, 9, 10);
        push_interval(&mut v, 9, 12);
        assert_eq!(v, [(3, 7), (9, 12)]);
    }
}
