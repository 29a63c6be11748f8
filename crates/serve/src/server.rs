//! The HTTP/JSON API: routes, handlers, bearer-token checks, size limits and JSON errors.
//! Handlers only translate: reads go to the published [`Registry`],
//! writes to the [`crate::writer`].

use std::future::Future;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use axum::body::Bytes;
use axum::extract::rejection::{BytesRejection, PathRejection};
use axum::extract::{DefaultBodyLimit, Path, Request, State};
use axum::http::{HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::{get, post, put};
use axum::{Json, Router};
use chronomap_core::observe::MAX_TIME_SECS;
use chronomap_core::{TemporalModel, binary_entropy};
use serde::de::DeserializeOwned;
use tokio::sync::{mpsc, oneshot};
use utoipa::OpenApi;

use crate::api::*;
use crate::heavy::{self, Cancel, Class, Heavy, HeavyLimits};
use crate::maps::Maps;
use crate::refit::{RefitFailure, Refits};
use crate::registry::{ApplyError, Entry, ModelConfig, Registry, check_id};
use crate::store::Store;
use crate::writer::{self, CheckpointPolicy, Shared, WriteCommand, WriteError, WriteOp};
use chronomap_models::AnyModel;
use std::borrow::Cow;

/// Largest request body by default (bytes): about a million observations in JSON.
pub const DEFAULT_MAX_BODY_BYTES: usize = 32 << 20;

/// Most predictions one model request may ask for, counted before any is computed: times
/// (`predict`, `entropy`, `detect`), ids (`forecast`, `forecastEntropy`), rows × orders
/// (`evaluate`). More is refused with `400` naming the field. At most about 4 s on one thread
/// with the costliest model (FreMEn of order 84), parsing and answering included; 0.5 s with
/// `fremen:2`.
pub const MAX_REQUEST_PREDICTIONS: u64 = 2_000_000;

/// Predictions computed between two checks whether the client went away (`evaluate` checks
/// between orders, `predict` and `entropy` are one call of the model: its values are bit for
/// bit those of `predict_many` over all the times).
pub const MODEL_CHUNK: usize = 4096;

/// How long connections may take, and how many may be open.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ConnectionLimits {
    /// A connection must send a complete request head within this time of opening or of its
    /// previous answer; else it is closed. This bounds slow headers and idle keep-alive
    /// connections alike (hyper's header-read timer runs while a connection waits for a head).
    pub header_timeout: Duration,
    /// A request body must arrive completely within this time of its head; else `408`.
    pub body_timeout: Duration,
    /// Connections open at once; one more is answered `503` and closed.
    pub max_connections: usize,
}

impl Default for ConnectionLimits {
    fn default() -> Self {
        ConnectionLimits {
            header_timeout: Duration::from_secs(10),
            body_timeout: Duration::from_secs(60),
            max_connections: 512,
        }
    }
}

/// How the service runs.
#[derive(Clone, Debug)]
pub struct ServiceConfig {
    /// Bearer token that writes and deletes need (`None`: no check).
    pub token: Option<String>,
    /// Largest request body (bytes); larger ones get `413`.
    pub max_body_bytes: usize,
    /// When models are snapshotted.
    pub checkpoint: CheckpointPolicy,
    /// Topological maps and grids served read-only.
    pub maps: Arc<Maps>,
    /// Host names (besides `localhost` and IP addresses) that requests may name in `Host`.
    pub allowed_hosts: Vec<String>,
    /// Timeouts and the connection limit.
    pub limits: ConnectionLimits,
    /// When models fitted on a whole series (`auto`, `fremen:auto`, ...) are refitted
    /// without being asked ([`crate::refit`]): by default after a day of data time or 100,000
    /// new observations.
    pub refit: chronomap_models::RefitPolicy,
    /// Behavior trees watched over the Groot2 protocol (`--bt-monitor`).
    pub bt_monitors: Arc<crate::bt_monitor::BtMonitors>,
    /// Threads and queue of the requests that compute for long (grid, activity and plan
    /// predictions, large model requests).
    pub heavy: HeavyLimits,
    /// Threads and queue of the small model requests ([`crate::heavy::Class::Light`]).
    pub light: HeavyLimits,
}

impl Default for ServiceConfig {
    fn default() -> Self {
        ServiceConfig {
            token: None,
            max_body_bytes: DEFAULT_MAX_BODY_BYTES,
            checkpoint: CheckpointPolicy::default(),
            maps: Arc::new(Maps::default()),
            allowed_hosts: Vec::new(),
            limits: ConnectionLimits::default(),
            refit: chronomap_models::RefitPolicy::default(),
            bt_monitors: Arc::default(),
            heavy: HeavyLimits::default(),
            light: HeavyLimits::light(),
        }
    }
}

/// The refit thread; stopped when dropped (a service dropped without [`Service::run`]).
struct RefitThread {
    refits: Arc<Refits>,
    handle: Option<std::thread::JoinHandle<()>>,
}

impl RefitThread {
    /// Stops it after the refit in progress and waits for it.
    fn join(mut self) {
        self.refits.stop();
        if let Some(handle) = self.handle.take() {
            let _ = handle.join();
        }
    }
}

impl Drop for RefitThread {
    fn drop(&mut self) {
        self.refits.stop();
    }
}

/// A recovered service, ready to answer requests.
pub struct Service {
    state: AppState,
    maps: crate::maps::MapsState,
    bt_monitors: Arc<crate::bt_monitor::BtMonitors>,
    max_body_bytes: usize,
    limits: ConnectionLimits,
    writer: std::thread::JoinHandle<()>,
    /// A fleet node's tailer and its stop flag.
    tailer: Option<(std::thread::JoinHandle<()>, Arc<AtomicBool>)>,
    refitter: RefitThread,
}

#[derive(Clone)]
struct AppState {
    shared: Arc<Shared>,
    writes: mpsc::Sender<WriteCommand>,
    refits: Arc<Refits>,
    token: Option<Arc<str>>,
    allowed_hosts: Arc<[String]>,
    body_timeout: Duration,
    max_body_bytes: usize,
    heavy: Arc<Heavy>,
    light: Arc<Heavy>,
}

impl Service {
    /// Recovers every model from `store` (last checkpoint + log replay) and starts the writer
    /// and the refit thread (which queues the models already due).
    ///
    /// Call outside an async context: recovery blocks on the store.
    ///
    /// # Errors
    /// The store cannot be read or holds damaged entries (named in the message).
    pub fn start(store: Arc<dyn Store>, config: ServiceConfig) -> Result<Self, String> {
        let heavy = Arc::new(Heavy::new(config.heavy)?);
        let light = Arc::new(Heavy::of_class(Class::Light, config.light)?);
        let shared = Arc::new(writer::recover(store)?);
        let (writes, commands) = mpsc::channel(1024);
        let writer_shared = Arc::clone(&shared);
        let policy = config.checkpoint;
        let writer = std::thread::Builder::new()
            .name("chronomap-writer".into())
            .spawn(move || writer::run(writer_shared, commands, policy))
            .map_err(|e| format!("cannot start the writer thread: {e}"))?;
        let refits = Arc::new(Refits::new(config.refit));
        let _ = shared.refits.set(Arc::clone(&refits));
        let refitter = {
            let (queue, shared, writes) =
                (Arc::clone(&refits), Arc::clone(&shared), writes.clone());
            let handle = std::thread::Builder::new()
                .name("chronomap-refit".into())
                .spawn(move || crate::refit::run(queue, shared, writes))
                .map_err(|e| format!("cannot start the refit thread: {e}"))?;
            RefitThread {
                refits: Arc::clone(&refits),
                handle: Some(handle),
            }
        };
        {
            let registry = shared.registry.read().expect("registry lock");
            refits.schedule_due(&registry, registry.ids());
        }
        let tailer = if shared.store.is_shared() {
            let stop = Arc::new(AtomicBool::new(false));
            let (tail_shared, tail_stop) = (Arc::clone(&shared), Arc::clone(&stop));
            let handle = std::thread::Builder::new()
                .name("chronomap-tailer".into())
                .spawn(move || crate::fleet::tail(tail_shared, tail_stop))
                .map_err(|e| format!("cannot start the log tailer thread: {e}"))?;
            Some((handle, stop))
        } else {
            None
        };
        Ok(Service {
            state: AppState {
                shared,
                writes,
                refits,
                token: config.token.map(Arc::from),
                allowed_hosts: config
                    .allowed_hosts
                    .iter()
                    .map(|h| h.to_ascii_lowercase())
                    .collect(),
                body_timeout: config.limits.body_timeout,
                max_body_bytes: config.max_body_bytes,
                heavy: Arc::clone(&heavy),
                light: Arc::clone(&light),
            },
            maps: crate::maps::MapsState::new(config.maps, heavy, light),
            bt_monitors: config.bt_monitors,
            max_body_bytes: config.max_body_bytes,
            limits: config.limits,
            writer,
            tailer,
            refitter,
        })
    }

