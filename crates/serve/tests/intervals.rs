//! Prediction intervals of models of continuous values through the service (issue 41): a
//! model with a `range` fed Beta-distributed values answers `POST /v1/predict` with
//! `coverage` by intervals that hold that share of fresh values; a binary model answers none;
//! a bad `coverage` is a `400` naming the field; and the intervals are bit for bit the same
//! after recovery by log replay (a crash) and from snapshots (a clean shutdown).

mod common;

use axum::http::StatusCode;
use chronomap_core::conformance::check_interval_coverage;
use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_serve::Service;
use common::{assert_same_after_replay_and_restart, ok, refit, send, start};
use serde_json::{Value, json};
use statrs::distribution::{Beta, ContinuousCDF};

const DAY: f64 = 86_400.0;
const START: f64 = 1.7e9;
const RANGE: [f64; 2] = [10.0, 30.0];

/// The law of the normalised value at `t`: its mean and concentration (so its variance)
/// follow the time of day.
fn law_at(t: f64) -> Beta {
    let phase = std::f64::consts::TAU * t / DAY;
    let m = 0.5 + 0.3 * phase.cos();
    let k = 12.0 + 6.0 * phase.sin();
    Beta::new(m * k, (1.0 - m) * k).unwrap()
}

/// A value of the law at `t`, in the model's range.
fn draw(rng: &mut Xoshiro256StarStar, t: f64) -> f64 {
    RANGE[0] + (RANGE[1] - RANGE[0]) * law_at(t).inverse_cdf(rng.next_f64())
}

fn floats(value: &Value) -> Vec<f64> {
    value
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect()
}

/// The answers of every model to the questions the test asks, as text (bit-equal floats
/// print alike).
fn answers(service: &Service, runtime: &tokio::runtime::Runtime, times: &[f64]) -> Vec<String> {
    let mut all = Vec::new();
    for id in ["temp", "auto-temp", "stack-temp", "door"] {
        for coverage in [0.5, 0.9, 0.99] {
            let body = json!({"id": id, "times": times, "coverage": coverage});
            all.push(send(service, runtime, "POST", "/v1/predict", &body).1);
        }
    }
    all
}

