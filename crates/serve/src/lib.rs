//! The chronomap world-model service and its client.
//!
//! Many processes of a robot add observations and ask for predictions while the robot runs
//! for months; the service keeps every model durable across crashes and restarts:
//!
//! * [`api`]: the wire protocol (the operations of the original FreMEn server as JSON).
//! * [`registry`]: the models held, and the one function that changes them.
//! * [`log`] and [`store`]: the append-only log of commit groups and the model snapshots,
//!   in an embedded redb file or in PostgreSQL.
//! * [`writer`]: group commit; a write is acknowledged only once it is durable.
//! * [`maps`]: topological maps and occupancy grids served read-only beside the models.
//! * [`server`]: the HTTP/JSON API (axum) with its OpenAPI description.
//! * [`client`]: a typed client.
//!
//! # Example
//! ```no_run
//! # async fn example() -> Result<(), chronomap_serve::client::ClientError> {
//! use chronomap_serve::client::Client;
//!
//! let client = Client::new("http://127.0.0.1:8470", Some("TOKEN".into()))?;
//! // The lab door was closed at night and open in the day; create the model on first use.
//! client.add("lab-door", &[0.0, 43200.0], &[false, true], Some("fremen:2")).await?;
//! let p = client.predict("lab-door", &[86400.0 + 43200.0], None).await?;
//! println!("p(open at noon tomorrow) = {:.2}", p.values[0]);
//! # Ok(())
//! # }
//! ```

pub mod api;
pub mod client;
pub mod log;
pub mod maps;
pub mod registry;
pub mod server;
pub mod store;
pub mod writer;

pub use server::{Service, ServiceConfig};