    /// Number of models recovered or held.
    pub fn models(&self) -> usize {
        self.state
            .shared
            .registry
            .read()
            .expect("registry lock")
            .len()
    }

    /// The API as an axum router.
    pub fn router(&self) -> Router {
        router(
            self.state.clone(),
            self.maps.clone(),
            Arc::clone(&self.bt_monitors),
            self.max_body_bytes,
        )
    }

    /// Serves on `listener` until `shutdown` completes, then finishes the requests in flight
    /// and the writes, and writes a last checkpoint. Connections follow the
    /// [`ConnectionLimits`] of the configuration.
    ///
    /// # Errors
    /// The listener fails.
    pub async fn run(
        self,
        listener: tokio::net::TcpListener,
        shutdown: impl Future<Output = ()> + Send + 'static,
    ) -> std::io::Result<()> {
        let app = self.router();
        let Service {
            state,
            writer,
            limits,
            tailer,
            refitter,
            bt_monitors,
            ..
        } = self;
        drop(state);
        // Streams of behavior-tree events end when shutting down, so that the connections
        // carrying them close.
        let shutdown = async move {
            shutdown.await;
            bt_monitors.stop();
        };
        serve_connections(listener, app, limits, shutdown).await;
        // The router is gone; the refit thread ends after the fit in progress (a fit not yet
        // logged is made again when due after the restart). Then no sender of writes is left:
        // the writer drains and checkpoints.
        tokio::task::spawn_blocking(move || {
            refitter.join();
            let _ = writer.join();
            if let Some((handle, stop)) = tailer {
                stop.store(true, Ordering::Release);
                let _ = handle.join();
            }
        })
        .await
        .ok();
        Ok(())
    }
}

/// The accept loop: one task per connection (HTTP/1.1), at most `limits.max_connections` at
/// once, the header-read timeout on hyper's timer; on `shutdown`, stops accepting, lets every
/// connection finish its request in flight and returns when all are closed.
async fn serve_connections(
    listener: tokio::net::TcpListener,
    app: Router,
    limits: ConnectionLimits,
    shutdown: impl Future<Output = ()> + Send + 'static,
) {
    use hyper_util::rt::{TokioIo, TokioTimer};
    use hyper_util::service::TowerToHyperService;

    let slots = Arc::new(tokio::sync::Semaphore::new(limits.max_connections));
    let (stop, stopped) = tokio::sync::watch::channel(false);
    let mut http = hyper::server::conn::http1::Builder::new();
    http.timer(TokioTimer::new())
        .header_read_timeout(limits.header_timeout)
        .keep_alive(true);
    let mut shutdown = std::pin::pin!(shutdown);
    loop {
        let (stream, _) = tokio::select! {
            () = &mut shutdown => break,
            accepted = listener.accept() => match accepted {
                Ok(connection) => connection,
                Err(_) => {
                    // Out of file descriptors or a connection reset before accept: try again
                    // shortly instead of spinning.
                    tokio::time::sleep(Duration::from_millis(20)).await;
                    continue;
                }
            },
        };
        let Ok(slot) = Arc::clone(&slots).try_acquire_owned() else {
            let body = r#"{"error":"unavailable","reason":"too many open connections (--max-connections)"}"#;
            let answer = format!(
                "HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/json\r\n\
                 connection: close\r\ncontent-length: {}\r\n\r\n{body}",
                body.len()
            );
            let _ = stream.try_write(answer.as_bytes());
            continue;
        };
        let _ = stream.set_nodelay(true);
        let connection =
            http.serve_connection(TokioIo::new(stream), TowerToHyperService::new(app.clone()));
        let mut stopped = stopped.clone();
        tokio::spawn(async move {
            let mut connection = std::pin::pin!(connection);
            tokio::select! {
                _ = connection.as_mut() => {}
                _ = async { let _ = stopped.wait_for(|&s| s).await; } => {
                    connection.as_mut().graceful_shutdown();
                    let _ = connection.await;
                }
            }
            drop(slot);
        });
    }
    drop(listener);
    let _ = stop.send(true);
    let all = u32::try_from(limits.max_connections).unwrap_or(u32::MAX);
    let _ = slots.acquire_many(all).await;
}

/// The OpenAPI 3.1 description, served at `/openapi.json`.
#[derive(OpenApi)]
#[openapi(
    info(
        title = "chronomap",
        description = "World models that know time: add observations of states, ask for \
                       predictions at any time. Writes need `Authorization: Bearer TOKEN` when \
                       the service has a token."
    ),
    paths(
        health, list, create, view, remove, observations, refit, add, addvalues, add_batch,
        predict,
        entropy, forecast, forecast_entropy, evaluate, detect, crate::maps::list,
        crate::maps::topo_info, crate::maps::topo_predict, crate::maps::topo_plan,
        crate::maps::grid_info, crate::maps::grid_predict, crate::maps::grid_cell,
        crate::maps::activity_info, crate::maps::activity_predict, crate::bt_monitor::list,
        crate::bt_monitor::view, crate::bt_monitor::events, crate::bt_monitor::transitions,
        crate::bt_monitor::blackboard
    ),
    modifiers(&BearerAuth)
)]
pub struct ApiDoc;

struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::{Http, HttpAuthScheme, SecurityScheme};
        openapi
            .components
            .get_or_insert_with(Default::default)
            .add_security_scheme(
                "bearer",
                SecurityScheme::Http(Http::new(HttpAuthScheme::Bearer)),
            );
    }
}

