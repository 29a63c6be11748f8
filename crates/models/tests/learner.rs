//! A learner fed the Greg door ([Krajník 2017] §V, ten weeks of a door observed every minute)
//! batch by batch, as a service or a robot feeds it, and refitted: bit for bit the model
//! `chronomap fit --model SPEC` makes of the same file ([`ModelSpec::fit`] with the options of
//! its flags: default periods, hold-out and orders, all threads).

use chronomap_core::{Parallelism, TemporalModel};
use chronomap_models::learner::DEFAULT_KEEP;
use chronomap_models::spec::Selection;
use chronomap_models::{FitOptions, ModelSpec};

fn bytes<T: serde::Serialize>(value: &T) -> Vec<u8> {
    postcard::to_allocvec(value).unwrap()
}

#[test]
fn the_greg_door_learned_batch_by_batch_and_refitted_is_the_offline_fit() {
    let door = chronomap_io::read_pairs(chronomap_testutil::data_path(
        "door_greg_2016/training_data.txt.xz",
    ))
    .unwrap();
    assert_eq!(door.times.len(), 96_480);
    // What `chronomap fit` passes (src/cli/mod.rs, `FitFlags::options`).
    let cli = FitOptions {
        parallelism: Parallelism::Rayon(0),
        ..FitOptions::default()
    };
    // The learner fits on one thread: the result does not depend on it.
    let learner_options = FitOptions::default();
    for text in ["auto", "fremen:auto"] {
        let spec: ModelSpec = text.parse().unwrap();
        let mut learner = spec.learner(DEFAULT_KEEP).unwrap();
        for (t, v) in door.times.chunks(1440).zip(door.values.chunks(1440)) {
            learner.observe(t, v).unwrap();
        }
        assert!(learner.refit(&learner_options).unwrap());
        let fitted = spec.fit(&door.times, &door.values, &cli).unwrap();
        assert_eq!(
            bytes(learner.model().unwrap()),
            bytes(&fitted.model),
            "{text}"
        );
        let record = learner.last_fit().unwrap();
        assert_eq!(record.selection, fitted.selection);
        assert_eq!(record.observations, 96_480);
        // The day after the training data (2016-03-14), every 10 minutes.
        for i in 0..144 {
            let t = 1_457_913_600.0 + 600.0 * f64::from(i);
            assert_eq!(
                learner.predict(t).to_bits(),
                fitted.model.predict(t).to_bits()
            );
        }
        match (text, &record.selection) {
            ("auto", Some(Selection::Stack(stack))) => {
                let total: f64 = stack.weights.iter().map(|(_, w)| w).sum();
                assert!((total - 1.0).abs() < 1e-12 && stack.weights.len() > 1);
                assert_eq!(stack.origins, 6);
            }
            ("fremen:auto", Some(Selection::Order(order))) => {
                assert_eq!(learner.model().unwrap().order(), Some(order.order));
            }
            _ => panic!("{text}: {:?}", record.selection),
        }
    }
}
