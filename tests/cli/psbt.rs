//! `chronomap psbt` and `chronomap psbt eval` on the bundled ATC day ([Stüde 2024] §5.4): the JSON
//! shape, measured values, determinism for a seed, and clear errors.

use crate::common;

use common::{
    assert_mentions, chronomap, close, error, fit_small_copa, repo, scratch, stdout, strings,
    usage_error, write_arg,
};
use serde_json::Value;

/// The quiet south-west of the lower hall.
const SOUTH_WEST: &str = "21.25,-18.25";

fn tracks(hours: &[u32]) -> String {
    hours
        .iter()
        .map(|h| repo(&format!("data/atc_20121024_1hz/atc-1024-{h}_train.csv.xz")))
        .collect::<Vec<_>>()
        .join(",")
}

/// `chronomap psbt` on the bundled ATC map with the activity model or tracks `activity`, help
/// requested at `from` (`x,y`) at `time`, plus `extra` flags.
fn psbt(activity: &str, from: &str, time: &str, extra: &[&str]) -> std::process::Output {
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let from = format!("--from={from}");
    let args = [
        "psbt",
        "--map",
        &map,
        "--activity",
        activity,
        &from,
        "--time",
        time,
    ];
    chronomap(&[&args[..], extra].concat())
}

/// [`psbt`] on the tracks of 13:00-15:00 JST, help requested at 14:30 JST.
fn synth(from: &str, extra: &[&str]) -> std::process::Output {
    psbt(&tracks(&[13, 14]), from, "2012-10-24T05:30Z", extra)
}

