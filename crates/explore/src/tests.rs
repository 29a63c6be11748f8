use super::*;
use chronomap_core::{FremenModel, MeanModel};

/// One state per location, observed every minute from time 0; the locations are named `a`,
/// `b`, `c`, … in order.
fn minute_world(truth: Vec<Vec<u8>>) -> World {
    let names = (b'a'..)
        .take(truth.len())
        .map(|c| char::from(c).to_string())
        .collect();
    World::one_state_per_location(0.0, 60.0, truth, names)
}

fn planner(strategy: Strategy, ratio: f64) -> Planner {
    Planner {
        strategy,
        ratio,
        next_location: 0,
        slot_counter: 0,
    }
}

#[test]
fn greedy_takes_the_most_informative_location_in_the_most_informative_slots() {
    // Two locations, eight slots; e = 0.25 keeps two slots.
    let mut information = vec![vec![0.1; 8], vec![0.2; 8]];
    information[0][3] = 0.9; // slot 3: location 0 is best, and the best slot overall
    information[1][6] = 0.7; // slot 6: location 1, second best
    let mut rng = Xoshiro256StarStar::seed_from_u64(1);
    let plan = planner(Strategy::Greedy, 0.25).plan(&information, 8, &mut rng);
    let expected: Vec<Option<usize>> = (0..8)
        .map(|s| match s {
            3 => Some(0),
            6 => Some(1),
            _ => None,
        })
        .collect();
    assert_eq!(plan, expected);
}

#[test]
fn round_robin_visits_every_location_equally_at_exactly_the_ratio() {
    let information = vec![vec![0.0; 144]; 7];
    let mut rr = planner(Strategy::RoundRobin, 0.3);
    let mut rng = Xoshiro256StarStar::seed_from_u64(0);
    let mut visits = [0usize; 7];
    let mut explored = 0;
    for _ in 0..10 {
        for l in rr.plan(&information, 144, &mut rng).into_iter().flatten() {
            visits[l] += 1;
            explored += 1;
        }
    }
    assert_eq!(explored, (0.3 * 1440.0f64).floor() as usize);
    let (min, max) = (visits.iter().min().unwrap(), visits.iter().max().unwrap());
    assert!(max - min <= 1, "{visits:?}");
}

#[test]
fn random_and_monte_carlo_respect_the_ratio_on_average() {
    let mut rng = Xoshiro256StarStar::seed_from_u64(7);
    // Uneven information: location 2 is the most uncertain, at noon.
    let information: Vec<Vec<f64>> = (0..4)
        .map(|l| {
            (0..144)
                .map(|s| 0.1 * (l as f64 + 1.0) * (1.0 + ((s as f64 - 72.0) / 40.0).cos()))
                .collect()
        })
        .collect();
    for strategy in [Strategy::Random, Strategy::MonteCarlo { iota: 0.01 }] {
        for e in [0.1, 0.5, 0.9] {
            let mut p = planner(strategy, e);
            let mut explored = 0usize;
            let mut per_location = [0usize; 4];
            let days = 400;
            for _ in 0..days {
                for l in p.plan(&information, 144, &mut rng).into_iter().flatten() {
                    explored += 1;
                    per_location[l] += 1;
                }
            }
            let fraction = explored as f64 / (days * 144) as f64;
            assert!(
                (fraction - e).abs() < 0.01,
                "{strategy:?} e = {e}: explored {fraction}"
            );
            if strategy == Strategy::Random {
                assert!(
                    per_location
                        .iter()
                        .all(|&v| (v as f64 / explored as f64 - 0.25).abs() < 0.02),
                    "{per_location:?}"
                );
            } else {
                // Monte-Carlo visits in proportion to information: location 3 about 4x location 0.
                let ratio = per_location[3] as f64 / per_location[0] as f64;
                assert!((3.0..5.0).contains(&ratio), "{per_location:?}");
            }
        }
    }
}

