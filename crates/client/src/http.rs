//! The typed HTTP client of the service (reqwest): one method per endpoint, the service's JSON
//! errors as [`ClientError::Api`].

pub use reqwest::{Method, StatusCode};
use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::api::*;

/// The largest answer a client reads (256 MiB, about 5 million predicted values as JSON): a
/// larger declared length is refused before the body is read, and a body that runs on past it
/// (chunked, or a server that sends more than it declared) is cut off there, so that a wrong
/// address or a hostile server cannot make the client hold more.
pub const MAX_RESPONSE_BYTES: usize = 256 << 20;

/// The body of `response`, at most [`MAX_RESPONSE_BYTES`]; `what` (the URL) names it in errors.
async fn read_body(mut response: reqwest::Response, what: &str) -> Result<Vec<u8>, ClientError> {
    let too_large = |what_it_does: String| {
        ClientError::Transport(format!(
            "{what}: the answer {what_it_does} the {MAX_RESPONSE_BYTES} bytes an answer may have"
        ))
    };
    if let Some(declared) = response.content_length()
        && declared > MAX_RESPONSE_BYTES as u64
    {
        return Err(too_large(format!("declares {declared} bytes, more than")));
    }
    let mut bytes = Vec::new();
    while let Some(chunk) = response
        .chunk()
        .await
        .map_err(|e| ClientError::Transport(format!("{what}: {e}")))?
    {
        if chunk.len() > MAX_RESPONSE_BYTES - bytes.len() {
            return Err(too_large("runs on past".into()));
        }
        bytes.extend_from_slice(&chunk);
    }
    Ok(bytes)
}

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

/// A connection to one service (cheap to clone; clones share connections).
#[derive(Clone, Debug)]
pub struct Client {
    base: String,
    token: Option<String>,
    read_after: Option<u64>,
    http: reqwest::Client,
}

impl Client {
    /// A client of the service at `base` (e.g. `http://127.0.0.1:8470`), sending `token` as
    /// bearer token with writes.
    ///
    /// # Errors
    /// A base that is not an `http://` URL.
    pub fn new(base: &str, token: Option<String>) -> Result<Self, ClientError> {
        if !base.starts_with("http://") {
            return Err(ClientError::Transport(format!(
                "service address {base:?} is not an http:// URL"
            )));
        }
        let http = reqwest::Client::builder()
            .no_proxy()
            .build()
            .map_err(|e| ClientError::Transport(e.to_string()))?;
        Ok(Client {
            base: base.trim_end_matches('/').to_owned(),
            token,
            read_after: None,
            http,
        })
    }

    /// A copy whose every request says `Chronomap-Read-After: seq`: the service answers only
    /// once it has applied the log up to `seq`, so a read after a write (the `seq` of its
    /// [`WriteAck`]) sees the write, also on another node of a fleet.
    pub fn reading_after(&self, seq: u64) -> Client {
        Client {
            read_after: Some(seq),
            ..self.clone()
        }
    }

    async fn call<B: Serialize + ?Sized, R: DeserializeOwned>(
        &self,
        method: Method,
        path: &str,
        body: Option<&B>,
    ) -> Result<R, ClientError> {
        let mut request = self.http.request(method, format!("{}{path}", self.base));
        if let Some(token) = &self.token {
            request = request.bearer_auth(token);
        }
        if let Some(seq) = self.read_after {
            request = request.header(READ_AFTER_HEADER, seq);
        }
        if let Some(body) = body {
            request = request.json(body);
        }
        let response = request
            .send()
            .await
            .map_err(|e| ClientError::Transport(format!("{}{path}: {e}", self.base)))?;
        let status = response.status();
        let bytes = read_body(response, &format!("{}{path}", self.base)).await?;
        if status.is_success() {
            serde_json::from_slice(&bytes).map_err(|e| {
                ClientError::Transport(format!("{}{path}: unexpected answer: {e}", self.base))
            })
        } else {
            let body = serde_json::from_slice(&bytes).unwrap_or_else(|_| ErrorBody {
                error: "unknown".into(),
                reason: String::from_utf8_lossy(&bytes).into_owned(),
            });
            Err(ClientError::Api { status, body })
        }
    }

