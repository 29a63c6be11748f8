//! `chronomap serve` + `chronomap client` on the bundled Greg door data: ten weeks of minute
//! observations added through the command-line client predict exactly what the same model
//! predicts when trained in one process, and the service documents every endpoint.

use crate::common::{assert_mentions, chronomap, error, fit_witham, repo, stdout, usage_error};
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
        ("/v1/models/{id}/refit", "post"),
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
        ("/v1/topo/{name}", "get"),
        ("/v1/topo/{name}/predict", "post"),
        ("/v1/topo/{name}/plan", "post"),
        ("/v1/grid/{name}", "get"),
        ("/v1/grid/{name}/predict", "post"),
        ("/v1/grid/{name}/cell", "post"),
        ("/v1/activity/{name}", "get"),
        ("/v1/activity/{name}/predict", "post"),
        ("/v1/bt/monitors", "get"),
        ("/v1/bt/monitors/{id}", "get"),
        ("/v1/bt/monitors/{id}/events", "get"),
        ("/v1/bt/monitors/{id}/transitions", "get"),
        ("/v1/bt/monitors/{id}/blackboard", "get"),
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
    // The deadline of a plan request and its answer are described.
    let schemas = &spec["components"]["schemas"];
    for field in ["deadline_secs", "confidence", "bucket_secs", "curve"] {
        assert!(
            schemas["PlanRequest"]["properties"][field].is_object(),
            "{field}"
        );
    }
    assert!(schemas["PlanResult"]["properties"]["deadline"].is_object());
    assert!(schemas["DeadlineResult"]["properties"]["probability"].is_object());
    // Writes declare the bearer token.
    assert!(paths["/v1/add"]["post"]["security"].is_array());
    assert!(paths["/v1/models/{id}/refit"]["post"]["security"].is_array());
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
    use chronomap_grid::AnyGrid;
    use chronomap_grid::{FremenGrid, GridConfig, GridGeometry, OrderChoice};
    use chronomap_serve::maps::{
        CellResponse, EdgesResponse, GridInfo, GridResponse, MapsResponse, PlanResponse, TopoInfo,
    };
    use chronomap_topo::mdp::SolverOptions;
    use chronomap_topo::plan::{Task, plan_at};

    let data = scratch("serve_cli_maps");
    // The Witham Wharf deployment's edge models, fitted by the command line.
    let witham = data.join("witham.cmt");
    fit_witham(&witham.display().to_string(), &["--success-order", "1"]);
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
    chronomap_io::grid_file::write_grid_file(&grid_path, &AnyGrid::State(Box::new(grid.clone())))
        .unwrap();
    // The same grid as the compact model, with order 1 in the door cell.
    let lossy = grid.fitted(
        OrderChoice::PerCell(vec![1, 0, 0]),
        chronomap_core::Parallelism::Sequential,
    );
    let lossy_path = data.join("door-lossy.cmg");
    chronomap_io::grid_file::write_grid_file(&lossy_path, &AnyGrid::Lossy(Box::new(lossy.clone())))
        .unwrap();

    let topo_flag = format!("witham={}", witham.display());
    let grid_flag = format!(
        "door={},lossy={}",
        grid_path.display(),
        lossy_path.display()
    );
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
    let get = |path: &str| -> (u16, String) {
        let (status, text) = runtime
            .block_on(client.raw(chronomap_client::Method::GET, path, vec![], None))
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
        let interval = models.duration_interval(k, t, 0.9).unwrap();
        assert_eq!(e.duration_interval_secs, Some([interval.0, interval.1]));
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
    assert_eq!(
        served.values,
        grid.predict_map(t, chronomap_core::Parallelism::Sequential)
    );
    let (status, _) = post("/v1/grid/nope/predict", serde_json::json!({ "time": t }));
    assert_eq!(status, 404);

    let (status, text) = get("/v1/maps");
    assert_eq!(status, 200, "{text}");
    let kinds: Vec<(String, String, u64)> = serde_json::from_str::<MapsResponse>(&text)
        .unwrap()
        .maps
        .into_iter()
        .map(|m| (m.name, m.kind, m.size))
        .collect();
    assert_eq!(
        kinds,
        [
            ("witham".into(), "topological".into(), 18),
            ("door".into(), "grid-state".into(), 3),
            ("lossy".into(), "grid-lossy".into(), 3),
        ]
    );

    // The map as a viewer draws it: the edge files carry no positions, so they are computed
    // (once, at start) by the library's layout, one edge length apart.
    let (status, text) = get("/v1/topo/witham");
    assert_eq!(status, 200, "{text}");
    let info: TopoInfo = serde_json::from_str(&text).unwrap();
    assert_eq!(
        (info.positions.as_str(), info.layout_file),
        ("computed", None)
    );
    let layout = chronomap_topo::layout::stress_layout(models.map(), 1.0);
    assert_eq!(info.nodes.len(), 18);
    for ((node, served), xy) in models.map().nodes().iter().zip(&info.nodes).zip(&layout) {
        assert_eq!((&served.name, [served.x, served.y]), (&node.name, *xy));
    }
    let served_edges: Vec<(&str, &str, &str)> = info
        .edges
        .iter()
        .map(|e| (e.id.as_str(), e.from.as_str(), e.to.as_str()))
        .collect();
    let predicted_edges: Vec<(&str, &str, &str)> = edges
        .edges
        .iter()
        .map(|e| (e.id.as_str(), e.from.as_str(), e.to.as_str()))
        .collect();
    assert_eq!(served_edges, predicted_edges);
    assert_eq!(
        (info.first_time, info.last_time),
        chronomap_serve::maps::training_span(&models)
    );
    assert_eq!(info.last_time, models.last_time());
    let first = info.first_time.unwrap();
    assert!(first < info.last_time.unwrap() && first > 1.3e9, "{first}");

    // The grids' shapes and frames, and single cells at many times: the served map's values.
    let (status, text) = get("/v1/grid/door");
    assert_eq!(status, 200, "{text}");
    let info: GridInfo = serde_json::from_str(&text).unwrap();
    let frames = (1_400_000_000.0, 1_400_000_000.0 + 143.0 * 1800.0);
    assert_eq!(
        (info.kind.as_str(), info.shape, info.resolution, info.origin),
        ("grid-state", [3, 1, 1], 0.5, [0.0, 0.0, 0.0])
    );
    assert_eq!(
        (info.frames, info.first_time, info.last_time),
        (144, Some(frames.0), Some(frames.1))
    );
    let (status, text) = get("/v1/grid/lossy");
    assert_eq!(status, 200, "{text}");
    let info: GridInfo = serde_json::from_str(&text).unwrap();
    assert_eq!(
        (info.kind.as_str(), info.frames, info.last_time),
        ("grid-lossy", 144, Some(frames.1))
    );
    let day: Vec<f64> = (0..48).map(|h| t + h as f64 * 1800.0).collect();
    for (name, maps) in [
        (
            "door",
            day.iter()
                .map(|&t| grid.predict_map(t, chronomap_core::Parallelism::Sequential))
                .collect::<Vec<_>>(),
        ),
        ("lossy", day.iter().map(|&t| lossy.predict_map(t)).collect()),
    ] {
        for x in 0..3u32 {
            let (status, text) = post(
                &format!("/v1/grid/{name}/cell"),
                serde_json::json!({ "cell": [x, 0], "times": day }),
            );
            assert_eq!(status, 200, "{text}");
            let cell: CellResponse = serde_json::from_str(&text).unwrap();
            assert_eq!(cell.cell, [x, 0, 0]);
            assert_eq!(cell.centre, [0.25 + 0.5 * f64::from(x), 0.25, 0.25]);
            let expected: Vec<f64> = maps.iter().map(|m| f64::from(m[x as usize])).collect();
            assert_eq!(cell.values, expected, "{name} cell {x}");
        }
        // Bit for bit what /predict serves for the whole map.
        let (_, text) = post(
            &format!("/v1/grid/{name}/predict"),
            serde_json::json!({ "time": day[7] }),
        );
        let whole: GridResponse = serde_json::from_str(&text).unwrap();
        let (_, text) = post(
            &format!("/v1/grid/{name}/cell"),
            serde_json::json!({ "cell": [0, 0, 0], "times": [day[7]] }),
        );
        let cell: CellResponse = serde_json::from_str(&text).unwrap();
        assert_eq!(cell.values, [f64::from(whole.values[0])]);
    }
    let door = post(
        "/v1/grid/door/cell",
        serde_json::json!({ "cell": [0, 0], "times": day }),
    )
    .1;
    let door: CellResponse = serde_json::from_str(&door).unwrap();
    // Open (free) at 14:00, closed at 04:00.
    assert!(door.values[0] < 0.5 && door.values[28] > 0.5, "{door:?}");

    // Bad requests name the field; unknown maps are 404.
    let bad = |path: &str, body: serde_json::Value, status: u16, reason: &[&str]| {
        let (got, text) = post(path, body);
        assert_eq!(got, status, "{path}: {text}");
        let body: serde_json::Value = serde_json::from_str(&text).unwrap();
        let kind = if status == 404 {
            "not_found"
        } else {
            "bad_request"
        };
        assert_eq!(body["error"], kind, "{text}");
        for part in reason {
            assert!(body["reason"].as_str().unwrap().contains(part), "{text}");
        }
    };
    let cell_path = "/v1/grid/door/cell";
    bad(
        cell_path,
        serde_json::json!({ "cell": [3, 0], "times": [t] }),
        400,
        &["field `cell`", "[3, 0]", "shape [3, 1, 1]"],
    );
    bad(
        cell_path,
        serde_json::json!({ "cell": [0, 0, 1], "times": [t] }),
        400,
        &["field `cell`", "shape [3, 1, 1]"],
    );
    bad(
        cell_path,
        serde_json::json!({ "cell": [-1, 0], "times": [t] }),
        400,
        &["field `cell`"],
    );
    bad(
        cell_path,
        serde_json::json!({ "cell": [0], "times": [t] }),
        400,
        &["field `cell`", "[x, y] or [x, y, z]"],
    );
    bad(
        cell_path,
        serde_json::json!({ "cell": [0, 0], "times": vec![t; 10_001] }),
        400,
        &["field `times`", "1 to 10000 times, not 10001"],
    );
    bad(
        cell_path,
        serde_json::json!({ "cell": [0, 0], "times": [] }),
        400,
        &["field `times`"],
    );
    bad(
        "/v1/grid/nope/cell",
        serde_json::json!({ "cell": [0, 0], "times": [t] }),
        404,
        &["no grid named \"nope\""],
    );
    for path in ["/v1/grid/nope", "/v1/topo/nope", "/v1/activity/nope"] {
        let (status, text) = get(path);
        assert_eq!(status, 404, "{path}: {text}");
        let body: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert!(
            body["reason"].as_str().unwrap().ends_with("named \"nope\""),
            "{text}"
        );
    }
}

