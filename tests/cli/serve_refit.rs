//! Models fitted on a whole series in `chronomap serve`: the stacked `auto` and `fremen:auto`
//! learn the ten Greg door weeks through the service, are refitted on request (`chronomap client
//! refit`) and on a schedule (`--refit-every`), and then predict bit for bit what `chronomap
//! fit --model SPEC` + `chronomap predict` say of the same file; what they learn after the fit
//! is learned online; SIGKILL right after a refit, and a graceful restart, keep every
//! prediction. Redb and PostgreSQL.

use crate::common::{chronomap, greg_tests, greg_training, stdout};
use crate::service;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use chronomap_client::Client;
use chronomap_core::TemporalModel;
use chronomap_core::TimeSeries;
use chronomap_models::{FitOptions, ModelSpec};
use service::{Backend, Server, free_port, on_each_backend, scratch, start, token};

const TRAIN: &str = "data/door_greg_2016/training_data.txt.xz";

/// The day after the training data (2016-03-14) hour by hour, and the day after the first test
/// week (2016-03-28) every 10 minutes.
fn probe_times() -> Vec<f64> {
    let hours = (0..=24).map(|h| 1_457_913_600.0 + 3600.0 * f64::from(h));
    let week = (0..144).map(|i| 1_459_123_200.0 + 600.0 * f64::from(i));
    hours.chain(week).collect()
}

fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
}

fn add(runtime: &tokio::runtime::Runtime, client: &Client, id: &str, series: &TimeSeries) {
    for (t, v) in series
        .times
        .chunks(20_000)
        .zip(series.values.chunks(20_000))
    {
        runtime.block_on(client.add_values(id, t, v, None)).unwrap();
    }
}

fn served(runtime: &tokio::runtime::Runtime, client: &Client, id: &str) -> Vec<u64> {
    let answer = runtime
        .block_on(client.predict(id, &probe_times(), None))
        .unwrap();
    answer.values.iter().map(|p| p.to_bits()).collect()
}

