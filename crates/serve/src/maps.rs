//! Spatial containers served read-only beside the models: topological maps whose edges know
//! time ([Fentanes 2015]), occupancy grids ([Krajník 2017] §VI) and maps of human activity
//! (CoPA-Map, [Stüde 2024] §4.2), loaded from their model files at start.
//!
//! * `GET /v1/maps`: what is served.
//! * `GET /v1/topo/{name}`: nodes with positions, edges and the models' time span.
//! * `POST /v1/topo/{name}/predict {time}`: every edge's success probability and expected
//!   duration at `time`.
//! * `POST /v1/topo/{name}/plan {from, task, times, deadline_secs?}`: "now or later?" — for each
//!   start time the maximum probability of fulfilling a co-safe LTL task, the expected time and
//!   the first edge; with `deadline_secs` also the plan most likely to fulfil it in time
//!   ([`chronomap_topo::deadline`], `chronomap plan --deadline`).
//! * `GET /v1/grid/{name}`: shape, placement and frames of a grid.
//! * `POST /v1/grid/{name}/predict {time}`: the predicted occupancy probability of every cell.
//! * `POST /v1/grid/{name}/cell {cell, times}`: one cell's occupancy probability at many times.
//! * `GET /v1/activity/{name}`: a CoPA-Map's domain, periods and unit of time.
//! * `POST /v1/activity/{name}/predict {t, cell?}`: mean and standard deviation of the rate
//!   of people in every cell.
//!
//! Grid and activity predictions and plans compute for a while: they run on the service's
//! pool for heavy requests ([`crate::heavy`]), are refused with `503` when it is full and are
//! given up when their client goes away. A grid cell's times and the edges at a time are
//! bounded and short: they run on the light pool. A grid that keeps its learning state is fitted once,
//! on its first prediction, into its compact model ([`FittedGrid`], [Krajník 2017] §VI),
//! which then predicts every map (the same bits as refitting every changed cell each time);
//! the served grids never change, so the compact model stays valid.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use axum::body::Bytes;
use axum::extract::rejection::{BytesRejection, PathRejection};
use axum::extract::{Path, State};
use axum::http::{HeaderValue, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use chronomap_core::observe::MAX_TIME_SECS;
use chronomap_core::observe::ObservedSpan;
use chronomap_grid::AnyGrid;
use chronomap_grid::{FittedGrid, GridGeometry, OrderChoice};
use chronomap_topo::deadline::{
    DEFAULT_MAX_CELLS, DeadlineError, DeadlineOptions, DeadlinePlanned, buckets_for, plan_deadline,
};
use chronomap_topo::edges::EVALUATION_COVERAGE;
use chronomap_topo::map::TopoMap;
use chronomap_topo::mdp::SolverOptions;
use chronomap_topo::plan::{Task, plan_at};
use serde::{Deserialize, Serialize};
use tokio::sync::watch;
use utoipa::ToSchema;

use crate::heavy::{self, Heavy};
use crate::server::{ApiError, check_time, parse_body};

mod activity;
mod topo;

pub use activity::{
    ActivityError, ActivityGrid, DEFAULT_CELL, MAX_ACTIVITY_CELLS, MAX_ACTIVITY_WORK,
    PREDICT_CHUNK, ServedActivity, TIME_UNIT, WALL_PERCENT,
};
pub use topo::{COMPUTED_EDGE_LENGTH, MissingPositions, PositionSource, ServedTopo, training_span};

/// Most start times of one `plan` request.
pub const MAX_PLAN_TIMES: usize = 1000;

/// Most times of one `cell` request.
pub const MAX_CELL_TIMES: usize = 10_000;

/// Most cells (start times × product states × buckets `K + 1`) of the deadline plans of one
/// `plan` request: as much as one `chronomap plan --deadline` may compute
/// ([`chronomap_topo::deadline::DEFAULT_MAX_CELLS`]).
pub const MAX_DEADLINE_CELLS: usize = DEFAULT_MAX_CELLS;

/// The longest deadline of a `plan` request (s): the bound of every time.
pub const MAX_DEADLINE_SECS: f64 = MAX_TIME_SECS;

/// The confidence of a deadline plan when the request gives none (as `chronomap plan`).
pub const DEFAULT_CONFIDENCE: f64 = 0.95;

/// The maps a service holds, by name.
#[derive(Debug, Default)]
pub struct Maps {
    /// Topological maps with edge models and node positions.
    pub topological: BTreeMap<String, ServedTopo>,
    /// Occupancy grids.
    pub grids: BTreeMap<String, AnyGrid>,
    /// CoPA-Maps of the rate of people.
    pub activity: BTreeMap<String, ServedActivity>,
}

/// A map in `GET /v1/maps`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MapInfo {
    /// Name given at start.
    pub name: String,
    /// `topological`, `grid-state`, `grid-lossy`, `grid-lossless` or `activity`.
    pub kind: String,
    /// Nodes (topological), cells (grids) or cells of [`DEFAULT_CELL`] metres (activity).
    pub size: u64,
    /// Edges of a topological map.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub edges: Option<u64>,
}

/// Answer of `GET /v1/maps`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MapsResponse {
    /// By name.
    pub maps: Vec<MapInfo>,
}