    /// `GET /v1/health`.
    pub async fn health(&self) -> Result<Health, ClientError> {
        self.call::<(), _>(Method::GET, "/v1/health", None).await
    }

    /// Creates a model (`model` spec, `range` for continuous values).
    pub async fn create(
        &self,
        id: &str,
        model: Option<&str>,
        range: Option<[f64; 2]>,
    ) -> Result<WriteAck, ClientError> {
        let body = CreateRequest {
            model: model.map(str::to_owned),
            range,
        };
        self.call(Method::PUT, &model_path(id, ""), Some(&body))
            .await
    }

    /// Removes a model.
    pub async fn remove(&self, id: &str) -> Result<WriteAck, ClientError> {
        self.call::<(), _>(Method::DELETE, &model_path(id, ""), None)
            .await
    }

    /// A model's parameters.
    pub async fn view(&self, id: &str) -> Result<ModelInfo, ClientError> {
        self.call::<(), _>(Method::GET, &model_path(id, ""), None)
            .await
    }

    /// All models.
    pub async fn list(&self) -> Result<ListResponse, ClientError> {
        self.call::<(), _>(Method::GET, "/v1/models", None).await
    }

    /// The models whose ids start with `prefix` (a robot's, a namespace's).
    pub async fn list_prefix(&self, prefix: &str) -> Result<ListResponse, ClientError> {
        let mut query = String::from("/v1/models?prefix=");
        percent_encode(prefix, &mut query);
        self.call::<(), _>(Method::GET, &query, None).await
    }

    /// Refits a model fitted on a whole series (`auto`, `fremen:auto`, ...) on its kept
    /// observations now; answers once the fit is in use and durable.
    pub async fn refit(&self, id: &str) -> Result<RefitResponse, ClientError> {
        self.call(
            Method::POST,
            &model_path(id, "/refit"),
            Some(&RefitRequest::default()),
        )
        .await
    }

    /// Every observation a model holds.
    pub async fn observations(&self, id: &str) -> Result<ObservationsResponse, ClientError> {
        self.call::<(), _>(Method::GET, &model_path(id, "/observations"), None)
            .await
    }

    /// Adds binary observations, creating the model as `model` if it does not exist.
    pub async fn add(
        &self,
        id: &str,
        times: &[f64],
        states: &[bool],
        model: Option<&str>,
    ) -> Result<WriteAck, ClientError> {
        let body = AddRequest {
            id: id.to_owned(),
            times: times.to_vec(),
            states: states.to_vec(),
            model: model.map(str::to_owned),
        };
        self.call(Method::POST, "/v1/add", Some(&body)).await
    }

    /// Adds observations with values.
    pub async fn add_values(
        &self,
        id: &str,
        times: &[f64],
        values: &[f64],
        model: Option<&str>,
    ) -> Result<WriteAck, ClientError> {
        let body = AddValuesRequest {
            id: id.to_owned(),
            times: times.to_vec(),
            values: values.to_vec(),
            model: model.map(str::to_owned),
        };
        self.call(Method::POST, "/v1/addvalues", Some(&body)).await
    }

    /// Adds observations of many models in one durable commit.
    pub async fn add_batches(
        &self,
        request: &ObservationsRequest,
    ) -> Result<WriteAck, ClientError> {
        self.call(Method::POST, "/v1/observations", Some(request))
            .await
    }

    /// `p(t)` at many times.
    pub async fn predict(
        &self,
        id: &str,
        times: &[f64],
        order: Option<usize>,
    ) -> Result<PredictResponse, ClientError> {
        self.at_times("/v1/predict", id, times, order).await
    }

    /// Entropies (bits) at many times.
    pub async fn entropy(
        &self,
        id: &str,
        times: &[f64],
        order: Option<usize>,
    ) -> Result<PredictResponse, ClientError> {
        self.at_times("/v1/entropy", id, times, order).await
    }

    async fn at_times(
        &self,
        path: &str,
        id: &str,
        times: &[f64],
        order: Option<usize>,
    ) -> Result<PredictResponse, ClientError> {
        let body = PredictRequest {
            id: id.to_owned(),
            times: times.to_vec(),
            order,
        };
        self.call(Method::POST, path, Some(&body)).await
    }

