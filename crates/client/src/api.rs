//! The wire protocol: request and response bodies of every endpoint, shared by the server
//! (`chronomap-serve`, which describes them in its OpenAPI document with the `openapi`
//! feature) and the typed [`Client`](crate::Client) (the `http` feature).
//!
//! The operations are those users of the original FreMEn server know (`add`, `addvalues`,
//! `predict`, `forecast`, `entropy`, `forecastEntropy`, `evaluate`, `detect`, `remove`, `view`,
//! `list`), as JSON over HTTP. Times are seconds (unix time for real robots), `f64`.

use serde::{Deserialize, Serialize};

/// Longest model id, in bytes of UTF-8. The original server's buffer held 100 bytes and its
/// check allowed 1000; here the bound is checked, documented and the same everywhere.
pub const MAX_ID_BYTES: usize = 256;

/// The model a `create` (or a first `add` with `model`) makes when none is named: FreMEn
/// of order 2 over the candidate periods one week / 1..=84.
pub const DEFAULT_MODEL: &str = "fremen:2";

/// Every error: a machine-readable kind and a sentence for people.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ErrorBody {
    /// `bad_request`, `unauthorized`, `not_found`, `conflict`, `payload_too_large`,
    /// `unavailable` or `internal`.
    pub error: String,
    /// What was wrong, naming the field (and element index) at fault.
    pub reason: String,
}

/// Creates a model (`PUT /v1/models/{id}`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct CreateRequest {
    /// Model spec (`fremen:K`, `persistence:K`, `hist:N[:PERIOD]`, `pergam:K[:PERIOD]`,
    /// `stm`, `mean`, which learn online; `auto`, `fremen:auto`, `pergam:auto`, `fft:L`, ...,
    /// which are refitted on their kept observations); default `fremen:2`.
    #[serde(default)]
    pub model: Option<String>,
    /// For continuous states: the range `[lo, hi]` of the values; values are mapped onto
    /// `[0, 1]` and predictions back. Absent: values must lie in `[0, 1]`.
    #[serde(default)]
    pub range: Option<[f64; 2]>,
    /// A calendar of days off (public holidays, closures): UTC dates `YYYY-MM-DD`, at most
    /// [`MAX_DAYS_OFF`], in any order (a date given twice is one day). Observations made on a
    /// day off are accepted but not learned; a time on a day off is predicted (its value,
    /// entropy and interval) as the same time of day on the most recent Sunday that is not a
    /// day off, as `chronomap eval --days-off` does offline. Absent or empty: no calendar.
    /// Part of the model's configuration: creating it again with other days is a `409`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub days_off: Option<Vec<String>>,
}

/// Most days off one model's calendar holds ([`CreateRequest::days_off`]): 27 years of
/// every day, far more than any calendar of holidays.
pub const MAX_DAYS_OFF: usize = 10_000;

/// Binary observations of one state (`POST /v1/add`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct AddRequest {
    /// Model id.
    pub id: String,
    /// Observation times (s), not decreasing, not earlier than the model's last observation.
    pub times: Vec<f64>,
    /// Observed states.
    pub states: Vec<bool>,
    /// Spec of the model to create if `id` does not exist yet (else `404`).
    #[serde(default)]
    pub model: Option<String>,
}

/// Observations with values of one state (`POST /v1/addvalues`), or one batch of
/// [`ObservationsRequest`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct AddValuesRequest {
    /// Model id.
    pub id: String,
    /// Observation times (s), not decreasing.
    pub times: Vec<f64>,
    /// Values in `[0, 1]`, or in the model's `range`.
    pub values: Vec<f64>,
    /// Spec of the model to create if `id` does not exist yet (else `404`).
    #[serde(default)]
    pub model: Option<String>,
}

/// Observations of many states in one durable commit (`POST /v1/observations`): all batches
/// are accepted or none is.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct ObservationsRequest {
    /// One batch per model.
    pub batches: Vec<AddValuesRequest>,
}