/// A time (`POST /v1/topo/{name}/predict`, `POST /v1/grid/{name}/predict`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct TimeRequest {
    /// Time (s).
    pub time: f64,
}

/// One edge's prediction.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct EdgePrediction {
    /// Edge id.
    pub id: String,
    /// Start node.
    pub from: String,
    /// End node.
    pub to: String,
    /// Probability that a traversal started then succeeds.
    pub success: f64,
    /// Expected duration of a traversal started then (s).
    pub duration_secs: f64,
    /// The interval that holds a successful traversal's duration with probability 0.9, `[lower,
    /// upper]` in seconds (absent for models written before intervals existed).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub duration_interval_secs: Option<[f64; 2]>,
}

/// Answer of `POST /v1/topo/{name}/predict`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct EdgesResponse {
    /// Every edge, in map order.
    pub edges: Vec<EdgePrediction>,
}

/// A task to plan (`POST /v1/topo/{name}/plan`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct PlanRequest {
    /// Start node.
    pub from: String,
    /// Co-safe LTL over node names, e.g. `F Kitchen` or `!Printer U Kitchen`.
    pub task: String,
    /// Start times (s) to compare: now, and later.
    pub times: Vec<f64>,
    /// Also plan for the greatest probability of fulfilling the task within this many seconds
    /// of each start time ("arrive by T"): finite, > 0, at most 10^11.
    #[serde(default)]
    pub deadline_secs: Option<f64>,
    /// With `deadline_secs`: the probability asked for, in [0, 1] (default 0.95); the answer
    /// says whether the deadline plan reaches it and within how many seconds it could.
    #[serde(default)]
    pub confidence: Option<f64>,
    /// With `deadline_secs`: the width of the time buckets durations are rounded up to (s;
    /// default `max(deadline_secs / 600, 1)`), finite, > 0, at most `deadline_secs`.
    #[serde(default)]
    pub bucket_secs: Option<f64>,
    /// With `deadline_secs`: also answer the `curve` of the probabilities within `d`.
    #[serde(default)]
    pub curve: bool,
}

/// The plan for one start time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PlanResult {
    /// Start time.
    pub time: f64,
    /// Maximum probability of fulfilling the task.
    pub pmax: f64,
    /// Expected time until the task is fulfilled or has failed (s).
    pub expected_secs: f64,
    /// First edge to take (`null`: the task holds already or cannot be fulfilled).
    pub first_edge: Option<String>,
    /// The deadline plan, when the request gave `deadline_secs`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deadline: Option<DeadlineResult>,
}

/// The plan most likely to fulfil the task within the deadline ([`chronomap_topo::deadline`]),
/// beside the expected-time plan of [`PlanResult`]: the fields of `chronomap plan --deadline
/// --json` of the same names.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct DeadlineResult {
    /// The deadline (s after the start).
    pub deadline_secs: f64,
    /// The probability asked for.
    pub confidence: f64,
    /// The bucket width durations are rounded up to (s).
    pub bucket_secs: f64,
    /// The greatest probability of fulfilling the task within the deadline (a certified lower
    /// bound: durations rounded up to buckets, the top 0.5 % of each edge's durations late).
    pub probability: f64,
    /// Whether `probability` reaches `confidence`.
    pub reaches_confidence: bool,
    /// The first edge to take (`null`: the task holds already or cannot be fulfilled in time).
    pub first_edge: Option<String>,
    /// The route if every edge succeeds in its median duration.
    pub median_route: Vec<String>,
    /// The shortest deadline (s, a multiple of the bucket) within which the task is fulfilled
    /// with probability `confidence`; `null` if not within the deadline.
    pub shortest_deadline_secs: Option<f64>,
    /// The expected-time plan's probability of fulfilling the task within the deadline.
    pub min_time_probability: f64,
    /// Whether the durations' laws come from their quantiles (else: sure expected durations).
    pub duration_quantiles: bool,
    /// States of the product of the Navigation MDP and the task automaton.
    pub product_states: u64,
    /// With `curve: true`: `[d, deadline plan, expected-time plan]`, the probabilities of
    /// fulfilling the task within `d` s, `d = 0, bucket_secs, …, deadline`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub curve: Option<Vec<[f64; 3]>>,
}

/// Answer of `POST /v1/topo/{name}/plan`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct PlanResponse {
    /// One plan per start time.
    pub plans: Vec<PlanResult>,
}

/// Answer of `POST /v1/grid/{name}/predict`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct GridResponse {
    /// Cells along x, y, z; cell `(x, y, z)` is `values[x + width·(y + height·z)]`.
    pub shape: [u32; 3],
    /// Cell edge (m).
    pub resolution: f64,
    /// Lower corner of cell (0, 0, 0) (m).
    pub origin: [f64; 3],
    /// Occupancy probability of every cell.
    pub values: Vec<f32>,
}

