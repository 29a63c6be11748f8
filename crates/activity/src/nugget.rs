//! How much of a model's residual spread belongs to the rate of a whole bin, and how much to
//! the noise of short observations: the *nugget* of the residuals' autocovariance over time.
//!
//! A robot sees a cell for seconds at a time, so one training rate is a glimpse: the cell's
//! rate over the whole hour (the *process*, what the ground truth of [Stüde 2024] §4.3.2
//! counts) plus the noise of counting a few people in a short window. Write a model's residual
//! in the log domain as
//!
//! ```text
//! (N1)  r_{c,d,h} = u_{c,d,h} + e_{c,d,h}
//! ```
//!
//! for cell `c`, day (period) `d` and phase bin `h`: `u` the deviation of the whole bin from the
//! model, `e` the glimpse's own noise. Glimpses in different bins are different observations,
//! so `e` is uncorrelated across bins, while a busy day keeps a cell busy for hours, so `u` is
//! correlated across neighbouring bins of one day. The autocovariance of the residuals at a lag
//! of `k ≥ 1` bins is therefore the process's alone,
//!
//! ```text
//! (N2)  C(k) = Cov(r_{c,d,h}, r_{c,d,h+k}) = Cov(u_{c,d,h}, u_{c,d,h+k}),   k ≥ 1,
//! ```
//!
//! and only at lag 0 does the glimpse noise add its variance: `C(0) = Var u + Var e`. The jump
//! of the covariance function at 0 is the *nugget effect* of geostatistics (Matheron 1962;
//! Cressie, *Statistics for Spatial Data*, 1993, §2.3.1). With the exponential covariance
//! model `C(k) = s² ρ^k` fitted to the lags 1..=[`NUGGET_LAGS`] (least squares on
//! `ln C(k) = ln s² + k ln ρ`),
//!
//! ```text
//! (N3)  Var u = s² = C(k → 0)   (the process's variance, the glimpse noise left out)
//! ```
//!
//! is the spread of a whole bin around the model. A white part of the process (hour-to-hour
//! changes uncorrelated even between neighbouring hours) is counted as glimpse noise: the
//! estimate is of the correlated part.

/// The largest lag, in phase bins, whose autocovariance the fit (N3) uses: 3 (further lags are
/// noisier and bend away from an exponential).
pub const NUGGET_LAGS: usize = 3;

/// The fewest pairs of bins at lag 1 for an estimate (with fewer, [`process_variance`] says
/// nothing).
pub const MIN_LAG_PAIRS: usize = 30;

/// One residual of a model on a training sample: where and when, and its weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BinResidual {
    /// Index of the cell.
    pub cell: usize,
    /// Index of the day (period) the sample is in.
    pub day: i64,
    /// Phase bin of the day (consecutive bins are neighbours in time).
    pub bin: usize,
    /// The residual `r` of (N1), in the model's domain.
    pub residual: f64,
    /// The sample's weight (1 for every sample alike).
    pub weight: f64,
}

/// What [`process_variance`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct ProcessVariance {
    /// `Var u = s²` of (N3).
    pub variance: f64,
    /// The correlation of the process from one bin to the next, `ρ` of (N3) (1 where no
    /// decay was found).
    pub correlation: f64,
    /// The autocovariance `C(k)` of (N2) for `k = 1..=NUGGET_LAGS` (`None`: no pair at that
    /// lag).
    pub lag_covariances: Vec<Option<f64>>,
    /// How many pairs of bins are at lag 1.
    pub lag1_pairs: usize,
}