/// What a write did, returned once it is durable.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct WriteAck {
    /// Observations added.
    pub observations: u64,
    /// Position of the commit in the observation log.
    pub seq: u64,
}

/// Predictions of one model at many times (`POST /v1/predict`, `POST /v1/entropy`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct PredictRequest {
    /// Model id.
    pub id: String,
    /// Times (s), any order.
    pub times: Vec<f64>,
    /// Order to predict with (models with an order); default the model's own.
    #[serde(default)]
    pub order: Option<usize>,
    /// `predict` only: the share of values that the prediction intervals of a model of
    /// continuous values should hold, strictly between 0 and 1 (for example 0.9). The answer
    /// then has `lower` and `upper`.
    #[serde(
        default,
        skip_serializing_if = "Option::is_none",
        deserialize_with = "coverage"
    )]
    #[cfg_attr(feature = "openapi", schema(nullable = false))]
    pub coverage: Option<f64>,
}

/// `coverage` given: a number. JSON has no NaN or infinity, and serialisers write them as
/// `null`, which must not pass for "no coverage".
fn coverage<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
    match Option::<f64>::deserialize(d)? {
        Some(c) => Ok(Some(c)),
        None => Err(serde::de::Error::custom(
            "field `coverage`: null is not a share strictly between 0 and 1 (NaN or infinity \
             written as JSON?); leave the field out for no intervals",
        )),
    }
}

/// Answer to [`PredictRequest`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct PredictResponse {
    /// `p(t)` in `[0, 1]` for `predict`, binary entropy in bits for `entropy`.
    pub values: Vec<f64>,
    /// For models with a `range` and `predict`: the predictions mapped back onto it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scaled: Option<Vec<f64>>,
    /// With `coverage`, for models with a `range`: the lower ends of the central prediction
    /// intervals, in the range (one per time). The interval is that of the Beta law matched
    /// to the predicted mean and variance of the normalised value, learnt from its values and
    /// their squares. Absent for binary models, for models fitted on a whole series (`auto`,
    /// `fremen:auto`, ...: see `docs/service.md`), and for models restored from a snapshot
    /// written before intervals were served.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lower: Option<Vec<f64>>,
    /// With `coverage`: the upper ends, as `lower`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upper: Option<Vec<f64>>,
}

/// Predictions of many models at one time (`POST /v1/forecast`, `POST /v1/forecastEntropy`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct ForecastRequest {
    /// Model ids.
    pub ids: Vec<String>,
    /// The time (s).
    pub time: f64,
    /// One order for every model.
    #[serde(default)]
    pub order: Option<usize>,
    /// One order per model (same length as `ids`); overrides `order`.
    #[serde(default)]
    pub orders: Option<Vec<usize>>,
}

/// Answer to [`ForecastRequest`]: one value per id, in the order of `ids`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ForecastResponse {
    /// `p(t)` or entropies (bits).
    pub values: Vec<f64>,
}

/// Errors of a model per order on given data (`POST /v1/evaluate`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct EvaluateRequest {
    /// Model id.
    pub id: String,
    /// Times (s).
    pub times: Vec<f64>,
    /// Observed values (in the model's range).
    pub values: Vec<f64>,
    /// Largest order evaluated (default 10, at most the model's largest).
    #[serde(default)]
    pub max_order: Option<usize>,
}

/// Answer to [`EvaluateRequest`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct EvaluateResponse {
    /// The orders evaluated (`[null]`-free: models without an order give one entry, 0).
    pub orders: Vec<usize>,
    /// Per order: the fraction of binary states mispredicted (`p > 0.5` vs state), as the
    /// original server reported; for non-binary values the mean absolute error.
    pub errors: Vec<f64>,
    /// Per order: mean squared error of `p(t)` (Brier score for binary states).
    pub brier: Vec<f64>,
    /// The order with the smallest error (the first, on ties).
    pub best_order: usize,
    /// `binary_error` or `mean_absolute_error`.
    pub metric: String,
}

