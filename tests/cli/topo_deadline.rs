//! Deadline plans ([`chronomap_topo::deadline`]: the policy most likely to fulfil a task within
//! D seconds) on the bundled Witham Wharf edges: the probabilities checked by simulating the
//! policies with the same duration laws, the deadline plan never behind the expected-time plan
//! of [Fentanes 2015] §V (and far ahead where time is short), and `chronomap plan --deadline`
//! end to end with its errors.

use std::path::PathBuf;

use chronomap_core::rng::Xoshiro256StarStar;
use chronomap_topo::deadline::{DeadlineOptions, DeadlinePlanned, plan_deadline, simulate};
use chronomap_topo::edges::{EdgeModelConfig, EdgeModels};
use chronomap_topo::plan::Task;
use serde_json::Value;

use crate::common::{chronomap, error, fit_witham, scratch, stdout, usage_error};

/// 2014-09-04 00:00 UTC, the day after the last attempt in the data.
pub const DAY: f64 = 1_409_788_800.0;

/// (start, task, hour of 2014-09-04 UTC, deadline in seconds): trips where the expected-time
/// plan, which maximises the probability of success first, takes a longer way than a short
/// deadline allows.
pub const CASES: [(&str, &str, u32, f64); 3] = [
    // Back from the kitchen: the expected-time plan starts by GroundCentral, the deadline
    // plan by Ramp2.
    ("Kitchen", "F Station", 14, 100.0),
    // Out of the lab door to the kitchen: by the printer and the ramps instead of WayPoint1.
    ("LabDoor2", "F Kitchen", 14, 80.0),
    // Through the lab door to the kitchen, the same first edge, other choices later.
    ("Station", "F Kitchen", 14, 110.0),
];

/// The edge models fitted on all of the bundled Witham data (default configuration).
pub fn witham_models() -> EdgeModels {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/witham_topological_nav/edges");
    let stats = chronomap_io::read_edge_directory(dir).unwrap();
    assert_eq!(stats.total_attempts(), 25_316);
    EdgeModels::fit(stats.map, &stats.attempts, EdgeModelConfig::default())
        .unwrap_or_else(|(edge, e)| panic!("edge {edge}: {e}"))
}

/// The deadline plan of one of [`CASES`].
pub fn plan_case(
    models: &EdgeModels,
    (start, task, hour, deadline): (&str, &str, u32, f64),
) -> DeadlinePlanned {
    let task = Task::parse(task, models.map()).unwrap();
    let start = models.map().node(start).unwrap();
    let time = DAY + 3600.0 * f64::from(hour);
    plan_deadline(
        models,
        start,
        &task,
        time,
        deadline,
        &DeadlineOptions::default(),
    )
    .unwrap()
}

#[test]
fn witham_deadline_plans_beat_the_expected_time_plans_and_simulation_agrees() {
    let models = witham_models();
    let edge = |e: Option<usize>| e.map_or("none", |e| models.map().edges()[e].id.as_str());
    let runs = 200_000;
    let mut margins = Vec::new();
    for (i, case) in CASES.into_iter().enumerate() {
        let planned = plan_case(&models, case);
        let plan = &planned.plan;
        assert!(plan.duration_quantiles);
        assert_eq!(plan.bucket_secs, 1.0);
        // The deadline plan is optimal: never behind, at any d up to D.
        for (k, (&p, &q)) in plan.curve.iter().zip(&plan.min_time_curve).enumerate() {
            assert!(p >= q - 1e-12, "{case:?} at {k} s: {p} < {q}");
        }
        margins.push(plan.probability - plan.min_time_probability);
        let mdp = planned.planned.product.mdp();
        for (what, solution, p) in [
            ("deadline", &planned.solution, plan.probability),
            (
                "expected-time",
                &planned.min_time,
                plan.min_time_probability,
            ),
        ] {
            let mut rng = Xoshiro256StarStar::seed_from_u64(2015 + i as u64);
            let hits = simulate(mdp, &planned.laws, solution, runs, &mut rng);
            let frequency = hits as f64 / runs as f64;
            let se = (p * (1.0 - p) / runs as f64).sqrt().max(1.0 / runs as f64);
            println!(
                "{} from {} at {:02}:00, {} s, {what} plan (first {}): DP {p:.6}, simulated \
                 {frequency:.6} ({runs} runs, |Δ| = {:.1} se)",
                case.1,
                case.0,
                case.2,
                case.3,
                edge(if what == "deadline" {
                    plan.first_edge
                } else {
                    plan.min_time_first_edge
                }),
                (frequency - p).abs() / se
            );
            assert!(
                (frequency - p).abs() <= 4.0 * se,
                "{case:?} {what}: simulated {frequency}, DP {p}"
            );
        }
    }
    // Where time is short the expected-time plan is rarely in time (measured: 0.50 vs 0.07,
    // 0.63 vs 0.01, 0.13 vs 0.03).
    assert!(
        margins[0] > 0.3 && margins[1] > 0.5 && margins[2] > 0.05,
        "{margins:?}"
    );
    // ... and with time enough both are the same plan.
    let loose = plan_case(&models, ("Kitchen", "F Station", 14, 600.0));
    let plan = &loose.plan;
    assert_eq!(plan.first_edge, plan.min_time_first_edge);
    assert!(
        (plan.probability - plan.min_time_probability).abs() < 1e-3,
        "{plan:?}"
    );
}