#[test]
fn range_models_answer_intervals_that_hold_their_share_and_survive_restarts() {
    let dir =
        std::env::temp_dir().join(format!("chronomap-serve-intervals-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("chronomap.redb");
    let (service, runtime) = start(&path);
    let mut rng = Xoshiro256StarStar::seed_from_u64(41);

    // Eight weeks of one value a minute for `temp` (learns online); two weeks every five
    // minutes for `auto-temp` and four for `stack-temp` (fitted on their kept observations); a
    // binary door.
    for (id, model, days, step) in [
        ("temp", "fremen:2", 56.0, 60.0),
        ("auto-temp", "fremen:auto", 14.0, 300.0),
        ("stack-temp", "auto", 28.0, 300.0),
    ] {
        let created = json!({"model": model, "range": RANGE});
        ok(send(
            &service,
            &runtime,
            "PUT",
            &format!("/v1/models/{id}"),
            &created,
        ));
        let n = (days * DAY / step) as usize;
        let times: Vec<f64> = (0..n).map(|i| START + step * i as f64).collect();
        for chunk in times.chunks(20_000) {
            let values: Vec<f64> = chunk.iter().map(|&t| draw(&mut rng, t)).collect();
            let body = json!({"id": id, "times": chunk, "values": values});
            ok(send(&service, &runtime, "POST", "/v1/addvalues", &body));
        }
    }
    let door_times: Vec<f64> = (0..48).map(|h| START + 3600.0 * f64::from(h)).collect();
    let states: Vec<bool> = (0..48).map(|h| (8..18).contains(&(h % 24))).collect();
    let door = json!({"id": "door", "model": "fremen:2", "times": door_times, "states": states});
    ok(send(&service, &runtime, "POST", "/v1/add", &door));

    // Fresh values at other times of the following week.
    let after = START + 56.0 * DAY;
    let fresh_times: Vec<f64> = (0..4000)
        .map(|_| after + rng.uniform(0.0, 7.0 * DAY))
        .collect();
    let fresh: Vec<f64> = fresh_times.iter().map(|&t| draw(&mut rng, t)).collect();
    for coverage in [0.5, 0.9, 0.99] {
        let body = json!({"id": "temp", "times": fresh_times, "coverage": coverage});
        let answer = ok(send(&service, &runtime, "POST", "/v1/predict", &body));
        let (lower, upper) = (floats(&answer["lower"]), floats(&answer["upper"]));
        let scaled = floats(&answer["scaled"]);
        assert_eq!(lower.len(), fresh.len());
        for ((lo, hi), mean) in lower.iter().zip(&upper).zip(&scaled) {
            assert!(RANGE[0] <= *lo && lo <= hi && *hi <= RANGE[1], "{lo} {hi}");
            assert!(lo <= mean && mean <= hi, "{lo} {mean} {hi}");
        }
        let intervals: Vec<(f64, f64)> = lower.into_iter().zip(upper).collect();
        let c = check_interval_coverage(
            &format!("service, fremen:2, {coverage}"),
            coverage,
            &intervals,
            &fresh,
        );
        println!("temp, {coverage}: {c:?}");
    }

    // A binary model answers no interval, nor does a model fitted on a whole series before its
    // fit, nor after it but for `auto` (see docs/service.md for why).
    for id in ["door", "auto-temp", "stack-temp"] {
        let at = json!({"id": id, "times": [after], "coverage": 0.9});
        let answer = ok(send(&service, &runtime, "POST", "/v1/predict", &at));
        assert!(
            answer.get("lower").is_none() && answer.get("upper").is_none(),
            "{answer}"
        );
    }
    refit(&service, &runtime, "auto-temp");
    let at = json!({"id": "auto-temp", "times": [after], "coverage": 0.9});
    let answer = ok(send(&service, &runtime, "POST", "/v1/predict", &at));
    assert!(
        answer.get("lower").is_none() && answer.get("scaled").is_some(),
        "{answer}"
    );
    // `auto` fits its second moment with its values (a stack of averages of the squares):
    // its intervals hold about their share.
    refit(&service, &runtime, "stack-temp");
    let body = json!({"id": "stack-temp", "times": fresh_times, "coverage": 0.9});
    let answer = ok(send(&service, &runtime, "POST", "/v1/predict", &body));
    let (lower, upper) = (floats(&answer["lower"]), floats(&answer["upper"]));
    let inside = fresh
        .iter()
        .zip(lower.iter().zip(&upper))
        .filter(|(v, (lo, hi))| (**lo..=**hi).contains(*v))
        .count() as f64
        / fresh.len() as f64;
    println!("stack-temp, 0.9: {inside}");
    assert!(
        (0.87..=0.93).contains(&inside),
        "auto's 90 % intervals held {inside}"
    );

    // A coverage that is no share is a 400 naming the field: out of (0, 1), null (how
    // serialisers write NaN), or on an endpoint without intervals.
    for bad in [json!(0.0), json!(1.0), json!(-0.5), json!(1.5), json!(null)] {
        let body = json!({"id": "temp", "times": [after], "coverage": bad});
        let (status, text) = send(&service, &runtime, "POST", "/v1/predict", &body);
        assert_eq!(status, StatusCode::BAD_REQUEST, "{bad}: {text}");
        assert!(text.contains("coverage"), "{bad}: {text}");
    }
    let body = json!({"id": "temp", "times": [after], "coverage": 0.9});
    let (status, text) = send(&service, &runtime, "POST", "/v1/entropy", &body);
    assert_eq!(status, StatusCode::BAD_REQUEST, "{text}");
    assert!(text.contains("field `coverage`"), "{text}");

    // The answers survive a crash (log replay) and a clean restart (snapshots).
    let probe: Vec<f64> = (0..200).map(|i| after + 3000.0 * f64::from(i)).collect();
    assert_same_after_replay_and_restart((service, runtime), &path, |service, runtime| {
        answers(service, runtime, &probe)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

/// A store whose log holds an `auto` model of continuous values refitted by a service from
/// before `auto` had a second moment (a `Refit` record without the fit of the squares): it
/// answers no interval, and a refit request — although the model itself is fitted on every
/// observation — fits the second moment, after which it does.
#[test]
fn an_auto_model_refitted_without_its_second_moment_gets_one_at_the_next_refit_request() {
    use chronomap_serve::log::{LogRecord, encode_group};
    use chronomap_serve::registry::{Entry, ModelConfig};
    use chronomap_serve::store::{RedbStore, Store};

    let dir = std::env::temp_dir().join(format!(
        "chronomap-serve-intervals-old-refit-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("chronomap.redb");
    let mut rng = Xoshiro256StarStar::seed_from_u64(7);
    let times: Vec<f64> = (0..7 * 288).map(|i| START + 300.0 * f64::from(i)).collect();
    let values: Vec<f64> = times.iter().map(|&t| draw(&mut rng, t)).collect();
    let config = ModelConfig::parse(Some("auto"), Some(RANGE)).unwrap();
    let mut entry = Entry::new(config.clone()).unwrap();
    entry.observe("old", &times, &values).unwrap();
    let fit = entry
        .model
        .refit_job()
        .unwrap()
        .run(&chronomap_serve::refit::fit_options())
        .unwrap();
    let records = [
        LogRecord::Create {
            id: "old".into(),
            config,
        },
        LogRecord::Observe {
            id: "old".into(),
            times: times.clone(),
            values,
        },
        LogRecord::Refit {
            id: "old".into(),
            refit: Box::new(fit),
            spread: None,
        },
    ];
    RedbStore::open(&path)
        .unwrap()
        .append(1, &encode_group(1, &records))
        .unwrap();

    let (service, runtime) = start(&path);
    let at = json!({"id": "old", "times": [START + 8.0 * DAY], "coverage": 0.9});
    let answer = ok(send(&service, &runtime, "POST", "/v1/predict", &at));
    assert!(
        answer.get("lower").is_none() && answer.get("scaled").is_some(),
        "{answer}"
    );
    refit(&service, &runtime, "old");
    let answer = ok(send(&service, &runtime, "POST", "/v1/predict", &at));
    let (lower, upper) = (floats(&answer["lower"]), floats(&answer["upper"]));
    let scaled = floats(&answer["scaled"]);
    assert!(lower[0] < scaled[0] && scaled[0] < upper[0], "{answer}");
    drop(service);
    let _ = std::fs::remove_dir_all(&dir);
}