/// Anomaly detection on given data (`POST /v1/detect`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct DetectRequest {
    /// Model id.
    pub id: String,
    /// Times (s).
    pub times: Vec<f64>,
    /// Observed values (in the model's range).
    pub values: Vec<f64>,
    /// Report observations with `|value - p(t)| >= confidence` (in `(0, 1]`).
    pub confidence: f64,
    /// Order to predict with; default the model's own.
    #[serde(default)]
    pub order: Option<usize>,
}

/// One anomalous observation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Anomaly {
    /// Its time.
    pub time: f64,
    /// Its value.
    pub value: f64,
    /// What the model predicted then (in the model's range).
    pub predicted: f64,
}

/// Answer to [`DetectRequest`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct DetectResponse {
    /// The anomalies, in the order given.
    pub anomalies: Vec<Anomaly>,
}

/// A periodic component of a spectral model ([Krajník 2017] eq. 2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Component {
    /// Period (s).
    pub period_secs: f64,
    /// Amplitude `|γ|`.
    pub amplitude: f64,
    /// Phase `arg γ` (rad).
    pub phase: f64,
}

/// A model's description (`GET /v1/models/{id}`, and the entries of `list`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ModelInfo {
    /// Model id.
    pub id: String,
    /// Its spec, e.g. `fremen:2`.
    pub model: String,
    /// Value range of continuous states.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range: Option<[f64; 2]>,
    /// Observations seen.
    pub observations: u64,
    /// First observation time.
    pub first_time: Option<f64>,
    /// Last observation time.
    pub last_time: Option<f64>,
    /// Mean of the (normalised) observations, for spectral models (`α_0`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mean: Option<f64>,
    /// Components used for prediction, strongest first, for spectral models (`view`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub components: Vec<Component>,
    /// For models fitted on a whole series (`auto`, `fremen:auto`, `fft:L`, ...): the
    /// observations kept for refits and the last fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refit: Option<RefitInfo>,
    /// The model's calendar of days off ([`CreateRequest::days_off`]); absent without one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub days_off: Option<DaysOffInfo>,
}

/// A model's calendar of days off, in brief.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct DaysOffInfo {
    /// Number of days off (distinct dates).
    pub days: u64,
    /// The earliest, `YYYY-MM-DD`.
    pub first: String,
    /// The latest, `YYYY-MM-DD`.
    pub last: String,
    /// Observations made on a day off: accepted, not learned (not in `observations`).
    pub skipped: u64,
}

/// What a model fitted on a whole series (`auto`, `fremen:auto`, ...) keeps, and its last fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct RefitInfo {
    /// Observations kept for refits: the most recent `keep` (older ones are dropped).
    pub kept: u64,
    /// The most observations kept.
    pub keep: u64,
    /// Observations added since the last fit (since creation, before the first).
    pub since_fit: u64,
    /// The last fit; absent before the first, when the model predicts 0.5.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last_fit: Option<FitInfo>,
}

/// One fit of a model on its kept observations.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct FitInfo {
    /// Observations fitted on.
    pub observations: u64,
    /// Observations the model had been given (since creation) when they were taken: the fit is
    /// of the kept ones among the first `through`; later ones were then learned online.
    pub through: u64,
    /// Time of the first observation fitted on (s).
    pub first_time: f64,
    /// Time of the last observation fitted on (s).
    pub last_time: f64,
    /// What was fitted: `fremen:3` for `fremen:auto`, `stack of 5` for `auto`.
    pub fitted: String,
    /// `auto`: the models combined and their weights, heaviest first.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub weights: Vec<StackWeight>,
    /// Error of the choice on held-back data: of the combination (Brier score over the rolling
    /// origins) for `auto`, of the chosen order for `auto` orders.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<f64>,
}