/// Answer of `GET /v1/grid/{name}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct GridInfo {
    /// Name given at start.
    pub name: String,
    /// `grid-state`, `grid-lossy` or `grid-lossless` (as in `GET /v1/maps`).
    pub kind: String,
    /// Cells along x, y, z.
    pub shape: [u32; 3],
    /// Cell edge (m).
    pub resolution: f64,
    /// Lower corner of cell (0, 0, 0) (m).
    pub origin: [f64; 3],
    /// Frames (whole maps) the grid learned from.
    pub frames: u64,
    /// Time of the first frame (s); `null` without frames.
    pub first_time: Option<f64>,
    /// Time of the last frame (s); `null` without frames.
    pub last_time: Option<f64>,
}

/// One cell at many times (`POST /v1/grid/{name}/cell`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CellRequest {
    /// `[x, y]` (layer 0) or `[x, y, z]`: cell indices from 0.
    pub cell: Vec<i64>,
    /// Times (s), 1 to 10,000.
    pub times: Vec<f64>,
}

/// Answer of `POST /v1/grid/{name}/cell`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct CellResponse {
    /// The cell `[x, y, z]`.
    pub cell: [u32; 3],
    /// Its centre, `origin + (cell + 0.5)·resolution` (m).
    pub centre: [f64; 3],
    /// Occupancy probability at each time: the single-precision value of
    /// `POST /v1/grid/{name}/predict` for that cell and time, widened exactly to `f64`;
    /// `null` for a cell never observed.
    #[serde(deserialize_with = "nan_for_null")]
    #[schema(value_type = Vec<Option<f64>>)]
    pub values: Vec<f64>,
}

/// Reads `null` as NaN (how JSON carries the prediction of a cell never observed).
fn nan_for_null<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
    let values: Vec<Option<f64>> = Deserialize::deserialize(d)?;
    Ok(values.into_iter().map(|v| v.unwrap_or(f64::NAN)).collect())
}

/// A node of `GET /v1/topo/{name}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TopoNode {
    /// Node name.
    pub name: String,
    /// Position (m; in edge lengths for a computed layout).
    pub x: f64,
    /// Position (m; in edge lengths for a computed layout).
    pub y: f64,
}

/// An edge of `GET /v1/topo/{name}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TopoEdge {
    /// Edge id.
    pub id: String,
    /// Start node.
    pub from: String,
    /// End node.
    pub to: String,
}

/// Answer of `GET /v1/topo/{name}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct TopoInfo {
    /// Name given at start.
    pub name: String,
    /// Where the positions come from: `file` (a `--topo-layout` file gave every node one;
    /// metres), `model` (the edge models' own map has a pose for every node; metres) or
    /// `computed` (stress majorization of hop distances, one edge length = 1; not metric).
    pub positions: String,
    /// The `--topo-layout` file, when it gave the positions.
    pub layout_file: Option<String>,
    /// Every node, in map order.
    pub nodes: Vec<TopoNode>,
    /// Every edge, in map order (as `POST /v1/topo/{name}/predict` lists them).
    pub edges: Vec<TopoEdge>,
    /// Earliest attempt any edge's models learned from (s); `null` if none.
    pub first_time: Option<f64>,
    /// Latest attempt of any edge (s); `null` if none.
    pub last_time: Option<f64>,
}

/// Answer of `GET /v1/activity/{name}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ActivityInfo {
    /// Name given at start.
    pub name: String,
    /// The training square `[x_min, y_min, x_max, y_max]` of the cell centres (m).
    pub domain: [f64; 4],
    /// The fitted periods, in units of `t`.
    pub periods: Vec<f64>,
    /// What `t` counts.
    pub time_unit: String,
    /// The training times `[t_min, t_max]` (units of `t`; at least one day period wide).
    pub t_range: [f64; 2],
    /// Side of a cell when a prediction asks for none (m).
    pub default_cell: f64,
    /// Whether cells on walls of a map (`--activity-map`) are left out.
    pub masked_by_map: bool,
}

/// A time of a CoPA-Map (`POST /v1/activity/{name}/predict`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ActivityRequest {
    /// Time, in the model's units (`time_unit` of `GET /v1/activity/{name}`).
    pub t: f64,
    /// Side of a cell (m); default 0.5.
    #[serde(default)]
    pub cell: Option<f64>,
}

/// Answer of `POST /v1/activity/{name}/predict`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct ActivityResponse {
    /// The time asked for.
    pub t: f64,
    /// Lower-left corner of cell (0, 0) (m).
    pub origin: [f64; 2],
    /// Side of a cell (m).
    pub cell: f64,
    /// Columns (along x) and rows (along y).
    pub shape: [u32; 2],
    /// Mean rate of cell `(col, row)` at `col + cols·row`, row 0 at the bottom; `null` on
    /// walls of the map.
    pub mean: Vec<Option<f64>>,
    /// Standard deviation of the rate, likewise.
    pub std: Vec<Option<f64>>,
}

/// The compact model of a grid served with its learning state, fitted on first use.
#[derive(Debug)]
struct FittedCache {
    /// Whether its fit was started.
    started: AtomicBool,
    /// `Some` once fitted (`Err`: the fit failed, a bug).
    ready: watch::Sender<Option<Result<Arc<FittedGrid>, String>>>,
}

/// What the map routes hold: the maps, the pools of heavy and light requests and the compact
/// models of grids served with their learning state.
#[derive(Clone, Debug)]
pub(crate) struct MapsState {
    maps: Arc<Maps>,
    heavy: Arc<Heavy>,
    light: Arc<Heavy>,
    fitted: Arc<BTreeMap<String, FittedCache>>,
}

