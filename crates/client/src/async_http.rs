//! The typed async HTTP client of the service (reqwest): one method per endpoint, the
//! service's JSON errors as [`ClientError::Api`].

use crate::MAX_RESPONSE_BYTES;
use crate::api::*;
use crate::call::{Call, ClientError, Method, StatusCode, base_url, decode, too_large};

/// The body of `response`, at most [`MAX_RESPONSE_BYTES`]; `url` names it in errors.
async fn read_body(mut response: reqwest::Response, url: &str) -> Result<Vec<u8>, ClientError> {
    if let Some(declared) = response.content_length()
        && declared > MAX_RESPONSE_BYTES as u64
    {
        return Err(too_large(url, Some(declared)));
    }
    let mut bytes = Vec::new();
    while let Some(chunk) = response
        .chunk()
        .await
        .map_err(|e| ClientError::Transport(format!("{url}: {e}")))?
    {
        if chunk.len() > MAX_RESPONSE_BYTES - bytes.len() {
            return Err(too_large(url, None));
        }
        bytes.extend_from_slice(&chunk);
    }
    Ok(bytes)
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
        let base = base_url(base)?;
        let http = reqwest::Client::builder()
            .no_proxy()
            .build()
            .map_err(|e| ClientError::Transport(e.to_string()))?;
        Ok(Client {
            base,
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

    async fn call<R: serde::de::DeserializeOwned>(
        &self,
        call: Result<Call, ClientError>,
    ) -> Result<R, ClientError> {
        let call = call?;
        let url = format!("{}{}", self.base, call.path);
        let mut request = self.http.request(call.method, &url);
        if let Some(token) = &self.token {
            request = request.bearer_auth(token);
        }
        if let Some(seq) = self.read_after {
            request = request.header(READ_AFTER_HEADER, seq);
        }
        if let Some(body) = call.body {
            request = request
                .header("content-type", "application/json")
                .body(body);
        }
        let response = request
            .send()
            .await
            .map_err(|e| ClientError::Transport(format!("{url}: {e}")))?;
        let status = response.status();
        let bytes = read_body(response, &url).await?;
        decode(status, &bytes, &url)
    }

    /// `GET /v1/health`.
    pub async fn health(&self) -> Result<Health, ClientError> {
        self.call(Ok(Call::health())).await
    }

    /// Creates a model (`model` spec, `range` for continuous values).
    pub async fn create(
        &self,
        id: &str,
        model: Option<&str>,
        range: Option<[f64; 2]>,
    ) -> Result<WriteAck, ClientError> {
        self.call(Call::create(id, model, range)).await
    }

    /// Removes a model.
    pub async fn remove(&self, id: &str) -> Result<WriteAck, ClientError> {
        self.call(Ok(Call::remove(id))).await
    }

    /// A model's parameters.
    pub async fn view(&self, id: &str) -> Result<ModelInfo, ClientError> {
        self.call(Ok(Call::view(id))).await
    }

    /// All models.
    pub async fn list(&self) -> Result<ListResponse, ClientError> {
        self.call(Ok(Call::list())).await
    }

    /// The models whose ids start with `prefix` (a robot's, a namespace's).
    pub async fn list_prefix(&self, prefix: &str) -> Result<ListResponse, ClientError> {
        self.call(Ok(Call::list_prefix(prefix))).await
    }

    /// Refits a model fitted on a whole series (`auto`, `fremen:auto`, ...) on its kept
    /// observations now; answers once the fit is in use and durable.
    pub async fn refit(&self, id: &str) -> Result<RefitResponse, ClientError> {
        self.call(Call::refit(id)).await
    }

    /// Every observation a model holds.
    pub async fn observations(&self, id: &str) -> Result<ObservationsResponse, ClientError> {
        self.call(Ok(Call::observations(id))).await
    }

    /// Adds binary observations, creating the model as `model` if it does not exist.
    pub async fn add(
        &self,
        id: &str,
        times: &[f64],
        states: &[bool],
        model: Option<&str>,
    ) -> Result<WriteAck, ClientError> {
        self.call(Call::add(id, times, states, model)).await
    }

    /// Adds observations with values.
    pub async fn add_values(
        &self,
        id: &str,
        times: &[f64],
        values: &[f64],
        model: Option<&str>,
    ) -> Result<WriteAck, ClientError> {
        self.call(Call::add_values(id, times, values, model)).await
    }

    /// Adds observations of many models in one durable commit.
    pub async fn add_batches(
        &self,
        request: &ObservationsRequest,
    ) -> Result<WriteAck, ClientError> {
        self.call(Call::add_batches(request)).await
    }

    /// `p(t)` at many times.
    pub async fn predict(
        &self,
        id: &str,
        times: &[f64],
        order: Option<usize>,
    ) -> Result<PredictResponse, ClientError> {
        self.call(Call::at_times("/v1/predict", id, times, order))
            .await
    }

    /// Entropies (bits) at many times.
    pub async fn entropy(
        &self,
        id: &str,
        times: &[f64],
        order: Option<usize>,
    ) -> Result<PredictResponse, ClientError> {
        self.call(Call::at_times("/v1/entropy", id, times, order))
            .await
    }

    /// `p(t)` of many models at one time.
    pub async fn forecast(
        &self,
        request: &ForecastRequest,
    ) -> Result<ForecastResponse, ClientError> {
        self.call(Call::forecast(request)).await
    }

    /// Entropies of many models at one time.
    pub async fn forecast_entropy(
        &self,
        request: &ForecastRequest,
    ) -> Result<ForecastResponse, ClientError> {
        self.call(Call::forecast_entropy(request)).await
    }

    /// Errors per order on given data.
    pub async fn evaluate(
        &self,
        request: &EvaluateRequest,
    ) -> Result<EvaluateResponse, ClientError> {
        self.call(Call::evaluate(request)).await
    }

    /// Anomalies in given data.
    pub async fn detect(&self, request: &DetectRequest) -> Result<DetectResponse, ClientError> {
        self.call(Call::detect(request)).await
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
        let url = format!("{}{path}", self.base);
        let mut request = self
            .http
            .request(method, &url)
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
        let bytes = read_body(response, &url).await?;
        Ok((status, String::from_utf8_lossy(&bytes).into_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::call::{answering, refusing};

    #[test]
    fn a_client_keeps_the_base_without_its_slash() {
        let client = Client::new("http://127.0.0.1:8470/", Some("t".into())).unwrap();
        assert_eq!(client.base, "http://127.0.0.1:8470");
        assert!(Client::new("https://robot:8470", None).is_err());
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
        let base = refusing();
        let client = Client::new(&base, None).unwrap();
        match client.health().await {
            Err(ClientError::Transport(text)) => {
                assert!(text.starts_with(&format!("{base}/v1/health: ")), "{text}");
            }
            other => panic!("expected a transport error, got {other:?}"),
        }
    }
}
