//! Security of `chronomap serve`: writes without the right bearer token get 401, oversize
//! bodies 413, hostile ids and JSON 400 — and none of them changes anything or stops the
//! service. Run for the embedded store and for PostgreSQL.

use crate::service;

use chronomap_client::Client;
use chronomap_client::{Method, StatusCode};
use chronomap_serve::api::{Health, ListResponse};
use service::{Backend, free_port, scratch, start, token};

/// Everything a client can see of the service's state.
fn snapshot(runtime: &tokio::runtime::Runtime, client: &Client) -> (u64, ListResponse, Vec<f64>) {
    runtime.block_on(async {
        let health: Health = client.health().await.unwrap();
        let list = client.list().await.unwrap();
        let p = client
            .predict("door", &[0.0, 3600.0, 50_000.0], None)
            .await
            .unwrap()
            .values;
        (health.seq, list, p)
    })
}

fn security_test(name: &str, backend: Backend) {
    let data = scratch(name);
    let port = free_port();
    let server = start(&data, port, &backend, &["--max-body-bytes", "20000"]);
    let token = token(&data);
    let client = Client::new(&server.url, Some(token.clone())).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    runtime
        .block_on(client.add(
            "door",
            &[0.0, 43_200.0, 86_400.0, 129_600.0],
            &[false, true, false, true],
            Some("fremen:2"),
        ))
        .unwrap();
    let before = snapshot(&runtime, &client);
    let raw = |method: Method, path: &str, body: &[u8], token: Option<&str>| {
        runtime
            .block_on(client.raw(method, path, body.to_vec(), token))
            .unwrap()
    };
    let good_add = br#"{"id":"door","times":[200000],"states":[true]}"#;

    // 401: every write endpoint, without a token and with a wrong one.
    let writes: [(Method, &str, &[u8]); 6] = [
        (Method::POST, "/v1/add", good_add),
        (
            Method::POST,
            "/v1/addvalues",
            br#"{"id":"door","times":[200000],"values":[1]}"#,
        ),
        (
            Method::POST,
            "/v1/observations",
            br#"{"batches":[{"id":"door","times":[200000],"values":[1]}]}"#,
        ),
        (
            Method::PUT,
            "/v1/models/new-door",
            br#"{"model":"fremen:1"}"#,
        ),
        (Method::PUT, "/v1/models/door", br#"{"model":"hist:24"}"#),
        (Method::DELETE, "/v1/models/door", b""),
    ];
    let wrong = "0".repeat(token.len());
    let mut unauthorised = 0;
    for (method, path, body) in &writes {
        for bad_token in [None, Some(wrong.as_str()), Some(&token[..token.len() - 1])] {
            let (status, text) = raw(method.clone(), path, body, bad_token);
            assert_eq!(status, StatusCode::UNAUTHORIZED, "{method} {path}: {text}");
            assert!(text.contains("\"error\":\"unauthorized\""), "{text}");
            unauthorised += 1;
        }
    }
    assert_eq!(
        snapshot(&runtime, &client),
        before,
        "a rejected write changed the service"
    );

    // 413: a body over --max-body-bytes, with the right token.
    let times: Vec<String> = (0..5000).map(|k| (300_000 + k).to_string()).collect();
    let states = vec!["true"; 5000].join(",");
    let big = format!(
        r#"{{"id":"door","times":[{}],"states":[{states}]}}"#,
        times.join(",")
    );
    assert!(big.len() > 20_000);
    let (status, text) = raw(Method::POST, "/v1/add", big.as_bytes(), Some(&token));
    assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE, "{text}");
    assert!(text.contains("payload_too_large"), "{text}");

    // 400: hostile ids and JSON, with the right token.
    let long_id = "x".repeat(257);
    let hostile: Vec<(Method, String, Vec<u8>)> = vec![
        (Method::POST, "/v1/add".into(), b"not json".to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[1"#.to_vec()),
        (Method::POST, "/v1/add".into(), b"\xff\xfe{}".to_vec()),
        (Method::POST, "/v1/add".into(), b"[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[".to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[NaN],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[1e999],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":["x"],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[1,2],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[-5],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[10],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[300000,200000],"states":[true,false]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[300000],"states":[true],"admin":true}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"","times":[300000],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), format!(r#"{{"id":"{long_id}","times":[300000],"states":[true]}}"#).into_bytes()),
        (Method::POST, "/v1/add".into(), br#"{"id":"do\u0000or","times":[300000],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"new","times":[300000],"states":[true],"model":"fremen:99999"}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"new","times":[300000],"states":[true],"model":"hyt-em:auto"}"#.to_vec()),
        (Method::POST, "/v1/addvalues".into(), br#"{"id":"door","times":[300000],"values":[1.5]}"#.to_vec()),
        (Method::POST, "/v1/addvalues".into(), br#"{"id":"door","times":[300000],"values":[-0.1]}"#.to_vec()),
        // One good batch and one bad one: all or nothing.
        (Method::POST, "/v1/observations".into(), br#"{"batches":[{"id":"door","times":[300000],"values":[1]},{"id":"door","times":[1],"values":[0]}]}"#.to_vec()),
        (Method::POST, "/v1/observations".into(), br#"{"batches":[{"id":"door","times":[300000],"values":[1]},{"id":"","times":[1],"values":[0]}]}"#.to_vec()),
        (Method::PUT, format!("/v1/models/{long_id}"), br#"{"model":"fremen:1"}"#.to_vec()),
        (Method::PUT, "/v1/models/a%00b".into(), br#"{"model":"fremen:1"}"#.to_vec()),
        (Method::PUT, "/v1/models/a%FFb".into(), br#"{"model":"fremen:1"}"#.to_vec()),
        (Method::PUT, "/v1/models/new".into(), br#"{"model":"fremen:1","range":[1,0]}"#.to_vec()),
        (Method::PUT, "/v1/models/new".into(), br#"{"model":"nonsense"}"#.to_vec()),
        (Method::PUT, "/v1/models/new".into(), br#"{"model":3}"#.to_vec()),
        (Method::POST, "/v1/predict".into(), br#"{"id":"door","times":[1],"order":1000}"#.to_vec()),
        (Method::POST, "/v1/predict".into(), br#"{"id":"door","times":[1],"order":-1}"#.to_vec()),
        (Method::POST, "/v1/forecast".into(), br#"{"ids":["door"],"time":1,"orders":[1,2]}"#.to_vec()),
        (Method::POST, "/v1/detect".into(), br#"{"id":"door","times":[1],"values":[1],"confidence":0}"#.to_vec()),
        (Method::POST, "/v1/evaluate".into(), br#"{"id":"door","times":[],"values":[]}"#.to_vec()),
    ];
    for (method, path, body) in &hostile {
        let (status, text) = raw(method.clone(), path, body, Some(&token));
        assert_eq!(
            status,
            StatusCode::BAD_REQUEST,
            "{method} {path} {}: {text}",
            String::from_utf8_lossy(body)
        );
        let error: chronomap_serve::api::ErrorBody = serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("{path}: the error is not JSON ({e}): {text}"));
        assert_eq!(error.error, "bad_request");
        assert!(!error.reason.is_empty());
    }
    // A deeply nested body is refused by the parser's depth limit, not by a stack overflow.
    let deep = "[".repeat(10_000);
    let (status, _) = raw(Method::POST, "/v1/predict", deep.as_bytes(), None);
    assert_eq!(status, StatusCode::BAD_REQUEST);

    let after = snapshot(&runtime, &client);
    assert_eq!(after, before, "a rejected request changed the service");
    // The service is still up and a good write still works.
    let (status, text) = raw(Method::POST, "/v1/add", good_add, Some(&token));
    assert_eq!(status, StatusCode::OK, "{text}");
    assert_eq!(snapshot(&runtime, &client).0, before.0 + 1);
    eprintln!(
        "{name}: {unauthorised} unauthorised writes -> 401, 1 oversize -> 413, {} hostile -> 400; \
         nothing changed",
        hostile.len() + 1
    );
}

service::on_each_backend!(
    security_test,
    "security",
    bad_tokens_oversize_bodies_and_hostile_input_change_nothing_redb,
    bad_tokens_oversize_bodies_and_hostile_input_change_nothing_postgres
);
