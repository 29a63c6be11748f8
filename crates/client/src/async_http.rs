//! The typed async HTTP client of the service (reqwest): one method per endpoint, the
//! service's JSON errors as [`ClientError::Api`].

use crate::MAX_RESPONSE_BYTES;
use crate::api::*;
use crate::call::{Call, ClientError, Method, StatusCode, base_url, decode, endpoints, too_large};

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

/// What [`Client::add_series`] added.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Added {
    /// Observations added.
    pub observations: u64,
    /// The log position of the last request (`None` for an empty series).
    pub seq: Option<u64>,
}

/// A request of [`Client::add_series`] that failed.
#[derive(Debug, thiserror::Error)]
#[error("observations {first}..{last} were not added ({added} were)")]
pub struct BatchError {
    /// Observations added before it.
    pub added: u64,
    /// The first observation of the failed request (counted from 1).
    pub first: u64,
    /// Its last observation.
    pub last: u64,
    /// Why it failed.
    #[source]
    pub source: ClientError,
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

    endpoints!(async);

    /// Adds the series `times`, `values` to the model `id` (created as `model` on first use)
    /// in requests of at most `batch` observations (`/v1/addvalues`), in order, up to the first
    /// request that fails.
    ///
    /// # Errors
    /// The first request that failed, with the observations added before it.
    pub async fn add_series(
        &self,
        id: &str,
        times: &[f64],
        values: &[f64],
        model: Option<&str>,
        batch: usize,
    ) -> Result<Added, BatchError> {
        let mut added = Added {
            observations: 0,
            seq: None,
        };
        let batch = batch.max(1);
        for (times, values) in times.chunks(batch).zip(values.chunks(batch)) {
            let ack = self
                .add_values(id, times, values, model)
                .await
                .map_err(|source| BatchError {
                    added: added.observations,
                    first: added.observations + 1,
                    last: added.observations + times.len() as u64,
                    source,
                })?;
            added.observations += ack.observations;
            added.seq = Some(ack.seq);
        }
        Ok(added)
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
