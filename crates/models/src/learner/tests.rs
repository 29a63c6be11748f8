use super::*;
use chronomap_core::conformance::check_temporal_model;
use chronomap_core::periods::{DAY, WEEK};

/// A door open 9:00–17:00 on weekdays, seen every 10 minutes for `weeks` weeks, each
/// observation flipped with probability 1/7 (binary and uniformly sampled, so that every
/// spec, `fft` included, can be fitted).
fn office(weeks: usize) -> (Vec<f64>, Vec<f64>) {
    let mut rng = chronomap_core::rng::Xoshiro256StarStar::seed_from_u64(5);
    let times: Vec<f64> = (0..weeks * 7 * 144).map(|i| 600.0 * i as f64).collect();
    let values = times
        .iter()
        .map(|&t| {
            let hour = (t % DAY) / 3600.0;
            let weekday = (t % WEEK) / DAY < 5.0;
            let open = weekday && (9.0..17.0).contains(&hour);
            f64::from(u8::from(open != rng.bernoulli(1.0 / 7.0)))
        })
        .collect();
    (times, values)
}

fn spec(text: &str) -> ModelSpec {
    text.parse().unwrap()
}

fn bytes<T: Serialize>(value: &T) -> Vec<u8> {
    postcard::to_allocvec(value).unwrap()
}

/// Times at which predictions are compared: a week after `from`, every 17 minutes.
fn probes(from: f64) -> Vec<f64> {
    (0..600).map(|i| from + 1020.0 * i as f64).collect()
}

fn same_predictions(a: &impl TemporalModel, b: &impl TemporalModel, times: &[f64]) {
    for &t in times {
        assert_eq!(a.predict(t).to_bits(), b.predict(t).to_bits(), "at {t}");
    }
}

#[test]
fn online_specs_are_their_online_model_bit_for_bit() {
    let (times, values) = office(2);
    for text in [
        "fremen:2",
        "hist:24",
        "persistence:1",
        "pergam:2",
        "stm",
        "mean",
    ] {
        let mut learner = spec(text).learner(DEFAULT_KEEP).unwrap();
        let mut model = spec(text).online_model().unwrap();
        assert!(matches!(learner, Learner::Online(_)), "{text}");
        assert!(!learner.is_refitting() && learner.keep().is_none());
        for (t, v) in times.chunks(500).zip(values.chunks(500)) {
            learner.observe(t, v).unwrap();
            model.observe(t, v).unwrap();
        }
        same_predictions(&learner, &model, &probes(2.0 * WEEK));
        assert_eq!(learner.span(), model.span());
        // The serialised learner is the variant index 0, then the model as before.
        let mut expected = vec![0u8];
        expected.extend(bytes(&model));
        assert_eq!(bytes(&learner), expected, "{text}");
        // Nothing to refit, never due, no kept observations.
        assert_eq!(learner.kept(), 0);
        assert!(!learner.is_due(&RefitPolicy::default()));
        assert!(learner.refit_job().is_none());
        assert!(!learner.refit(&FitOptions::default()).unwrap());
        assert_eq!(learner.spec(), spec(text));
    }
    // Errors of online specs are those of `online_model`.
    let error = spec("fremen:85").learner(DEFAULT_KEEP).unwrap_err();
    assert!(error.to_string().contains("order 85 is above"), "{error}");
    let error = spec("auto").learner(0).unwrap_err().to_string();
    assert!(
        error.contains("keep") && error.contains("at least 1"),
        "{error}"
    );
}