    /// `p(t)` of many models at one time.
    pub async fn forecast(
        &self,
        request: &ForecastRequest,
    ) -> Result<ForecastResponse, ClientError> {
        self.call(Method::POST, "/v1/forecast", Some(request)).await
    }

    /// Entropies of many models at one time.
    pub async fn forecast_entropy(
        &self,
        request: &ForecastRequest,
    ) -> Result<ForecastResponse, ClientError> {
        self.call(Method::POST, "/v1/forecastEntropy", Some(request))
            .await
    }

    /// Errors per order on given data.
    pub async fn evaluate(
        &self,
        request: &EvaluateRequest,
    ) -> Result<EvaluateResponse, ClientError> {
        self.call(Method::POST, "/v1/evaluate", Some(request)).await
    }

    /// Anomalies in given data.
    pub async fn detect(&self, request: &DetectRequest) -> Result<DetectResponse, ClientError> {
        self.call(Method::POST, "/v1/detect", Some(request)).await
    }

    /// A raw request, for tests of hostile input: method, path, body bytes; returns status
    /// and body.
    pub async fn raw(
        &self,
        method: Method,
        path: &str,
        body: Vec<u8>,
        token: Option<&str>,
    ) -> Result<(StatusCode, String), ClientError> {
        let mut request = self
            .http
            .request(method, format!("{}{path}", self.base))
            .header("content-type", "application/json")
            .body(body);
        if let Some(token) = token {
            request = request.bearer_auth(token);
        }
        let response = request
            .send()
            .await
            .map_err(|e| ClientError::Transport(e.to_string()))?;
        let status = response.status();
        let bytes = read_body(response, &format!("{}{path}", self.base)).await?;
        Ok((status, String::from_utf8_lossy(&bytes).into_owned()))
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
    }

    #[test]
    fn only_http_addresses_make_a_client() {
        let error = Client::new("https://robot:8470", None).unwrap_err();
        assert_eq!(
            error.to_string(),
            "service address \"https://robot:8470\" is not an http:// URL"
        );
        assert_eq!(error.status(), None);
        let client = Client::new("http://127.0.0.1:8470/", Some("t".into())).unwrap();
        assert_eq!(client.base, "http://127.0.0.1:8470");
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

    /// A one-connection HTTP server on a loopback port that answers the first request with
    /// `head` and then `body_bytes` bytes of `[` (sent in 64 KiB pieces, as chunks if `head`
    /// says so), stopping when the client hangs up; its base URL.
    fn answering(head: &'static str, body_bytes: usize) -> String {
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

    #[tokio::test]
    async fn an_answer_larger_than_the_limit_is_refused() {
        // A declared length beyond the limit: refused before the body is read.
        let base = answering(
            "HTTP/1.1 200 OK\r\ncontent-length: 1099511627776\r\n\r\n",
            0,
        );
        let error = Client::new(&base, None)
            .unwrap()
            .health()
            .await
            .unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "{base}/v1/health: the answer declares 1099511627776 bytes, more than the \
                 268435456 bytes an answer may have"
            )
        );
        // A chunked body that runs on (64 KiB more than the limit): cut off at the limit.
        let base = answering(
            "HTTP/1.1 200 OK\r\ntransfer-encoding: chunked\r\n\r\n",
            MAX_RESPONSE_BYTES + (64 << 10),
        );
        let client = Client::new(&base, None).unwrap();
        let error = client
            .raw(Method::GET, "/v1/health", Vec::new(), None)
            .await
            .unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "{base}/v1/health: the answer runs on past the 268435456 bytes an answer may have"
            )
        );
    }

    #[tokio::test]
    async fn a_refused_connection_is_a_transport_error_naming_the_endpoint() {
        // A loopback port that was free a moment ago: nothing listens there now.
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let base = format!("http://127.0.0.1:{port}");
        let client = Client::new(&base, None).unwrap();
        match client.health().await {
            Err(ClientError::Transport(text)) => {
                assert!(text.starts_with(&format!("{base}/v1/health: ")), "{text}");
            }
            other => panic!("expected a transport error, got {other:?}"),
        }
    }
}
