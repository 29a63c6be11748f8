//! Spatial containers served read-only beside the models: topological maps whose edges know
//! time ([Fentanes 2015]) and occupancy grids ([Krajník 2017] §VI), loaded from their model files at start.
//!
//! * `POST /v1/topo/{name}/predict {time}`: every edge's success probability and expected
//!   duration at `time`.
//! * `POST /v1/topo/{name}/plan {from, task, times}`: "now or later?" — for each start time the
//!   maximum probability of fulfilling a co-safe LTL task, the expected time and the first edge.
//! * `POST /v1/grid/{name}/predict {time}`: the predicted occupancy probability of every cell.

use std::collections::BTreeMap;
use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::rejection::{BytesRejection, PathRejection};
use axum::extract::{Path, State};
use axum::routing::{get, post};
use axum::{Json, Router};
use chronomap_grid::GridGeometry;
use chronomap_io::grid_file::GridFile;
use chronomap_topo::edges::EdgeModels;
use chronomap_topo::mdp::SolverOptions;
use chronomap_topo::plan::{Task, now_or_later};
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use crate::server::{ApiError, parse_body};

/// Most start times of one `plan` request.
pub const MAX_PLAN_TIMES: usize = 1000;

/// The maps a service holds, by name.
#[derive(Debug, Default)]
pub struct Maps {
    /// Topological maps with edge models.
    pub topological: BTreeMap<String, EdgeModels>,
    /// Occupancy grids.
    pub grids: BTreeMap<String, GridFile>,
}

/// A map in `GET /v1/maps`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct MapInfo {
    /// Name given at start.
    pub name: String,
    /// `topological`, `grid-state`, `grid-lossy` or `grid-lossless`.
    pub kind: String,
    /// Nodes (topological) or cells (grids).
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

/// The routes, with their state.
pub fn router(maps: Arc<Maps>) -> Router {
    Router::new()
        .route("/v1/maps", get(list))
        .route("/v1/topo/{name}/predict", post(topo_predict))
        .route("/v1/topo/{name}/plan", post(topo_plan))
        .route("/v1/grid/{name}/predict", post(grid_predict))
        .with_state(maps)
}

fn name(path: Result<Path<String>, PathRejection>) -> Result<String, ApiError> {
    let Path(name) =
        path.map_err(|e| ApiError::bad_request(format!("map name in the path: {e}")))?;
    Ok(name)
}

fn finite(time: f64, field: &str) -> Result<f64, ApiError> {
    if time.is_finite() {
        Ok(time)
    } else {
        Err(ApiError::bad_request(format!(
            "field `{field}`: not a finite time"
        )))
    }
}

fn topo<'a>(maps: &'a Maps, name: &str) -> Result<&'a EdgeModels, ApiError> {
    maps.topological
        .get(name)
        .ok_or_else(|| ApiError::not_found(format!("no topological map named {name:?}")))
}

/// The maps held.
#[utoipa::path(get, path = "/v1/maps", responses((status = 200, body = MapsResponse)))]
pub(crate) async fn list(State(maps): State<Arc<Maps>>) -> Json<MapsResponse> {
    let mut list: Vec<MapInfo> = maps
        .topological
        .iter()
        .map(|(name, m)| MapInfo {
            name: name.clone(),
            kind: "topological".into(),
            size: m.map().nodes().len() as u64,
            edges: Some(m.map().edges().len() as u64),
        })
        .collect();
    list.extend(maps.grids.iter().map(|(name, g)| MapInfo {
        name: name.clone(),
        kind: g.kind().into(),
        size: geometry(g).cells() as u64,
        edges: None,
    }));
    Json(MapsResponse { maps: list })
}

/// Every edge's success probability and expected duration at a time.
#[utoipa::path(post, path = "/v1/topo/{name}/predict", request_body = TimeRequest,
    params(("name" = String, Path, description = "map name")),
    responses((status = 200, body = EdgesResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody)))]
pub(crate) async fn topo_predict(
    State(maps): State<Arc<Maps>>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<EdgesResponse>, ApiError> {
    let name = name(path)?;
    let request: TimeRequest = parse_body(body)?;
    let time = finite(request.time, "time")?;
    let models = topo(&maps, &name)?;
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
        })
        .collect();
    Ok(Json(EdgesResponse { edges }))
}

/// Now or later: the best plan for a co-safe LTL task at each start time ([Fentanes 2015] §V).
#[utoipa::path(post, path = "/v1/topo/{name}/plan", request_body = PlanRequest,
    params(("name" = String, Path, description = "map name")),
    responses((status = 200, body = PlanResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody)))]
pub(crate) async fn topo_plan(
    State(maps): State<Arc<Maps>>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<PlanResponse>, ApiError> {
    let name = name(path)?;
    let request: PlanRequest = parse_body(body)?;
    if request.times.is_empty() || request.times.len() > MAX_PLAN_TIMES {
        return Err(ApiError::bad_request(format!(
            "field `times`: give 1 to {MAX_PLAN_TIMES} start times, not {}",
            request.times.len()
        )));
    }
    for (i, &t) in request.times.iter().enumerate() {
        finite(t, &format!("times[{i}]"))?;
    }
    let models = topo(&maps, &name)?;
    let start = models
        .map()
        .node(&request.from)
        .map_err(|e| ApiError::bad_request(format!("field `from`: {e}")))?;
    let task = Task::parse(&request.task, models.map())
        .map_err(|e| ApiError::bad_request(format!("field `task`: {e}")))?;
    let plans = now_or_later(
        models,
        start,
        &task,
        &request.times,
        &SolverOptions::default(),
    )
    .map_err(|e| ApiError::bad_request(format!("cannot plan: {e}")))?
    .into_iter()
    .map(|p| PlanResult {
        time: p.time,
        pmax: p.pmax,
        expected_secs: p.expected_secs,
        first_edge: p.first_edge.map(|e| models.map().edges()[e].id.clone()),
    })
    .collect();
    Ok(Json(PlanResponse { plans }))
}

fn geometry(grid: &GridFile) -> GridGeometry {
    match grid {
        GridFile::State(g) => *g.geometry(),
        GridFile::Lossy(g) => *g.geometry(),
        GridFile::Lossless(g) => *g.fitted.geometry(),
    }
}

/// The occupancy probability of every cell of a grid at a time.
#[utoipa::path(post, path = "/v1/grid/{name}/predict", request_body = TimeRequest,
    params(("name" = String, Path, description = "grid name")),
    responses((status = 200, body = GridResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody)))]
pub(crate) async fn grid_predict(
    State(maps): State<Arc<Maps>>,
    path: Result<Path<String>, PathRejection>,
    body: Result<Bytes, BytesRejection>,
) -> Result<Json<GridResponse>, ApiError> {
    let name = name(path)?;
    let request: TimeRequest = parse_body(body)?;
    let time = finite(request.time, "time")?;
    let grid = maps
        .grids
        .get(&name)
        .ok_or_else(|| ApiError::not_found(format!("no grid named {name:?}")))?;
    let g = geometry(grid);
    let values = match grid {
        GridFile::State(g) => g.predict_map(time),
        GridFile::Lossy(g) => g.predict(time),
        GridFile::Lossless(g) => g.fitted.predict(time),
    };
    Ok(Json(GridResponse {
        shape: [g.width, g.height, g.depth],
        resolution: g.resolution,
        origin: g.origin,
        values,
    }))
}