#[test]
fn a_refit_is_the_offline_fit_of_the_kept_observations_for_every_offline_spec() {
    let (times, values) = office(3);
    let options = FitOptions::default();
    let mut specs = vec![
        "auto",
        "fremen:auto",
        "persistence:auto",
        "pergam:auto",
        "fft:auto",
        "fft:4",
    ];
    if cfg!(feature = "hypertime") {
        specs.push("hyt-km");
    }
    for text in specs {
        let mut learner = spec(text).learner(DEFAULT_KEEP).unwrap();
        assert!(learner.is_refitting(), "{text}");
        for (t, v) in times.chunks(1000).zip(values.chunks(1000)) {
            learner.observe(t, v).unwrap();
        }
        // Before the first fit: the prior of a model that knows nothing.
        assert!(learner.model().is_none() && learner.last_fit().is_none());
        assert_eq!(learner.predict(1e6), 0.5);
        assert_eq!(learner.predict_many(&[1.0, 2.0]), [0.5, 0.5]);
        assert_eq!(learner.kept(), times.len());
        assert!(learner.refit(&options).unwrap(), "{text}");
        let fitted = spec(text).fit(&times, &values, &options).unwrap();
        assert_eq!(
            bytes(learner.model().unwrap()),
            bytes(&fitted.model),
            "{text}"
        );
        let record = learner.last_fit().unwrap();
        assert_eq!(record.selection, fitted.selection, "{text}");
        assert_eq!(
            (record.through, record.observations),
            (times.len() as u64, times.len() as u64)
        );
        assert_eq!(
            (record.first_time, record.last_time),
            (times[0], times[times.len() - 1])
        );
        same_predictions(&learner, &fitted.model, &probes(3.0 * WEEK));
        assert_eq!(learner.spec(), spec(text));
        assert_eq!(learner.since_fit(), (0, 0.0));
    }
}

#[test]
fn the_fit_goes_on_learning_online_until_the_next_refit() {
    let (times, values) = office(4);
    let options = FitOptions::default();
    let cut = 3 * 7 * 144;
    for text in ["auto", "fremen:auto", "fft:auto"] {
        let mut learner = spec(text).learner(DEFAULT_KEEP).unwrap();
        learner.observe(&times[..cut], &values[..cut]).unwrap();
        learner.refit(&options).unwrap();
        for (t, v) in times[cut..].chunks(333).zip(values[cut..].chunks(333)) {
            learner.observe(t, v).unwrap();
        }
        let mut expected = spec(text)
            .fit(&times[..cut], &values[..cut], &options)
            .unwrap()
            .model;
        if text != "fft:auto" {
            // The members of `auto` and the chosen FreMEn order learn online.
            expected.observe(&times[cut..], &values[cut..]).unwrap();
        }
        // FFT FreMEn stays as fitted.
        assert_eq!(bytes(learner.model().unwrap()), bytes(&expected), "{text}");
        assert_eq!(learner.span().count, times.len() as u64);
        assert_eq!(
            learner.since_fit(),
            (
                (times.len() - cut) as u64,
                times[times.len() - 1] - times[cut - 1]
            )
        );
        // The next refit is the fit of everything.
        learner.refit(&options).unwrap();
        let all = spec(text).fit(&times, &values, &options).unwrap().model;
        assert_eq!(bytes(learner.model().unwrap()), bytes(&all), "{text}");
    }
}

#[test]
fn a_job_run_elsewhere_installs_and_catches_up_with_what_arrived_meanwhile() {
    let (times, values) = office(3);
    let options = FitOptions::default();
    let cut = 2 * 7 * 144;
    let mut learner = spec("auto").learner(DEFAULT_KEEP).unwrap();
    learner.observe(&times[..cut], &values[..cut]).unwrap();
    let job = learner.refit_job().unwrap();
    assert_eq!((job.through(), job.observations()), (cut as u64, cut));
    // The learner goes on observing while the job runs.
    learner.observe(&times[cut..], &values[cut..]).unwrap();
    let refit = std::thread::spawn(move || job.run(&FitOptions::default()))
        .join()
        .unwrap()
        .unwrap();
    learner.install(refit.clone()).unwrap();
    let mut expected = spec("auto")
        .fit(&times[..cut], &values[..cut], &options)
        .unwrap()
        .model;
    expected.observe(&times[cut..], &values[cut..]).unwrap();
    assert_eq!(bytes(learner.model().unwrap()), bytes(&expected));
    // The same fit again is no change; an older one is refused; so is a fit of another
    // spec or of other observations, and the learner is then unchanged.
    let before = bytes(&learner);
    learner.install(refit.clone()).unwrap();
    assert_eq!(bytes(&learner), before);
    learner.refit(&options).unwrap();
    let fitted = bytes(&learner);
    assert_eq!(
        learner.install(refit.clone()),
        Err(RefitError::Superseded {
            through: cut as u64,
            current: times.len() as u64
        })
    );
    let mut other = refit.clone();
    other.spec = spec("fremen:auto");
    assert!(matches!(
        learner.install(other),
        Err(RefitError::WrongSpec { .. })
    ));
    let mut shifted = refit.clone();
    shifted.record.through = times.len() as u64 + 1;
    assert!(matches!(
        learner.install(shifted),
        Err(RefitError::NotThisLearner { .. })
    ));
    let mut moved = refit;
    moved.record.through = times.len() as u64;
    moved.record.last_time += 1.0;
    assert!(matches!(
        learner.install(moved),
        Err(RefitError::NotThisLearner { .. })
    ));
    assert_eq!(bytes(&learner), fitted);
    // Online learners refuse fits.
    let mut online = spec("fremen:2").learner(DEFAULT_KEEP).unwrap();
    let job = {
        let mut l = spec("fremen:auto").learner(DEFAULT_KEEP).unwrap();
        l.observe(&times, &values).unwrap();
        l.refit_job().unwrap()
    };
    assert!(matches!(
        online.install(job.run(&options).unwrap()),
        Err(RefitError::Online { .. })
    ));
}