impl MapsState {
    pub(crate) fn new(maps: Arc<Maps>, heavy: Arc<Heavy>, light: Arc<Heavy>) -> Self {
        let fitted = maps
            .grids
            .iter()
            .filter(|(_, g)| matches!(g, AnyGrid::State(_)))
            .map(|(name, _)| {
                let cache = FittedCache {
                    started: AtomicBool::new(false),
                    ready: watch::Sender::new(None),
                };
                (name.clone(), cache)
            })
            .collect();
        MapsState {
            maps,
            heavy,
            light,
            fitted: Arc::new(fitted),
        }
    }

    /// The compact model of the grid `name` served with its learning state: fitted on the
    /// heavy pool by the first request that needs it (whether or not that request stays),
    /// awaited by the others without holding a thread. `None` for a grid that is stored
    /// fitted.
    async fn fitted(&self, name: &str) -> Result<Option<Arc<FittedGrid>>, ApiError> {
        let Some(cache) = self.fitted.get(name) else {
            return Ok(None);
        };
        let mut ready = cache.ready.subscribe();
        if !cache.started.swap(true, Ordering::AcqRel) {
            let (state, name) = (self.clone(), name.to_owned());
            self.heavy.prepare(move || {
                let outcome = match state.maps.grids.get(&name) {
                    Some(AnyGrid::State(g)) => std::panic::catch_unwind(|| {
                        // On the worker's thread alone, as every heavy request computes.
                        let order = OrderChoice::Fixed(g.config().fremen.order);
                        Arc::new(g.fitted(order, heavy::PARALLELISM))
                    })
                    .map_err(|_| format!("the grid {name:?} could not be fitted")),
                    _ => Err(format!("no grid {name:?} with a learning state")),
                };
                if let Some(cache) = state.fitted.get(&name) {
                    cache.ready.send_replace(Some(outcome));
                }
            });
        }
        let fitted = ready
            .wait_for(Option::is_some)
            .await
            .map_err(|_| ApiError::internal("the grid's fit was dropped".into()))?;
        match fitted.as_ref() {
            Some(Ok(fitted)) => Ok(Some(Arc::clone(fitted))),
            Some(Err(reason)) => Err(ApiError::internal(reason.clone())),
            None => Err(ApiError::internal("the grid's fit was dropped".into())),
        }
    }
}

/// A JSON answer serialised off the async threads.
fn json_answer<T: Serialize>(value: &T) -> Result<Vec<u8>, ApiError> {
    serde_json::to_vec(value).map_err(|e| ApiError::internal(format!("cannot write JSON: {e}")))
}

/// An answer of JSON bytes.
pub(crate) fn json_response(body: Vec<u8>) -> Response {
    let mut response = body.into_response();
    response.headers_mut().insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/json"),
    );
    response
}

/// The routes, with their state.
pub(crate) fn router(maps: MapsState) -> Router {
    Router::new()
        .route("/v1/maps", get(list))
        .route("/v1/topo/{name}", get(topo_info))
        .route("/v1/topo/{name}/predict", post(topo_predict))
        .route("/v1/topo/{name}/plan", post(topo_plan))
        .route("/v1/grid/{name}", get(grid_info))
        .route("/v1/grid/{name}/predict", post(grid_predict))
        .route("/v1/grid/{name}/cell", post(grid_cell))
        .route("/v1/activity/{name}", get(activity_info))
        .route("/v1/activity/{name}/predict", post(activity_predict))
        .with_state(maps)
}

fn name(path: Result<Path<String>, PathRejection>) -> Result<String, ApiError> {
    let Path(name) =
        path.map_err(|e| ApiError::bad_request(format!("map name in the path: {e}")))?;
    Ok(name)
}

fn topo<'a>(maps: &'a Maps, name: &str) -> Result<&'a ServedTopo, ApiError> {
    maps.topological
        .get(name)
        .ok_or_else(|| ApiError::not_found(format!("no topological map named {name:?}")))
}

fn grid<'a>(maps: &'a Maps, name: &str) -> Result<&'a AnyGrid, ApiError> {
    maps.grids
        .get(name)
        .ok_or_else(|| ApiError::not_found(format!("no grid named {name:?}")))
}

fn activity<'a>(maps: &'a Maps, name: &str) -> Result<&'a ServedActivity, ApiError> {
    maps.activity
        .get(name)
        .ok_or_else(|| ApiError::not_found(format!("no activity map named {name:?}")))
}

/// The maps held.
#[utoipa::path(get, path = "/v1/maps", responses((status = 200, body = MapsResponse)))]
pub(crate) async fn list(State(state): State<MapsState>) -> Json<MapsResponse> {
    let maps = &*state.maps;
    let mut list: Vec<MapInfo> = maps
        .topological
        .iter()
        .map(|(name, m)| MapInfo {
            name: name.clone(),
            kind: "topological".into(),
            size: m.models().map().nodes().len() as u64,
            edges: Some(m.models().map().edges().len() as u64),
        })
        .collect();
    list.extend(maps.grids.iter().map(|(name, g)| MapInfo {
        name: name.clone(),
        kind: chronomap_io::grid_kind(g).into(),
        size: geometry(g).cells() as u64,
        edges: None,
    }));
    list.extend(maps.activity.iter().map(|(name, a)| MapInfo {
        name: name.clone(),
        kind: "activity".into(),
        size: a.region(DEFAULT_CELL).map_or(0, |g| g.len() as u64),
        edges: None,
    }));
    Json(MapsResponse { maps: list })
}