/// Deadline plans: `POST /v1/topo/{name}/plan` with `deadline_secs` answers, at every start
/// time, what `chronomap plan --deadline --json` prints, bit for bit, on Witham trips where the
/// plan most likely to arrive in time is not the expected-time plan.
#[test]
fn deadline_plans_are_served_as_chronomap_plan_deadline_prints_them() {
    use chronomap_serve::maps::PlanResponse;

    let data = scratch("serve_cli_deadline");
    let witham = data.join("witham.cmt").display().to_string();
    // As the README fits them.
    fit_witham(&witham, &["--success-order", "1"]);
    let topo_flag = format!("witham={witham}");
    let server = start(&data, free_port(), &Backend::Redb, &["--topo", &topo_flag]);
    let client = Client::new(&server.url, None).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let post = |body: &serde_json::Value| -> (u16, String) {
        let (status, text) = runtime
            .block_on(client.raw(
                chronomap_client::Method::POST,
                "/v1/topo/witham/plan",
                body.to_string().into_bytes(),
                None,
            ))
            .unwrap();
        (status.as_u16(), text)
    };
    // 2014-09-04 14:00 and 02:00 UTC.
    let times = [1_409_839_200.0, 1_409_796_000.0];
    // (from, task, deadline, confidence, bucket): the README's trip, two of
    // tests/cli/topo_deadline.rs, and a two-step task in buckets of 2.5 s.
    type Case<'a> = (&'a str, &'a str, f64, Option<f64>, Option<f64>);
    let cases: [Case; 4] = [
        ("Kitchen", "F Station", 100.0, Some(0.5), None),
        ("LabDoor2", "F Kitchen", 80.0, None, None),
        ("Station", "F Kitchen", 110.0, Some(0.8), None),
        (
            "Station",
            "F (Printer & F Kitchen)",
            300.0,
            Some(0.9),
            Some(2.5),
        ),
    ];
    let mut differ = 0;
    for (from, task, deadline, confidence, bucket) in cases {
        let mut body = serde_json::json!({
            "from": from, "task": task, "times": times, "deadline_secs": deadline, "curve": true,
        });
        if let Some(c) = confidence {
            body["confidence"] = c.into();
        }
        if let Some(b) = bucket {
            body["bucket_secs"] = b.into();
        }
        let started = std::time::Instant::now();
        let (status, text) = post(&body);
        assert_eq!(status, 200, "{text}");
        eprintln!(
            "{from} {task:?} within {deadline} s at 2 times: {:.1} ms",
            started.elapsed().as_secs_f64() * 1e3
        );
        // The typed answer reads back; the fields are compared as the JSON carries them.
        let typed: PlanResponse = serde_json::from_str(&text).unwrap();
        assert_eq!(typed.plans.len(), times.len());
        let served: serde_json::Value = serde_json::from_str(&text).unwrap();
        for (i, &time) in times.iter().enumerate() {
            let time_arg = time.to_string();
            let deadline_arg = deadline.to_string();
            let mut args = vec![
                "plan",
                "--model",
                &witham,
                "--from",
                from,
                "--task",
                task,
                "--time",
                &time_arg,
                "--deadline",
                &deadline_arg,
                "--json",
            ];
            let (confidence_arg, bucket_arg) = (
                confidence.map(|c| c.to_string()),
                bucket.map(|b| b.to_string()),
            );
            if let Some(c) = &confidence_arg {
                args.extend(["--confidence", c]);
            }
            if let Some(b) = &bucket_arg {
                args.extend(["--bucket-secs", b]);
            }
            let cli: serde_json::Value = serde_json::from_str(&stdout(&chronomap(&args))).unwrap();
            let plan = &served["plans"][i];
            // The expected-time plan beside it is the CLI's.
            assert_eq!(plan["time"], cli["time"]);
            assert_eq!(plan["pmax"], cli["pmax"]);
            assert_eq!(plan["expected_secs"], cli["expected_secs"]);
            assert_eq!(plan["first_edge"], cli["min_time_first_edge"]);
            let deadline_plan = plan["deadline"].as_object().unwrap();
            assert_eq!(deadline_plan.len(), 12, "{deadline_plan:?}");
            for (key, value) in deadline_plan {
                assert_eq!(value, &cli[key], "{from} {task:?} at {time}: {key}");
            }
            let curve = deadline_plan["curve"].as_array().unwrap();
            assert_eq!(
                curve.len(),
                typed.plans[i]
                    .deadline
                    .as_ref()
                    .unwrap()
                    .curve
                    .as_ref()
                    .unwrap()
                    .len()
            );
            if deadline_plan["first_edge"] != plan["first_edge"] {
                differ += 1;
            }
        }
    }
    // The afternoon trips of the README and tests/cli/topo_deadline.rs start another way.
    assert!(differ >= 2, "{differ}");
    let readme = post(&serde_json::json!({
        "from": "Kitchen", "task": "F Station", "times": [times[0]], "deadline_secs": 100,
        "confidence": 0.5,
    }));
    let plan = &serde_json::from_str::<serde_json::Value>(&readme.1).unwrap()["plans"][0];
    assert_eq!(plan["first_edge"], "Kitchen_GroundCentral");
    assert_eq!(plan["deadline"]["first_edge"], "Kitchen_Ramp2");
    assert_eq!(plan["deadline"]["reaches_confidence"], true);
    // Without `curve`, no curve; without `deadline_secs`, no deadline plan.
    assert!(plan["deadline"].get("curve").is_none(), "{plan}");
    let (status, text) = post(&serde_json::json!({
        "from": "Kitchen", "task": "F Station", "times": [times[0]],
    }));
    assert_eq!(status, 200, "{text}");
    assert!(!text.contains("deadline"), "{text}");
}