#[test]
fn observations_are_validated_as_every_model_validates_them() {
    let (times, values) = office(1);
    let mut learner = spec("auto").learner(DEFAULT_KEEP).unwrap();
    learner.observe(&times[..100], &values[..100]).unwrap();
    let last = times[99];
    let before = bytes(&learner);
    for (t, v, expected) in [
        (
            vec![last + 1.0, last - 1.0],
            vec![0.0, 1.0],
            ObservationError::TimeNotIncreasing {
                index: 1,
                time: last - 1.0,
                previous: last + 1.0,
            },
        ),
        (
            vec![last + 1.0, f64::NAN],
            vec![0.0, 1.0],
            ObservationError::NonFiniteTime {
                index: 1,
                time: f64::NAN,
            },
        ),
        (
            vec![last, last + 5.0],
            vec![0.5, 1.5],
            ObservationError::ValueOutOfRange {
                index: 1,
                value: 1.5,
            },
        ),
        (
            vec![last + 1.0],
            vec![0.0, 1.0],
            ObservationError::LengthMismatch {
                times: 1,
                values: 2,
            },
        ),
    ] {
        let error = learner.observe(&t, &v).unwrap_err();
        // NaN != NaN: compare the messages.
        assert_eq!(error.to_string(), expected.to_string());
        assert_eq!(bytes(&learner), before, "a refused batch changes nothing");
    }
    // The same after a fit (the fitted model validates too).
    learner.refit(&FitOptions::default()).unwrap();
    let before = bytes(&learner);
    assert!(learner.observe(&[last - 1.0], &[0.0]).is_err());
    assert_eq!(bytes(&learner), before);
    // Equal times are allowed, as everywhere.
    learner.observe(&[last, last], &[1.0, 0.0]).unwrap();
    assert_eq!(learner.span().count, 102);
}

#[test]
fn at_most_keep_observations_are_kept_the_oldest_dropped() {
    let (times, values) = office(2);
    let options = FitOptions::default();
    // Across chunk boundaries (4096) and with batches of several sizes.
    for (keep, batch) in [(1000, 1), (1000, 700), (CHUNK + 5, 333), (2 * CHUNK, 4097)] {
        let mut learner = spec("fremen:auto").learner(keep).unwrap();
        let mut fed = 0;
        for (t, v) in times.chunks(batch).zip(values.chunks(batch)) {
            learner.observe(t, v).unwrap();
            fed += t.len();
            assert_eq!(learner.kept(), fed.min(keep));
        }
        assert_eq!(learner.span().count, times.len() as u64);
        assert_eq!(learner.keep(), Some(keep));
        learner.refit(&options).unwrap();
        let start = times.len().saturating_sub(keep);
        let fitted = spec("fremen:auto")
            .fit(&times[start..], &values[start..], &options)
            .unwrap();
        assert_eq!(
            bytes(learner.model().unwrap()),
            bytes(&fitted.model),
            "keep {keep}, batch {batch}"
        );
        let record = learner.last_fit().unwrap();
        assert_eq!(record.observations, (times.len() - start) as u64);
        assert_eq!(record.first_time, times[start]);
        // A fit overtaken by more than `keep` observations cannot catch up.
        let job = learner.refit_job().unwrap();
        let next: Vec<f64> = (1..=keep + 1)
            .map(|i| times[times.len() - 1] + i as f64)
            .collect();
        learner.observe(&next, &vec![1.0; next.len()]).unwrap();
        assert_eq!(
            learner.install(job.run(&options).unwrap()),
            Err(RefitError::TooLate {
                after: keep as u64 + 1,
                kept: keep
            })
        );
    }
}