#[test]
fn plan_with_a_deadline_on_the_command_line() {
    let dir = scratch("plan_deadline");
    let model = dir.join("witham.cmt").display().to_string();
    fit_witham(&model, &["--success-order", "1"]);
    let png = dir.join("curve.png").display().to_string();
    // `plan` from the kitchen to the F Station, `when` (one time, or a table of them).
    let plan = |when: &[&str], extra: &[&str]| {
        let mut args = vec![
            "plan",
            "--model",
            &model,
            "--from",
            "Kitchen",
            "--task",
            "F Station",
        ];
        args.extend_from_slice(when);
        args.extend_from_slice(extra);
        chronomap(&args)
    };
    let run = |extra: &[&str]| plan(&["--time", "2014-09-04T14:00Z"], extra);
    let out = stdout(&run(&["--deadline", "100", "--json", "--plot", &png]));
    let report: Value = serde_json::from_str(out.trim()).unwrap();
    let number = |key: &str| report[key].as_f64().unwrap();

    // The same numbers as the library on the model file.
    let models = chronomap_io::read_edge_models(&model).unwrap();
    let ours = plan_case(&models, ("Kitchen", "F Station", 14, 100.0));
    assert_eq!(number("probability"), ours.plan.probability);
    assert_eq!(
        number("min_time_probability"),
        ours.plan.min_time_probability
    );
    assert_eq!(number("confidence"), 0.95);
    assert_eq!(report["reaches_confidence"], false);
    assert_eq!(report["shortest_deadline_secs"], Value::Null);
    // Measured: 0.5216 by Ramp2, against 0.0878 for the expected-time plan by GroundCentral.
    assert!(number("probability") > 0.5, "{report}");
    assert!(number("min_time_probability") < 0.1, "{report}");
    assert_eq!(report["first_edge"], "Kitchen_Ramp2");
    assert_eq!(report["min_time_first_edge"], "Kitchen_GroundCentral");
    assert_eq!(report["median_route"][0], "Kitchen_Ramp2");
    assert_eq!(
        report["median_route"].as_array().unwrap().last().unwrap(),
        "LabDoor1_Station"
    );
    let curve = report["curve"].as_array().unwrap();
    assert_eq!(curve.len(), 101);
    assert_eq!(curve[100][0], 100.0);
    assert_eq!(curve[100][1].as_f64(), Some(number("probability")));
    assert_eq!(&std::fs::read(&png).unwrap()[1..4], b"PNG");

    // The text, with a confidence it reaches.
    let text = stdout(&run(&["--deadline", "100", "--confidence", "0.5"]));
    for part in [
        "deadline 100 s",
        "probability of fulfilling it in time: 0.52",
        "(reaches 0.5;",
        "first action: Kitchen_Ramp2",
        "0.5 is reached within 99 s (1 s to spare)",
        "first action Kitchen_GroundCentral): 0.08",
    ] {
        assert!(text.contains(part), "{part:?} missing from:\n{text}");
    }

    // Usage errors exit 2, before anything is planned.
    for (flags, expected) in [
        (&["--deadline", "nan"][..], "not a finite number > 0"),
        (&["--deadline", "0"], "not a finite number > 0"),
        (&["--deadline=-5"], "not a finite number > 0"),
        (&["--deadline", "inf"], "not a finite number > 0"),
        (
            &["--deadline", "100", "--confidence", "1.5"],
            "not a probability",
        ),
        (
            &["--deadline", "100", "--bucket-secs", "0"],
            "not a finite number > 0",
        ),
        (&["--confidence", "0.9"], "--deadline"),
        (&["--plot", "x.png"], "--plot draws"),
    ] {
        let err = usage_error(&run(flags));
        assert!(err.contains(expected), "{flags:?}: {err}");
    }
    // The now-or-later table with a deadline: at each start time the deadline plan's
    // probability and first edge, as the library plans it at that time alone.
    let day_table = |extra: &[&str]| {
        let when = [
            "--day-table",
            "--week-of",
            "2014-09-04",
            "--days",
            "1",
            "--step-mins",
            "240",
            "--deadline",
            "100",
        ];
        plan(&when, extra)
    };
    let table: Value = serde_json::from_str(stdout(&day_table(&["--json"])).trim()).unwrap();
    assert_eq!(table["deadline_secs"], 100.0);
    let rows = table["plans"].as_array().unwrap();
    assert_eq!(rows.len(), 6);
    for (i, row) in rows.iter().enumerate() {
        let plan = plan_case(&models, ("Kitchen", "F Station", 4 * i as u32, 100.0)).plan;
        assert_eq!(row["deadline_probability"].as_f64(), Some(plan.probability));
        assert_eq!(
            row["min_time_probability"].as_f64(),
            Some(plan.min_time_probability)
        );
        let edge = plan.first_edge.map(|e| models.map().edges()[e].id.clone());
        assert_eq!(
            row["deadline_first_edge"].as_str(),
            edge.as_deref(),
            "{row}"
        );
    }
    let text = stdout(&day_table(&[]));
    assert!(
        text.contains("greatest probability of fulfilling it within 100 s and first action"),
        "{text}"
    );
    assert!(usage_error(&day_table(&["--confidence", "0.9"])).contains("--confidence"));
    // Too many buckets is a failure of the plan (exit 1), said clearly.
    let err = error(&run(&["--deadline", "100", "--bucket-secs", "0.00001"]));
    assert!(err.contains("widen the buckets"), "{err}");
    // A bucket wider than the deadline: refused as the service refuses it.
    let err = error(&run(&["--deadline", "100", "--bucket-secs", "101"]));
    assert!(
        err.contains("the bucket width 101 s is wider than the deadline 100 s"),
        "{err}"
    );
}
