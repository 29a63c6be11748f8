//! `chronomap bench serve` end to end with tiny parameters: the service starts on loopback,
//! answers every kind of request, acknowledges every batch, and the JSON report has every
//! field with plausible values. (Speed itself is measured by the command, never by a test.)

use std::path::PathBuf;
use std::process::Command;

use crate::common::{json, positive_at};

#[test]
fn bench_serve_reports_latencies_throughput_and_baselines() {
    let data = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("bench_serve_cli");
    let _ = std::fs::remove_dir_all(&data);
    let out = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args([
            "bench",
            "serve",
            "--models",
            "5",
            "--clients",
            "2",
            "--preload",
            "600",
            "--requests",
            "30",
            "--forecast-ids",
            "4",
            "--predict-times",
            "3",
            "--observations",
            "20000",
            "--batch",
            "2000",
            "--batch-ids",
            "2",
            "--json",
            "--data",
        ])
        .arg(&data)
        .output()
        .expect("run chronomap");
    let report = json(&out);
    let positive = |path: &[&str]| positive_at(&report, path);

    assert_eq!(report["models"], 5);
    assert_eq!(positive(&["preload", "observations"]), 3000.0);
    for probe in ["health", "predict_1", "predict_3", "forecast_4"] {
        assert_eq!(positive(&["latency", probe, "requests"]), 60.0, "{probe}");
        let p50 = positive(&["latency", probe, "p50_us"]);
        let p99 = positive(&["latency", probe, "p99_us"]);
        let max = positive(&["latency", probe, "max_us"]);
        assert!(p50 <= p99 && p99 <= max, "{probe}: {p50} {p99} {max}");
        positive(&["latency", probe, "requests_per_second"]);
    }
    for probe in ["predict_1", "predict_3", "forecast_4"] {
        positive(&["latency", probe, "in_process_ns"]);
        positive(&["latency", probe, "ratio_p50_to_in_process"]);
        positive(&["latency", probe, "ratio_p50_to_health"]);
    }
    assert_eq!(positive(&["throughput", "observations"]), 20000.0);
    assert_eq!(positive(&["throughput", "requests"]), 10.0);
    let commits = positive(&["throughput", "commits"]);
    assert!(commits <= 10.0, "{commits} commit groups for 10 requests");
    positive(&["throughput", "observations_per_second"]);
    for baseline in ["json_parse", "model_update", "log_encode", "redb_append"] {
        assert_eq!(
            positive(&["throughput", "baselines", baseline, "observations"]),
            20000.0,
            "{baseline}"
        );
        positive(&[
            "throughput",
            "baselines",
            baseline,
            "observations_per_second",
        ]);
        positive(&[
            "throughput",
            "baselines",
            baseline,
            "ratio_service_to_baseline",
        ]);
    }
    positive(&["throughput", "ratio_service_to_pipeline"]);
    assert!(report["goals"]["predict_p99_under_1ms"].is_boolean());
    assert!(report["goals"]["durable_1m_observations_per_second"].is_boolean());

    // --data keeps the store (and only it): a service started on it recovers the five models.
    assert!(!data.join("baseline.redb").exists());
    let store = chronomap_serve::store::RedbStore::open(data.join("chronomap.redb")).unwrap();
    let service =
        chronomap_serve::Service::start(std::sync::Arc::new(store), Default::default()).unwrap();
    assert_eq!(service.models(), 5);
    drop(service);
    let _ = std::fs::remove_dir_all(&data);
}

#[test]
fn bench_serve_grid_load_measures_both_services_in_turns() {
    let binary = env!("CARGO_BIN_EXE_chronomap");
    let out = Command::new(binary)
        .args(["bench", "serve", "--grid-load", "--baseline-bin", binary])
        .args(["--grid-cells", "640", "--grid-clients", "3"])
        .args(["--grid-seconds", "0.3", "--grid-rounds", "1", "--json"])
        .output()
        .expect("run chronomap");
    let report = json(&out);
    assert_eq!(report["cells"], 640);
    assert_eq!(report["grid_clients"], 3);
    positive_at(&report, &["changing_cells"]);
    // 640 values of at least a digit and a comma, with the shape around them.
    assert!(positive_at(&report, &["map_bytes"]) > 1280.0, "{report}");
    let services = report["services"].as_array().expect("services");
    let names: Vec<&str> = services
        .iter()
        .map(|s| s["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["baseline", "this build"]);
    for s in services {
        for kind in [
            "quiet_predict",
            "quiet_health",
            "loaded_grid",
            "loaded_health",
            "loaded_predict",
        ] {
            let at = |field: &str| s[kind][field].as_f64().unwrap_or(f64::NAN);
            assert!(at("requests") >= 1.0, "{kind}: {s}");
            assert!(
                0.0 < at("p50_us") && at("p50_us") <= at("p99_us") && at("p99_us") <= at("max_us"),
                "{kind}: {s}"
            );
        }
        assert!(s["grid_per_second"].as_f64().unwrap() > 0.0, "{s}");
    }
    let bad = Command::new(binary)
        .args(["bench", "serve", "--grid-load", "--grid-clients", "0"])
        .output()
        .expect("run chronomap");
    assert_eq!(bad.status.code(), Some(2), "{bad:?}");
    assert!(
        String::from_utf8_lossy(&bad.stderr).contains("--grid-clients: 1 to 256 clients"),
        "{bad:?}"
    );
}