/// Nodes with their positions, edges, and the time span the edge models learned from.
#[utoipa::path(get, path = "/v1/topo/{name}",
    params(("name" = String, Path, description = "map name")),
    responses((status = 200, body = TopoInfo), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody)))]
pub(crate) async fn topo_info(
    State(state): State<MapsState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<TopoInfo>, ApiError> {
    let name = name(path)?;
    let served = topo(&state.maps, &name)?;
    let map = served.models().map();
    let nodes = map
        .nodes()
        .iter()
        .zip(served.positions())
        .map(|(n, &[x, y])| TopoNode {
            name: n.name.clone(),
            x,
            y,
        })
        .collect();
    let edges = map
        .edges()
        .iter()
        .map(|e| TopoEdge {
            id: e.id.clone(),
            from: map.nodes()[e.from].name.clone(),
            to: map.nodes()[e.to].name.clone(),
        })
        .collect();
    let (first_time, last_time) = served.span();
    Ok(Json(TopoInfo {
        name,
        positions: served.source().as_str().into(),
        layout_file: served.layout_file().map(str::to_owned),
        nodes,
        edges,
        first_time,
        last_time,
    }))
}

/// Every edge's success probability and expected duration at a time.
#[utoipa::path(post, path = "/v1/topo/{name}/predict", request_body = TimeRequest,
    params(("name" = String, Path, description = "map name")),
    responses((status = 200, body = EdgesResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody),
              (status = 503, description = "too many requests computing; `Retry-After` says \
               when to ask again", body = crate::api::ErrorBody)))]
pub(crate) async fn topo_predict(
    State(state): State<MapsState>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let name = name(path)?;
    let request: TimeRequest = parse_body(body)?;
    let time = check_time(request.time, "time")?;
    topo(&state.maps, &name)?;
    // Every edge's models at one time: bounded by the map, on the light pool.
    let maps = Arc::clone(&state.maps);
    let body = state
        .light
        .run(move |_| {
            let models = topo(&maps, &name)?.models();
            let (success, duration) = models.at(time);
            let map = models.map();
            let edges = map
                .edges()
                .iter()
                .enumerate()
                .map(|(k, e)| EdgePrediction {
                    id: e.id.clone(),
                    from: map.nodes()[e.from].name.clone(),
                    to: map.nodes()[e.to].name.clone(),
                    success: success[k],
                    duration_secs: duration[k],
                    duration_interval_secs: models
                        .duration_interval(k, time, EVALUATION_COVERAGE)
                        .map(|(lower, upper)| [lower, upper]),
                })
                .collect();
            json_answer(&EdgesResponse { edges })
        })
        .await?;
    Ok(json_response(body))
}

/// Now or later: the best plan for a co-safe LTL task at each start time ([Fentanes 2015] §V);
/// with `deadline_secs`, also the plan most likely to fulfil it within the deadline
/// ([`chronomap_topo::deadline`], what `chronomap plan --deadline --json` says).
#[utoipa::path(post, path = "/v1/topo/{name}/plan", request_body = PlanRequest,
    params(("name" = String, Path, description = "map name")),
    responses((status = 200, body = PlanResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody),
              (status = 503, description = "too many heavy requests; `Retry-After` says when \
               to ask again", body = crate::api::ErrorBody)))]
pub(crate) async fn topo_plan(
    State(state): State<MapsState>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let name = name(path)?;
    let request: PlanRequest = parse_body(body)?;
    if request.times.is_empty() || request.times.len() > MAX_PLAN_TIMES {
        return Err(ApiError::bad_request(format!(
            "field `times`: give 1 to {MAX_PLAN_TIMES} start times, not {}",
            request.times.len()
        )));
    }
    for (i, &t) in request.times.iter().enumerate() {
        check_time(t, &format!("times[{i}]"))?;
    }
    let deadline = DeadlineAsk::check(&request)?;
    let models = topo(&state.maps, &name)?.models();
    let start = models
        .map()
        .node(&request.from)
        .map_err(|e| ApiError::bad_request(format!("field `from`: {e}")))?;
    let task = Task::parse(&request.task, models.map())
        .map_err(|e| ApiError::bad_request(format!("field `task`: {e}")))?;
    // "Now or later" (`now_or_later`), one start time at a time so that a request whose
    // client went away stops.
    let maps = Arc::clone(&state.maps);
    let body = state
        .heavy
        .run(move |cancel| {
            let models = topo(&maps, &name)?.models();
            let edges = models.map().edges();
            let mut plans = Vec::with_capacity(request.times.len());
            for &time in &request.times {
                if cancel.is_cancelled() {
                    return Err(heavy::cancelled());
                }
                let Some(ask) = &deadline else {
                    let p = plan_at(models, start, &task, time, &SolverOptions::default())
                        .map_err(|e| ApiError::bad_request(format!("cannot plan: {e}")))?;
                    plans.push(PlanResult {
                        time: p.time,
                        pmax: p.pmax,
                        expected_secs: p.expected_secs,
                        first_edge: p.first_edge.map(|e| edges[e].id.clone()),
                        deadline: None,
                    });
                    continue;
                };
                let planned = plan_deadline(models, start, &task, time, ask.secs, &ask.options)
                    .map_err(|e| ask.error(e))?;
                let p = &planned.planned.plan;
                plans.push(PlanResult {
                    time: p.time,
                    pmax: p.pmax,
                    expected_secs: p.expected_secs,
                    first_edge: p.first_edge.map(|e| edges[e].id.clone()),
                    deadline: Some(ask.result(models.map(), &planned)),
                });
            }
            json_answer(&PlanResponse { plans })
        })
        .await?;
    Ok(json_response(body))
}