#[test]
fn a_learner_round_trips_through_serde_exactly_and_goes_on_identically() {
    let (times, values) = office(3);
    let options = FitOptions::default();
    let cut = 2 * 7 * 144;
    for text in ["auto", "fremen:auto"] {
        let mut learner = spec(text).learner(5000).unwrap();
        learner.observe(&times[..cut], &values[..cut]).unwrap();
        learner.refit(&options).unwrap();
        learner
            .observe(&times[cut..cut + 100], &values[cut..cut + 100])
            .unwrap();
        let saved = bytes(&learner);
        let mut restored: Learner = postcard::from_bytes(&saved).unwrap();
        assert_eq!(bytes(&restored), saved);
        assert!(restored.is_consistent());
        same_predictions(&restored, &learner, &probes(3.0 * WEEK));
        for l in [&mut learner, &mut restored] {
            l.observe(&times[cut + 100..], &values[cut + 100..])
                .unwrap();
            l.refit(&options).unwrap();
        }
        assert_eq!(bytes(&restored), bytes(&learner), "{text}");
        assert_eq!(restored.last_fit(), learner.last_fit());
    }
    // Inconsistent learners are refused when read.
    let mut learner = spec("fremen:auto").learner(5000).unwrap();
    learner.observe(&times[..3000], &values[..3000]).unwrap();
    learner.refit(&options).unwrap();
    let Learner::Refitting(r) = &learner else {
        unreachable!()
    };
    let mut broken = [r.clone(), r.clone(), r.clone(), r.clone()];
    broken[0].keep = 10;
    broken[1].span.count += 1;
    broken[2].model = None;
    broken[3].last_fit.as_mut().unwrap().observations -= 1;
    for (i, b) in broken.into_iter().enumerate() {
        let b = Learner::Refitting(b);
        assert!(!b.is_consistent(), "{i}");
        let error = postcard::from_bytes::<Learner>(&bytes(&b)).unwrap_err();
        assert!(
            matches!(error, postcard::Error::SerdeDeCustom),
            "{i}: {error}"
        );
    }
}

#[test]
fn refits_are_due_by_new_observations_or_data_time() {
    let policy = RefitPolicy {
        observations: 100,
        data_secs: 3600.0,
    };
    let mut learner = spec("auto").learner(DEFAULT_KEEP).unwrap();
    assert!(!learner.is_due(&policy), "nothing observed");
    // 99 observations a second apart: neither limit.
    let times: Vec<f64> = (0..99).map(f64::from).collect();
    learner.observe(&times, &vec![1.0; 99]).unwrap();
    assert_eq!(learner.since_fit(), (99, 98.0));
    assert!(!learner.is_due(&policy));
    learner.observe(&[99.0], &[0.0]).unwrap();
    assert!(learner.is_due(&policy), "100 observations");
    assert!(!learner.is_due(&RefitPolicy::NEVER));
    // One observation an hour later is due by data time.
    let mut sparse = spec("fremen:auto").learner(DEFAULT_KEEP).unwrap();
    sparse.observe(&[0.0, 3599.0], &[0.0, 1.0]).unwrap();
    assert!(!sparse.is_due(&policy));
    sparse.observe(&[3600.0], &[1.0]).unwrap();
    assert!(sparse.is_due(&policy));
    assert!(RefitPolicy::default().is_due(100_000, 0.0));
    assert!(RefitPolicy::default().is_due(1, 86_400.0));
    assert!(!RefitPolicy::default().is_due(0, 1e9));
}

#[test]
fn a_refitting_learner_keeps_the_temporal_model_contract() {
    let (times, values) = office(1);
    check_temporal_model(
        || spec("auto").learner(DEFAULT_KEEP).unwrap(),
        &times[..300],
        &values[..300],
    );
}
