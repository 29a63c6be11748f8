//! `chronomap serve` + `chronomap client` on the bundled Greg door data: ten weeks of minute
//! observations added through the command-line client predict exactly what the same model
//! predicts when trained in one process, and the service documents every endpoint.

use crate::common::{chronomap, repo, stdout};
use crate::service;

use std::process::Command;

use chronomap_client::Client;
use chronomap_core::{FremenModel, TemporalModel};
use service::{Backend, free_port, scratch, start};

const TRAIN: &str = "data/door_greg_2016/training_data.txt.xz";

fn client_command(url: &str, data: &std::path::Path, args: &[&str]) -> String {
    let output = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(["client", "--url", url, "--token-file"])
        .arg(data.join("token"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "chronomap client {args:?}: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    String::from_utf8(output.stdout).unwrap()
}

#[test]
fn door_data_through_the_service_predict_as_the_model_trained_offline() {
    let data = scratch("serve_cli_door");
    let server = start(&data, free_port(), &Backend::Redb, &[]);
    let out = client_command(
        &server.url,
        &data,
        &[
            "add",
            "greg-door",
            "--file",
            TRAIN,
            "--model",
            "fremen:2",
            "--batch",
            "20000",
        ],
    );
    assert_eq!(out.trim(), "added 96480 observations to \"greg-door\"");

    let series = chronomap_io::read_pairs(TRAIN).unwrap();
    let mut reference = FremenModel::with_order(2);
    reference.observe(&series.times, &series.values).unwrap();
    // The day after the training data (2016-03-14), hour by hour.
    let day: Vec<f64> = (0..=24)
        .map(|h| 1_457_913_600.0 + h as f64 * 3600.0)
        .collect();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let client = Client::new(&server.url, None).unwrap();
    let served = runtime
        .block_on(client.predict("greg-door", &day, None))
        .unwrap();
    let expected = reference.predict_many(&day);
    assert_eq!(served.values, expected);
    // The door's daily rhythm: closed at night, open now and then around midday.
    assert!(expected[3] < 0.01 && expected[13] > 0.25, "{expected:?}");

    let table = client_command(
        &server.url,
        &data,
        &[
            "predict",
            "greg-door",
            "--from",
            "2016-03-14T00:00Z",
            "--to",
            "2016-03-15T00:00Z",
            "--step",
            "3600",
        ],
    );
    let rows: Vec<&str> = table.lines().skip(1).collect();
    assert_eq!(rows.len(), 25);
    for (row, p) in rows.iter().zip(&expected) {
        let printed: f64 = row.split('\t').nth(1).unwrap().parse().unwrap();
        assert!((printed - p).abs() <= 5e-5, "{row} vs {p}");
    }

    // evaluate: the binary error of every order on the first test week, as computed here.
    let out = client_command(
        &server.url,
        &data,
        &[
            "evaluate",
            "greg-door",
            "--file",
            "data/door_greg_2016/test_times_1.txt.xz,data/door_greg_2016/test_data_1.txt.xz",
            "--max-order",
            "4",
        ],
    );
    let test = chronomap_io::read_test_set(
        "data/door_greg_2016/test_times_1.txt.xz",
        "data/door_greg_2016/test_data_1.txt.xz",
    )
    .unwrap();
    let mismatches = test
        .times
        .iter()
        .zip(&test.values)
        .filter(|&(&t, &s)| (reference.predict(t) > 0.5) != (s > 0.5))
        .count();
    let error = mismatches as f64 / test.times.len() as f64;
    let order2 = out.lines().find(|l| l.starts_with("2\t")).unwrap();
    let printed: f64 = order2.split('\t').nth(1).unwrap().parse().unwrap();
    assert!((printed - error).abs() <= 5e-5, "{order2} vs {error}");

    // View: the two strongest periodicities of the door are the day and the week.
    let info = runtime.block_on(client.view("greg-door")).unwrap();
    let mut periods: Vec<f64> = info.components.iter().map(|c| c.period_secs).collect();
    periods.sort_by(f64::total_cmp);
    assert_eq!(periods, [86_400.0, 604_800.0]);
}

#[test]
fn every_endpoint_is_documented_and_the_web_page_is_served() {
    let data = scratch("serve_cli_openapi");
    let server = start(&data, free_port(), &Backend::Redb, &[]);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let client = Client::new(&server.url, None).unwrap();
    let get = |path: &str| {
        let (status, text) = runtime
            .block_on(client.raw(chronomap_client::Method::GET, path, vec![], None))
            .unwrap();
        assert_eq!(status, 200, "{path}");
        text
    };
    let spec: serde_json::Value = serde_json::from_str(&get("/openapi.json")).unwrap();
    let expected = [
        ("/v1/health", "get"),
        ("/v1/models", "get"),
        ("/v1/models/{id}", "get"),
        ("/v1/models/{id}", "put"),
        ("/v1/models/{id}", "delete"),
        ("/v1/models/{id}/observations", "get"),
        ("/v1/add", "post"),
        ("/v1/addvalues", "post"),
        ("/v1/observations", "post"),
        ("/v1/predict", "post"),
        ("/v1/entropy", "post"),
        ("/v1/forecast", "post"),
        ("/v1/forecastEntropy", "post"),
        ("/v1/evaluate", "post"),
        ("/v1/detect", "post"),
        ("/v1/maps", "get"),
        ("/v1/topo/{name}/predict", "post"),
        ("/v1/topo/{name}/plan", "post"),
        ("/v1/grid/{name}/predict", "post"),
    ];
    let paths = spec["paths"].as_object().unwrap();
    let documented: usize = paths.values().map(|p| p.as_object().unwrap().len()).sum();
    assert_eq!(documented, expected.len());
    for (path, method) in expected {
        assert!(
            paths[path][method].is_object(),
            "{method} {path} is not documented"
        );
    }
    // Writes declare the bearer token.
    assert!(paths["/v1/add"]["post"]["security"].is_array());
    assert_eq!(
        spec["components"]["securitySchemes"]["bearer"]["scheme"],
        "bearer"
    );
    let page = get("/");
    assert!(page.contains("/v1/predict") && page.contains("<svg"));
}

#[test]
fn the_readme_service_example_runs() {
    if Command::new("curl").arg("--version").output().is_err() {
        eprintln!("skipped: the README example needs curl");
        return;
    }
    let readme = include_str!("../../README.md");
    let block = readme
        .split("<!-- service-example")
        .nth(1)
        .and_then(|rest| rest.split("```sh\n").nth(1))
        .and_then(|rest| rest.split("\n```").next())
        .expect("the service example block in README.md");
    let data = scratch("serve_cli_readme");
    let port = free_port();
    let (serve_line, script) = block.split_once('\n').unwrap();
    assert!(serve_line.starts_with("chronomap serve --data chronomap-data &"));
    let _server = start(&data, port, &Backend::Redb, &[]);
    let script = script
        .replace("chronomap-data", &data.display().to_string())
        .replace("8470", &port.to_string());
    let bin_dir = std::path::Path::new(env!("CARGO_BIN_EXE_chronomap"))
        .parent()
        .unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let output = Command::new("bash")
        .args(["-euo", "pipefail", "-c", &script])
        .env("PATH", path)
        .env("CHRONOMAP_URL", format!("http://127.0.0.1:{port}"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(stdout.contains(r#"{"observations":4,"seq":1}"#), "{stdout}");
    assert!(stdout.contains("added 96480 observations"), "{stdout}");
    assert!(
        stdout.contains(r#"{"values":[0.0,0.0,0.0,0.0,0.0,0.0,0.03783847058902408,"#),
        "{stdout}"
    );
    assert!(stdout.contains("2016-03-14 13:00 UTC\t0.2913"), "{stdout}");
}

#[test]
fn forecast_entropy_detect_ranges_and_remove_answer_as_the_models_do() {
    use chronomap_core::binary_entropy;
    use chronomap_serve::api::{DetectRequest, ForecastRequest};

    let data = scratch("serve_cli_operations");
    let server = start(&data, free_port(), &Backend::Redb, &[]);
    let token = service::token(&data);
    let client = Client::new(&server.url, Some(token)).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let series = chronomap_io::read_pairs(TRAIN).unwrap();
    // Two doors: the first five weeks and the last five weeks of the Greg door.
    let half = series.times.len() / 2;
    let parts = [(0, half), (half, series.times.len())];
    let mut references = Vec::new();
    for (k, &(a, b)) in parts.iter().enumerate() {
        let id = format!("door-{k}");
        runtime
            .block_on(client.create(&id, Some("fremen:4"), None))
            .unwrap();
        runtime
            .block_on(client.add_values(&id, &series.times[a..b], &series.values[a..b], None))
            .unwrap();
        let mut model = FremenModel::with_order(4);
        model
            .observe(&series.times[a..b], &series.values[a..b])
            .unwrap();
        references.push(model);
    }
    let t = 1_457_956_800.0; // 2016-03-14 12:00 UTC
    let request = ForecastRequest {
        ids: vec!["door-0".into(), "door-1".into()],
        time: t,
        order: None,
        orders: Some(vec![1, 3]),
    };
    let forecast = runtime.block_on(client.forecast(&request)).unwrap();
    let entropies = runtime.block_on(client.forecast_entropy(&request)).unwrap();
    for (k, order) in [1, 3].into_iter().enumerate() {
        let mut model = references[k].clone();
        chronomap_core::Ordered::set_order(&mut model, order);
        assert_eq!(forecast.values[k], model.predict(t));
        assert_eq!(entropies.values[k], binary_entropy(model.predict(t)));
    }

    // detect: the observations of the first test week that the model finds anomalous.
    let test = chronomap_io::read_test_set(
        "data/door_greg_2016/test_times_1.txt.xz",
        "data/door_greg_2016/test_data_1.txt.xz",
    )
    .unwrap();
    let detect = DetectRequest {
        id: "door-1".into(),
        times: test.times.clone(),
        values: test.values.clone(),
        confidence: 0.8,
        order: None,
    };
    let found = runtime.block_on(client.detect(&detect)).unwrap().anomalies;
    let expected: Vec<f64> = test
        .times
        .iter()
        .zip(&test.values)
        .filter(|&(&t, &v)| (v - references[1].predict(t)).abs() >= 0.8)
        .map(|(&t, _)| t)
        .collect();
    assert!(!expected.is_empty());
    assert_eq!(found.iter().map(|a| a.time).collect::<Vec<_>>(), expected);

    // A continuous state in a range: temperatures 10..30 °C.
    runtime
        .block_on(client.create("lab-temperature", Some("hist:24:86400"), Some([10.0, 30.0])))
        .unwrap();
    runtime
        .block_on(client.add_values("lab-temperature", &[3600.0, 90_000.0], &[14.0, 18.0], None))
        .unwrap();
    let p = runtime
        .block_on(client.predict("lab-temperature", &[5400.0], None))
        .unwrap();
    // Both observations fall in the same hourly bin of the day: (0.2 + 0.4) / 2.
    assert!((p.values[0] - 0.3).abs() < 1e-12, "{p:?}");
    assert!(
        (p.scaled.as_ref().unwrap()[0] - 16.0).abs() < 1e-10,
        "{p:?}"
    );
    let out_of_range = runtime
        .block_on(client.add_values("lab-temperature", &[200_000.0], &[31.0], None))
        .unwrap_err();
    assert_eq!(
        out_of_range.status(),
        Some(chronomap_client::StatusCode::BAD_REQUEST)
    );

    // remove, then the model is gone and its id free for another kind.
    runtime.block_on(client.remove("door-0")).unwrap();
    let gone = runtime.block_on(client.view("door-0")).unwrap_err();
    assert_eq!(gone.status(), Some(chronomap_client::StatusCode::NOT_FOUND));
    runtime
        .block_on(client.create("door-0", Some("stm"), None))
        .unwrap();
    let list = runtime.block_on(client.list()).unwrap();
    let kinds: Vec<(&str, &str)> = list
        .models
        .iter()
        .map(|m| (m.id.as_str(), m.model.as_str()))
        .collect();
    assert_eq!(
        kinds,
        [
            ("door-0", "stm"),
            ("door-1", "fremen:4"),
            ("lab-temperature", "hist:24:86400")
        ]
    );
}

#[test]
fn topological_maps_and_grids_are_served_as_their_models_predict_and_plan() {
    use chronomap_grid::{FremenGrid, GridConfig, GridGeometry};
    use chronomap_serve::maps::{EdgesResponse, GridResponse, PlanResponse};
    use chronomap_topo::mdp::SolverOptions;
    use chronomap_topo::plan::{Task, plan_at};

    let data = scratch("serve_cli_maps");
    // The Witham Wharf deployment's edge models, fitted by the command line.
    let witham = data.join("witham.cmt");
    stdout(&chronomap(&[
        "topo",
        "fit",
        "--edges",
        &repo("data/witham_topological_nav/edges"),
        "-o",
        &witham.display().to_string(),
        "--success-order",
        "1",
    ]));
    // A small grid: a door cell open by day, a wall, a free cell; three days of frames.
    let geometry = GridGeometry::planar(3, 1, 0.5, [0.0, 0.0]).unwrap();
    let mut grid = FremenGrid::new(geometry, GridConfig::default()).unwrap();
    for k in 0..3 * 48 {
        let t = 1_400_000_000.0 + k as f64 * 1800.0;
        let day = ((t % 86_400.0) / 3600.0 - 12.0).abs() < 5.0;
        grid.observe_occupancy(t, &[if day { 0 } else { 100 }, 100, 0])
            .unwrap();
    }
    let grid_path = data.join("door.cmg");
    chronomap_io::grid_file::write_grid_file(
        &grid_path,
        &chronomap_io::grid_file::GridFile::State(Box::new(grid.clone())),
    )
    .unwrap();

    let topo_flag = format!("witham={}", witham.display());
    let grid_flag = format!("door={}", grid_path.display());
    let server = start(
        &data,
        free_port(),
        &Backend::Redb,
        &["--topo", &topo_flag, "--grid", &grid_flag],
    );
    let client = Client::new(&server.url, None).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let post = |path: &str, body: serde_json::Value| -> (u16, String) {
        let (status, text) = runtime
            .block_on(client.raw(
                chronomap_client::Method::POST,
                path,
                body.to_string().into_bytes(),
                None,
            ))
            .unwrap();
        (status.as_u16(), text)
    };

    let models = chronomap_io::model_file::read_edge_models(&witham).unwrap();
    let t = 1_409_839_200.0; // 2014-09-04 14:00 UTC
    let (status, text) = post("/v1/topo/witham/predict", serde_json::json!({ "time": t }));
    assert_eq!(status, 200, "{text}");
    let edges: EdgesResponse = serde_json::from_str(&text).unwrap();
    let (success, duration) = models.at(t);
    assert_eq!(edges.edges.len(), 61);
    for (k, e) in edges.edges.iter().enumerate() {
        assert_eq!(
            (e.success, e.duration_secs),
            (success[k], duration[k]),
            "{}",
            e.id
        );
    }
    let door = edges
        .edges
        .iter()
        .find(|e| e.id == "LabDoor1_LabDoor2")
        .unwrap();
    assert_eq!(
        (door.from.as_str(), door.to.as_str()),
        ("LabDoor1", "LabDoor2")
    );

    // Now or later: the night against the afternoon, as the planner in one process says.
    let times = [1_409_796_000.0, t]; // 02:00 and 14:00
    let (status, text) = post(
        "/v1/topo/witham/plan",
        serde_json::json!({ "from": "Station", "task": "F Kitchen", "times": times }),
    );
    assert_eq!(status, 200, "{text}");
    let plans: PlanResponse = serde_json::from_str(&text).unwrap();
    let task = Task::parse("F Kitchen", models.map()).unwrap();
    let start_node = models.map().node("Station").unwrap();
    for (served, &time) in plans.plans.iter().zip(&times) {
        let expected =
            plan_at(&models, start_node, &task, time, &SolverOptions::default()).unwrap();
        assert_eq!(
            (served.pmax, served.expected_secs),
            (expected.pmax, expected.expected_secs)
        );
        assert_eq!(
            served.first_edge,
            expected
                .first_edge
                .map(|e| models.map().edges()[e].id.clone())
        );
    }
    assert!(plans.plans[0].pmax < plans.plans[1].pmax, "{plans:?}");
    let (status, text) = post(
        "/v1/topo/witham/plan",
        serde_json::json!({ "from": "Station", "task": "F Kitchn", "times": [t] }),
    );
    assert_eq!(status, 400);
    assert!(text.contains("did you mean"), "{text}");

    let (status, text) = post("/v1/grid/door/predict", serde_json::json!({ "time": t }));
    assert_eq!(status, 200, "{text}");
    let served: GridResponse = serde_json::from_str(&text).unwrap();
    assert_eq!(served.shape, [3, 1, 1]);
    assert_eq!(served.values, grid.predict_map(t));
    let (status, _) = post("/v1/grid/nope/predict", serde_json::json!({ "time": t }));
    assert_eq!(status, 404);
}

#[test]
fn the_client_prints_json_and_refuses_contradicting_flags_before_connecting() {
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_chronomap"))
            .args(args)
            .output()
            .unwrap()
    };
    // No service runs at this address: the usage errors come first (exit 2), then a refused
    // connection is a failure at run time (exit 1).
    let url = format!("http://127.0.0.1:{}", free_port());
    for (args, expected) in [
        (vec!["predict", "door"], "give --at TIMES"),
        (
            vec!["predict", "door", "--from", "100", "--to", "50"],
            "--to is before --from",
        ),
        (
            vec![
                "predict", "door", "--from", "0", "--to", "1e9", "--step", "1",
            ],
            "choose a larger --step",
        ),
    ] {
        let mut all = vec!["client", "--url", &url];
        all.extend(args);
        let out = run(&all);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(expected), "{err}");
    }
    let out = run(&["client", "--url", &url, "predict", "door", "--at", "0,3600"]);
    assert_eq!(out.status.code(), Some(1));

    let data = scratch("serve_cli_json");
    let server = start(&data, free_port(), &Backend::Redb, &[]);
    let json = |args: &[&str]| -> serde_json::Value {
        let mut all = args.to_vec();
        all.push("--json");
        serde_json::from_str(&client_command(&server.url, &data, &all)).unwrap()
    };
    let v = json(&["add", "greg-door", "--file", TRAIN, "--model", "fremen:2"]);
    assert_eq!(v["added"], 96_480);
    assert_eq!(v["id"], "greg-door");
    let series = chronomap_io::read_pairs(TRAIN).unwrap();
    let mut reference = FremenModel::with_order(2);
    reference.observe(&series.times, &series.values).unwrap();
    // Three hours of the day after the data, as ISO 8601 and seconds, comma-separated.
    let v = json(&[
        "predict",
        "greg-door",
        "--at",
        "2016-03-14T03:00Z,1457960400",
        "--at",
        "1457964000",
    ]);
    let times = [1_457_924_400.0, 1_457_960_400.0, 1_457_964_000.0];
    assert_eq!(v["times"], serde_json::json!(times));
    let expected = reference.predict_many(&times);
    let served: Vec<f64> = v["probability"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p.as_f64().unwrap())
        .collect();
    assert_eq!(served, expected);
    assert_eq!(v["entropy"].as_array().unwrap().len(), 3);
    let v = json(&["list"]);
    assert_eq!(v["models"][0]["id"], "greg-door");
    assert_eq!(v["models"][0]["observations"], 96_480);
    let v = json(&["forecast", "--ids", "greg-door", "--at", "1457960400"]);
    assert_eq!(v["probability"][0].as_f64(), Some(expected[1]));
    let v = json(&["remove", "greg-door"]);
    assert_eq!(v["removed"], true);
    assert!(json(&["list"])["models"].as_array().unwrap().is_empty());
}