fn router(
    state: AppState,
    maps: crate::maps::MapsState,
    bt_monitors: Arc<crate::bt_monitor::BtMonitors>,
    max_body_bytes: usize,
) -> Router {
    let writes = Router::new()
        .route("/v1/models/{id}", put(create).delete(remove))
        .route("/v1/models/{id}/refit", post(refit))
        .route("/v1/add", post(add))
        .route("/v1/addvalues", post(addvalues))
        .route("/v1/observations", post(add_batch))
        .route_layer(middleware::from_fn(require_json))
        .route_layer(middleware::from_fn_with_state(state.clone(), require_token));
    let outer = state.clone();
    Router::new()
        .route("/", get(web_page))
        .route("/openapi.json", get(openapi))
        .route("/v1/health", get(health))
        .route("/v1/models", get(list))
        .route("/v1/models/{id}", get(view))
        .route("/v1/models/{id}/observations", get(observations))
        .route("/v1/predict", post(predict))
        .route("/v1/entropy", post(entropy))
        .route("/v1/forecast", post(forecast))
        .route("/v1/forecastEntropy", post(forecast_entropy))
        .route("/v1/evaluate", post(evaluate))
        .route("/v1/detect", post(detect))
        .merge(writes)
        .with_state(state.clone())
        .merge(crate::maps::router(maps))
        .merge(crate::bt_monitor::router(bt_monitors))
        .fallback(|| async { ApiError::not_found("no such endpoint; see /openapi.json".into()) })
        .method_not_allowed_fallback(|| async {
            ApiError::new(
                StatusCode::METHOD_NOT_ALLOWED,
                "method_not_allowed",
                "this endpoint does not take that method; see /openapi.json".into(),
            )
        })
        .layer(DefaultBodyLimit::max(max_body_bytes))
        .layer(middleware::from_fn_with_state(outer.clone(), read_after))
        .layer(middleware::from_fn_with_state(outer.clone(), read_body))
        .layer(middleware::from_fn_with_state(outer, check_host))
}

// ---------------------------------------------------------------------------------------------
// Errors and extraction

/// An error response: status and [`ErrorBody`].
#[derive(Debug)]
pub struct ApiError {
    status: StatusCode,
    body: ErrorBody,
    /// Seconds for a `Retry-After` header.
    retry_after: Option<u32>,
}

impl ApiError {
    pub(crate) fn new(status: StatusCode, error: &str, reason: String) -> Self {
        ApiError {
            status,
            body: ErrorBody {
                error: error.to_owned(),
                reason,
            },
            retry_after: None,
        }
    }

    /// `503` with `Retry-After`: too many heavy requests ([`crate::heavy`]).
    pub(crate) fn busy(reason: String) -> Self {
        ApiError {
            retry_after: Some(crate::heavy::RETRY_AFTER_SECS),
            ..ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "busy", reason)
        }
    }

    pub(crate) fn bad_request(reason: String) -> Self {
        ApiError::new(StatusCode::BAD_REQUEST, "bad_request", reason)
    }

    pub(crate) fn not_found(reason: String) -> Self {
        ApiError::new(StatusCode::NOT_FOUND, "not_found", reason)
    }

    pub(crate) fn internal(reason: String) -> Self {
        ApiError::new(StatusCode::INTERNAL_SERVER_ERROR, "internal", reason)
    }

    fn unknown(id: &str) -> Self {
        ApiError::not_found(format!("no model with id {id:?}"))
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let mut response = (self.status, Json(self.body)).into_response();
        if self.status == StatusCode::UNAUTHORIZED {
            response
                .headers_mut()
                .insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer"));
        }
        if let Some(secs) = self.retry_after {
            response
                .headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from(secs));
        }
        response
    }
}

impl From<WriteError> for ApiError {
    fn from(e: WriteError) -> Self {
        match e {
            WriteError::Apply(e @ ApplyError::NotFound(_)) => ApiError::not_found(e.to_string()),
            WriteError::Apply(e @ (ApplyError::Conflict(_) | ApplyError::Refit(..))) => {
                ApiError::new(StatusCode::CONFLICT, "conflict", e.to_string())
            }
            WriteError::Apply(e) => ApiError::bad_request(e.to_string()),
            WriteError::Store(reason) => {
                ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "unavailable", reason)
            }
        }
    }
}

/// Parses a JSON body whatever its content type, with `413` for oversize bodies and `400`
/// naming the line, column and field of anything malformed.
pub(crate) fn parse_body<T: DeserializeOwned>(
    body: Result<Bytes, BytesRejection>,
) -> Result<T, ApiError> {
    parse_json(&body_bytes(body)?)
}

/// The bytes of a body, with `413` for oversize bodies.
fn body_bytes(body: Result<Bytes, BytesRejection>) -> Result<Bytes, ApiError> {
    body.map_err(|rejection| {
        if rejection.status() == StatusCode::PAYLOAD_TOO_LARGE {
            too_large_error()
        } else {
            ApiError::bad_request(format!("cannot read the request body: {rejection}"))
        }
    })
}

/// A JSON body, with `400` naming the line, column and field of anything malformed.
fn parse_json<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    serde_json::from_slice(bytes)
        .map_err(|e| ApiError::bad_request(format!("malformed JSON body: {e}")))
}

fn path_id(path: Result<Path<String>, PathRejection>) -> Result<String, ApiError> {
    let Path(id) = path.map_err(|e| ApiError::bad_request(format!("model id in the path: {e}")))?;
    check_id(&id).map_err(ApiError::bad_request)?;
    Ok(id)
}

fn checked_id(id: &str, field: &str) -> Result<(), ApiError> {
    check_id(id).map_err(|e| ApiError::bad_request(format!("field `{field}`: {e}")))
}

/// The model `id` (given in `field`): `400` for a malformed id, `404` for an unknown one.
fn model_entry<'a>(registry: &'a Registry, id: &str, field: &str) -> Result<&'a Entry, ApiError> {
    checked_id(id, field)?;
    registry.get(id).ok_or_else(|| ApiError::unknown(id))
}

/// The bearer token of an `Authorization` header: the scheme is case-insensitive (RFC 9110
/// §11.1), so `Bearer`, `bearer` and `BEARER` all work.
fn bearer(headers: &axum::http::HeaderMap) -> Option<&str> {
    let value = headers.get(header::AUTHORIZATION)?.to_str().ok()?;
    let (scheme, token) = value.trim().split_once(' ')?;
    scheme
        .eq_ignore_ascii_case("bearer")
        .then(|| token.trim_start())
}

/// Whether the request carries the service's token (always, without one).
fn authorized(state: &AppState, headers: &axum::http::HeaderMap) -> bool {
    state.token.as_ref().is_none_or(|token| {
        bearer(headers).is_some_and(|g| constant_time_eq(g.as_bytes(), token.as_bytes()))
    })
}

async fn require_token(
    State(state): State<AppState>,
    request: Request,
    next: Next,
) -> Result<Response, ApiError> {
    if !authorized(&state, request.headers()) {
        let reason = if bearer(request.headers()).is_none() {
            "this endpoint changes models and needs `Authorization: Bearer TOKEN` \
             (the token file was printed when the service started)"
        } else {
            "wrong bearer token"
        };
        return Err(ApiError::new(
            StatusCode::UNAUTHORIZED,
            "unauthorized",
            reason.into(),
        ));
    }
    Ok(next.run(request).await)
}

/// Writes with a body must say `Content-Type: application/json` (`415` otherwise): a page of
/// another origin can send `text/plain` or form bodies without asking (no CORS preflight), but
/// not JSON. `DELETE` takes no body and is always preflighted, so it needs none.
async fn require_json(request: Request, next: Next) -> Result<Response, ApiError> {
    if request.method() != axum::http::Method::DELETE {
        let given = request
            .headers()
            .get(header::CONTENT_TYPE)
            .map(|v| String::from_utf8_lossy(v.as_bytes()).into_owned());
        let json = given.as_deref().is_some_and(|v| {
            v.split(';')
                .next()
                .is_some_and(|media| media.trim().eq_ignore_ascii_case("application/json"))
        });
        if !json {
            return Err(ApiError::new(
                StatusCode::UNSUPPORTED_MEDIA_TYPE,
                "unsupported_media_type",
                format!(
                    "writes need `Content-Type: application/json` (got {})",
                    given.map_or_else(|| "none".into(), |v| format!("{v:?}"))
                ),
            ));
        }
    }
    Ok(next.run(request).await)
}

