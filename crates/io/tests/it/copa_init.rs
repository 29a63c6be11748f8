//! CoPA-Map's period initialisation ([Stüde 2024] §4.2.4, Algorithm 4.1) on the bundled ATC grid,
//! training days only (`t < 96`, as `chronomap activity eval --split-at 96`). The numbers
//! asserted are the ones measured with the defaults (Λ = 10, ψ_max = 10, σ²_max = 0.95, 5 m ×
//! 5 m × 1 h regions, candidate periods 2 ..= 84 h in steps of 0.05).

use chronomap_activity::{RateSamples, SpectralInitConfig, initial_periods};
use chronomap_io::read_rate_samples;
use chronomap_testutil::data_path;

fn atc_training() -> RateSamples {
    let path = data_path("atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz");
    read_rate_samples(path).unwrap().split_at(96.0).0
}

fn near(values: &[f64], target: f64) -> bool {
    values.iter().any(|v| (v - target).abs() <= 0.2)
}

#[test]
fn atc_series_have_the_day_and_half_day_but_the_clusters_merge_them() {
    let train = atc_training();
    let init = initial_periods(&train, None, &SpectralInitConfig::default()).unwrap();
    // Exactly ten regions have the 10 hourly bins five folds need: all are drawn.
    assert_eq!(init.per_series.len(), 10);
    assert!(init.per_series.iter().all(|s| s.bins == 96));
    // Every series with a component has one within 0.2 h of the 12 h day; 7 of the 10 also
    // have the 6 h half day (the dissertation's "two periods of twelve and six hours").
    let periodic: Vec<_> = init
        .per_series
        .iter()
        .filter(|s| s.fit.components > 0)
        .collect();
    assert_eq!(periodic.len(), 9);
    assert!(periodic.iter().all(|s| near(&s.fit.periods, 12.0)));
    let half_day = periodic
        .iter()
        .filter(|s| near(&s.fit.periods, 6.0))
        .count();
    assert_eq!(half_day, 7);
    // b_l: 5, 5, 1, 5, 4, 2, 1, 2, 0, 4 → ψ = ⌊2.9⌋ = 2. The series also carry 24 h (two
    // recorded days) and longer periods, so the 2-means of the periods puts 6 h and 12 h in
    // one cluster (11.1 h) and the long periods in the other (30.5 h).
    let total: usize = init.per_series.iter().map(|s| s.fit.components).sum();
    assert_eq!(total, 29);
    assert_eq!(init.psi, 2);
    assert_eq!(init.none, None);
    assert!((init.periods[0] - 11.12).abs() < 0.01, "{:?}", init.periods);
    assert!((init.periods[1] - 30.45).abs() < 0.01, "{:?}", init.periods);
    assert_eq!(init.variances[0], 0.95);
    assert!(
        (init.variances[1] - 0.264).abs() < 0.001,
        "{:?}",
        init.variances
    );
    // Every seed draws the same ten regions (in another order): the same periods.
    let other = initial_periods(
        &train,
        None,
        &SpectralInitConfig {
            seed: 3,
            ..SpectralInitConfig::default()
        },
    )
    .unwrap();
    assert_ne!(other.per_series, init.per_series);
    assert!((other.periods[0] - init.periods[0]).abs() < 1e-9);
}
