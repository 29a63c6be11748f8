//! Property tests of the service's request decoding (proptest, seeded): whatever bytes or JSON
//! a client sends to any endpoint, the answer is a `4xx` with a JSON error naming what was
//! wrong, or a success — never a `5xx`, a panic or a change to a model it did not write; valid
//! predictions answer one probability per time.
//!
//! `PROPTEST_CASES` sets the cases per property (default 128).

use std::sync::Arc;

use axum::Router;
use axum::body::{Body, to_bytes};
use axum::http::{Request, StatusCode};
use chronomap_activity::{CopaConfig, CopaMap};
use chronomap_grid::AnyGrid;
use chronomap_grid::{FremenGrid, GridConfig, GridGeometry};
use chronomap_serve::maps::{Maps, ServedActivity};
use chronomap_serve::store::RedbStore;
use chronomap_serve::{Service, ServiceConfig};
use chronomap_testutil::proptest_config;
use proptest::prelude::*;
use tower::ServiceExt;

const TOKEN: &str = "0123456789abcdef0123456789abcdef";

/// Every endpoint that takes a body, and some that take a path only.
const ENDPOINTS: [(&str, &str); 20] = [
    ("PUT", "/v1/models/door"),
    ("POST", "/v1/models/door/refit"),
    ("POST", "/v1/add"),
    ("POST", "/v1/addvalues"),
    ("POST", "/v1/observations"),
    ("POST", "/v1/predict"),
    ("POST", "/v1/entropy"),
    ("POST", "/v1/forecast"),
    ("POST", "/v1/forecastEntropy"),
    ("POST", "/v1/evaluate"),
    ("POST", "/v1/detect"),
    ("GET", "/v1/models/door"),
    ("GET", "/v1/models/door/observations"),
    ("DELETE", "/v1/models/nothing-here"),
    ("POST", "/v1/maps"),
    ("POST", "/v1/grid/door/predict"),
    ("POST", "/v1/grid/door/cell"),
    ("GET", "/v1/grid/door"),
    ("POST", "/v1/activity/atc/predict"),
    ("GET", "/v1/activity/atc"),
];

/// A CoPA-Map of `inducing` points fitted in `iterations` on the bundled ATC grid.
fn atc_map(inducing: usize, iterations: usize) -> CopaMap {
    let train = chronomap_io::read_rate_samples(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../data/atc_copa_map_grid/grid_atc_50cm_60min_train_xy.csv.xz"
    ))
    .unwrap();
    let config = CopaConfig {
        inducing,
        iterations,
        ..CopaConfig::default()
    };
    CopaMap::fit(&train, &config).unwrap()
}

/// The maps served: `door`, a grid of three cells (a door open by day, a wall, a free cell)
/// over three days, and `atc`, a CoPA-Map fitted cheaply on the bundled ATC grid.
fn maps() -> Maps {
    let geometry = GridGeometry::planar(3, 1, 0.5, [0.0, 0.0]).unwrap();
    let mut grid = FremenGrid::new(geometry, GridConfig::default()).unwrap();
    for k in 0..3 * 48 {
        let t = 1_400_000_000.0 + f64::from(k) * 1800.0;
        let day = ((t % 86_400.0) / 3600.0 - 12.0).abs() < 5.0;
        grid.observe_occupancy(t, &[if day { 0 } else { 100 }, 100, 0])
            .unwrap();
    }
    let mut maps = Maps::default();
    maps.grids
        .insert("door".into(), AnyGrid::State(Box::new(grid)));
    maps.activity
        .insert("atc".into(), ServedActivity::new(atc_map(10, 3), None));
    maps
}

/// A service with one model, `door`, of a day of hourly observations, and the [`maps`]; its
/// router, and the runtime to drive it.
struct Fixture {
    router: Router,
    runtime: tokio::runtime::Runtime,
    _service: Service,
    _dir: std::path::PathBuf,
}

