//! What the async [`Client`](crate::Client) and the [`blocking::Client`](crate::blocking::Client)
//! share: the endpoints as [`Call`]s (method, path, JSON body), the errors, the limit on the
//! size of an answer and the decoding of answers. Only the transport differs.

pub use http::{Method, StatusCode};
use serde::Serialize;
use serde::de::DeserializeOwned;

/// Every endpoint of the service once, as the methods of a client (`async` ones or blocking
/// ones), each building its [`Call`] and handing it to the client's `call`: the two clients
/// cannot offer different endpoints, arguments or documentation.
macro_rules! endpoints {
    ($($mode:ident)?) => {
        endpoints! { @methods [$($mode)?]
            /// `GET /v1/health`.
            fn health() -> Health = Ok(Call::health());
            /// Creates a model (`model` spec, `range` for continuous values).
            fn create(id: &str, model: Option<&str>, range: Option<[f64; 2]>) -> WriteAck =
                Call::create(id, model, range);
            /// Creates a model as `request` says: its spec, range and calendar of days off
            /// ([`CreateRequest::days_off`]).
            fn create_with(id: &str, request: &CreateRequest) -> WriteAck =
                Call::create_with(id, request);
            /// Removes a model.
            fn remove(id: &str) -> WriteAck = Ok(Call::remove(id));
            /// A model's parameters.
            fn view(id: &str) -> ModelInfo = Ok(Call::view(id));
            /// All models.
            fn list() -> ListResponse = Ok(Call::list());
            /// The models whose ids start with `prefix` (a robot's, a namespace's).
            fn list_prefix(prefix: &str) -> ListResponse = Ok(Call::list_prefix(prefix));
            /// Refits a model fitted on a whole series (`auto`, `fremen:auto`, ...) on its kept
            /// observations now; answers once the fit is in use and durable.
            fn refit(id: &str) -> RefitResponse = Call::refit(id);
            /// Every observation a model holds.
            fn observations(id: &str) -> ObservationsResponse = Ok(Call::observations(id));
            /// Adds binary observations, creating the model as `model` if it does not exist.
            fn add(id: &str, times: &[f64], states: &[bool], model: Option<&str>) -> WriteAck =
                Call::add(id, times, states, model);
            /// Adds observations with values.
            fn add_values(id: &str, times: &[f64], values: &[f64], model: Option<&str>)
                -> WriteAck = Call::add_values(id, times, values, model);
            /// Adds observations of many models in one durable commit.
            fn add_batches(request: &ObservationsRequest) -> WriteAck =
                Call::add_batches(request);
            /// `p(t)` at many times.
            fn predict(id: &str, times: &[f64], order: Option<usize>) -> PredictResponse =
                Call::at_times("/v1/predict", id, times, order);
            /// `p(t)` at many times with the central prediction intervals of coverage
            /// `coverage` (strictly between 0 and 1) of a model of continuous values
            /// (`lower`, `upper`; absent for binary models).
            fn predict_interval(id: &str, times: &[f64], order: Option<usize>, coverage: f64)
                -> PredictResponse = Call::predict_interval(id, times, order, coverage);
            /// Entropies (bits) at many times.
            fn entropy(id: &str, times: &[f64], order: Option<usize>) -> PredictResponse =
                Call::at_times("/v1/entropy", id, times, order);
            /// `p(t)` of many models at one time.
            fn forecast(request: &ForecastRequest) -> ForecastResponse = Call::forecast(request);
            /// Entropies of many models at one time.
            fn forecast_entropy(request: &ForecastRequest) -> ForecastResponse =
                Call::forecast_entropy(request);
            /// Errors per order on given data.
            fn evaluate(request: &EvaluateRequest) -> EvaluateResponse = Call::evaluate(request);
            /// Anomalies in given data.
            fn detect(request: &DetectRequest) -> DetectResponse = Call::detect(request);
        }
    };
    (@methods [async] $($(#[$doc:meta])* fn $name:ident($($arg:ident: $ty:ty),*) -> $ret:ty = $call:expr;)*) => {
        $(
            $(#[$doc])*
            pub async fn $name(&self, $($arg: $ty),*) -> Result<$ret, ClientError> {
                self.call($call).await
            }
        )*
    };
    (@methods [] $($(#[$doc:meta])* fn $name:ident($($arg:ident: $ty:ty),*) -> $ret:ty = $call:expr;)*) => {
        $(
            $(#[$doc])*
            pub fn $name(&self, $($arg: $ty),*) -> Result<$ret, ClientError> {
                self.call($call)
            }
        )*
    };
}
pub(crate) use endpoints;

use crate::api::*;

/// The largest answer a client reads (256 MiB, about 5 million predicted values as JSON): a
/// larger declared length is refused before the body is read, and a body that runs on past it
/// (chunked, or a server that sends more than it declared) is cut off there, so that a wrong
/// address or a hostile server cannot make the client hold more.
pub const MAX_RESPONSE_BYTES: usize = 256 << 20;

/// Why a call failed.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// The service answered with an error.
    #[error("{status}: {}", body.reason)]
    Api {
        /// HTTP status.
        status: StatusCode,
        /// The service's error.
        body: ErrorBody,
    },
    /// No answer (connection refused or reset, timeout) or an answer that is not the API's.
    #[error("{0}")]
    Transport(String),
}

impl ClientError {
    /// The HTTP status of an API error.
    pub fn status(&self) -> Option<StatusCode> {
        match self {
            ClientError::Api { status, .. } => Some(*status),
            ClientError::Transport(_) => None,
        }
    }
}

/// The base URL of a service, checked: `http://` only (no TLS), without a trailing slash.
pub(crate) fn base_url(base: &str) -> Result<String, ClientError> {
    if !base.starts_with("http://") {
        return Err(ClientError::Transport(format!(
            "service address {base:?} is not an http:// URL"
        )));
    }
    Ok(base.trim_end_matches('/').to_owned())
}

/// The error of an answer that declares (`declared`) or sends more than
/// [`MAX_RESPONSE_BYTES`]; `url` names the request.
pub(crate) fn too_large(url: &str, declared: Option<u64>) -> ClientError {
    let what_it_does = match declared {
        Some(n) => format!("declares {n} bytes, more than"),
        None => "runs on past".into(),
    };
    ClientError::Transport(format!(
        "{url}: the answer {what_it_does} the {MAX_RESPONSE_BYTES} bytes an answer may have"
    ))
}

/// An answer's body as the endpoint's type, or the service's error.
pub(crate) fn decode<R: DeserializeOwned>(
    status: StatusCode,
    bytes: &[u8],
    url: &str,
) -> Result<R, ClientError> {
    if status.is_success() {
        serde_json::from_slice(bytes)
            .map_err(|e| ClientError::Transport(format!("{url}: unexpected answer: {e}")))
    } else {
        let body = serde_json::from_slice(bytes).unwrap_or_else(|_| ErrorBody {
            error: "unknown".into(),
            reason: String::from_utf8_lossy(bytes).into_owned(),
        });
        Err(ClientError::Api { status, body })
    }
}

/// One request of the API: method, path (and query) under the base URL, JSON body.
pub(crate) struct Call {
    pub method: Method,
    pub path: String,
    pub body: Option<Vec<u8>>,
}

impl Call {
    fn new(method: Method, path: impl Into<String>) -> Call {
        Call {
            method,
            path: path.into(),
            body: None,
        }
    }

    fn json<B: Serialize + ?Sized>(
        method: Method,
        path: impl Into<String>,
        body: &B,
    ) -> Result<Call, ClientError> {
        let path = path.into();
        let body = serde_json::to_vec(body).map_err(|e| {
            ClientError::Transport(format!("{path}: cannot write the request: {e}"))
        })?;
        Ok(Call {
            method,
            path,
            body: Some(body),
        })
    }

    pub fn health() -> Call {
        Call::new(Method::GET, "/v1/health")
    }

    pub fn create(
        id: &str,
        model: Option<&str>,
        range: Option<[f64; 2]>,
    ) -> Result<Call, ClientError> {
        let body = CreateRequest {
            model: model.map(str::to_owned),
            range,
            days_off: None,
        };
        Call::create_with(id, &body)
    }

    pub fn create_with(id: &str, request: &CreateRequest) -> Result<Call, ClientError> {
        Call::json(Method::PUT, model_path(id, ""), request)
    }

    pub fn remove(id: &str) -> Call {
        Call::new(Method::DELETE, model_path(id, ""))
    }

    pub fn view(id: &str) -> Call {
        Call::new(Method::GET, model_path(id, ""))
    }

    pub fn list() -> Call {
        Call::new(Method::GET, "/v1/models")
    }

    pub fn list_prefix(prefix: &str) -> Call {
        let mut query = String::from("/v1/models?prefix=");
        percent_encode(prefix, &mut query);
        Call::new(Method::GET, query)
    }

    pub fn refit(id: &str) -> Result<Call, ClientError> {
        Call::json(
            Method::POST,
            model_path(id, "/refit"),
            &RefitRequest::default(),
        )
    }

    pub fn observations(id: &str) -> Call {
        Call::new(Method::GET, model_path(id, "/observations"))
    }

    pub fn add(
        id: &str,
        times: &[f64],
        states: &[bool],
        model: Option<&str>,
    ) -> Result<Call, ClientError> {
        let body = AddRequest {
            id: id.to_owned(),
            times: times.to_vec(),
            states: states.to_vec(),
            model: model.map(str::to_owned),
        };
        Call::json(Method::POST, "/v1/add", &body)
    }

    pub fn add_values(
        id: &str,
        times: &[f64],
        values: &[f64],
        model: Option<&str>,
    ) -> Result<Call, ClientError> {
        let body = AddValuesRequest {
            id: id.to_owned(),
            times: times.to_vec(),
            values: values.to_vec(),
            model: model.map(str::to_owned),
        };
        Call::json(Method::POST, "/v1/addvalues", &body)
    }

    pub fn add_batches(request: &ObservationsRequest) -> Result<Call, ClientError> {
        Call::json(Method::POST, "/v1/observations", request)
    }

    /// `/v1/predict` or `/v1/entropy`.
    pub fn at_times(
        path: &str,
        id: &str,
        times: &[f64],
        order: Option<usize>,
    ) -> Result<Call, ClientError> {
        let body = PredictRequest {
            id: id.to_owned(),
            times: times.to_vec(),
            order,
            coverage: None,
        };
        Call::json(Method::POST, path, &body)
    }

    /// `/v1/predict` with `coverage`.
    pub fn predict_interval(
        id: &str,
        times: &[f64],
        order: Option<usize>,
        coverage: f64,
    ) -> Result<Call, ClientError> {
        let body = PredictRequest {
            id: id.to_owned(),
            times: times.to_vec(),
            order,
            coverage: Some(coverage),
        };
        Call::json(Method::POST, "/v1/predict", &body)
    }

    pub fn forecast(request: &ForecastRequest) -> Result<Call, ClientError> {
        Call::json(Method::POST, "/v1/forecast", request)
    }

    pub fn forecast_entropy(request: &ForecastRequest) -> Result<Call, ClientError> {
        Call::json(Method::POST, "/v1/forecastEntropy", request)
    }

    pub fn evaluate(request: &EvaluateRequest) -> Result<Call, ClientError> {
        Call::json(Method::POST, "/v1/evaluate", request)
    }

    pub fn detect(request: &DetectRequest) -> Result<Call, ClientError> {
        Call::json(Method::POST, "/v1/detect", request)
    }
}

/// Appends `text` percent-encoded (every byte but RFC 3986's unreserved characters).
fn percent_encode(text: &str, into: &mut String) {
    for byte in text.bytes() {
        if byte.is_ascii_alphanumeric() || b"-._~".contains(&byte) {
            into.push(byte as char);
        } else {
            into.push_str(&format!("%{byte:02X}"));
        }
    }
}

/// `/v1/models/{id}{suffix}` with the id percent-encoded.
pub(crate) fn model_path(id: &str, suffix: &str) -> String {
    let mut path = String::from("/v1/models/");
    percent_encode(id, &mut path);
    path.push_str(suffix);
    path
}

/// A one-connection HTTP server on a loopback port that answers the first request with
/// `head` and then `body_bytes` bytes of `[` (sent in 64 KiB pieces, as chunks if `head`
/// says so), stopping when the client hangs up; its base URL. For the tests of both clients.
#[cfg(test)]
pub(crate) fn answering(head: &'static str, body_bytes: usize) -> String {
    use std::io::{Read, Write};
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    std::thread::spawn(move || {
        let (mut stream, _) = listener.accept().unwrap();
        let mut request = Vec::new();
        let mut byte = [0u8; 1];
        while !request.ends_with(b"\r\n\r\n") && stream.read(&mut byte).unwrap_or(0) == 1 {
            request.push(byte[0]);
        }
        let chunked = head.contains("chunked");
        let piece = vec![b'['; 64 << 10];
        let mut sent = stream.write_all(head.as_bytes()).is_ok();
        let mut left = body_bytes;
        while sent && left > 0 {
            let n = left.min(piece.len());
            sent = if chunked {
                write!(stream, "{n:x}\r\n").is_ok()
                    && stream.write_all(&piece[..n]).is_ok()
                    && stream.write_all(b"\r\n").is_ok()
            } else {
                stream.write_all(&piece[..n]).is_ok()
            };
            left -= n;
        }
    });
    base
}

/// A loopback base URL where nothing listens (a port that was free a moment ago).
#[cfg(test)]
pub(crate) fn refusing() -> String {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    format!("http://127.0.0.1:{port}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn model_ids_are_percent_encoded_in_paths() {
        assert_eq!(model_path("lab-door", ""), "/v1/models/lab-door");
        assert_eq!(
            model_path("kitchen door/2", "/observations"),
            "/v1/models/kitchen%20door%2F2/observations"
        );
        // UTF-8 bytes one by one: "é" is C3 A9.
        assert_eq!(model_path("café", ""), "/v1/models/caf%C3%A9");
        assert_eq!(model_path("a.b_c~d", ""), "/v1/models/a.b_c~d");
        assert_eq!(
            Call::list_prefix("robot 1/").path,
            "/v1/models?prefix=robot%201%2F"
        );
    }

    #[test]
    fn only_http_addresses_are_services() {
        let error = base_url("https://robot:8470").unwrap_err();
        assert_eq!(
            error.to_string(),
            "service address \"https://robot:8470\" is not an http:// URL"
        );
        assert_eq!(error.status(), None);
        assert_eq!(
            base_url("http://127.0.0.1:8470/").unwrap(),
            "http://127.0.0.1:8470"
        );
    }

    #[test]
    fn api_errors_show_status_and_reason() {
        let error = ClientError::Api {
            status: StatusCode::NOT_FOUND,
            body: ErrorBody {
                error: "not_found".into(),
                reason: "no model \"door\"".into(),
            },
        };
        assert_eq!(error.to_string(), "404 Not Found: no model \"door\"");
        assert_eq!(error.status(), Some(StatusCode::NOT_FOUND));
    }

    #[test]
    fn answers_decode_or_become_errors() {
        let ok: WriteAck = decode(
            StatusCode::OK,
            br#"{"observations": 2, "seq": 7}"#,
            "http://s/v1/add",
        )
        .unwrap();
        assert_eq!((ok.observations, ok.seq), (2, 7));
        let api = decode::<WriteAck>(
            StatusCode::BAD_REQUEST,
            br#"{"error": "bad_request", "reason": "observation 2: value 1.5"}"#,
            "http://s/v1/add",
        )
        .unwrap_err();
        assert_eq!(api.to_string(), "400 Bad Request: observation 2: value 1.5");
        // An error answer that is not the API's: its text is the reason.
        let proxy = decode::<WriteAck>(StatusCode::BAD_GATEWAY, b"upstream down", "u").unwrap_err();
        assert_eq!(proxy.to_string(), "502 Bad Gateway: upstream down");
        let garbage = decode::<WriteAck>(StatusCode::OK, b"[", "http://s/v1/add").unwrap_err();
        assert!(
            garbage
                .to_string()
                .starts_with("http://s/v1/add: unexpected answer: "),
            "{garbage}"
        );
    }

    #[test]
    fn request_bodies_are_the_api_types() {
        let call = Call::add_values("door", &[0.0, 60.0], &[1.0, 0.5], Some("fremen:2")).unwrap();
        assert_eq!(
            (call.method, call.path.as_str()),
            (Method::POST, "/v1/addvalues")
        );
        let body: AddValuesRequest = serde_json::from_slice(&call.body.unwrap()).unwrap();
        assert_eq!(body.times, [0.0, 60.0]);
        assert_eq!(body.values, [1.0, 0.5]);
        assert_eq!(body.model.as_deref(), Some("fremen:2"));
        assert!(Call::health().body.is_none());
    }
}