/// The variance of the process (N3) from the residuals of a model on its training samples;
/// `None` when there are fewer than [`MIN_LAG_PAIRS`] pairs of neighbouring bins (of one cell
/// and one day), or the residuals of neighbouring bins are not positively correlated (nothing
/// tells the process from the noise then).
///
/// Samples that share a cell, day and bin are averaged first (the mean of their residuals is
/// one value of `r`); each pair counts with the weight of its earlier bin's first sample. The
/// result is at most the residuals' own weighted variance (the process cannot vary more than
/// what is observed).
pub fn process_variance(residuals: &[BinResidual]) -> Option<ProcessVariance> {
    // Mean residual per (cell, day, bin), in time order within each (cell, day).
    let mut order: Vec<&BinResidual> = residuals
        .iter()
        .filter(|r| r.residual.is_finite() && r.weight > 0.0)
        .collect();
    if order.is_empty() {
        return None;
    }
    order.sort_by_key(|a| (a.cell, a.day, a.bin));
    let mut bins: Vec<(usize, i64, usize, f64, f64)> = Vec::new(); // cell, day, bin, mean, weight
    let mut count = 0.0;
    for r in &order {
        match bins.last_mut() {
            Some(last) if (last.0, last.1, last.2) == (r.cell, r.day, r.bin) => {
                count += 1.0;
                last.3 += (r.residual - last.3) / count;
            }
            _ => {
                count = 1.0;
                bins.push((r.cell, r.day, r.bin, r.residual, r.weight));
            }
        }
    }
    let total_weight: f64 = order.iter().map(|r| r.weight).sum();
    let observed_variance = order
        .iter()
        .map(|r| r.weight * r.residual * r.residual)
        .sum::<f64>()
        / total_weight;

    let mut sums = [(0.0_f64, 0.0_f64); NUGGET_LAGS];
    let mut lag1_pairs = 0;
    for (i, a) in bins.iter().enumerate() {
        for b in bins[i + 1..].iter().take(NUGGET_LAGS) {
            if (a.0, a.1) != (b.0, b.1) {
                break;
            }
            let lag = b.2 - a.2;
            if lag > NUGGET_LAGS {
                break;
            }
            sums[lag - 1].0 += a.4 * a.3 * b.3;
            sums[lag - 1].1 += a.4;
            if lag == 1 {
                lag1_pairs += 1;
            }
        }
    }
    let lag_covariances: Vec<Option<f64>> = sums
        .iter()
        .map(|&(s, w)| (w > 0.0).then(|| s / w))
        .collect();
    let c1 = lag_covariances[0]?;
    if lag1_pairs < MIN_LAG_PAIRS || c1 <= 0.0 {
        return None;
    }
    // Least squares of ln C(k) on k over the positive lags of a run starting at lag 1.
    let points: Vec<(f64, f64)> = lag_covariances
        .iter()
        .enumerate()
        .map_while(|(k, c)| c.filter(|&c| c > 0.0).map(|c| ((k + 1) as f64, c.ln())))
        .collect();
    let (variance, correlation) = if points.len() < 2 {
        (c1, 1.0)
    } else {
        let n = points.len() as f64;
        let mean_k = points.iter().map(|p| p.0).sum::<f64>() / n;
        let mean_l = points.iter().map(|p| p.1).sum::<f64>() / n;
        let sxy: f64 = points.iter().map(|p| (p.0 - mean_k) * (p.1 - mean_l)).sum();
        let sxx: f64 = points.iter().map(|p| (p.0 - mean_k).powi(2)).sum();
        let slope = sxy / sxx;
        if slope >= 0.0 {
            // No decay over the lags: the flat covariance is the process's.
            (points.iter().map(|p| p.1.exp()).sum::<f64>() / n, 1.0)
        } else {
            ((mean_l - slope * mean_k).exp(), slope.exp())
        }
    };
    Some(ProcessVariance {
        variance: variance.min(observed_variance),
        correlation,
        lag_covariances,
        lag1_pairs,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(cell: usize, day: i64, bin: usize, residual: f64) -> BinResidual {
        BinResidual {
            cell,
            day,
            bin,
            residual,
            weight: 1.0,
        }
    }

    /// Hand-computed: one cell-day of residuals 1, 2, 4 in bins 0, 1, 2, repeated over 30
    /// days: C(1) = (1·2 + 2·4)/2 = 5, C(2) = 1·4 = 4; ln C on k = 1, 2 gives the line through
    /// (1, ln 5) and (2, ln 4): ρ = 4/5, s² = 5 / 0.8 = 6.25, capped at the observed variance
    /// (1 + 4 + 16)/3 = 7 (not reached).
    #[test]
    fn exponential_fit_through_two_lags_by_hand() {
        let mut rows = Vec::new();
        for day in 0..30 {
            for (bin, r) in [1.0, 2.0, 4.0].into_iter().enumerate() {
                rows.push(at(0, day, bin, r));
            }
        }
        let p = process_variance(&rows).unwrap();
        assert_eq!(p.lag1_pairs, 60);
        assert!((p.lag_covariances[0].unwrap() - 5.0).abs() < 1e-12);
        assert!((p.lag_covariances[1].unwrap() - 4.0).abs() < 1e-12);
        assert_eq!(p.lag_covariances[2], None);
        assert!((p.correlation - 0.8).abs() < 1e-12);
        assert!((p.variance - 6.25).abs() < 1e-12, "{}", p.variance);
    }

    /// Pairs never cross a cell or a day, samples of one bin are averaged, and too few pairs
    /// or uncorrelated neighbours give no estimate.
    #[test]
    fn pairs_stay_inside_a_cell_and_day() {
        // Bins 0 and 1 of different days or cells are not neighbours.
        let rows: Vec<BinResidual> = (0..40)
            .flat_map(|d| [at(0, d, 0, 1.0), at(1, d, 1, 1.0), at(0, d + 100, 1, 1.0)])
            .collect();
        assert_eq!(process_variance(&rows), None);
        // Two samples in one bin: their mean (0) is the bin's residual, so C(1) = 0.
        let rows: Vec<BinResidual> = (0..40)
            .flat_map(|d| [at(0, d, 0, 1.0), at(0, d, 0, -1.0), at(0, d, 1, 3.0)])
            .collect();
        assert_eq!(process_variance(&rows), None);
        // 29 pairs are too few.
        let rows: Vec<BinResidual> = (0..29)
            .flat_map(|d| [at(0, d, 0, 1.0), at(0, d, 1, 1.0)])
            .collect();
        assert_eq!(process_variance(&rows), None);
        let rows: Vec<BinResidual> = (0..30)
            .flat_map(|d| [at(0, d, 0, 1.0), at(0, d, 1, 1.0)])
            .collect();
        assert_eq!(process_variance(&rows).unwrap().variance, 1.0);
    }

    /// The known answer of (N1): an AR(1) process over 12 bins a day (variance 0.25,
    /// correlation 0.8 from bin to bin) plus white noise of variance 0.64. The estimate is
    /// the process's variance, not the residuals' 0.89.
    #[test]
    fn recovers_the_process_under_white_noise() {
        let mut rng = chronomap_core::rng::Xoshiro256StarStar::seed_from_u64(3);
        let (var_u, rho, var_e) = (0.25_f64, 0.8_f64, 0.64_f64);
        let mut rows = Vec::new();
        for cell in 0..50 {
            for day in 0..100 {
                let mut u = var_u.sqrt() * rng.standard_normal();
                for bin in 0..12 {
                    if bin > 0 {
                        u = rho * u + (var_u * (1.0 - rho * rho)).sqrt() * rng.standard_normal();
                    }
                    let e = var_e.sqrt() * rng.standard_normal();
                    rows.push(at(cell, day, bin, u + e));
                }
            }
        }
        let p = process_variance(&rows).unwrap();
        assert!((p.variance - var_u).abs() < 0.02, "{p:?}");
        assert!((p.correlation - rho).abs() < 0.05, "{p:?}");
    }
}
