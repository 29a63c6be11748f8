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