/// The host of a `Host` header value, lower case, without the port (`[::1]:8470` → `::1`).
fn host_name(value: &str) -> &str {
    if let Some(rest) = value.strip_prefix('[') {
        return rest.split(']').next().unwrap_or(rest);
    }
    match value.rsplit_once(':') {
        Some((host, port)) if port.bytes().all(|b| b.is_ascii_digit()) => host,
        _ => value,
    }
}

/// DNS rebinding defence: a request must name the service in `Host` by an IP address (a
/// rebinding page's requests name the attacker's domain, never an address), `localhost`, or a
/// name given with `--allow-host`; else `421`. Applies to every request, reads too.
async fn check_host(
    State(state): State<AppState>,
    request: Request,
    next: Next,
) -> Result<Response, ApiError> {
    let value = request
        .headers()
        .get(header::HOST)
        .map(|v| String::from_utf8_lossy(v.as_bytes()).to_ascii_lowercase());
    let Some(value) = value else {
        return Err(ApiError::bad_request(
            "the request has no `Host` header".into(),
        ));
    };
    let host = host_name(value.trim()).trim_end_matches('.');
    let allowed = host.parse::<std::net::IpAddr>().is_ok()
        || host == "localhost"
        || state.allowed_hosts.iter().any(|h| h == host);
    if !allowed {
        return Err(ApiError::new(
            StatusCode::MISDIRECTED_REQUEST,
            "misdirected",
            format!(
                "`Host: {value}` is not a name of this service (it answers to IP addresses, \
                 `localhost` and the names given with --allow-host); a page that rebinds a \
                 domain to this address must not reach it. Start the service with \
                 `--allow-host {host}` if that name is yours"
            ),
        ));
    }
    Ok(next.run(request).await)
}

/// Reads the whole request body within `--body-timeout` (`408` and the connection closed
/// otherwise) and at most `--max-body-bytes` of it (`413`), before any handler runs.
async fn read_body(
    State(state): State<AppState>,
    request: Request,
    next: Next,
) -> Result<Response, Response> {
    let (parts, body) = request.into_parts();
    let limit = state.max_body_bytes;
    let read = tokio::time::timeout(state.body_timeout, axum::body::to_bytes(body, limit)).await;
    let bytes = match read {
        Ok(Ok(bytes)) => bytes,
        Ok(Err(_)) => {
            let too_large = parts
                .headers
                .get(header::CONTENT_LENGTH)
                .and_then(|v| v.to_str().ok()?.parse::<usize>().ok())
                .is_none_or(|n| n > limit);
            let mut response = if too_large {
                too_large_error().into_response()
            } else {
                ApiError::bad_request("the request body ended early".into()).into_response()
            };
            response
                .headers_mut()
                .insert(header::CONNECTION, HeaderValue::from_static("close"));
            return Err(response);
        }
        Err(_) => {
            let mut response = ApiError::new(
                StatusCode::REQUEST_TIMEOUT,
                "request_timeout",
                format!(
                    "the request body did not arrive within {:.0} s (--body-timeout)",
                    state.body_timeout.as_secs_f64()
                ),
            )
            .into_response();
            response
                .headers_mut()
                .insert(header::CONNECTION, HeaderValue::from_static("close"));
            return Err(response);
        }
    };
    Ok(next
        .run(Request::from_parts(parts, axum::body::Body::from(bytes)))
        .await)
}

fn too_large_error() -> ApiError {
    ApiError::new(
        StatusCode::PAYLOAD_TOO_LARGE,
        "payload_too_large",
        "the request body is larger than the service's limit (--max-body-bytes); \
         split it into several requests"
            .into(),
    )
}

/// Compares without stopping at the first difference (no timing hint about the token).
fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

async fn submit(state: &AppState, ops: Vec<WriteOp>) -> Result<WriteAck, ApiError> {
    let (reply, outcome) = oneshot::channel();
    let unavailable = || {
        ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "unavailable",
            "the service is shutting down".into(),
        )
    };
    state
        .writes
        .send(WriteCommand { ops, reply })
        .await
        .map_err(|_| unavailable())?;
    let written = outcome.await.map_err(|_| unavailable())??;
    Ok(WriteAck {
        observations: written.observations,
        seq: written.seq,
    })
}

fn create_config(model: Option<&str>) -> Result<Option<ModelConfig>, ApiError> {
    model
        .map(|m| ModelConfig::parse(Some(m), None).map_err(ApiError::bad_request))
        .transpose()
}

// ---------------------------------------------------------------------------------------------
// Handlers

async fn web_page() -> Html<&'static str> {
    Html(include_str!("web/index.html"))
}

async fn openapi() -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        ApiDoc::openapi()
            .to_pretty_json()
            .expect("the OpenAPI description serialises"),
    )
        .into_response()
}

/// Service health. `store` is the kind of store (`redb`, `postgres`); with the bearer token
/// (or on a service without one) it is the full description (file path or schema).
///
/// A node of a fleet also reports the shared log's `head`, its `lag` behind it and for how
/// long it has not been level with it; `status` is `behind` after 5 s and `failed` when it
/// stopped applying the log. `heavy_running`, `heavy_waiting` and `heavy_cancelled` count the
/// requests that compute on the heavy pool, `light_*` those on the light pool
/// ([`crate::heavy`]).
#[utoipa::path(get, path = "/v1/health", responses((status = 200, body = Health),
    (status = 503, body = ErrorBody)))]
async fn health(
    State(state): State<AppState>,
    headers: axum::http::HeaderMap,
) -> Result<Json<Health>, ApiError> {
    let models = state.shared.registry.read().expect("registry lock").len() as u64;
    let (load, light) = (state.heavy.load(), state.light.load());
    let store = state.shared.store.describe();
    let store = if authorized(&state, &headers) {
        store
    } else {
        store.split(' ').next().unwrap_or("store").to_owned()
    };
    let shared = Arc::clone(&state.shared);
    let sync = tokio::task::spawn_blocking(move || crate::fleet::sync(&shared))
        .await
        .map_err(|e| ApiError::internal(e.to_string()))?
        .map_err(|e| {
            ApiError::new(
                StatusCode::SERVICE_UNAVAILABLE,
                "unavailable",
                format!("the store cannot be read: {e}"),
            )
        })?;
    Ok(Json(Health {
        status: sync.status().into(),
        models,
        store,
        seq: sync.applied,
        auth: state.token.is_some(),
        fleet: state.shared.store.is_shared(),
        head: sync.head,
        lag: sync.head - sync.applied,
        behind_secs: sync.behind_secs,
        reason: sync.broken,
        heavy_running: load.running,
        heavy_waiting: load.waiting,
        heavy_cancelled: load.cancelled,
        light_running: light.running,
        light_waiting: light.waiting,
        light_cancelled: light.cancelled,
    }))
}