/// The deadline of a plan request, checked before anything is computed.
struct DeadlineAsk {
    /// `deadline_secs`.
    secs: f64,
    /// `confidence`, or its default.
    confidence: f64,
    /// Whether the request gave `bucket_secs`.
    bucket_given: bool,
    /// Start times of the request.
    times: usize,
    /// Whether to answer the curves.
    curve: bool,
    /// The planner's settings: the bucket, and the cells each start time may take
    /// ([`MAX_DEADLINE_CELLS`] shared by the start times).
    options: DeadlineOptions,
}

impl DeadlineAsk {
    /// `None` without `deadline_secs`; `400` naming the field for a deadline, confidence or
    /// bucket that is not a number in its range, for `confidence`, `bucket_secs` or `curve`
    /// without a deadline, and for buckets that cannot fit [`MAX_DEADLINE_CELLS`] even on a
    /// product of one state.
    fn check(request: &PlanRequest) -> Result<Option<Self>, ApiError> {
        let Some(secs) = request.deadline_secs else {
            let without = [
                ("confidence", request.confidence.is_some()),
                ("bucket_secs", request.bucket_secs.is_some()),
                ("curve", request.curve),
            ];
            if let Some((field, _)) = without.iter().find(|(_, given)| *given) {
                return Err(ApiError::bad_request(format!(
                    "field `{field}`: only with `deadline_secs`"
                )));
            }
            return Ok(None);
        };
        if !(secs.is_finite() && secs > 0.0 && secs <= MAX_DEADLINE_SECS) {
            return Err(ApiError::bad_request(format!(
                "field `deadline_secs`: {secs} is not a number of seconds in (0, \
                 {MAX_DEADLINE_SECS:e}]"
            )));
        }
        let confidence = request.confidence.unwrap_or(DEFAULT_CONFIDENCE);
        if !(0.0..=1.0).contains(&confidence) {
            return Err(ApiError::bad_request(format!(
                "field `confidence`: {confidence} is not a probability in [0, 1]"
            )));
        }
        let ask = DeadlineAsk {
            secs,
            confidence,
            bucket_given: request.bucket_secs.is_some(),
            times: request.times.len(),
            curve: request.curve,
            options: DeadlineOptions {
                bucket_secs: request.bucket_secs,
                max_cells: MAX_DEADLINE_CELLS / request.times.len(),
                ..DeadlineOptions::default()
            },
        };
        // Every product has a state: refuse what cannot fit before planning anything.
        let (_, k) = buckets_for(secs, request.bucket_secs).map_err(|e| ask.error(e))?;
        if (ask.times as f64) * (k + 1.0) > MAX_DEADLINE_CELLS as f64 {
            return Err(ask.too_many_cells(None, k + 1.0));
        }
        Ok(Some(ask))
    }

