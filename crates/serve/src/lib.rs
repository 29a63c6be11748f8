//! The chronomap world-model service.
//!
//! Many processes of a robot add observations and ask for predictions while the robot runs
//! for months; the service keeps every model durable across crashes and restarts:
//!
//! * [`api`]: the wire protocol (the operations of the original FreMEn server as JSON), shared
//!   with the typed client of `chronomap-client` (re-exported from there, so both sides use
//!   the same types).
//! * [`registry`]: the models held, and the one function that changes them.
//! * [`log`] and [`store`]: the append-only log of commit groups and the model snapshots,
//!   in an embedded redb file or in PostgreSQL (feature `postgres`, on by default).
//! * [`writer`]: group commit; a write is acknowledged only once it is durable.
//! * [`refit`]: models fitted on a whole series (`auto`, `fremen:auto`, ...) keep their
//!   observations and are refitted on a schedule and on request, on a thread of their own;
//!   each fit is logged and durable like any write.
//! * [`fleet`]: several services over one shared PostgreSQL log (`chronomap serve --fleet`):
//!   tailing, read-your-writes tokens, lag.
//! * [`check`]: every snapshot and log entry verified at start (`chronomap serve --check`), and
//!   the salvage of what is intact in a damaged store (`--salvage`); the reading side of a
//!   store beside a running service.
//! * [`startup`]: what a service needs before it serves: its data folder, its token file, the
//!   map files it serves, its store.
//! * `export` (feature `parquet`, on by default): a store's observations and predictions as
//!   Parquet tables (`chronomap export parquet`).
//! * [`maps`]: topological maps, occupancy grids and CoPA-Maps of people served read-only beside
//!   the models.
//! * [`bt_monitor`]: behavior trees watched live over the Groot2 protocol
//!   (`--bt-monitor HOST:PORT`), any number of trees of any size.
//! * [`heavy`]: the requests that compute for a while (grid, activity and plan predictions) on
//!   a bounded pool of their own, cancelled when their client goes away.
//! * [`server`]: the HTTP/JSON API (axum) with its OpenAPI description.
//!
//! The server does not compile an HTTP client: processes that only talk to a service depend on
//! `chronomap-client`, which does not compile this crate.

pub use chronomap_client::api;
pub mod bt_monitor;
pub mod check;
#[cfg(feature = "parquet")]
pub mod export;
pub mod fleet;
pub mod heavy;
pub mod log;
pub mod maps;
pub mod refit;
pub mod registry;
pub mod server;
pub mod startup;
pub mod store;
pub mod writer;

pub use server::{Service, ServiceConfig};