/// Read-your-writes: a request with `Chronomap-Read-After: SEQ` is answered only once this
/// node has applied the log at least up to `SEQ` (a fleet node catches up first); every answer
/// says in `Chronomap-Seq` at which position it was computed.
async fn read_after(
    State(state): State<AppState>,
    request: Request,
    next: Next,
) -> Result<Response, ApiError> {
    if let Some(value) = request.headers().get(READ_AFTER_HEADER) {
        let token: u64 = value
            .to_str()
            .ok()
            .and_then(|v| v.trim().parse().ok())
            .ok_or_else(|| {
                ApiError::bad_request(format!(
                    "header `{READ_AFTER_HEADER}`: not a log position (a non-negative integer)"
                ))
            })?;
        if state.shared.seq.load(Ordering::Acquire) < token && state.shared.store.is_shared() {
            let shared = Arc::clone(&state.shared);
            tokio::task::spawn_blocking(move || crate::fleet::catch_up(&shared))
                .await
                .map_err(|e| ApiError::internal(e.to_string()))?
                .map_err(|e| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "unavailable", e))?;
        }
        let applied = state.shared.seq.load(Ordering::Acquire);
        if applied < token {
            return Err(ApiError::bad_request(format!(
                "header `{READ_AFTER_HEADER}`: position {token} is beyond the end of the log \
                 ({applied}); send the `seq` a write returned"
            )));
        }
    }
    let applied = state.shared.seq.load(Ordering::Acquire);
    let mut response = next.run(request).await;
    response
        .headers_mut()
        .insert(SEQ_HEADER, HeaderValue::from(applied));
    Ok(response)
}

/// All models, by id (`list`); with `?prefix=robot7/` only the ids starting with it.
#[utoipa::path(get, path = "/v1/models", params(ListQuery),
    responses((status = 200, body = ListResponse), (status = 400, body = ErrorBody)))]
async fn list(
    State(state): State<AppState>,
    query: Result<axum::extract::Query<ListQuery>, axum::extract::rejection::QueryRejection>,
) -> Result<Json<ListResponse>, ApiError> {
    let query = query.map_err(|e| ApiError::bad_request(e.body_text()))?.0;
    let prefix = query.prefix.unwrap_or_default();
    let registry = state.shared.registry.read().expect("registry lock");
    let models = registry
        .ids()
        .into_iter()
        .filter(|id| id.starts_with(prefix.as_str()))
        .map(|id| {
            let mut info = registry.get(id).expect("listed id").info(id);
            info.components.clear();
            info
        })
        .collect();
    Ok(Json(ListResponse { models }))
}

/// Creates a model; no change if it exists with the same configuration.
#[utoipa::path(put, path = "/v1/models/{id}", request_body = CreateRequest,
    params(("id" = String, Path, description = "model id, 1 to 256 bytes of UTF-8")),
    security(("bearer" = [])),
    responses((status = 200, body = WriteAck), (status = 400, body = ErrorBody),
              (status = 401, body = ErrorBody), (status = 409, body = ErrorBody)))]
async fn create(
    State(state): State<AppState>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<WriteAck>, ApiError> {
    let id = path_id(path)?;
    let request: CreateRequest = parse_body(body)?;
    let mut config = ModelConfig::parse(request.model.as_deref(), request.range)
        .map_err(ApiError::bad_request)?;
    if let Some(dates) = &request.days_off {
        let days_off = crate::registry::parse_days_off(dates).map_err(ApiError::bad_request)?;
        config = config.with_days_off(days_off);
    }
    Ok(Json(
        submit(&state, vec![WriteOp::create(id, config)]).await?,
    ))
}

/// A model's parameters (`view`).
#[utoipa::path(get, path = "/v1/models/{id}",
    params(("id" = String, Path, description = "model id")),
    responses((status = 200, body = ModelInfo), (status = 404, body = ErrorBody)))]
async fn view(
    State(state): State<AppState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<ModelInfo>, ApiError> {
    let id = path_id(path)?;
    let registry = state.shared.registry.read().expect("registry lock");
    let entry = registry.get(&id).ok_or_else(|| ApiError::unknown(&id))?;
    Ok(Json(entry.info(&id)))
}

/// Removes a model (`remove`).
#[utoipa::path(delete, path = "/v1/models/{id}",
    params(("id" = String, Path, description = "model id")),
    security(("bearer" = [])),
    responses((status = 200, body = WriteAck), (status = 401, body = ErrorBody),
              (status = 404, body = ErrorBody)))]
async fn remove(
    State(state): State<AppState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<WriteAck>, ApiError> {
    let id = path_id(path)?;
    Ok(Json(submit(&state, vec![WriteOp::remove(id)]).await?))
}

/// Every observation the model holds, read back from the durable log.
#[utoipa::path(get, path = "/v1/models/{id}/observations",
    params(("id" = String, Path, description = "model id")),
    responses((status = 200, body = ObservationsResponse), (status = 404, body = ErrorBody)))]
async fn observations(
    State(state): State<AppState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<ObservationsResponse>, ApiError> {
    let id = path_id(path)?;
    if state
        .shared
        .registry
        .read()
        .expect("registry lock")
        .get(&id)
        .is_none()
    {
        return Err(ApiError::unknown(&id));
    }
    let store = Arc::clone(&state.shared.store);
    let (times, values) =
        tokio::task::spawn_blocking(move || writer::observations_of(&*store, &id))
            .await
            .map_err(|e| ApiError::internal(e.to_string()))?
            .map_err(|e| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "unavailable", e))?;
    Ok(Json(ObservationsResponse { times, values }))
}

/// Refits a model fitted on a whole series (`auto`, `fremen:auto`, `fft:L`, ...) on its kept
/// observations now: bit for bit the model `chronomap fit --model SPEC` makes of them. Answers
/// once the fit is in use and durable (seconds for `auto` on weeks of data; the service goes on
/// answering and writing meanwhile). Body `{}` or empty. Such models are also refitted without
/// being asked (`chronomap serve --refit-every`, `--refit-secs`).
#[utoipa::path(post, path = "/v1/models/{id}/refit", request_body = RefitRequest,
    params(("id" = String, Path, description = "model id")),
    security(("bearer" = [])),
    responses((status = 200, body = RefitResponse), (status = 400, body = ErrorBody),
              (status = 401, body = ErrorBody), (status = 404, body = ErrorBody),
              (status = 409, body = ErrorBody), (status = 503, body = ErrorBody)))]
async fn refit(
    State(state): State<AppState>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<RefitResponse>, ApiError> {
    let id = path_id(path)?;
    if !matches!(&body, Ok(bytes) if bytes.is_empty()) {
        let _: RefitRequest = parse_body(body)?;
    }
    let outcome = state.refits.request(&id);
    let outcome = outcome.await.unwrap_or(Err(RefitFailure::Stopping));
    outcome.map(Json).map_err(|failure| match failure {
        RefitFailure::NotFound(_) => ApiError::not_found(failure.to_string()),
        RefitFailure::Online(..) => ApiError::bad_request(failure.to_string()),
        RefitFailure::Fit(..) => {
            ApiError::new(StatusCode::CONFLICT, "conflict", failure.to_string())
        }
        RefitFailure::Write(e) => e.into(),
        RefitFailure::Stopping => ApiError::new(
            StatusCode::SERVICE_UNAVAILABLE,
            "unavailable",
            failure.to_string(),
        ),
    })
}

/// Adds binary observations of one state (`add`); answers once they are durable.
#[utoipa::path(post, path = "/v1/add", request_body = AddRequest, security(("bearer" = [])),
    responses((status = 200, body = WriteAck), (status = 400, body = ErrorBody),
              (status = 401, body = ErrorBody), (status = 404, body = ErrorBody),
              (status = 413, body = ErrorBody)))]
