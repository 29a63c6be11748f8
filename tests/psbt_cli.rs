//! `chronomap psbt` and `chronomap psbt eval` on the bundled ATC day (seed 002 §5.4): the JSON
//! shape, measured values, determinism for a seed, and clear errors.

mod common;

use common::{chronomap, close, error, repo, stdout};
use serde_json::Value;

fn tracks(hours: &[u32]) -> String {
    hours
        .iter()
        .map(|h| repo(&format!("data/atc_20121024_1hz/atc-1024-{h}_train.csv.xz")))
        .collect::<Vec<_>>()
        .join(",")
}

fn synth(from: &str, extra: &[&str]) -> std::process::Output {
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let activity = tracks(&[13, 14]);
    let from = format!("--from={from}");
    let mut args = vec![
        "psbt",
        "--map",
        &map,
        "--activity",
        &activity,
        &from,
        "--time",
        "2012-10-24T05:30Z",
    ];
    args.extend_from_slice(extra);
    chronomap(&args)
}

/// In the quiet south-west of the lower hall (21.25, −18.25), the tree searches and waits at
/// five places and searches to a sixth: p_s,T(200 s) = 0.9474 and E[T|S] = 23.2 s, measured.
#[test]
fn synthesis_json_has_the_tree_and_measured_values() {
    let out = synth("21.25,-18.25", &["--json", "--seed", "0"]);
    let v: Value = serde_json::from_str(&stdout(&out)).unwrap();
    let xml = v["tree_xml"].as_str().unwrap();
    assert!(xml.contains(r#"<root BTCPP_format="4" main_tree_to_execute="PersonSearch">"#));
    assert_eq!(xml.matches("<SearchPath ").count(), 6);
    assert_eq!(xml.matches("<WaitAt ").count(), 5);
    assert!(xml.contains(r#"<MoveTo x="21.25" y="-18.25"/>"#));
    assert!(xml.contains("<TreeNodesModel>"));
    close(&v["p_success"], 0.9474, 0.002);
    close(&v["expected_time_s"], 23.2, 0.5);
    assert!(v["synthesis_ms"].as_f64().unwrap() > 0.0);
    assert_eq!(v["candidates"], 730);
    assert_eq!(v["places"].as_array().unwrap().len(), 6);
    // Deterministic for a seed.
    let again: Value =
        serde_json::from_str(&stdout(&synth("21.25,-18.25", &["--json", "--seed", "0"]))).unwrap();
    assert_eq!(again["tree_xml"], v["tree_xml"]);
    assert_eq!(again["p_success"], v["p_success"]);
}

/// In the busy corridor (10, −3) waiting right there is best: W, p_s = p'_s = 0.9.
#[test]
fn a_busy_start_waits() {
    let v: Value = serde_json::from_str(&stdout(&synth("10,-3", &["--json"]))).unwrap();
    close(&v["p_success"], 0.9, 1e-6);
    assert_eq!(v["choices"], "wait at the start (W)");
    let text = stdout(&synth("10,-3", &[]));
    assert!(text.contains("730 candidate trees over 6 places"), "{text}");
    assert!(text.contains(r#"<WaitAt x="10.00" y="-3.00""#), "{text}");
}

/// A negative x after a space is the value of `--from`, not an unknown option.
#[test]
fn a_negative_x_needs_no_equals_sign() {
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let activity = tracks(&[13]);
    let out = chronomap(&[
        "psbt",
        "--map",
        &map,
        "--activity",
        &activity,
        "--from",
        "-100,0",
        "--time",
        "0",
    ]);
    let err = error(&out);
    assert!(
        err.contains("--from -100,0: the start (-100, 0) lies outside the map"),
        "{err}"
    );
}

#[test]
fn bad_input_is_a_clear_error() {
    let err = error(&synth("100,0", &[]));
    assert!(
        err.contains("--from 100,0: the start (100, 0) lies outside the map"),
        "{err}"
    );
    let err = error(&synth("0,8", &[]));
    assert!(err.contains("is on an obstacle"), "{err}");
    let err = error(&synth("10", &[]));
    assert!(err.contains("is not a point x,y"), "{err}");
    let err = error(&synth("10,-3", &["--places", "20"]));
    assert!(err.contains("at most 16"), "{err}");
    let dir = std::env::temp_dir().join(format!("chronomap-psbt-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.csv");
    std::fs::write(
        &bad,
        "1351036800,7,1.0,2.0,0.5,0.1\n1351036801,7,1.0,x,0.5,0.1\n",
    )
    .unwrap();
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let out = chronomap(&[
        "psbt",
        "--map",
        &map,
        "--activity",
        bad.to_str().unwrap(),
        "--from",
        "10,-3",
        "--time",
        "0",
    ]);
    let err = error(&out);
    assert!(err.contains("bad.csv:2: y: \"x\" is not"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Fig. 5.11 on 20 help locations: the shape of the JSON, and what holds by construction:
/// PSBT's candidates include W and PP, so its mean p_s,T(t_max) is at least theirs.
#[test]
fn eval_compares_every_method() {
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let activity = tracks(&[9, 10, 11, 13]);
    let out = chronomap(&[
        "psbt",
        "eval",
        "--map",
        &map,
        "--activity",
        &activity,
        "--time",
        "2012-10-24T04:30Z",
        "--starts",
        "20",
        "--seed",
        "1",
        "--json",
    ]);
    let v: Value = serde_json::from_str(&stdout(&out)).unwrap();
    assert_eq!(v["starts"], 20);
    assert_eq!(v["times_s"].as_array().unwrap().len(), 10);
    for side in ["planning_model", "scoring_model"] {
        let m = &v[side];
        let last = |name: &str| m[name]["p_success_mean"][9].as_f64().unwrap();
        for name in ["PSBT", "GM", "GC", "RND", "W", "PP"] {
            assert_eq!(
                m[name]["p_success_mean"].as_array().unwrap().len(),
                10,
                "{side} {name}"
            );
        }
        if side == "planning_model" {
            assert!(last("PSBT") >= last("W") - 1e-9 && last("PSBT") >= last("PP") - 1e-9);
        }
    }
    assert!(v["psbt_over_gm_at_140_percent"].is_number());
}