fn fixture() -> Fixture {
    let dir = std::env::temp_dir().join(format!(
        "chronomap-serve-requests-{}-{:?}",
        std::process::id(),
        std::thread::current().id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let store = Arc::new(RedbStore::open(dir.join("chronomap.redb")).unwrap());
    let service = Service::start(
        store,
        ServiceConfig {
            token: Some(TOKEN.into()),
            maps: Arc::new(maps()),
            ..ServiceConfig::default()
        },
    )
    .unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let fixture = Fixture {
        router: service.router(),
        runtime,
        _service: service,
        _dir: dir,
    };
    let times: Vec<f64> = (0..24).map(|h| 1.7e9 + 3600.0 * f64::from(h)).collect();
    let states: Vec<bool> = (0..24).map(|h| (8..18).contains(&h)).collect();
    let body =
        serde_json::json!({"id": "door", "model": "fremen:2", "times": times, "states": states});
    let (status, text) = fixture.send("POST", "/v1/add", body.to_string().into_bytes());
    assert_eq!(status, StatusCode::OK, "{text}");
    fixture
}

impl Fixture {
    fn send(&self, method: &str, path: &str, body: Vec<u8>) -> (StatusCode, String) {
        let request = Request::builder()
            .method(method)
            .uri(path)
            .header("host", "127.0.0.1")
            .header("content-type", "application/json")
            .header("authorization", format!("Bearer {TOKEN}"))
            .body(Body::from(body))
            .unwrap();
        self.runtime.block_on(async {
            let response = self.router.clone().oneshot(request).await.unwrap();
            let status = response.status();
            let bytes = to_bytes(response.into_body(), usize::MAX).await.unwrap();
            (status, String::from_utf8_lossy(&bytes).into_owned())
        })
    }

    fn door_prediction(&self) -> String {
        let body = serde_json::json!({"id": "door", "times": [1.7e9 + 12.5 * 3600.0]});
        self.send("POST", "/v1/predict", body.to_string().into_bytes())
            .1
    }
}

/// JSON values of any shape, with the field names and numbers the API uses among them.
fn json_value() -> impl Strategy<Value = serde_json::Value> {
    use serde_json::Value;
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::Bool),
        any::<f64>()
            .prop_filter("finite", |f| f.is_finite())
            .prop_map(|f| serde_json::json!(f)),
        any::<i64>().prop_map(|i| serde_json::json!(i)),
        // Times and sizes at the edges: beyond any time, below any cell, a cell or a time the
        // maps know.
        prop_oneof![
            Just(1e308),
            Just(-1e308),
            Just(1e-300),
            Just(1.0000001e11),
            Just(0.5),
            Just(5.0),
            Just(1.4e9),
        ]
        .prop_map(|f| serde_json::json!(f)),
        prop_oneof![
            Just("door".to_owned()),
            Just("fremen:2".to_owned()),
            Just(String::new()),
            ".{0,12}",
        ]
        .prop_map(Value::String),
    ];
    leaf.prop_recursive(4, 48, 6, |inner| {
        let key = prop_oneof![
            Just("id".to_owned()),
            Just("ids".to_owned()),
            Just("times".to_owned()),
            Just("values".to_owned()),
            Just("states".to_owned()),
            Just("time".to_owned()),
            Just("model".to_owned()),
            Just("range".to_owned()),
            Just("order".to_owned()),
            Just("confidence".to_owned()),
            Just("batches".to_owned()),
            Just("t".to_owned()),
            Just("cell".to_owned()),
            "[a-z]{1,6}",
        ];
        prop_oneof![
            proptest::collection::vec(inner.clone(), 0..6).prop_map(Value::Array),
            proptest::collection::btree_map(key, inner, 0..6)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// Numbers for times and cell sides: any finite one, the extremes, and ones the maps use.
fn number() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<f64>().prop_filter("finite", |f| f.is_finite()),
        prop_oneof![
            Just(1e308),
            Just(-1e308),
            Just(1e-300),
            Just(-1e-300),
            Just(0.0),
            Just(1e11),
            Just(-1.0000001e11),
        ],
        -2e11..2e11f64,
        0.3..100.0f64,
    ]
}

fn assert_answered(status: StatusCode, text: &str) -> Result<(), TestCaseError> {
    prop_assert!(!status.is_server_error(), "answered {status}: {text}");
    if status.is_client_error() {
        let body: serde_json::Value = serde_json::from_str(text).map_err(|e| {
            TestCaseError::fail(format!("{status} without a JSON body ({e}): {text}"))
        })?;
        let reason = body["reason"].as_str().unwrap_or_default();
        prop_assert!(!reason.is_empty(), "{status} without a reason: {text}");
    }
    Ok(())
}

proptest! {
    #![proptest_config(proptest_config(128, 20_261_203))]

    #[test]
    fn any_bytes_to_any_endpoint_get_a_client_error_or_an_answer(
        endpoint in 0..ENDPOINTS.len(),
        body in proptest::collection::vec(any::<u8>(), 0..256),
    ) {
        thread_local!(static FIXTURE: Fixture = fixture());
        FIXTURE.with(|f| {
            let before = f.door_prediction();
            let (method, path) = ENDPOINTS[endpoint];
            let (status, text) = f.send(method, path, body.clone());
            assert_answered(status, &text)?;
            // Bytes that are not JSON change nothing.
            if serde_json::from_slice::<serde_json::Value>(&body).is_err() {
                prop_assert_eq!(f.door_prediction(), before);
            }
            Ok(())
        })?;
    }

    #[test]
    fn any_json_to_any_endpoint_gets_a_client_error_or_an_answer(
        endpoint in 0..ENDPOINTS.len(),
        body in json_value(),
    ) {
        thread_local!(static FIXTURE: Fixture = fixture());
        FIXTURE.with(|f| {
            let (method, path) = ENDPOINTS[endpoint];
            let (status, text) = f.send(method, path, body.to_string().into_bytes());
            assert_answered(status, &text)
        })?;
    }

    #[test]
    fn any_time_or_cell_to_the_grid_and_activity_maps_gets_a_client_error_or_an_answer(
        endpoint in 0..3usize,
        time in number(),
        cell in proptest::option::of(number()),
    ) {
        thread_local!(static FIXTURE: Fixture = fixture());
        FIXTURE.with(|f| {
            let (path, body) = match endpoint {
                0 => ("/v1/grid/door/predict", serde_json::json!({ "time": time })),
                1 => ("/v1/grid/door/cell", serde_json::json!({ "cell": [2, 0], "times": [time] })),
                _ => ("/v1/activity/atc/predict", serde_json::json!({ "t": time, "cell": cell })),
            };
            let (status, text) = f.send("POST", path, body.to_string().into_bytes());
            assert_answered(status, &text)?;
            let finite = |x: f64| x.is_finite() && x.abs() <= 1e11;
            // A time within ±1e11 s (and a cell giving at most 250,000 cells) is answered.
            let cell_ok = cell.is_none_or(|c| (0.1..=1e11).contains(&c));
            if finite(time) && (endpoint < 2 || cell_ok) {
                prop_assert_eq!(status, StatusCode::OK, "{} {}: {}", path, body, text);
            } else if !finite(time) {
                prop_assert_eq!(status, StatusCode::BAD_REQUEST, "{} {}: {}", path, body, text);
            }
            Ok(())
        })?;
    }

    #[test]
    fn valid_predictions_answer_one_probability_per_time(
        times in proptest::collection::vec(0.0f64..1e11, 1..64),
    ) {
        thread_local!(static FIXTURE: Fixture = fixture());
        FIXTURE.with(|f| {
            let body = serde_json::json!({"id": "door", "times": times});
            let (status, text) = f.send("POST", "/v1/predict", body.to_string().into_bytes());
            prop_assert_eq!(status, StatusCode::OK, "{}", text);
            let answer: serde_json::Value = serde_json::from_str(&text).unwrap();
            let values = answer["values"].as_array().unwrap();
            prop_assert_eq!(values.len(), times.len());
            for v in values {
                let p = v.as_f64().unwrap();
                prop_assert!((0.0..=1.0).contains(&p), "{}", p);
            }
            Ok(())
        })?;
    }
}

#[test]
fn times_and_cells_beyond_the_limits_are_refused_naming_the_field() {
    use serde_json::json;
    let f = fixture();
    let refused = [
        (
            "/v1/grid/door/predict",
            json!({"time": 1e308}),
            "field `time`",
        ),
        (
            "/v1/grid/door/predict",
            json!({"time": -1e308}),
            "field `time`",
        ),
        (
            "/v1/grid/door/cell",
            json!({"cell": [0, 0], "times": [1.4e9, 1e308]}),
            "field `times[1]`",
        ),
        (
            "/v1/predict",
            json!({"id": "door", "times": [1.7e9, 1.0000001e11]}),
            "field `times[1]`",
        ),
        (
            "/v1/forecast",
            json!({"ids": ["door"], "time": -1e308}),
            "field `time`",
        ),
        ("/v1/activity/atc/predict", json!({"t": 1e308}), "field `t`"),
        (
            "/v1/activity/atc/predict",
            json!({"t": 5.0, "cell": 1e-300}),
            "field `cell`: cells of 1e-300 m give 2.4e301 × 2.4e301 cells",
        ),
        // 24 m of ATC in cells of 1 cm: 2401 × 2401 cells.
        (
            "/v1/activity/atc/predict",
            json!({"t": 5.0, "cell": 0.01}),
            "field `cell`: cells of 0.01 m give 2401 × 2401 cells over the model's domain, \
             more than 250000",
        ),
        (
            "/v1/activity/atc/predict",
            json!({"t": 5.0, "cell": -1.0}),
            "field `cell`: -1 is not a positive number",
        ),
    ];
    for (path, body, reason) in refused {
        let (status, text) = f.send("POST", path, body.to_string().into_bytes());
        assert_eq!(status, StatusCode::BAD_REQUEST, "{path} {body}: {text}");
        assert!(text.contains(reason), "{path} {body}: {text}");
    }
    // The limits themselves are times.
    for (path, body) in [
        ("/v1/grid/door/predict", json!({"time": 1e11})),
        ("/v1/predict", json!({"id": "door", "times": [-1e11, 1e11]})),
        ("/v1/activity/atc/predict", json!({"t": -1e11})),
    ] {
        let (status, text) = f.send("POST", path, body.to_string().into_bytes());
        assert_eq!(status, StatusCode::OK, "{path} {body}: {text}");
    }
}

#[test]
fn model_requests_beyond_the_work_bound_are_refused_naming_the_field() {
    use serde_json::json;
    let f = fixture();
    let zeros = |n: usize| vec![0.0; n];
    // The door's `fremen:2` has orders 0 to 84: `max_order` 1000 evaluates 85 of them.
    let refused = [
        (
            "/v1/predict",
            json!({"id": "door", "times": zeros(2_000_001)}),
            "field `times`: 2000001 times are 2000001 predictions, more than 2000000 per \
             request",
        ),
        (
            "/v1/entropy",
            json!({"id": "door", "times": zeros(2_000_001)}),
            "field `times`: 2000001 times",
        ),
        (
            "/v1/forecast",
            json!({"ids": vec!["door"; 2_000_001], "time": 1.7e9}),
            "field `ids`: 2000001 ids are 2000001 predictions",
        ),
        (
            "/v1/evaluate",
            json!({"id": "door", "times": zeros(23_530), "values": zeros(23_530),
                   "max_order": 1000}),
            "field `times`: 23530 times × 85 orders are 2000050 predictions, more than \
             2000000 per request; send fewer times or a lower `max_order`",
        ),
        (
            "/v1/detect",
            json!({"id": "door", "times": zeros(2_000_001), "values": zeros(2_000_001),
                   "confidence": 0.5}),
            "field `times`: 2000001 times",
        ),
    ];
    for (path, body, reason) in refused {
        let text = body.to_string();
        let start = std::time::Instant::now();
        let (status, answer) = f.send("POST", path, text.into_bytes());
        assert_eq!(status, StatusCode::BAD_REQUEST, "{path}: {answer}");
        assert!(answer.contains(reason), "{path}: {answer}");
        // Refused once parsed, before any prediction.
        assert!(start.elapsed().as_secs_f64() < 5.0, "{path}");
    }
    // One row less is answered: 23,529 rows × 85 orders.
    let (status, answer) = f.send(
        "POST",
        "/v1/evaluate",
        json!({"id": "door", "times": zeros(23_529), "values": zeros(23_529),
               "max_order": 1000})
        .to_string()
        .into_bytes(),
    );
    assert_eq!(status, StatusCode::OK, "{answer}");
    let answer: serde_json::Value = serde_json::from_str(&answer).unwrap();
    assert_eq!(answer["orders"].as_array().unwrap().len(), 85);
}

#[test]
fn an_activity_prediction_is_bounded_by_cells_times_inducing_points_squared() {
    // A CoPA-Map of 100 inducing points (one training iteration: its shape is what counts).
    let model = atc_map(100, 1);
    assert_eq!(model.inducing_points(), 100);
    let served = ServedActivity::new(model, None);
    // Over the 24 m square of ATC: cells of 5 cm are 481 × 481 = 231,361 (under the 250,000
    // cells), × 100² = 2,313,610,000 units of work, more than 10^9.
    let refused = served.predict(5.0, 0.05).unwrap_err();
    assert_eq!(
        refused.to_string(),
        "field `cell`: cells of 0.05 m give 231361 cells; with the model's 100 inducing points \
         that is 2313610000 units of work (cells × inducing points²), more than 1000000000; \
         ask for larger cells"
    );
    // Cells of 8 cm: 301 × 301 = 90,601 cells, 906,010,000 units: allowed.
    let grid = served.checked_region(0.08).unwrap();
    assert_eq!((grid.cols, grid.rows), (301, 301));
    // And through the service: 400 naming the field, before any work.
    let mut maps = Maps::default();
    maps.activity.insert("atc100".into(), served);
    let dir = std::env::temp_dir().join(format!(
        "chronomap-serve-requests-work-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let store = Arc::new(RedbStore::open(dir.join("chronomap.redb")).unwrap());
    let service = Service::start(
        store,
        ServiceConfig {
            maps: Arc::new(maps),
            ..ServiceConfig::default()
        },
    )
    .unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let request = Request::builder()
        .method("POST")
        .uri("/v1/activity/atc100/predict")
        .header("host", "127.0.0.1")
        .body(Body::from(r#"{"t": 5, "cell": 0.05}"#))
        .unwrap();
    let (status, text) = runtime.block_on(async {
        let response = service.router().oneshot(request).await.unwrap();
        let status = response.status();
        let bytes = to_bytes(response.into_body(), usize::MAX).await.unwrap();
        (status, String::from_utf8_lossy(&bytes).into_owned())
    });
    assert_eq!(status, StatusCode::BAD_REQUEST, "{text}");
    assert!(text.contains("2313610000 units of work"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_health_answer_of_docs_fleet_md_has_the_services_keys() {
    let f = fixture();
    let (status, text) = f.send("GET", "/v1/health", Vec::new());
    assert_eq!(status, StatusCode::OK, "{text}");
    let served: serde_json::Map<String, serde_json::Value> = serde_json::from_str(&text).unwrap();
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/fleet.md"))
        .unwrap();
    // The answer shown after `curl -s http://…/v1/health`.
    let mut lines = doc.lines().skip_while(|l| !l.ends_with("/v1/health"));
    lines.next().expect("docs/fleet.md asks for /v1/health");
    let shown = lines
        .next()
        .and_then(|l| l.strip_prefix("# → "))
        .expect("docs/fleet.md shows the answer of /v1/health on the next line");
    let documented: serde_json::Map<String, serde_json::Value> =
        serde_json::from_str(shown).unwrap();
    let keys = |m: &serde_json::Map<String, serde_json::Value>| {
        m.keys().cloned().collect::<std::collections::BTreeSet<_>>()
    };
    assert_eq!(
        keys(&documented),
        keys(&served),
        "docs/fleet.md: {shown}\nserved: {text}"
    );
}