async fn add(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<WriteAck>, ApiError> {
    let request: AddRequest = parse_body(body)?;
    checked_id(&request.id, "id")?;
    let values = request
        .states
        .iter()
        .map(|&s| f64::from(u8::from(s)))
        .collect();
    let create = create_config(request.model.as_deref())?;
    let op = WriteOp::observe(request.id, request.times, values, create);
    Ok(Json(submit(&state, vec![op]).await?))
}

/// Adds observations with values of one state (`addvalues`); answers once they are durable.
#[utoipa::path(post, path = "/v1/addvalues", request_body = AddValuesRequest,
    security(("bearer" = [])),
    responses((status = 200, body = WriteAck), (status = 400, body = ErrorBody),
              (status = 401, body = ErrorBody), (status = 404, body = ErrorBody),
              (status = 413, body = ErrorBody)))]
async fn addvalues(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<WriteAck>, ApiError> {
    let request: AddValuesRequest = parse_body(body)?;
    let op = values_op(request, "id")?;
    Ok(Json(submit(&state, vec![op]).await?))
}

fn values_op(request: AddValuesRequest, field: &str) -> Result<WriteOp, ApiError> {
    checked_id(&request.id, field)?;
    let create = create_config(request.model.as_deref())?;
    Ok(WriteOp::observe(
        request.id,
        request.times,
        request.values,
        create,
    ))
}

/// Adds observations of many states in one durable commit: all batches or none.
#[utoipa::path(post, path = "/v1/observations", request_body = ObservationsRequest,
    security(("bearer" = [])),
    responses((status = 200, body = WriteAck), (status = 400, body = ErrorBody),
              (status = 401, body = ErrorBody), (status = 404, body = ErrorBody),
              (status = 413, body = ErrorBody)))]
async fn add_batch(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<WriteAck>, ApiError> {
    let request: ObservationsRequest = parse_body(body)?;
    let ops = request
        .batches
        .into_iter()
        .enumerate()
        .map(|(i, batch)| values_op(batch, &format!("batches[{i}].id")))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Json(submit(&state, ops).await?))
}

/// A time a prediction is asked for: finite and within [`MAX_TIME_SECS`] of the epoch, either
/// way (`400` naming `field` otherwise). JSON has no NaN or infinity, but a client library
/// may still send 1e999 or 1e308; a time beyond 10^11 s is a unit error (milliseconds).
pub(crate) fn check_time(time: f64, field: &str) -> Result<f64, ApiError> {
    if !time.is_finite() {
        return Err(ApiError::bad_request(format!(
            "field `{field}`: not a finite number"
        )));
    }
    if time.abs() > MAX_TIME_SECS {
        return Err(ApiError::bad_request(format!(
            "field `{field}`: {time} is beyond ±{MAX_TIME_SECS:e} s (about the year 5138; \
             a time in milliseconds?)"
        )));
    }
    Ok(time)
}

fn check_times(times: &[f64]) -> Result<(), ApiError> {
    for (i, &t) in times.iter().enumerate() {
        check_time(t, &format!("times[{i}]"))?;
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Model requests that compute

/// A request that computes predictions of models: checked against the registry before any
/// prediction is made, then computed on a pool ([`compute`]).
trait ModelRequest: DeserializeOwned + Send + 'static {
    /// Checks the request (`400` naming the field, `404` for an unknown model) and returns the
    /// predictions it asks for, at most [`MAX_REQUEST_PREDICTIONS`].
    fn check(&self, registry: &Registry) -> Result<u64, ApiError>;
}

/// `work` predictions asked for in `field`, or `400` naming it when they are more than
/// [`MAX_REQUEST_PREDICTIONS`]; `how` says how they were counted, `hint` what to do instead.
fn bounded(work: u64, field: &str, how: &str, hint: &str) -> Result<u64, ApiError> {
    if work > MAX_REQUEST_PREDICTIONS {
        return Err(ApiError::bad_request(format!(
            "field `{field}`: {how} are {work} predictions, more than \
             {MAX_REQUEST_PREDICTIONS} per request; {hint}"
        )));
    }
    Ok(work)
}

/// Checks a request against the models, holding the registry only while it does.
fn checked<R: ModelRequest>(request: &R, shared: &Shared) -> Result<u64, ApiError> {
    request.check(&shared.registry.read().expect("registry lock"))
}

/// Runs a model request: a body of at most [`heavy::LIGHT_MAX_BODY_BYTES`] is parsed and
/// checked here and computed here too when it asks for at most
/// [`heavy::INLINE_MAX_PREDICTIONS`] (microseconds, less than the parse), on the light pool when
/// it asks for at most [`heavy::LIGHT_MAX_PREDICTIONS`], else on the heavy pool; a larger
/// body is parsed, checked and computed on the heavy pool (parsing megabytes of JSON is work
/// too). `job` gets the request, the models, the cancel flag and the pool it runs on, and
/// answers JSON bytes (serialised off the async threads too).
async fn compute<R: ModelRequest>(
    state: &AppState,
    body: Result<Bytes, BytesRejection>,
    job: impl FnOnce(R, &Shared, &Cancel, Class) -> Result<Vec<u8>, ApiError> + Send + 'static,
) -> Result<Response, ApiError> {
    let bytes = body_bytes(body)?;
    let shared = Arc::clone(&state.shared);
    let answer = if bytes.len() > heavy::LIGHT_MAX_BODY_BYTES {
        state
            .heavy
            .run(move |cancel| {
                let request: R = parse_json(&bytes)?;
                checked(&request, &shared)?;
                if cancel.is_cancelled() {
                    return Err(heavy::cancelled());
                }
                job(request, &shared, cancel, Class::Heavy)
            })
            .await?
    } else {
        let request: R = parse_json(&bytes)?;
        let work = checked(&request, &shared)?;
        if work <= heavy::INLINE_MAX_PREDICTIONS {
            // Nothing to cancel in microseconds of work.
            let answer = job(request, &shared, &Cancel::default(), Class::Light)?;
            return Ok(crate::maps::json_response(answer));
        }
        let (pool, class) = if work <= heavy::LIGHT_MAX_PREDICTIONS {
            (&state.light, Class::Light)
        } else {
            (&state.heavy, Class::Heavy)
        };
        pool.run(move |cancel| job(request, &shared, cancel, class))
            .await?
    };
    Ok(crate::maps::json_response(answer))
}

/// The JSON bytes of an answer.
fn json_bytes<T: serde::Serialize>(value: &T) -> Result<Vec<u8>, ApiError> {
    serde_json::to_vec(value).map_err(|e| ApiError::internal(format!("cannot write JSON: {e}")))
}

/// Runs `f` on the model of `id` at `order` and its configuration: on the light pool under
/// the registry's lock (milliseconds at most; copying a large model, a histogram of 2^20
/// bins, would take longer), on the heavy pool on a copy, so that writes never wait for a
/// long computation.
fn on_model<T>(
    shared: &Shared,
    class: Class,
    id: &str,
    order: Option<usize>,
    f: impl FnOnce(&AnyModel, &ModelConfig) -> Result<T, ApiError>,
) -> Result<T, ApiError> {
    let registry = shared.registry.read().expect("registry lock");
    let entry = model_entry(&registry, id, "id")?;
    let model = entry.with_order(order).map_err(ApiError::bad_request)?;
    match class {
        Class::Light => f(&model, &entry.config),
        Class::Heavy => {
            let (model, config) = (model.into_owned(), entry.config.clone());
            drop(registry);
            f(&model, &config)
        }
    }
}

/// The work of a request of the model `id` at `order` at each of `times`: `404` or `400` if
/// there is no such model or order, else [`bounded`], one prediction per time.
fn one_model_at_times(
    registry: &Registry,
    id: &str,
    order: Option<usize>,
    times: &[f64],
) -> Result<u64, ApiError> {
    model_entry(registry, id, "id")?
        .with_order(order)
        .map_err(ApiError::bad_request)?;
    bounded(
        times.len() as u64,
        "times",
        &format!("{} times", times.len()),
        "split the request",
    )
}

impl ModelRequest for PredictRequest {
    fn check(&self, registry: &Registry) -> Result<u64, ApiError> {
        check_times(&self.times)?;
        if let Some(coverage) = self.coverage {
            check_coverage(coverage)?;
        }
        let work = one_model_at_times(registry, &self.id, self.order, &self.times)?;
        // Intervals predict the second moment too.
        Ok(work * (1 + u64::from(self.coverage.is_some())))
    }
}

/// A `coverage` of prediction intervals: strictly between 0 and 1 (`400` naming the field
/// otherwise).
fn check_coverage(coverage: f64) -> Result<(), ApiError> {
    if !(coverage > 0.0 && coverage < 1.0) {
        return Err(ApiError::bad_request(format!(
            "field `coverage`: {coverage} is not a share strictly between 0 and 1 (0.9 asks \
             for intervals that hold 90 % of the values)"
        )));
    }
    Ok(())
}

/// The central intervals of coverage `coverage` in the model's range, from the predicted means
/// `means` (normalised) and the model of the second moment ([`chronomap_core::spread`]).
fn intervals(
    spread: &AnyModel,
    config: &ModelConfig,
    times: &[f64],
    means: &[f64],
    coverage: f64,
) -> (Vec<f64>, Vec<f64>) {
    let seconds = spread.predict_many(times);
    means
        .iter()
        .zip(&seconds)
        .map(|(&m, &s)| {
            let (lo, hi) = chronomap_core::spread::beta_interval(m, s, coverage);
            (config.scale(lo), config.scale(hi))
        })
        .unzip()
}

/// `predict` and `entropy`: one call of the model over all the times (and for intervals, one
/// of the model of the second moment).
async fn predictions(
    state: &AppState,
    body: Result<Bytes, BytesRejection>,
    map: fn(f64) -> f64,
    scaled: bool,
) -> Result<Response, ApiError> {
    compute(
        state,
        body,
        move |request: PredictRequest, shared, cancel, class| {
            let coverage = match request.coverage {
                Some(_) if !scaled => {
                    return Err(ApiError::bad_request(
                        "field `coverage`: only `POST /v1/predict` gives intervals".into(),
                    ));
                }
                coverage => coverage,
            };
            let (mut values, scaled, bands) = on_model_and_spread(
                shared,
                class,
                &request.id,
                request.order,
                |model, spread, config| {
                    if cancel.is_cancelled() {
                        return Err(heavy::cancelled());
                    }
                    // A time on a day off is asked at its stand-in, for the value and the
                    // second moment alike.
                    let times = config.days_off.stand_ins(&request.times);
                    let values = model.predict_many(&times);
                    let scaled = (scaled && config.range.is_some())
                        .then(|| values.iter().map(|&p| config.scale(p)).collect());
                    let bands = match (coverage, spread) {
                        (Some(c), Some(spread)) if config.range.is_some() => {
                            Some(intervals(spread, config, &times, &values, c))
                        }
                        _ => None,
                    };
                    Ok((values, scaled, bands))
                },
            )?;
            values.iter_mut().for_each(|v| *v = map(*v));
            let (lower, upper) = bands.unzip();
            json_bytes(&PredictResponse {
                values,
                scaled,
                lower,
                upper,
            })
        },
    )
    .await
}

/// [`on_model`] with the model of the second moment at the same order, where the model has
/// one that predicts ([`Entry::spread_with_order`]).
fn on_model_and_spread<T>(
    shared: &Shared,
    class: Class,
    id: &str,
    order: Option<usize>,
    f: impl FnOnce(&AnyModel, Option<&AnyModel>, &ModelConfig) -> Result<T, ApiError>,
) -> Result<T, ApiError> {
    let registry = shared.registry.read().expect("registry lock");
    let entry = model_entry(&registry, id, "id")?;
    let model = entry.with_order(order).map_err(ApiError::bad_request)?;
    let spread = entry.spread_with_order(order);
    match class {
        Class::Light => f(&model, spread.as_deref(), &entry.config),
        Class::Heavy => {
            let (model, spread, config) = (
                model.into_owned(),
                spread.map(std::borrow::Cow::into_owned),
                entry.config.clone(),
            );
            drop(registry);
            f(&model, spread.as_ref(), &config)
        }
    }
}

/// `p(t)` of one model at many times (`predict`).
#[utoipa::path(post, path = "/v1/predict", request_body = PredictRequest,
    responses((status = 200, body = PredictResponse), (status = 400, body = ErrorBody),
              (status = 404, body = ErrorBody),
              (status = 503, description = "too many requests computing; `Retry-After` says \
               when to ask again", body = ErrorBody)))]