#[test]
fn laid_out_topological_maps_and_activity_maps_are_served_as_their_files_and_the_cli_say() {
    use chronomap_activity::grids::RegionGrid;
    use chronomap_serve::maps::{ActivityInfo, ActivityResponse, MapsResponse, TopoInfo};
    use chronomap_topo::TopoMap;

    let data = scratch("serve_cli_layout_activity");
    let arg = |name: &str| data.join(name).display().to_string();
    let witham = arg("witham.cmt");
    fit_witham(&witham, &["--success-order", "1"]);
    let models = chronomap_io::model_file::read_edge_models(&witham).unwrap();
    // A route graph placing every node (made-up poses), and one more node.
    let mut placed = TopoMap::new();
    let pose = |i: usize| [1.5 * i as f64 - 7.25, (i % 4) as f64 * 0.1 + 0.3, 0.0];
    for (i, node) in models.map().nodes().iter().enumerate() {
        placed.add_node(&node.name, Some(pose(i))).unwrap();
    }
    placed
        .add_node("Elsewhere", Some([100.0, 100.0, 0.0]))
        .unwrap();
    for edge in models.map().edges() {
        let name = |n: usize| models.map().nodes()[n].name.clone();
        placed
            .add_edge(&edge.id, &name(edge.from), &name(edge.to))
            .unwrap();
    }
    let layout = arg("witham.geojson");
    let metadata =
        vec![chronomap_io::topo_files::RouteEdgeMetadata::new(0.5, 10.0); placed.edges().len()];
    chronomap_io::topo_files::write_route_geojson(&layout, &placed, &metadata).unwrap();

    // A CoPA-Map fitted cheaply on the bundled ATC grid, masked by the ATC map.
    let model_path = arg("atc.cmcopa");
    stdout(&chronomap(&[
        "activity",
        "fit",
        "--train",
        &repo("data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz"),
        "--inducing",
        "10",
        "--iterations",
        "3",
        "-o",
        &model_path,
    ]));
    let model = chronomap_io::read_copa_map(&model_path).unwrap();
    let atc_map = repo("data/atc_copa_map_grid/atc_map.yaml");

    let topo_flag = format!("witham={witham}");
    let layout_flag = format!("witham={layout}");
    let activity_flag = format!("atc={model_path}");
    let activity_map_flag = format!("atc={atc_map}");
    let server = start(
        &data.join("store"),
        free_port(),
        &Backend::Redb,
        &[
            "--topo",
            &topo_flag,
            "--topo-layout",
            &layout_flag,
            "--activity",
            &activity_flag,
            "--activity-map",
            &activity_map_flag,
        ],
    );
    let client = Client::new(&server.url, None).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let call = |method: chronomap_client::Method, path: &str, body: Option<serde_json::Value>| {
        let body = body.map_or_else(Vec::new, |b| b.to_string().into_bytes());
        let (status, text) = runtime
            .block_on(client.raw(method, path, body, None))
            .unwrap();
        (status.as_u16(), text)
    };
    let get = |path: &str| call(chronomap_client::Method::GET, path, None);
    let post = |path: &str, body: serde_json::Value| {
        call(chronomap_client::Method::POST, path, Some(body))
    };

    let (status, text) = get("/v1/topo/witham");
    assert_eq!(status, 200, "{text}");
    let info: TopoInfo = serde_json::from_str(&text).unwrap();
    assert_eq!(info.positions, "file");
    assert_eq!(info.layout_file.as_deref(), Some(layout.as_str()));
    assert_eq!(info.nodes.len(), 18);
    for (i, (node, served)) in models.map().nodes().iter().zip(&info.nodes).enumerate() {
        assert_eq!(&served.name, &node.name);
        assert_eq!(
            [served.x, served.y],
            [pose(i)[0], pose(i)[1]],
            "{}",
            node.name
        );
    }
    assert_eq!(info.edges.len(), 61);

    let (status, text) = get("/v1/maps");
    assert_eq!(status, 200, "{text}");
    let maps = serde_json::from_str::<MapsResponse>(&text).unwrap().maps;
    assert_eq!(
        (maps[1].name.as_str(), maps[1].kind.as_str(), maps[1].size),
        ("atc", "activity", 49 * 49)
    );

    let (status, text) = get("/v1/activity/atc");
    assert_eq!(status, 200, "{text}");
    let info: ActivityInfo = serde_json::from_str(&text).unwrap();
    assert_eq!(
        (
            info.domain,
            info.periods,
            info.default_cell,
            info.masked_by_map
        ),
        (model.domain(), model.periods(), 0.5, true)
    );
    assert!(info.time_unit.contains("time bins"), "{}", info.time_unit);
    // The ATC training grid: bins 0 .. 119 (ten days of twelve hours).
    assert_eq!(info.t_range, [0.0, 119.0]);
    assert_eq!(info.t_range, model.time_span());

    // Every cell off the walls, bit for bit as `chronomap activity predict` writes it, and the
    // walls the cells it leaves out; the default cell is the command's default.
    for (t, cell, body) in [
        (123.0, 0.5, serde_json::json!({ "t": 123 })),
        (129.5, 1.5, serde_json::json!({ "t": 129.5, "cell": 1.5 })),
    ] {
        let (status, text) = post("/v1/activity/atc/predict", body);
        assert_eq!(status, 200, "{text}");
        let served: ActivityResponse = serde_json::from_str(&text).unwrap();
        let csv = arg(&format!("atc_{t}.csv"));
        stdout(&chronomap(&[
            "activity",
            "predict",
            "--model",
            &model_path,
            "--t",
            &t.to_string(),
            "--cell",
            &cell.to_string(),
            "--map",
            &atc_map,
            "-o",
            &csv,
        ]));
        let rows: Vec<Vec<f64>> = std::fs::read_to_string(&csv)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
            .collect();
        let grid = RegionGrid::around_centres(model.domain(), cell).unwrap();
        let (cols, rows_n) = (grid.cols, grid.rows);
        assert_eq!((served.t, served.cell), (t, cell));
        assert_eq!(served.shape, [cols as u32, rows_n as u32]);
        assert_eq!(
            served.origin,
            [grid.min[0], grid.max[1] - rows_n as f64 * cell]
        );
        assert_eq!(served.mean.len(), cols * rows_n);
        // The command lists cells from the top row; the service from the bottom one.
        let mut expected = rows.iter();
        for (i, centre) in grid.centres().iter().enumerate() {
            let (col, row) = (i % cols, rows_n - 1 - i / cols);
            let at = col + cols * row;
            let lower_left = [
                served.origin[0] + col as f64 * cell,
                served.origin[1] + row as f64 * cell,
            ];
            assert!((centre[0] - lower_left[0] - cell / 2.0).abs() < 1e-9);
            assert!((centre[1] - lower_left[1] - cell / 2.0).abs() < 1e-9);
            match (served.mean[at], served.std[at]) {
                (Some(mean), Some(std)) => {
                    let row = expected.next().expect("the command predicts this cell too");
                    assert_eq!(row[..2], centre[..], "cell {i}");
                    assert_eq!((row[2], row[3], row[4]), (t, mean, std), "cell {i}");
                }
                (None, None) => {}
                other => panic!("cell {i}: {other:?}"),
            }
        }
        assert!(expected.next().is_none(), "the command predicts more cells");
        let masked = served.mean.iter().filter(|m| m.is_none()).count();
        assert!(masked > 0 && masked < cols * rows_n / 2, "{masked}");
    }

    // Bad requests name the field; unknown maps are 404.
    for (body, status, reason) in [
        (
            serde_json::json!({ "t": 1, "cell": 0.01 }),
            400,
            "more than 250000",
        ),
        (
            serde_json::json!({ "t": 1, "cell": -1 }),
            400,
            "field `cell`",
        ),
        (
            serde_json::json!({ "t": 1, "cell": 0 }),
            400,
            "field `cell`",
        ),
        (
            serde_json::json!({ "t": 1, "cells": 1 }),
            400,
            "unknown field `cells`",
        ),
        (serde_json::json!({ "cell": 1 }), 400, "missing field `t`"),
    ] {
        let (got, text) = post("/v1/activity/atc/predict", body.clone());
        assert_eq!(got, status, "{body}: {text}");
        assert!(text.contains(reason), "{body}: {text}");
    }
    let (status, text) = post("/v1/activity/nope/predict", serde_json::json!({ "t": 1 }));
    assert_eq!(status, 404, "{text}");
    assert!(text.contains("no activity map named"), "{text}");
}