#[test]
fn novelty_values_a_location_that_surprised_the_long_term_model() {
    // Location 0's state was always 0 for a week; location 1's always 1.
    let world = minute_world(vec![vec![0; 20_160], vec![1; 20_160]]);
    let mut long_term: Vec<Box<dyn DailyModel>> = Vec::new();
    for state in 0..2u8 {
        let mut m = FremenModel::with_order(2);
        let times: Vec<f64> = (0..10_080).map(|k| 60.0 * k as f64).collect();
        m.observe(&times, &vec![f64::from(state); times.len()])
            .unwrap();
        long_term.push(Box::new(m));
    }
    // Just now (t = 7 days), the robot saw state 0 occupied for ten minutes.
    let now = 7.0 * 86_400.0;
    let mut short_term = vec![MarkovModel::new(), MarkovModel::new()];
    short_term[0]
        .observe(&[now - 86_400.0, now - 600.0, now - 60.0], &[0.0, 1.0, 1.0])
        .unwrap();
    short_term[1].observe(&[now - 600.0], &[1.0]).unwrap();
    // Location 0's short-term model now expects occupancy that the long-term model rules out:
    // re-observing it promises much more than eq. (10) says.
    let surprise = expected_information(&world, 0, &long_term, &short_term, 10_080, 10);
    assert!(surprise > 1.0, "{surprise}");
    // Location 1 was seen as the long-term model expects: little information either way.
    let calm = expected_information(&world, 1, &long_term, &short_term, 10_080, 10);
    assert!(calm < 0.05, "{calm}");
}

#[test]
fn model_error_of_eq_2_on_a_known_world() {
    // Two states observed at one location each, for two days at one-minute steps: state 0 is
    // always 1, state 1 always 0. With e = 1/144 the robot observes one slot a day (round
    // robin: location 0 on day 1, location 1 on day 2). Day 1: state 0 was observed, so its mean
    // model says 1 (all right); state 1 has no data, p = 0.5, estimated 0 (right): error 0.
    let world = minute_world(vec![vec![1; 2880], vec![0; 2880]]);
    let config = ExploreConfig {
        ratio: 1.0 / 144.0,
        ..ExploreConfig::default()
    };
    let mean: &dyn Fn() -> Box<dyn DailyModel> = &|| Box::new(MeanModel::new());
    let result = explore(&world, Strategy::RoundRobin, mean, &config).unwrap();
    assert_eq!(result.daily_error_percent, vec![0.0, 0.0]);
    assert_eq!(result.visits, vec![1, 1]);
    // Flip state 1 to always 1: on day 1 it is unobserved and estimated 0 (p = 0.5 is not
    // > 0.5) — wrong at all 1440 steps of 2 × 1440 state-steps: 50 %. Day 2 it is observed
    // for 10 minutes and its mean model says 1: right.
    let world = minute_world(vec![vec![1; 2880], vec![1; 2880]]);
    let result = explore(&world, Strategy::RoundRobin, mean, &config).unwrap();
    assert_eq!(result.daily_error_percent, vec![50.0, 0.0]);
    assert_eq!(result.error_percent, 25.0);
}

#[test]
fn runs_are_repeatable_and_bad_parameters_are_errors() {
    let truth: Vec<Vec<u8>> = (0..3)
        .map(|i| {
            (0..3 * 1440)
                .map(|k| u8::from((k / 60 + i) % 5 == 0))
                .collect()
        })
        .collect();
    let world = minute_world(truth);
    let fremen: &dyn Fn() -> Box<dyn DailyModel> =
        &|| Box::new(AutoOrder::new(FremenModel::with_order(0)));
    let config = ExploreConfig {
        seed: 42,
        trace_days: 1,
        ..ExploreConfig::default()
    };
    for strategy in Strategy::all() {
        let a = explore(&world, strategy, fremen, &config).unwrap();
        let b = explore(&world, strategy, fremen, &config).unwrap();
        assert_eq!(a, b, "{strategy:?}");
        assert_eq!(a.trace.slot_times.len(), 144);
    }
    let bad = |c: ExploreConfig| explore(&world, Strategy::Random, fremen, &c).is_err();
    assert!(bad(ExploreConfig {
        ratio: 0.0,
        ..config
    }));
    assert!(bad(ExploreConfig {
        ratio: 1.5,
        ..config
    }));
    assert!(bad(ExploreConfig {
        slot_secs: 90.0,
        ..config
    }));
    let mut broken = world.clone();
    broken.truth[1].pop();
    assert!(explore(&broken, Strategy::Random, fremen, &config).is_err());
}