async fn predict(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    predictions(&state, body, |p| p, true).await
}

/// Binary entropy (bits) of one model's predictions at many times (`entropy`).
#[utoipa::path(post, path = "/v1/entropy", request_body = PredictRequest,
    responses((status = 200, body = PredictResponse), (status = 400, body = ErrorBody),
              (status = 404, body = ErrorBody),
              (status = 503, description = "too many requests computing; `Retry-After` says \
               when to ask again", body = ErrorBody)))]
async fn entropy(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    predictions(&state, body, binary_entropy, false).await
}

impl ModelRequest for ForecastRequest {
    fn check(&self, registry: &Registry) -> Result<u64, ApiError> {
        check_time(self.time, "time")?;
        if let Some(orders) = &self.orders
            && orders.len() != self.ids.len()
        {
            return Err(ApiError::bad_request(format!(
                "field `orders`: {} orders for {} ids",
                orders.len(),
                self.ids.len()
            )));
        }
        let work = bounded(
            self.ids.len() as u64,
            "ids",
            &format!("{} ids", self.ids.len()),
            "split the request",
        )?;
        for (i, id) in self.ids.iter().enumerate() {
            model_entry(registry, id, &format!("ids[{i}]"))?;
        }
        Ok(work)
    }
}

/// `forecast` and `forecastEntropy`: [`MODEL_CHUNK`] ids at a time, each chunk under the
/// registry's lock (so that writes wait for one chunk at most).
async fn forecasts(
    state: &AppState,
    body: Result<Bytes, BytesRejection>,
    map: fn(f64) -> f64,
) -> Result<Response, ApiError> {
    compute(
        state,
        body,
        move |request: ForecastRequest, shared, cancel, _| {
            let mut values = Vec::with_capacity(request.ids.len());
            for (chunk, ids) in request.ids.chunks(MODEL_CHUNK).enumerate() {
                if cancel.is_cancelled() {
                    return Err(heavy::cancelled());
                }
                let registry = shared.registry.read().expect("registry lock");
                for (k, id) in ids.iter().enumerate() {
                    let i = chunk * MODEL_CHUNK + k;
                    let entry = model_entry(&registry, id, &format!("ids[{i}]"))?;
                    let order = request.orders.as_ref().map(|o| o[i]).or(request.order);
                    let model = entry
                        .with_order(order)
                        .map_err(|e| ApiError::bad_request(format!("ids[{i}]: {e}")))?;
                    values.push(map(
                        model.predict(entry.config.days_off.stand_in(request.time))
                    ));
                }
            }
            json_bytes(&ForecastResponse { values })
        },
    )
    .await
}