#[test]
fn a_topo_layout_that_misses_nodes_or_names_no_topo_map_stops_the_start() {
    let data = scratch("serve_cli_bad_layout");
    let arg = |name: &str| data.join(name).display().to_string();
    let witham = arg("witham.cmt");
    fit_witham(&witham, &[]);
    let models = chronomap_io::model_file::read_edge_models(&witham).unwrap();
    // A tmap2 map of 3 of the 18 nodes: 15 have no position.
    let mut partial = chronomap_topo::TopoMap::new();
    for node in &models.map().nodes()[..3] {
        partial.add_node(&node.name, Some([1.0, 2.0, 0.0])).unwrap();
    }
    let layout = arg("partial.yaml");
    chronomap_io::topo_files::write_tmap2(&layout, &partial, "partial").unwrap();
    let store = arg("store");
    let serve = |extra: &[&str]| {
        let mut args = vec!["serve", "--data", &store, "--listen", "127.0.0.1:0"];
        args.extend(extra);
        chronomap(&args)
    };
    let topo_flag = format!("witham={witham}");
    let layout_flag = format!("witham={layout}");
    let err = error(&serve(&[
        "--topo",
        &topo_flag,
        "--topo-layout",
        &layout_flag,
    ]));
    let named: Vec<&str> = models.map().nodes()[3..13]
        .iter()
        .map(|n| n.name.as_str())
        .collect();
    assert_mentions(
        &err,
        &[
            "--topo-layout witham",
            &format!("{layout}: no position for 15 of the 18 nodes of the map: "),
            &format!("{} and 5 more", named.join(", ")),
        ],
    );

    // A route graph of every node, but the first one's position is made up (synthetic).
    let mut synthetic = chronomap_topo::TopoMap::new();
    for (i, node) in models.map().nodes().iter().enumerate() {
        let pose = (i > 0).then_some([i as f64, 0.0, 0.0]);
        synthetic.add_node(&node.name, pose).unwrap();
    }
    let geojson = arg("synthetic.geojson");
    chronomap_io::topo_files::write_route_geojson(&geojson, &synthetic, &[]).unwrap();
    let geojson_flag = format!("witham={geojson}");
    let err = error(&serve(&[
        "--topo",
        &topo_flag,
        "--topo-layout",
        &geojson_flag,
    ]));
    let first = &models.map().nodes()[0].name;
    assert!(
        err.contains(&format!(
            "{geojson}: no position for 1 of the 18 nodes of the map: {first}\n"
        )),
        "{err}"
    );

    let other = format!("other={layout}");
    let err = usage_error(&serve(&["--topo", &topo_flag, "--topo-layout", &other]));
    assert!(
        err.contains("--topo-layout other: no --topo map is named"),
        "{err}"
    );
    let err = usage_error(&serve(&["--activity-map", &other]));
    assert!(
        err.contains("--activity-map other: no --activity map"),
        "{err}"
    );
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

    // A continuous state in [10, 30] and its 90 % intervals: those of the Beta law matched to
    // fremen:2 models of the normalised values and of their squares.
    let (t, x): (Vec<f64>, Vec<f64>) = (0..2016)
        .map(|i| {
            let t = 600.0 * f64::from(i);
            let day = (std::f64::consts::TAU * t / 86_400.0).sin();
            let x = (0.5 + 0.3 * day + 0.15 * (f64::from(i) * 0.754).sin()).clamp(0.0, 1.0);
            (t, x)
        })
        .unzip();
    let file = scratch("serve_cli_json_values").join("temperature.txt");
    let lines: String = t
        .iter()
        .zip(&x)
        .map(|(t, x)| format!("{t} {}\n", 10.0 + 20.0 * x))
        .collect();
    std::fs::write(&file, lines).unwrap();
    json(&[
        "create",
        "temperature",
        "--range",
        "10,30",
        "--model",
        "fremen:2",
    ]);
    json(&["add", "temperature", "--file", file.to_str().unwrap()]);
    let at = ["1300000", "1300600"];
    let v = json(&[
        "predict",
        "temperature",
        "--at",
        at[0],
        "--at",
        at[1],
        "--coverage",
        "0.9",
    ]);
    assert_eq!(v["coverage"], 0.9);
    let (mut mean, mut second) = (FremenModel::with_order(2), FremenModel::with_order(2));
    // What the service learnt: the values as the file gives them, normalised.
    let normalised: Vec<f64> = x
        .iter()
        .map(|x| ((10.0 + 20.0 * x) - 10.0) / 20.0)
        .collect();
    let squares: Vec<f64> = normalised.iter().map(|x| x * x).collect();
    mean.observe(&t, &normalised).unwrap();
    second.observe(&t, &squares).unwrap();
    for (k, at) in at.iter().enumerate() {
        let time: f64 = at.parse().unwrap();
        let (m, s) = (mean.predict(time), second.predict(time));
        let (lo, hi) = chronomap_core::spread::beta_interval(m, s, 0.9);
        assert_eq!(v["lower"][k].as_f64(), Some(10.0 + 20.0 * lo), "{v}");
        assert_eq!(v["upper"][k].as_f64(), Some(10.0 + 20.0 * hi), "{v}");
        assert_eq!(v["value"][k].as_f64(), Some(10.0 + 20.0 * m), "{v}");
        assert!(lo < m && m < hi, "{v}");
    }
    // A binary model has none: a failure naming it; a coverage of 1 is a usage error.
    let out = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args([
            "client",
            "--url",
            &server.url,
            "predict",
            "greg-door",
            "--at",
            "0",
        ])
        .args(["--coverage", "0.9"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("model \"greg-door\" has no prediction intervals"),
        "{err}"
    );
    let out = run(&[
        "client",
        "--url",
        &url,
        "predict",
        "door",
        "--at",
        "0",
        "--coverage",
        "1",
    ]);
    assert_eq!(out.status.code(), Some(2));
    json(&["remove", "temperature"]);
    // A calendar of days off from a file: the training weeks hold no holiday, and Good Friday
    // is predicted as the Sunday before.
    json(&[
        "create",
        "greg-holidays",
        "--days-off",
        "data/calendars/england_wales_2016.txt",
    ]);
    json(&["add", "greg-holidays", "--file", TRAIN]);
    let view = json(&["view", "greg-holidays"]);
    assert_eq!(view["days_off"]["days"], 8, "{view}");
    assert_eq!(view["days_off"]["first"], "2016-01-01", "{view}");
    let v = json(&[
        "predict",
        "greg-holidays",
        "--at",
        "2016-03-25T10:00Z,2016-03-20T10:00Z,2016-03-24T10:00Z",
    ]);
    assert_eq!(v["probability"][0], v["probability"][1], "{v}");
    assert_eq!(
        v["probability"][2].as_f64(),
        Some(reference.predict(1_458_813_600.0)),
        "{v}"
    );
    json(&["remove", "greg-holidays"]);
    let err = Command::new(env!("CARGO_BIN_EXE_chronomap"))
        .args(["client", "--url", &server.url, "create", "x", "--days-off"])
        .arg(TRAIN)
        .output()
        .unwrap();
    assert_eq!(err.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&err.stderr).contains("--days-off"));
    let v = json(&["remove", "greg-door"]);
    assert_eq!(v["removed"], true);
    assert!(json(&["list"])["models"].as_array().unwrap().is_empty());
}
