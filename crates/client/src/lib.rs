//! # chronomap-client
//!
//! Talk to a running chronomap world-model service (`chronomap serve`) without compiling it: a
//! robot process that only adds observations and asks for predictions depends on this crate,
//! not on `chronomap-serve` (axum, redb, PostgreSQL).
//!
//! * [`api`]: the wire protocol, the request and response bodies of every endpoint (the
//!   operations of the original FreMEn server as JSON). The server uses the same types, so the
//!   two cannot drift apart; it enables the `openapi` feature to describe them.
//! * [`Client`] (default feature `http`, reqwest and tokio): one async method per endpoint,
//!   the service's JSON errors as [`ClientError::Api`].
//! * [`blocking::Client`] (feature `blocking`, ureq over `std` sockets): the same methods,
//!   blocking, without an async runtime; what the Python package uses.
//!
//! # Example
//! ```no_run
//! # async fn example() -> Result<(), chronomap_client::ClientError> {
//! use chronomap_client::Client;
//!
//! let client = Client::new("http://127.0.0.1:8470", Some("TOKEN".into()))?;
//! // The lab door was closed at night and open in the day; create the model on first use.
//! client.add("lab-door", &[0.0, 43200.0], &[false, true], Some("fremen:2")).await?;
//! let p = client.predict("lab-door", &[86400.0 + 43200.0], None).await?;
//! println!("p(open at noon tomorrow) = {:.2}", p.values[0]);
//! # Ok(())
//! # }
//! ```
#![deny(missing_docs)]

pub mod api;
#[cfg(feature = "http")]
mod async_http;
#[cfg(feature = "blocking")]
pub mod blocking;
#[cfg(any(feature = "http", feature = "blocking"))]
mod call;

#[cfg(feature = "http")]
pub use async_http::{Added, BatchError, Client};
#[cfg(any(feature = "http", feature = "blocking"))]
pub use call::{ClientError, MAX_RESPONSE_BYTES, Method, StatusCode};
