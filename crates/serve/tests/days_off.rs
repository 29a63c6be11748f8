//! Calendars of days off through the service (issue 41, "Known calendar effects"): a model
//! created with `days_off` learns nothing on a day off and answers a day off (its value,
//! entropy, interval) as the same time of day on the most recent Sunday that is not one; the
//! answers are bit for bit the same after recovery by log replay and from snapshots; a log and
//! a snapshot written before calendars load as they did; and a bad date is a `400` naming the
//! field and its index.

mod common;

use axum::http::StatusCode;
use chronomap_core::time::days_from_civil;
use chronomap_models::{Learner, ModelSpec};
use chronomap_serve::Service;
use chronomap_serve::log::LogRecord;
use chronomap_serve::registry::{Entry, ModelConfig};
use chronomap_serve::store::{Checkpoint, RedbStore, Store};
use common::{assert_same_after_replay_and_restart, get, ok, refit, send, start};
use serde_json::{Value, json};

const DAY: f64 = 86_400.0;

/// Midnight (UTC) of a day of March 2016.
fn march(day: u32) -> f64 {
    DAY * days_from_civil(2016, 3, day) as f64
}

fn bits(value: &Value) -> Vec<u64> {
    value
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap().to_bits())
        .collect()
}

fn temp_dir(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("chronomap-serve-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Three weeks of hourly observations from Monday 2016-03-07: the door open on weekdays
/// 8–18 h (also on Friday 2016-03-11 and Good Friday 2016-03-25, days off the robot saw
/// open: a calendar must not learn them), the temperature warmer when it is open.
fn observations() -> (Vec<f64>, Vec<bool>, Vec<f64>) {
    let times: Vec<f64> = (0..21 * 24)
        .map(|h| march(7) + 3600.0 * f64::from(h))
        .collect();
    let open: Vec<bool> = times
        .iter()
        .map(|&t| {
            let (day, hour) = (((t - march(7)) / DAY).floor() as i64, (t % DAY) / 3600.0);
            day % 7 < 5 && (8.0..18.0).contains(&hour)
        })
        .collect();
    let temperature = open
        .iter()
        .zip(&times)
        .map(|(&o, &t)| if o { 24.0 } else { 16.0 } + (t / 3600.0 % 7.0) * 0.5)
        .collect();
    (times, open, temperature)
}

const CALENDAR: [&str; 3] = ["2016-03-28", "2016-03-11", "2016-03-25"];

/// The answers the test compares across restarts, as text (bit-equal floats print alike).
fn answers(service: &Service, runtime: &tokio::runtime::Runtime, times: &[f64]) -> Vec<String> {
    let mut all = Vec::new();
    for id in ["door", "plain", "temp", "auto"] {
        all.push(
            send(
                service,
                runtime,
                "GET",
                &format!("/v1/models/{id}"),
                &json!({}),
            )
            .1,
        );
        let at = json!({"id": id, "times": times, "coverage": 0.9});
        all.push(send(service, runtime, "POST", "/v1/predict", &at).1);
        let at = json!({"id": id, "times": times});
        all.push(send(service, runtime, "POST", "/v1/entropy", &at).1);
        let at = json!({"ids": [id], "time": times[0]});
        all.push(send(service, runtime, "POST", "/v1/forecast", &at).1);
    }
    all
}

#[test]
fn a_calendar_is_not_learned_predicts_its_sundays_and_survives_restarts() {
    let dir = temp_dir("days-off");
    let path = dir.join("chronomap.redb");
    let (service, runtime) = start(&path);
    let (times, open, temperature) = observations();
    let put = |id: &str, body: Value| {
        ok(send(
            &service,
            &runtime,
            "PUT",
            &format!("/v1/models/{id}"),
            &body,
        ))
    };
    put("door", json!({"model": "fremen:2", "days_off": CALENDAR}));
    put("plain", json!({"model": "fremen:2"}));
    put(
        "temp",
        json!({"model": "fremen:2", "range": [10.0, 30.0], "days_off": CALENDAR}),
    );
    put(
        "temp-plain",
        json!({"model": "fremen:2", "range": [10.0, 30.0]}),
    );
    put(
        "auto",
        json!({"model": "fremen:auto", "days_off": CALENDAR}),
    );
    put("auto-plain", json!({"model": "fremen:auto"}));
    // Creating again with the same calendar, in another order, is no change; with another
    // calendar, or none, it is a conflict.
    let again = json!({"model": "fremen:2", "days_off": ["2016-03-25", "2016-03-11", "2016-03-28", "2016-03-25"]});
    assert_eq!(
        send(&service, &runtime, "PUT", "/v1/models/door", &again).0,
        StatusCode::OK
    );
    for other in [
        json!({"model": "fremen:2"}),
        json!({"model": "fremen:2", "days_off": ["2016-03-25"]}),
    ] {
        let (status, text) = send(&service, &runtime, "PUT", "/v1/models/door", &other);
        assert_eq!(status, StatusCode::CONFLICT, "{other}: {text}");
    }

    // The models with a calendar get every observation; those without one only the working
    // days' (Fridays 2016-03-11 and Good Friday 2016-03-25 left out).
    let day_off =
        |t: f64| (march(11)..march(12)).contains(&t) || (march(25)..march(26)).contains(&t);
    let working: Vec<usize> = (0..times.len()).filter(|&i| !day_off(times[i])).collect();
    let pick = |xs: &[f64]| -> Vec<f64> { working.iter().map(|&i| xs[i]).collect() };
    let states: Vec<f64> = open.iter().map(|&o| f64::from(u8::from(o))).collect();
    for (id, values, all) in [
        ("door", &states, true),
        ("plain", &states, false),
        ("auto", &states, true),
        ("auto-plain", &states, false),
        ("temp", &temperature, true),
        ("temp-plain", &temperature, false),
    ] {
        let (t, v) = if all {
            (times.clone(), values.clone())
        } else {
            (pick(&times), pick(values))
        };
        let ack = ok(send(
            &service,
            &runtime,
            "POST",
            "/v1/addvalues",
            &json!({"id": id, "times": t, "values": v}),
        ));
        assert_eq!(ack["observations"], json!(t.len()), "{id}: {ack}");
    }
    for id in ["auto", "auto-plain"] {
        refit(&service, &runtime, id);
    }

    // What `GET` says: the calendar in brief, the observations learned and those skipped.
    let door = get(&service, &runtime, "/v1/models/door");
    assert_eq!(door["observations"], json!(working.len()), "{door}");
    assert_eq!(
        door["days_off"],
        json!({"days": 3, "first": "2016-03-11", "last": "2016-03-28", "skipped": 48}),
    );
    let plain = get(&service, &runtime, "/v1/models/plain");
    assert!(plain.get("days_off").is_none(), "{plain}");

    // Nothing was learned on the day off: at working times, a model with a calendar answers
    // bit for bit as the same model fed the working days only.
    let working_times: Vec<f64> = (0..7 * 24)
        .map(|h| march(29) + 3600.0 * f64::from(h) + 600.0)
        .collect();
    for (id, reference) in [
        ("door", "plain"),
        ("temp", "temp-plain"),
        ("auto", "auto-plain"),
    ] {
        for path in ["/v1/predict", "/v1/entropy"] {
            let at = |id: &str| match path {
                "/v1/predict" => json!({"id": id, "times": working_times, "coverage": 0.9}),
                _ => json!({"id": id, "times": working_times}),
            };
            let with = send(&service, &runtime, "POST", path, &at(id)).1;
            let without = send(&service, &runtime, "POST", path, &at(reference)).1;
            assert_eq!(with, without, "{id} against {reference}, {path}");
        }
    }

    // A day off is answered as its stand-in: Good Friday and Easter Monday 2016 as Sunday
    // 2016-03-20 (the 27th, Easter Sunday, is a Sunday and no day off: Monday the 28th is it).
    let good_friday: Vec<f64> = (0..24).map(|h| march(25) + 3600.0 * f64::from(h)).collect();
    let easter_monday: Vec<f64> = good_friday.iter().map(|t| t + 3.0 * DAY).collect();
    let sunday_20: Vec<f64> = good_friday.iter().map(|t| t - 5.0 * DAY).collect();
    for id in ["door", "temp", "auto"] {
        let predict = |times: &[f64]| {
            ok(send(
                &service,
                &runtime,
                "POST",
                "/v1/predict",
                &json!({"id": id, "times": times, "coverage": 0.9}),
            ))
        };
        let entropy = |times: &[f64]| {
            ok(send(
                &service,
                &runtime,
                "POST",
                "/v1/entropy",
                &json!({"id": id, "times": times}),
            ))
        };
        let sunday = predict(&sunday_20);
        for off in [&good_friday, &easter_monday] {
            let answer = predict(off);
            for field in ["values", "scaled", "lower", "upper"] {
                if let Some(values) = sunday.get(field) {
                    assert_eq!(bits(&answer[field]), bits(values), "{id} {field}");
                }
            }
            assert_eq!(
                bits(&entropy(off)["values"]),
                bits(&entropy(&sunday_20)["values"]),
                "{id} entropy"
            );
        }
        if id == "temp" {
            assert!(sunday.get("lower").is_some(), "{sunday}");
        }
        // A day off at noon is less likely open than a Friday at noon.
        if id == "door" {
            let friday_noon = predict(&[march(18) + 12.0 * 3600.0])["values"][0]
                .as_f64()
                .unwrap();
            let holiday_noon = predict(&[march(25) + 12.0 * 3600.0])["values"][0]
                .as_f64()
                .unwrap();
            assert!(holiday_noon < friday_noon, "{friday_noon} {holiday_noon}");
        }
    }

    // The answers survive a crash (log replay) and a clean restart (snapshots).
    let probe: Vec<f64> = (0..120)
        .map(|i| march(24) + 3600.0 * f64::from(i))
        .collect();
    assert_same_after_replay_and_restart((service, runtime), &path, |service, runtime| {
        answers(service, runtime, &probe)
    });
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_calendars_are_refused_naming_the_field_and_the_index() {
    let dir = temp_dir("days-off-bad");
    let (service, runtime) = start(&dir.join("chronomap.redb"));
    let too_many: Vec<String> = (0..=chronomap_serve::api::MAX_DAYS_OFF as i64)
        .map(|d| chronomap_core::time::format_date(16_000 + d))
        .collect();
    for (days_off, expected) in [
        (json!(["2016-03-25", "2016-02-30"]), "element 1"),
        (json!(["2016-3-25"]), "element 0"),
        (json!(["2016-03-25", "2016-03-25T00:00:00Z"]), "element 1"),
        (json!(["1969-12-31"]), "element 0"),
        (json!(["Good Friday"]), "element 0"),
        (json!(too_many), "10001 dates"),
        // Not a list of strings: serde's message, at a column of the body.
        (json!("2016-03-25"), "expected a sequence"),
        (json!([20_160_325]), "expected a string"),
    ] {
        let body = json!({"model": "fremen:2", "days_off": days_off});
        let (status, text) = send(&service, &runtime, "PUT", "/v1/models/door", &body);
        assert_eq!(status, StatusCode::BAD_REQUEST, "{days_off}: {text}");
        assert!(
            text.contains(expected)
                && (text.contains("field `days_off`") || text.contains("malformed JSON")),
            "{days_off}: {text}"
        );
    }
    // The OpenAPI description shows the field and the calendar in `GET`.
    let openapi = get(&service, &runtime, "/openapi.json");
    let schemas = &openapi["components"]["schemas"];
    assert_eq!(
        schemas["CreateRequest"]["properties"]["days_off"]["type"],
        json!(["array", "null"]),
        "{}",
        schemas["CreateRequest"]
    );
    assert!(schemas["DaysOffInfo"]["properties"]["skipped"].is_object());
    // Nothing was created.
    let (status, _) = send(&service, &runtime, "GET", "/v1/models/door", &json!({}));
    assert_eq!(status, StatusCode::NOT_FOUND);
    // An empty calendar is none.
    ok(send(
        &service,
        &runtime,
        "PUT",
        "/v1/models/door",
        &json!({"model": "fremen:2", "days_off": []}),
    ));
    let door = get(&service, &runtime, "/v1/models/door");
    assert!(door.get("days_off").is_none(), "{door}");
    drop(service);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The configuration as services before calendars wrote it.
#[derive(serde::Serialize)]
struct OldConfig {
    spec: ModelSpec,
    range: Option<[f64; 2]>,
}

/// The log record as services before calendars wrote it.
#[derive(serde::Serialize)]
#[allow(dead_code)]
enum OldRecord {
    Create {
        id: String,
        config: OldConfig,
    },
    Observe {
        id: String,
        times: Vec<f64>,
        values: Vec<f64>,
    },
    Remove {
        id: String,
    },
}

/// A snapshot as services before calendars wrote it (version 3).
#[derive(serde::Serialize)]
struct OldSnapshot<'a> {
    config: OldConfig,
    model: &'a Learner,
    spread: Option<&'a Learner>,
}

/// A commit group of format 2 around `records` as services before calendars wrote it.
fn old_group(seq: u64, records: &[OldRecord]) -> Vec<u8> {
    let payload = postcard::to_allocvec(records).unwrap();
    let mut crc = crc32fast::Hasher::new();
    crc.update(&seq.to_le_bytes());
    crc.update(&payload);
    let mut bytes = b"CMLOG\x002\n".to_vec();
    bytes.extend_from_slice(&crc.finalize().to_le_bytes());
    bytes.extend_from_slice(&seq.to_le_bytes());
    bytes.extend_from_slice(&payload);
    bytes
}

#[test]
fn logs_and_snapshots_written_before_calendars_load_as_they_did() {
    let dir = temp_dir("days-off-old");
    let (times, _, temperature) = observations();
    let spec: ModelSpec = "fremen:2".parse().unwrap();
    let range = Some([10.0, 30.0]);
    let old_config = || OldConfig {
        spec: spec.clone(),
        range,
    };
    let create = OldRecord::Create {
        id: "temp".into(),
        config: old_config(),
    };
    let observe = OldRecord::Observe {
        id: "temp".into(),
        times: times.clone(),
        values: temperature.clone(),
    };
    let old_log = old_group(1, &[create, observe]);
    // The same records written now are the same bytes: a model without a calendar is logged
    // as before.
    let config = ModelConfig::parse(Some("fremen:2"), range).unwrap();
    let records = [
        LogRecord::Create {
            id: "temp".into(),
            config: config.clone(),
        },
        LogRecord::Observe {
            id: "temp".into(),
            times: times.clone(),
            values: temperature.clone(),
        },
    ];
    assert_eq!(chronomap_serve::log::encode_group(1, &records), old_log);
    assert_eq!(
        chronomap_serve::log::decode_group(1, &old_log).unwrap(),
        records
    );

    // The model as it was learned, and its snapshot of version 3.
    let mut entry = Entry::new(config.clone()).unwrap();
    entry.observe("temp", &times, &temperature).unwrap();
    let old_snapshot = chronomap_io::model_file::encode_model(
        "serve-snapshot-3",
        &OldSnapshot {
            config: old_config(),
            model: &entry.model,
            spread: entry.spread.as_ref(),
        },
    )
    .unwrap();
    assert_eq!(
        chronomap_serve::store::encode_snapshot(&entry),
        old_snapshot
    );

    // Store `log`: the old log alone, replayed. Store `snapshot`: the creation in the log and
    // the learned model only in the snapshot of its checkpoint (an empty model if the snapshot
    // were not read).
    let log_path = dir.join("log.redb");
    RedbStore::open(&log_path)
        .unwrap()
        .append(1, &old_log)
        .unwrap();
    let snapshot_path = dir.join("snapshot.redb");
    {
        let store = RedbStore::open(&snapshot_path).unwrap();
        store
            .append(
                1,
                &old_group(
                    1,
                    &[OldRecord::Create {
                        id: "temp".into(),
                        config: old_config(),
                    }],
                ),
            )
            .unwrap();
        store
            .checkpoint(&Checkpoint {
                seq: 1,
                snapshots: &[("temp".to_string(), old_snapshot)],
                removed: &[],
            })
            .unwrap();
    }
    let probe: Vec<f64> = (0..100)
        .map(|i| march(28) + 1800.0 * f64::from(i))
        .collect();
    let mut seen = Vec::new();
    for path in [&log_path, &snapshot_path] {
        let (service, runtime) = start(path);
        let info = get(&service, &runtime, "/v1/models/temp");
        assert_eq!(info["observations"], json!(times.len()), "{info}");
        assert!(info.get("days_off").is_none(), "{info}");
        let at = json!({"id": "temp", "times": probe, "coverage": 0.9});
        let answer = ok(send(&service, &runtime, "POST", "/v1/predict", &at));
        // Probes on Easter Monday are their own predictions: no calendar.
        let expected: Vec<u64> = {
            use chronomap_core::TemporalModel;
            let p = entry.model.predict_many(&probe);
            p.iter().map(|p| p.to_bits()).collect()
        };
        assert_eq!(bits(&answer["values"]), expected);
        seen.push(answer.to_string());
    }
    assert_eq!(seen[0], seen[1]);
    let _ = std::fs::remove_dir_all(&dir);
}
