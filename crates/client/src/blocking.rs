//! The typed blocking HTTP client of the service (ureq, plain `std` sockets): the same
//! endpoints, errors and answer limit as the async [`Client`](crate::Client), for programs
//! without an async runtime (the Python package's `chronomap.Client`, scripts, robot loops).

use std::io::Read;

use crate::MAX_RESPONSE_BYTES;
use crate::api::*;
use crate::call::{Call, ClientError, Method, StatusCode, base_url, decode, endpoints, too_large};

/// The body of `response`, at most [`MAX_RESPONSE_BYTES`]; `url` names it in errors.
fn read_body(response: &mut http::Response<ureq::Body>, url: &str) -> Result<Vec<u8>, ClientError> {
    let body = response.body_mut();
    if let Some(declared) = body.content_length()
        && declared > MAX_RESPONSE_BYTES as u64
    {
        return Err(too_large(url, Some(declared)));
    }
    let mut bytes = Vec::new();
    body.as_reader()
        .take(MAX_RESPONSE_BYTES as u64 + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| ClientError::Transport(format!("{url}: {e}")))?;
    if bytes.len() > MAX_RESPONSE_BYTES {
        return Err(too_large(url, None));
    }
    Ok(bytes)
}

/// A connection to one service; every method blocks until the service answers (cheap to
/// clone; clones share connections).
#[derive(Clone, Debug)]
pub struct Client {
    base: String,
    token: Option<String>,
    read_after: Option<u64>,
    agent: ureq::Agent,
}

impl Client {
    /// A client of the service at `base` (e.g. `http://127.0.0.1:8470`), sending `token` as
    /// bearer token with writes.
    ///
    /// # Errors
    /// A base that is not an `http://` URL.
    pub fn new(base: &str, token: Option<String>) -> Result<Self, ClientError> {
        let base = base_url(base)?;
        let config = ureq::Agent::config_builder()
            // Error answers are the API's: read them, not ureq's status error.
            .http_status_as_error(false)
            // As the async client: the address given, never a proxy from the environment.
            .proxy(None)
            .build();
        Ok(Client {
            base,
            token,
            read_after: None,
            agent: config.into(),
        })
    }

    /// A copy whose every request says `Chronomap-Read-After: seq` (see
    /// [`Client::reading_after`](crate::Client::reading_after)).
    pub fn reading_after(&self, seq: u64) -> Client {
        Client {
            read_after: Some(seq),
            ..self.clone()
        }
    }

    /// Sends `method path` with `body` and `token`; the status and body of the answer.
    fn send(
        &self,
        method: Method,
        url: &str,
        body: Option<Vec<u8>>,
        token: Option<&str>,
    ) -> Result<(StatusCode, Vec<u8>), ClientError> {
        let mut request = http::Request::builder().method(method).uri(url);
        if let Some(token) = token {
            request = request.header("authorization", format!("Bearer {token}"));
        }
        if let Some(seq) = self.read_after {
            request = request.header(READ_AFTER_HEADER, seq);
        }
        let transport = |e: &dyn std::fmt::Display| ClientError::Transport(format!("{url}: {e}"));
        let answer = match body {
            Some(body) => request
                .header("content-type", "application/json")
                .body(body)
                .map_err(|e| transport(&e))
                .and_then(|r| self.agent.run(r).map_err(|e| transport(&e))),
            None => request
                .body(())
                .map_err(|e| transport(&e))
                .and_then(|r| self.agent.run(r).map_err(|e| transport(&e))),
        };
        let mut response = answer?;
        let bytes = read_body(&mut response, url)?;
        Ok((response.status(), bytes))
    }

    fn call<R: serde::de::DeserializeOwned>(
        &self,
        call: Result<Call, ClientError>,
    ) -> Result<R, ClientError> {
        let call = call?;
        let url = format!("{}{}", self.base, call.path);
        let (status, bytes) = self.send(call.method, &url, call.body, self.token.as_deref())?;
        decode(status, &bytes, &url)
    }

    endpoints!();

    /// A raw request, for tests of hostile input: method, path, body bytes; returns status
    /// and body.
    pub fn raw(
        &self,
        method: Method,
        path: &str,
        body: Vec<u8>,
        token: Option<&str>,
    ) -> Result<(StatusCode, String), ClientError> {
        let url = format!("{}{path}", self.base);
        let (status, bytes) = self.send(method, &url, Some(body), token)?;
        Ok((status, String::from_utf8_lossy(&bytes).into_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::call::{answering, refusing};

    #[test]
    fn an_answer_larger_than_the_limit_is_refused() {
        // A declared length beyond the limit: refused before the body is read.
        let base = answering(
            "HTTP/1.1 200 OK\r\ncontent-length: 1099511627776\r\n\r\n",
            0,
        );
        let error = Client::new(&base, None).unwrap().health().unwrap_err();
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
        let error = Client::new(&base, None)
            .unwrap()
            .raw(Method::GET, "/v1/health", Vec::new(), None)
            .unwrap_err();
        assert_eq!(
            error.to_string(),
            format!(
                "{base}/v1/health: the answer runs on past the 268435456 bytes an answer may have"
            )
        );
    }

    #[test]
    fn an_error_answer_is_the_services_error() {
        // 404 with a body that is not the API's JSON (three `[`): its text is the reason.
        let base = answering("HTTP/1.1 404 Not Found\r\ncontent-length: 3\r\n\r\n", 3);
        let error = Client::new(&base, None).unwrap().view("door").unwrap_err();
        assert_eq!(error.status(), Some(StatusCode::NOT_FOUND));
        assert_eq!(error.to_string(), "404 Not Found: [[[");
    }

    #[test]
    fn a_refused_connection_is_a_transport_error_naming_the_endpoint() {
        let base = refusing();
        match Client::new(&base, None).unwrap().health() {
            Err(ClientError::Transport(text)) => {
                assert!(text.starts_with(&format!("{base}/v1/health: ")), "{text}");
            }
            other => panic!("expected a transport error, got {other:?}"),
        }
        assert!(Client::new("https://robot:8470", None).is_err());
    }
}