/// A member of a stacked (`auto`) model.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct StackWeight {
    /// The member's spec, e.g. `hist:168`.
    pub model: String,
    /// Its weight (the weights sum to 1).
    pub weight: f64,
}

/// Asks for a refit (`POST /v1/models/{id}/refit`): `{}` (no options yet; an empty body is
/// accepted too).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
#[serde(deny_unknown_fields)]
pub struct RefitRequest {}

/// A refit (`POST /v1/models/{id}/refit`): the model now predicts with `fit`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct RefitResponse {
    /// Log position of the refit (the sequence token for `Chronomap-Read-After`).
    pub seq: u64,
    /// Whether a new fit was made (`false`: the last fit already covered every observation).
    pub refitted: bool,
    /// The fit in use.
    pub fit: FitInfo,
    /// Seconds the fit took (0 without a new fit).
    pub secs: f64,
}

/// All models (`GET /v1/models`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ListResponse {
    /// By id.
    pub models: Vec<ModelInfo>,
}

/// Every observation a model holds, from the durable log (`GET /v1/models/{id}/observations`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct ObservationsResponse {
    /// Times (s).
    pub times: Vec<f64>,
    /// Values as given (in the model's range).
    pub values: Vec<f64>,
}

/// The request header of read-your-writes: the service answers only after applying the log up
/// to this position (the `seq` of a [`WriteAck`], from any node of a fleet).
pub const READ_AFTER_HEADER: &str = "chronomap-read-after";

/// The response header giving the log position an answer was computed at.
pub const SEQ_HEADER: &str = "chronomap-seq";

/// Service health (`GET /v1/health`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct Health {
    /// `ok`; for a node of a fleet also `behind` (not level with the shared log for 5 s) or
    /// `failed` (it stopped applying the log; see `reason`).
    pub status: String,
    /// Models held.
    pub models: u64,
    /// The store, e.g. `redb DIR/chronomap.redb`.
    pub store: String,
    /// Last position of the observation log applied to the models this node serves: the
    /// sequence token a reader may send in `Chronomap-Read-After`.
    pub seq: u64,
    /// Whether writes need a bearer token.
    pub auth: bool,
    /// Whether this node shares its log with other nodes (`chronomap serve --fleet`).
    #[serde(default)]
    pub fleet: bool,
    /// Last position of the shared log (equal to `seq` for a single service).
    #[serde(default)]
    pub head: u64,
    /// `head - seq`: commit groups appended by other nodes and not yet applied here.
    #[serde(default)]
    pub lag: u64,
    /// Seconds since this node last knew it had applied the whole log (0 when level).
    #[serde(default)]
    pub behind_secs: f64,
    /// Why the node is `failed`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// Heavy requests (grid, activity and plan predictions, large model requests) computing
    /// now.
    #[serde(default)]
    pub heavy_running: u64,
    /// Heavy requests admitted and waiting for a worker.
    #[serde(default)]
    pub heavy_waiting: u64,
    /// Heavy requests given up since the start because their client went away.
    #[serde(default)]
    pub heavy_cancelled: u64,
    /// Light requests (small `predict`, `forecast`, `evaluate`, `detect`, grid cells, edge
    /// predictions) computing now.
    #[serde(default)]
    pub light_running: u64,
    /// Light requests admitted and waiting for a worker.
    #[serde(default)]
    pub light_waiting: u64,
    /// Light requests given up since the start because their client went away.
    #[serde(default)]
    pub light_cancelled: u64,
}

/// Which models `GET /v1/models` lists.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "openapi", derive(utoipa::IntoParams))]
#[serde(deny_unknown_fields)]
pub struct ListQuery {
    /// Only ids starting with this text (e.g. `robot7/`): a robot's or a namespace's models.
    #[serde(default)]
    pub prefix: Option<String>,
}

/// Most times [`time_range`] makes: one request of `chronomap client predict --from --to`.
pub const MAX_RANGE_TIMES: usize = 1_000_000;