    /// The field to blame for too many cells: the bucket if given, else the start times if
    /// several, else the deadline.
    fn cells_field(&self) -> &'static str {
        if self.bucket_given {
            "bucket_secs"
        } else if self.times > 1 {
            "times"
        } else {
            "deadline_secs"
        }
    }

    /// `400`: the deadline plans of `states` product states (`None`: not known yet, at least
    /// one) and `buckets` buckets at each start time are more than [`MAX_DEADLINE_CELLS`].
    fn too_many_cells(&self, states: Option<usize>, buckets: f64) -> ApiError {
        let (states, at_least) = match states {
            Some(n) => (n, ""),
            None => (1, "at least "),
        };
        let cells = self.times as f64 * states as f64 * buckets;
        // Whole numbers below 10^15, else 1.000e306.
        let buckets = if buckets < 1e15 {
            format!("{buckets:.0}")
        } else {
            format!("{buckets:.3e}")
        };
        ApiError::bad_request(format!(
            "field `{}`: {} start time(s) × {at_least}{states} product state(s) × {buckets} \
             buckets = {at_least}{cells:.3e} cells, more than the limit of {MAX_DEADLINE_CELLS} \
             per request (widen `bucket_secs`, shorten `deadline_secs` or give fewer `times`)",
            self.cells_field(),
            self.times,
        ))
    }

    /// A planner's error as an answer: `400` naming the field, or `500` for what would be a bug.
    fn error(&self, e: DeadlineError) -> ApiError {
        match e {
            DeadlineError::InvalidDeadline(_) => {
                ApiError::bad_request(format!("field `deadline_secs`: {e}"))
            }
            DeadlineError::InvalidBucket(_) | DeadlineError::BucketWiderThanDeadline { .. } => {
                ApiError::bad_request(format!("field `bucket_secs`: {e}"))
            }
            DeadlineError::TooManyCells {
                states, buckets, ..
            } => self.too_many_cells(Some(states), buckets),
            DeadlineError::Plan(e) => ApiError::bad_request(format!("cannot plan: {e}")),
            e => ApiError::internal(format!("cannot plan for the deadline: {e}")),
        }
    }

    /// What the answer says of a deadline plan: the fields of `chronomap plan --deadline
    /// --json` (`chronomap_app::topo::deadline_report`) of the same names.
    fn result(&self, map: &TopoMap, planned: &DeadlinePlanned) -> DeadlineResult {
        let plan = &planned.plan;
        let edges = map.edges();
        DeadlineResult {
            deadline_secs: self.secs,
            confidence: self.confidence,
            bucket_secs: plan.bucket_secs,
            probability: plan.probability,
            reaches_confidence: plan.probability >= self.confidence,
            first_edge: plan.first_edge.map(|e| edges[e].id.clone()),
            median_route: planned
                .median_route()
                .iter()
                .map(|&e| edges[e].id.clone())
                .collect(),
            shortest_deadline_secs: plan.shortest_deadline(self.confidence),
            min_time_probability: plan.min_time_probability,
            duration_quantiles: plan.duration_quantiles,
            product_states: planned.planned.product.states().len() as u64,
            curve: self.curve.then(|| {
                plan.curve
                    .iter()
                    .zip(&plan.min_time_curve)
                    .enumerate()
                    .map(|(k, (&p, &q))| [k as f64 * plan.bucket_secs, p, q])
                    .collect()
            }),
        }
    }
}

fn geometry(grid: &AnyGrid) -> GridGeometry {
    *grid.geometry()
}

/// The occupancy probability of every cell of a grid at a time.
#[utoipa::path(post, path = "/v1/grid/{name}/predict", request_body = TimeRequest,
    params(("name" = String, Path, description = "grid name")),
    responses((status = 200, body = GridResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody),
              (status = 503, description = "too many heavy requests; `Retry-After` says when \
               to ask again", body = crate::api::ErrorBody)))]
pub(crate) async fn grid_predict(
    State(state): State<MapsState>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let name = name(path)?;
    let request: TimeRequest = parse_body(body)?;
    let time = check_time(request.time, "time")?;
    grid(&state.maps, &name)?;
    // Admitted before it waits for the grid's fit, so that a full pool refuses it at once.
    let admitted = state.heavy.admit()?;
    let cached = state.fitted(&name).await?;
    let maps = Arc::clone(&state.maps);
    let body = admitted
        .run(move |_| {
            let grid = grid(&maps, &name)?;
            let g = geometry(grid);
            let fitted: &FittedGrid = match (grid, cached.as_deref()) {
                (AnyGrid::Lossy(g), _) => g,
                (AnyGrid::Lossless(g), _) => &g.fitted,
                (AnyGrid::State(_), Some(fitted)) => fitted,
                (AnyGrid::State(_), None) => {
                    return Err(ApiError::internal(format!(
                        "the grid {name:?} is not fitted"
                    )));
                }
            };
            json_answer(&GridResponse {
                shape: [g.width, g.height, g.depth],
                resolution: g.resolution,
                origin: g.origin,
                values: fitted.predict_map(time),
            })
        })
        .await?;
    Ok(json_response(body))
}

/// Count and times of the frames a grid learned from.
fn frame_span(grid: &AnyGrid) -> ObservedSpan {
    grid.frame_span()
}

/// Shape, placement and frames of a grid.
#[utoipa::path(get, path = "/v1/grid/{name}",
    params(("name" = String, Path, description = "grid name")),
    responses((status = 200, body = GridInfo), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody)))]
pub(crate) async fn grid_info(
    State(state): State<MapsState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<GridInfo>, ApiError> {
    let name = name(path)?;
    let grid = grid(&state.maps, &name)?;
    let g = geometry(grid);
    let span = frame_span(grid);
    let known = span.count > 0;
    Ok(Json(GridInfo {
        name,
        kind: chronomap_io::grid_kind(grid).into(),
        shape: [g.width, g.height, g.depth],
        resolution: g.resolution,
        origin: g.origin,
        frames: span.count,
        first_time: known.then_some(span.first),
        last_time: known.then_some(span.last),
    }))
}

/// One cell's occupancy probability at many times: the values of `POST /v1/grid/{name}/predict`
/// for that cell.
#[utoipa::path(post, path = "/v1/grid/{name}/cell", request_body = CellRequest,
    params(("name" = String, Path, description = "grid name")),
    responses((status = 200, body = CellResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody),
              (status = 503, description = "too many requests computing; `Retry-After` says \
               when to ask again", body = crate::api::ErrorBody)))]