/// In the quiet south-west of the lower hall (21.25, −18.25), the tree skips three places and
/// searches and waits at three: p_s,T(200 s) = 0.9557 and E[T|S] = 21.4 s, measured.
#[test]
fn synthesis_json_has_the_tree_and_measured_values() {
    let out = synth("21.25,-18.25", &["--json", "--seed", "0"]);
    let v: Value = serde_json::from_str(&stdout(&out)).unwrap();
    let xml = v["tree_xml"].as_str().unwrap();
    assert!(xml.contains(r#"<root BTCPP_format="4" main_tree_to_execute="PersonSearch">"#));
    assert_eq!(xml.matches("<SearchPath ").count(), 3);
    assert_eq!(xml.matches("<WaitAt ").count(), 3);
    assert!(xml.contains(r#"<MoveTo x="21.25" y="-18.25"/>"#));
    assert!(xml.contains("<TreeNodesModel>"));
    close(&v["p_success"], 0.9557, 0.002);
    close(&v["expected_time_s"], 21.4, 0.5);
    let choices = strings(&v["choices"]);
    assert_eq!(
        choices,
        [
            "skip",
            "skip",
            "skip",
            "search+wait",
            "search+wait",
            "search+wait"
        ]
    );
    assert!(v["synthesis_ms"].as_f64().unwrap() > 0.0);
    assert_eq!(v["candidates"], 730);
    assert_eq!(v["places"].as_array().unwrap().len(), 6);
    // Deterministic for a seed.
    let again: Value =
        serde_json::from_str(&stdout(&synth("21.25,-18.25", &["--json", "--seed", "0"]))).unwrap();
    assert_eq!(again["tree_xml"], v["tree_xml"]);
    assert_eq!(again["p_success"], v["p_success"]);
}

/// In the busy corridor (10, −3) waiting right there (W) would succeed with p'_s = 0.9; the
/// close maximum 3.6 m away (GC's target, always among the places) does better: the tree
/// searches to it and waits, then on: p_s,T(200 s) = 0.9576, measured.
#[test]
fn a_busy_start_waits_at_the_close_maximum() {
    let v: Value = serde_json::from_str(&stdout(&synth("10,-3", &["--json"]))).unwrap();
    close(&v["p_success"], 0.9576, 0.002);
    assert_eq!(v["choices"][0], "search+wait");
    assert_eq!(v["places"][0], serde_json::json!([12.25, -6.25]));
    let text = stdout(&synth("10,-3", &[]));
    assert!(text.contains("730 candidate trees over 6 places"), "{text}");
    assert!(text.contains(r#"<WaitAt x="12.25" y="-6.25""#), "{text}");
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
    let err = usage_error(&synth("10", &[]));
    assert!(err.contains("is not a point x,y"), "{err}");
    let err = usage_error(&synth("10,-3", &["--places", "20"]));
    assert!(err.contains("--places") && err.contains("1..=16"), "{err}");
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
/// PSBT's candidates include W, PP, GM and GC, so its mean p_s,T(t_max) is at least theirs.
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
            for name in ["W", "PP", "GM", "GC"] {
                assert!(last("PSBT") >= last(name) - 1e-9, "{name}");
            }
        }
    }
    assert!(v["psbt_over_gm_at_140_percent"].is_number());
}

/// A small CoPA-Map fitted here (30 inducing points, 20 iterations: about 2 s) and saved as
/// `activity fit` saves it.
fn small_copa_model(dir: &std::path::Path) -> String {
    let model = dir.join("atc_small.cmcopa").display().to_string();
    fit_small_copa(&model);
    model
}

/// `--activity MODEL.cmcopa`: the synthesis runs on the saved CoPA-Map's field. 14:30 JST on
/// the first day is t = 5.5 on the ATC grid's axis; measured p_s,T(200 s) = 0.9733 (the track
/// model of the same hour gives 0.9557).
#[test]
fn synthesis_from_a_saved_copa_map() {
    let dir = scratch("psbt_copa");
    let model = small_copa_model(&dir);
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let run = |extra: &[&str]| {
        let out = psbt(
            &model,
            SOUTH_WEST,
            "2012-10-24T05:30Z",
            &[&["--json"], extra].concat(),
        );
        serde_json::from_str::<Value>(&stdout(&out)).unwrap()
    };
    let json = run(&[]);
    close(&json["model_t"], 5.5, 1e-9);
    close(&json["p_success"], 0.9733, 0.01);
    assert!(json["expected_time_s"].as_f64().unwrap() > 0.0);
    assert!(
        json["tree_xml"]
            .as_str()
            .unwrap()
            .contains("<MoveTo x=\"21.25\" y=\"-18.25\"/>")
    );
    // --model-t overrides the mapping: 20:30 JST of the first day (t = 11.5).
    let late = run(&["--model-t", "11.5"]);
    close(&late["model_t"], 11.5, 1e-12);
    assert!(late["p_success"].as_f64().unwrap() > 0.5);

    // Errors: a night hour without --model-t, a file that is not a model, a model mixed
    // with tracks, and `psbt eval`, which needs tracks.
    let night = error(&psbt(&model, SOUTH_WEST, "2012-10-24T14:00Z", &[]));
    assert_mentions(&night, &["outside 09:00-21:00 JST", "--model-t"]);
    let fake = write_arg(&dir, "fake.cmcopa", "t,person,x,y\n");
    let err = error(&psbt(&fake, SOUTH_WEST, "0", &[]));
    assert_mentions(&err, &["fake.cmcopa", "not a chronomap model file"]);
    let mixed = format!("{model},{}", tracks(&[13]));
    let err = error(&psbt(&mixed, SOUTH_WEST, "0", &[]));
    assert!(err.contains("not both (1 of 2 files are models)"), "{err}");
    let err = error(&chronomap(&[
        "psbt",
        "eval",
        "--map",
        &map,
        "--activity",
        &model,
        "--time",
        "2012-10-24T05:30Z",
    ]));
    assert!(err.contains("psbt eval needs pedestrian tracks"), "{err}");
}

#[test]
fn synthesis_without_a_map_is_a_usage_error_and_bad_values_a_failure() {
    // No --map and --activity: the command cannot run at all (exit 2).
    let err = usage_error(&chronomap(&[
        "psbt",
        "--from=10,-3",
        "--time",
        "2012-10-24T05:30Z",
    ]));
    assert_mentions(&err, &["--map", "--activity"]);
    // A time that is neither seconds nor ISO 8601 is refused by the parser (exit 2)...
    let map = repo("data/atc_copa_map_grid/atc_map.yaml");
    let activity = tracks(&[13]);
    let err = usage_error(&chronomap(&[
        "psbt",
        "--map",
        &map,
        "--activity",
        &activity,
        "--from=10,-3",
        "--time",
        "noon",
    ]));
    assert!(err.contains("ISO 8601"), "{err}");
    // ... a start off the map only when the map is read (exit 1).
    error(&synth("-500,0", &[]));
}