/// Why [`time_range`] makes no times.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TimeRangeError {
    /// The end is before the start.
    Backwards,
    /// More than [`MAX_RANGE_TIMES`] times (this many; infinite or NaN for a step of 0 or
    /// NaN).
    TooMany {
        /// Times the range would have.
        times: f64,
    },
}

impl std::fmt::Display for TimeRangeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TimeRangeError::Backwards => f.write_str("the end is before the start"),
            TimeRangeError::TooMany { times } => {
                write!(f, "{times:e} times: at most {MAX_RANGE_TIMES}")
            }
        }
    }
}

impl std::error::Error for TimeRangeError {}

/// The times `from, from + step, …` up to `to` (`to` itself when `step` divides the span), at
/// most [`MAX_RANGE_TIMES`] of them; counted before any is made.
///
/// # Errors
/// `to` is before `from`, or there would be more than [`MAX_RANGE_TIMES`] times.
pub fn time_range(from: f64, to: f64, step: f64) -> Result<Vec<f64>, TimeRangeError> {
    if to < from {
        return Err(TimeRangeError::Backwards);
    }
    // In floating point first: a cast would saturate (1e9 / 1e-300) and the + 1 wrap to 0.
    let steps = ((to - from) / step).floor();
    if !(steps.is_finite() && steps < MAX_RANGE_TIMES as f64) {
        return Err(TimeRangeError::TooMany { times: steps + 1.0 });
    }
    let n = steps as usize + 1;
    Ok((0..n).map(|i| from + i as f64 * step).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_have_the_documented_json_shape() {
        let request = AddValuesRequest {
            id: "door".into(),
            times: vec![0.0, 60.0],
            values: vec![1.0, 0.5],
            model: Some(DEFAULT_MODEL.into()),
        };
        assert_eq!(
            serde_json::to_string(&request).unwrap(),
            r#"{"id":"door","times":[0.0,60.0],"values":[1.0,0.5],"model":"fremen:2"}"#
        );
        // Optional fields may be left out; unknown ones are refused, naming them.
        let create: CreateRequest = serde_json::from_str("{}").unwrap();
        assert_eq!(create, CreateRequest::default());
        let error = serde_json::from_str::<CreateRequest>(r#"{"modle":"stm"}"#).unwrap_err();
        assert!(
            error.to_string().contains("unknown field `modle`"),
            "{error}"
        );
    }

    #[test]
    fn responses_read_back_what_the_server_writes() {
        let ack: WriteAck = serde_json::from_str(r#"{"observations":3,"seq":17}"#).unwrap();
        assert_eq!(
            ack,
            WriteAck {
                observations: 3,
                seq: 17
            }
        );
        let error: ErrorBody =
            serde_json::from_str(r#"{"error":"not_found","reason":"no model \"x\""}"#).unwrap();
        assert_eq!(error.reason, "no model \"x\"");
    }

    #[test]
    fn a_time_range_has_its_ends_and_at_most_a_million_times() {
        assert_eq!(
            time_range(0.0, 3600.0, 1200.0),
            Ok(vec![0.0, 1200.0, 2400.0, 3600.0])
        );
        assert_eq!(time_range(10.0, 10.0, 5.0), Ok(vec![10.0]));
        assert_eq!(time_range(0.0, 2500.0, 1000.0).unwrap().len(), 3);
        assert_eq!(time_range(5.0, 4.0, 1.0), Err(TimeRangeError::Backwards));
        assert_eq!(
            time_range(0.0, 999_999.0, 1.0).unwrap().len(),
            MAX_RANGE_TIMES
        );
        assert_eq!(
            time_range(0.0, 1_000_000.0, 1.0),
            Err(TimeRangeError::TooMany { times: 1_000_001.0 })
        );
        assert!(matches!(
            time_range(0.0, 1e9, 1e-300),
            Err(TimeRangeError::TooMany { times }) if times.is_infinite()
        ));
        assert!(time_range(0.0, 1.0, 0.0).is_err());
    }
}