pub(crate) async fn grid_cell(
    State(state): State<MapsState>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let name = name(path)?;
    let request: CellRequest = parse_body(body)?;
    if request.times.is_empty() || request.times.len() > MAX_CELL_TIMES {
        return Err(ApiError::bad_request(format!(
            "field `times`: give 1 to {MAX_CELL_TIMES} times, not {}",
            request.times.len()
        )));
    }
    for (i, &t) in request.times.iter().enumerate() {
        check_time(t, &format!("times[{i}]"))?;
    }
    let g = geometry(grid(&state.maps, &name)?);
    let shape = [g.width, g.height, g.depth];
    let cell = match request.cell[..] {
        [x, y] => [x, y, 0],
        [x, y, z] => [x, y, z],
        _ => {
            return Err(ApiError::bad_request(format!(
                "field `cell`: give [x, y] or [x, y, z], not {} numbers",
                request.cell.len()
            )));
        }
    };
    let outside = || {
        ApiError::bad_request(format!(
            "field `cell`: {:?} is outside the grid's shape {shape:?}",
            request.cell
        ))
    };
    let mut index = [0u32; 3];
    for k in 0..3 {
        index[k] = u32::try_from(cell[k])
            .ok()
            .filter(|&i| i < shape[k])
            .ok_or_else(outside)?;
    }
    let [x, y, z] = index.map(|i| i as usize);
    let flat = x + g.width as usize * (y + g.height as usize * z);
    // One cell (fitted from its learning state for a state grid) at ≤ 10,000 times: on the
    // light pool.
    let maps = Arc::clone(&state.maps);
    let body = state
        .light
        .run(move |_| {
            let values = grid(&maps, &name)?.predict_cell(flat, &request.times);
            json_answer(&CellResponse {
                cell: index,
                centre: [0, 1, 2].map(|k| g.origin[k] + (f64::from(index[k]) + 0.5) * g.resolution),
                values: values.into_iter().map(f64::from).collect(),
            })
        })
        .await?;
    Ok(json_response(body))
}

/// Domain, periods and unit of time of a CoPA-Map.
#[utoipa::path(get, path = "/v1/activity/{name}",
    params(("name" = String, Path, description = "activity map name")),
    responses((status = 200, body = ActivityInfo), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody)))]
pub(crate) async fn activity_info(
    State(state): State<MapsState>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<ActivityInfo>, ApiError> {
    let name = name(path)?;
    let served = activity(&state.maps, &name)?;
    Ok(Json(ActivityInfo {
        name,
        domain: served.model().domain(),
        periods: served.model().periods(),
        time_unit: TIME_UNIT.into(),
        t_range: served.model().time_span(),
        default_cell: DEFAULT_CELL,
        masked_by_map: served.masked(),
    }))
}

/// Mean and standard deviation of the rate of people in every cell over the training square
/// at `t` (CoPA-Map, [Stüde 2024] §4.2): the values of `chronomap activity predict`.
#[utoipa::path(post, path = "/v1/activity/{name}/predict", request_body = ActivityRequest,
    params(("name" = String, Path, description = "activity map name")),
    responses((status = 200, body = ActivityResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody),
              (status = 503, description = "too many heavy requests; `Retry-After` says when \
               to ask again", body = crate::api::ErrorBody)))]
pub(crate) async fn activity_predict(
    State(state): State<MapsState>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Response, ApiError> {
    let name = name(path)?;
    let request: ActivityRequest = parse_body(body)?;
    let t = check_time(request.t, "t")?;
    let cell = request.cell.unwrap_or(DEFAULT_CELL);
    // The cells and the work are counted before the request waits for a worker.
    activity(&state.maps, &name)?
        .checked_region(cell)
        .map_err(activity_error)?;
    let maps = Arc::clone(&state.maps);
    let body = state
        .heavy
        .run(move |cancel| {
            let grid = activity(&maps, &name)?
                .predict_until(t, cell, heavy::PARALLELISM, &|| cancel.is_cancelled())
                .map_err(activity_error)?;
            json_answer(&ActivityResponse {
                t,
                origin: grid.origin,
                cell: grid.cell,
                shape: [grid.cols as u32, grid.rows as u32],
                mean: grid.mean,
                std: grid.std,
            })
        })
        .await?;
    Ok(json_response(body))
}

fn activity_error(e: ActivityError) -> ApiError {
    match e {
        ActivityError::Model(_) => ApiError::internal(e.to_string()),
        ActivityError::Cancelled => heavy::cancelled(),
        ActivityError::Time(_)
        | ActivityError::Cell(_)
        | ActivityError::TooManyCells { .. }
        | ActivityError::TooMuchWork { .. } => ApiError::bad_request(e.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cell_never_observed_travels_as_null_and_comes_back_as_nan() {
        let cell = CellResponse {
            cell: [1, 2, 0],
            centre: [0.15, 0.25, 0.05],
            values: vec![0.25, f64::NAN],
        };
        let text = serde_json::to_string(&cell).unwrap();
        assert!(text.ends_with(r#""values":[0.25,null]}"#), "{text}");
        let back: CellResponse = serde_json::from_str(&text).unwrap();
        assert_eq!(back.values[0], 0.25);
        assert!(back.values[1].is_nan());
    }
}