/// `p(t)` of many models at one time (`forecast`), with one order each or one for all.
#[utoipa::path(post, path = "/v1/forecast", request_body = ForecastRequest,
    responses((status = 200, body = ForecastResponse), (status = 400, body = ErrorBody),
              (status = 404, body = ErrorBody),
              (status = 503, description = "too many requests computing; `Retry-After` says \
               when to ask again", body = ErrorBody)))]
async fn forecast(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    forecasts(&state, body, |p| p).await
}

/// Binary entropy (bits) of many models at one time (`forecastEntropy`).
#[utoipa::path(post, path = "/v1/forecastEntropy", request_body = ForecastRequest,
    responses((status = 200, body = ForecastResponse), (status = 400, body = ErrorBody),
              (status = 404, body = ErrorBody),
              (status = 503, description = "too many requests computing; `Retry-After` says \
               when to ask again", body = ErrorBody)))]
async fn forecast_entropy(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    forecasts(&state, body, binary_entropy).await
}

fn check_data(times: &[f64], values: &[f64]) -> Result<(), ApiError> {
    check_times(times)?;
    if times.len() != values.len() {
        return Err(ApiError::bad_request(format!(
            "{} times but {} values",
            times.len(),
            values.len()
        )));
    }
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(ApiError::bad_request(format!(
            "field `values`, element {i}: not a finite number"
        ))),
        None => Ok(()),
    }
}

/// The orders `evaluate` computes for `entry`: `0..=max_order` (default 10) up to the model's
/// largest, or `[0]` for a model without orders.
fn evaluated_orders(entry: &Entry, max_order: Option<usize>) -> Vec<usize> {
    match entry.model.model().and_then(crate::registry::max_order) {
        Some(max) => (0..=max_order.unwrap_or(10).min(max)).collect(),
        None => vec![0],
    }
}

impl ModelRequest for EvaluateRequest {
    fn check(&self, registry: &Registry) -> Result<u64, ApiError> {
        check_data(&self.times, &self.values)?;
        if self.times.is_empty() {
            return Err(ApiError::bad_request(
                "field `times`: nothing to evaluate on".into(),
            ));
        }
        let entry = model_entry(registry, &self.id, "id")?;
        let orders = evaluated_orders(entry, self.max_order).len();
        let rows = self.times.len();
        bounded(
            (rows as u64).saturating_mul(orders as u64),
            "times",
            &format!("{rows} times × {orders} orders"),
            "send fewer times or a lower `max_order`",
        )
    }
}

/// Errors of a model for every order on given data (`evaluate`).
#[utoipa::path(post, path = "/v1/evaluate", request_body = EvaluateRequest,
    responses((status = 200, body = EvaluateResponse), (status = 400, body = ErrorBody),
              (status = 404, body = ErrorBody),
              (status = 503, description = "too many requests computing; `Retry-After` says \
               when to ask again", body = ErrorBody)))]
async fn evaluate(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    compute(
        &state,
        body,
        |request: EvaluateRequest, shared, cancel, class| {
            // The model at every order: under the registry's lock on the light pool, copied on
            // the heavy pool (as `on_model`).
            let registry = shared.registry.read().expect("registry lock");
            let entry = model_entry(&registry, &request.id, "id")?;
            let ordered = entry.model.model().and_then(crate::registry::max_order);
            let orders = evaluated_orders(entry, request.max_order);
            let models = orders
                .iter()
                .map(|&order| {
                    entry
                        .with_order(ordered.map(|_| order))
                        .map_err(ApiError::bad_request)
                })
                .collect::<Result<Vec<_>, _>>()?;
            let targets: Vec<f64> = request
                .values
                .iter()
                .map(|&v| entry.config.normalise(v))
                .collect();
            let binary = targets.iter().all(|&v| v == 0.0 || v == 1.0);
            // Days off are scored against their stand-ins' predictions, as they are answered.
            let times = entry.config.days_off.stand_ins(&request.times);
            let scored = |models: &[&AnyModel]| score(models, &times, &targets, binary, cancel);
            let (errors, brier) = match class {
                Class::Light => scored(&models.iter().map(|m| &**m).collect::<Vec<_>>())?,
                Class::Heavy => {
                    let models: Vec<AnyModel> = models.into_iter().map(Cow::into_owned).collect();
                    drop(registry);
                    scored(&models.iter().collect::<Vec<_>>())?
                }
            };
            let best = errors
                .iter()
                .enumerate()
                .fold(0, |best, (i, &e)| if e < errors[best] { i } else { best });
            json_bytes(&EvaluateResponse {
                best_order: orders[best],
                orders,
                errors,
                brier,
                metric: if binary {
                    "binary_error"
                } else {
                    "mean_absolute_error"
                }
                .into(),
            })
        },
    )
    .await
}

/// The error (binary or mean absolute) and Brier score of each of `models` on the data,
/// checking between models whether the client went away.
fn score(
    models: &[&AnyModel],
    times: &[f64],
    targets: &[f64],
    binary: bool,
    cancel: &Cancel,
) -> Result<(Vec<f64>, Vec<f64>), ApiError> {
    let mut errors = Vec::with_capacity(models.len());
    let mut brier = Vec::with_capacity(models.len());
    for model in models {
        if cancel.is_cancelled() {
            return Err(heavy::cancelled());
        }
        let p = model.predict_many(times);
        let n = p.len() as f64;
        let error = p
            .iter()
            .zip(targets)
            .map(|(&p, &s)| {
                if binary {
                    f64::from(u8::from((p > 0.5) != (s > 0.5)))
                } else {
                    (p - s).abs()
                }
            })
            .sum::<f64>()
            / n;
        errors.push(error);
        brier.push(
            p.iter()
                .zip(targets)
                .map(|(p, s)| (p - s) * (p - s))
                .sum::<f64>()
                / n,
        );
    }
    Ok((errors, brier))
}

impl ModelRequest for DetectRequest {
    fn check(&self, registry: &Registry) -> Result<u64, ApiError> {
        check_data(&self.times, &self.values)?;
        if !(self.confidence > 0.0 && self.confidence <= 1.0) {
            return Err(ApiError::bad_request(format!(
                "field `confidence`: {} is not in (0, 1]",
                self.confidence
            )));
        }
        one_model_at_times(registry, &self.id, self.order, &self.times)
    }
}

/// Observations that differ from the prediction by at least `confidence` (`detect`).
#[utoipa::path(post, path = "/v1/detect", request_body = DetectRequest,
    responses((status = 200, body = DetectResponse), (status = 400, body = ErrorBody),
              (status = 404, body = ErrorBody),
              (status = 503, description = "too many requests computing; `Retry-After` says \
               when to ask again", body = ErrorBody)))]
async fn detect(
    State(state): State<AppState>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    compute(
        &state,
        body,
        |request: DetectRequest, shared, cancel, class| {
            let anomalies = on_model(
                shared,
                class,
                &request.id,
                request.order,
                |model, config| {
                    let mut anomalies = Vec::new();
                    for (times, values) in request
                        .times
                        .chunks(MODEL_CHUNK)
                        .zip(request.values.chunks(MODEL_CHUNK))
                    {
                        if cancel.is_cancelled() {
                            return Err(heavy::cancelled());
                        }
                        anomalies.extend(times.iter().zip(values).filter_map(|(&time, &value)| {
                            let p = model.predict(config.days_off.stand_in(time));
                            ((config.normalise(value) - p).abs() >= request.confidence).then(|| {
                                Anomaly {
                                    time,
                                    value,
                                    predicted: config.scale(p),
                                }
                            })
                        }));
                    }
                    Ok(anomalies)
                },
            )?;
            json_bytes(&DetectResponse { anomalies })
        },
    )
    .await
}
