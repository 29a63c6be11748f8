//! What the tests that drive one in-process service through its router share: a service on
//! a redb store that refits only on request, a request and its answer, a `200`'s JSON, a
//! `GET`, a refit on request, and the check that a service answers alike after a crash and after a
//! restart.

use std::sync::Arc;

use axum::body::{Body, to_bytes};
use axum::http::{Request, StatusCode};
use chronomap_models::RefitPolicy;
use chronomap_serve::store::RedbStore;
use chronomap_serve::{Service, ServiceConfig};
use serde_json::Value;
use tower::ServiceExt;

/// A service on the redb store at `path` (refits only on request, so that the models change
/// only when the test says) and a runtime to send it requests.
pub fn start(path: &std::path::Path) -> (Service, tokio::runtime::Runtime) {
    let store = Arc::new(RedbStore::open(path).unwrap());
    let service = Service::start(
        store,
        ServiceConfig {
            refit: RefitPolicy::NEVER,
            ..ServiceConfig::default()
        },
    )
    .unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    (service, runtime)
}

/// `method path` with the JSON `body`: the status and the answer's text.
pub fn send(
    service: &Service,
    runtime: &tokio::runtime::Runtime,
    method: &str,
    path: &str,
    body: &Value,
) -> (StatusCode, String) {
    let request = Request::builder()
        .method(method)
        .uri(path)
        .header("host", "127.0.0.1")
        .header("content-type", "application/json")
        .body(Body::from(body.to_string()))
        .unwrap();
    runtime.block_on(async {
        let response = service.router().oneshot(request).await.unwrap();
        let status = response.status();
        let bytes = to_bytes(response.into_body(), usize::MAX).await.unwrap();
        (status, String::from_utf8_lossy(&bytes).into_owned())
    })
}

/// The JSON of a `200` answer (a failure naming the answer otherwise).
pub fn ok(answer: (StatusCode, String)) -> Value {
    assert_eq!(answer.0, StatusCode::OK, "{}", answer.1);
    serde_json::from_str(&answer.1).unwrap()
}

/// The JSON of a `GET` of `path` that answers `200`.
#[allow(dead_code)] // not every test binary sharing this module reads
pub fn get(service: &Service, runtime: &tokio::runtime::Runtime, path: &str) -> Value {
    ok(send(service, runtime, "GET", path, &serde_json::json!({})))
}

/// Refits model `id` on request and checks that it was refitted.
pub fn refit(service: &Service, runtime: &tokio::runtime::Runtime, id: &str) {
    let path = format!("/v1/models/{id}/refit");
    let answer = ok(send(
        service,
        runtime,
        "POST",
        &path,
        &serde_json::json!({}),
    ));
    assert_eq!(
        answer["refitted"],
        serde_json::json!(true),
        "{id}: {answer}"
    );
}

/// What `answers` says of `service` (whose store is at `path`) is said again, bit for bit, by
/// a service recovered from a copy of the store as it is now (a crash: the log is replayed)
/// and, after a clean shutdown of `service` (which writes a checkpoint), by one restarted
/// from the store (the snapshots are loaded).
pub fn assert_same_after_replay_and_restart(
    (service, runtime): (Service, tokio::runtime::Runtime),
    path: &std::path::Path,
    answers: impl Fn(&Service, &tokio::runtime::Runtime) -> Vec<String>,
) {
    let live = answers(&service, &runtime);
    let crashed = path.with_extension("crashed.redb");
    std::fs::copy(path, &crashed).unwrap();
    {
        let (replayed, runtime) = start(&crashed);
        assert_eq!(answers(&replayed, &runtime), live, "after log replay");
    }
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        service.run(listener, async {}).await.unwrap();
    });
    let (restarted, runtime) = start(path);
    assert_eq!(answers(&restarted, &runtime), live, "after snapshots");
}