/// `chronomap fit --train TRAIN --model SPEC` and `chronomap predict --json` of the model file.
fn fit_and_predict(dir: &std::path::Path, spec: &str) -> Vec<u64> {
    let file = dir.join(format!("{}.cmm", spec.replace(':', "-")));
    let file = file.to_str().unwrap();
    let fit = chronomap(&["fit", "--train", TRAIN, "--model", spec, "-o", file]);
    assert!(
        fit.status.success(),
        "{}",
        String::from_utf8_lossy(&fit.stderr)
    );
    let times: Vec<String> = probe_times().iter().map(|t| t.to_string()).collect();
    let predicted = chronomap(&["predict", file, "--json", "--at", &times.join(",")]);
    let answer: serde_json::Value = serde_json::from_str(&stdout(&predicted)).unwrap();
    answer["predictions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["p"].as_f64().unwrap().to_bits())
        .collect()
}

/// What a model fitted on the first `through` observations of `series` predicts having then
/// learned the rest online.
fn fitted_then_online(spec: &str, series: &TimeSeries, through: usize) -> Vec<u64> {
    let spec: ModelSpec = spec.parse().unwrap();
    let mut model = spec
        .fit(
            &series.times[..through],
            &series.values[..through],
            &FitOptions::default(),
        )
        .unwrap()
        .model;
    model
        .observe(&series.times[through..], &series.values[through..])
        .unwrap();
    probe_times()
        .iter()
        .map(|&t| model.predict(t).to_bits())
        .collect()
}

fn refit_on_request(name: &str, backend: Backend) {
    let data = scratch(name);
    let port = free_port();
    let only_on_request = ["--refit-every", "0", "--refit-secs", "0"];
    let server = start(&data, port, &backend, &only_on_request);
    let runtime = runtime();
    let client = Client::new(&server.url, Some(token(&data))).unwrap();
    let door = greg_training();
    let specs = [("door-auto", "auto"), ("door-order", "fremen:auto")];
    for (id, spec) in specs {
        runtime
            .block_on(client.create(id, Some(spec), None))
            .unwrap();
        add(&runtime, &client, id, &door);
        // Not fitted yet: the prior of a model that knows nothing, and what is kept.
        assert!(served(&runtime, &client, id) == vec![0.5f64.to_bits(); probe_times().len()]);
        let info = runtime.block_on(client.view(id)).unwrap();
        assert_eq!(info.model, spec);
        assert_eq!(info.observations, 96_480);
        let refit = info.refit.unwrap();
        assert_eq!(
            (refit.kept, refit.keep, refit.since_fit),
            (96_480, 1 << 21, 96_480)
        );
        assert!(refit.last_fit.is_none());
    }

    // `auto` through the command-line client, `fremen:auto` through the typed client.
    let out = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(["client", "--url", &server.url, "--token-file"])
        .arg(data.join("token"))
        .args(["refit", "door-auto", "--json"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let answer: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(answer["refitted"], true);
    assert_eq!(answer["fit"]["observations"], 96_480);
    assert_eq!(answer["fit"]["through"], 96_480);
    assert_eq!(answer["fit"]["first_time"], door.times[0]);
    assert_eq!(answer["fit"]["last_time"], door.times[96_479]);
    let weights = answer["fit"]["weights"].as_array().unwrap();
    let members = weights.len();
    assert!(members > 1, "{answer}");
    assert_eq!(answer["fit"]["fitted"], format!("stack of {members}"));
    let total: f64 = weights.iter().map(|w| w["weight"].as_f64().unwrap()).sum();
    assert!((total - 1.0).abs() < 1e-12, "{answer}");
    let order = runtime.block_on(client.refit("door-order")).unwrap();
    assert!(order.refitted && order.fit.fitted.starts_with("fremen:"));
    assert!(order.fit.error.is_some() && order.fit.weights.is_empty());
    // A second request with nothing new makes no new fit.
    let again = runtime.block_on(client.refit("door-order")).unwrap();
    assert!(!again.refitted);
    assert_eq!((again.fit.clone(), again.secs), (order.fit.clone(), 0.0));
    // Models that learn online have nothing to refit.
    runtime
        .block_on(client.create("door-online", Some("fremen:2"), None))
        .unwrap();
    let error = runtime
        .block_on(client.refit("door-online"))
        .unwrap_err()
        .to_string();
    assert!(
        error.starts_with("400") && error.contains("learns online"),
        "{error}"
    );

    // Exactly what `chronomap fit` and `chronomap predict` say of the same file.
    let offline: Vec<Vec<u64>> = specs
        .iter()
        .map(|(_, spec)| fit_and_predict(&data, spec))
        .collect();
    for ((id, spec), expected) in specs.iter().zip(&offline) {
        assert_eq!(&served(&runtime, &client, id), expected, "{spec}");
    }

    // SIGKILL right after the refits (no checkpoint since: they are only in the log). A new
    // client each time: the old one's connections went with the killed process.
    server.kill();
    let server = start(&data, port, &backend, &only_on_request);
    let client = Client::new(&server.url, Some(token(&data))).unwrap();
    for ((id, _), expected) in specs.iter().zip(&offline) {
        assert_eq!(
            &served(&runtime, &client, id),
            expected,
            "{id} after SIGKILL"
        );
    }
    let info = runtime.block_on(client.view("door-order")).unwrap();
    assert_eq!(info.refit.unwrap().last_fit.unwrap(), order.fit);

    // A week more, learned online by the fitted models; SIGKILL, then a graceful restart
    // (snapshots of the kept observations and the fits).
    let week = &greg_tests()[0];
    let mut all = door.clone();
    all.times.extend_from_slice(&week.times);
    all.values.extend_from_slice(&week.values);
    let online: Vec<Vec<u64>> = specs
        .iter()
        .map(|(_, spec)| fitted_then_online(spec, &all, 96_480))
        .collect();
    for (id, _) in specs {
        add(&runtime, &client, id, week);
    }
    server.kill();
    let server = start(&data, port, &backend, &only_on_request);
    let client = Client::new(&server.url, Some(token(&data))).unwrap();
    for ((id, _), expected) in specs.iter().zip(&online) {
        assert_eq!(&served(&runtime, &client, id), expected, "{id}");
    }
    server.stop();
    let server = start(&data, port, &backend, &only_on_request);
    let client = Client::new(&server.url, Some(token(&data))).unwrap();
    for ((id, _), expected) in specs.iter().zip(&online) {
        assert_eq!(
            &served(&runtime, &client, id),
            expected,
            "{id} after a restart"
        );
        let info = runtime.block_on(client.view(id)).unwrap();
        assert_eq!(info.refit.unwrap().since_fit, week.times.len() as u64);
    }
}

on_each_backend!(
    refit_on_request,
    "refit",
    auto_and_fremen_auto_refitted_on_request_predict_as_chronomap_fit_redb,
    auto_and_fremen_auto_refitted_on_request_predict_as_chronomap_fit_postgres
);

/// `chronomap serve` with its standard output kept (the refit log).
fn start_logged(
    data: &std::path::Path,
    port: u16,
    extra: &[&str],
) -> (Server, Arc<Mutex<Vec<String>>>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(["serve", "--data"])
        .arg(data)
        .args(["--listen", &format!("127.0.0.1:{port}")])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let first = lines.next().unwrap().unwrap();
    assert!(first.contains("listening on"), "{first}");
    let log = Arc::new(Mutex::new(Vec::new()));
    let kept = Arc::clone(&log);
    std::thread::spawn(move || {
        for line in lines.map_while(Result::ok) {
            kept.lock().unwrap().push(line);
        }
    });
    let server = Server {
        child,
        url: format!("http://127.0.0.1:{port}"),
        started_in: Duration::ZERO,
    };
    (server, log)
}

/// Waits until the model's last fit covers `through` observations.
fn wait_for_fit(runtime: &tokio::runtime::Runtime, client: &Client, id: &str, through: u64) {
    let start = Instant::now();
    loop {
        let info = runtime.block_on(client.view(id)).unwrap();
        let fit = info.refit.and_then(|r| r.last_fit).map(|f| f.through);
        if fit == Some(through) {
            return;
        }
        assert!(
            start.elapsed() < Duration::from_secs(120),
            "{id}: no fit of {through} observations (last: {fit:?})"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn auto_is_refitted_on_a_schedule_logged_and_kept_across_sigkill() {
    let data = scratch("serve_refit_schedule");
    let port = free_port();
    let flags = ["--refit-every", "40000", "--refit-secs", "0"];
    let (server, log) = start_logged(&data, port, &flags);
    let runtime = runtime();
    let client = Client::new(&server.url, Some(token(&data))).unwrap();
    let door = greg_training();
    let first = |n: usize| TimeSeries {
        times: door.times[..n].to_vec(),
        values: door.values[..n].to_vec(),
    };
    runtime
        .block_on(client.create("door", Some("auto"), None))
        .unwrap();
    // 20,000 observations: not due; 40,000: due, refitted in the background.
    add(&runtime, &client, "door", &first(20_000));
    std::thread::sleep(Duration::from_millis(300));
    let info = runtime.block_on(client.view("door")).unwrap();
    assert!(info.refit.unwrap().last_fit.is_none());
    let rest = |from: usize, to: usize| TimeSeries {
        times: door.times[from..to].to_vec(),
        values: door.values[from..to].to_vec(),
    };
    add(&runtime, &client, "door", &rest(20_000, 40_000));
    wait_for_fit(&runtime, &client, "door", 40_000);
    let expected = fitted_then_online("auto", &first(40_000), 40_000);
    assert_eq!(served(&runtime, &client, "door"), expected);
    // The rest in one request: due again.
    let last = rest(40_000, door.times.len());
    runtime
        .block_on(client.add_values("door", &last.times, &last.values, None))
        .unwrap();
    wait_for_fit(&runtime, &client, "door", 96_480);
    let expected = fit_and_predict(&data, "auto");
    assert_eq!(served(&runtime, &client, "door"), expected);
    // Each refit is one line of the log.
    let lines: Vec<String> = log
        .lock()
        .unwrap()
        .iter()
        .filter(|l| l.starts_with("refit: "))
        .cloned()
        .collect();
    assert_eq!(lines.len(), 2, "{lines:?}");
    for (line, n) in lines.iter().zip(["40000", "96480"]) {
        assert!(
            line.starts_with("refit: refit of model \"door\" (auto, scheduled): stack of ")
                && line.contains(&format!(" on {n} observations 2016-01-04"))
                && line.contains("; log position "),
            "{line}"
        );
    }
    server.kill();
    let server = start(&data, port, &Backend::Redb, &flags);
    let client = Client::new(&server.url, Some(token(&data))).unwrap();
    assert_eq!(served(&runtime, &client, "door"), expected);
}
