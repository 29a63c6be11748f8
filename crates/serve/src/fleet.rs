//! Several services over one shared log (`chronomap serve --fleet`): every node appends to the
//! store's log under its global append lock ([`crate::store::Store::append_next`]) and applies,
//! in log order, the groups the other nodes appended. The log is the only source of truth;
//! a node's models are a deterministic function of the log prefix it has applied, so two nodes
//! at the same position hold bit-identical models.
//!
//! * [`tail`]: the node's tailer thread, woken by the store's notifications (PostgreSQL
//!   `LISTEN`/`NOTIFY`) and at least every [`POLL`] in case one was missed.
//! * [`catch_up`]: applies everything in the log after the node's position; a read carrying a
//!   sequence token (`Chronomap-Read-After`) calls it when the node is behind the token, so a
//!   read after a write on any node sees that write.
//! * [`Sync`]: the node's position, the log's head and how long the node has been behind, for
//!   `/v1/health`.
//!
//! Design, guarantee and numbers: docs/fleet.md.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use crate::writer::Shared;

/// Longest wait of the tailer between two looks at the log.
pub const POLL: Duration = Duration::from_millis(500);

/// A node that has not been level with the log for this long reports `behind`.
pub const BEHIND_AFTER: Duration = Duration::from_secs(5);

/// Applies every commit group after the node's position, in order; returns the new position.
///
/// # Errors
/// The store cannot be read (try again later), or a group cannot be applied: the node then
/// stops applying for good and says so in its health (its reads still answer from the
/// last position).
pub fn catch_up(shared: &Shared) -> Result<u64, String> {
    let _applying = shared.applying.lock().expect("applying lock");
    if let Some(reason) = shared.broken.lock().expect("broken lock").clone() {
        return Err(reason);
    }
    let started = Instant::now();
    let from = shared.seq.load(Ordering::Acquire) + 1;
    match shared
        .store
        .scan(from, &mut |seq, bytes| shared.apply_logged(seq, bytes))
    {
        Ok(()) => {
            *shared.synced.lock().expect("synced lock") = started;
            Ok(shared.seq.load(Ordering::Acquire))
        }
        // `apply_logged` set `broken` if the log itself was at fault; else the store failed.
        Err(e) => Err(shared
            .broken
            .lock()
            .expect("broken lock")
            .clone()
            .unwrap_or_else(|| e.to_string())),
    }
}

/// Runs the tailer until `stop` is set: waits for another node's append (or [`POLL`]), then
/// [`catch_up`]. Failures are printed once per kind and retried.
pub fn tail(shared: Arc<Shared>, stop: Arc<AtomicBool>) {
    let mut last_error: Option<String> = None;
    while !stop.load(Ordering::Acquire) {
        shared.store.wait_for_appends(POLL);
        if stop.load(Ordering::Acquire) {
            break;
        }
        match catch_up(&shared) {
            Ok(_) => last_error = None,
            Err(e) => {
                if last_error.as_ref() != Some(&e) {
                    eprintln!("warning: {e}");
                    last_error = Some(e);
                }
            }
        }
    }
}

/// Where a node stands against the shared log.
#[derive(Clone, Debug, PartialEq)]
pub struct Sync {
    /// Last position applied.
    pub applied: u64,
    /// Last position in the log.
    pub head: u64,
    /// Seconds since the node last knew it had applied the whole log (0 when level).
    pub behind_secs: f64,
    /// Why the node stopped applying the log, if it did.
    pub broken: Option<String>,
}

impl Sync {
    /// `ok`, `behind` (not level with the log for [`BEHIND_AFTER`]) or `failed`.
    pub fn status(&self) -> &'static str {
        if self.broken.is_some() {
            "failed"
        } else if self.behind_secs >= BEHIND_AFTER.as_secs_f64() {
            "behind"
        } else {
            "ok"
        }
    }
}

/// The node's [`Sync`] (asks the store for its head: call from a blocking context).
///
/// # Errors
/// The store cannot be read.
pub fn sync(shared: &Shared) -> Result<Sync, String> {
    let applied = shared.seq.load(Ordering::Acquire);
    let head = shared
        .store
        .head()
        .map_err(|e| e.to_string())?
        .unwrap_or(applied)
        .max(applied);
    let behind_secs = if head > applied {
        shared
            .synced
            .lock()
            .expect("synced lock")
            .elapsed()
            .as_secs_f64()
    } else {
        0.0
    };
    Ok(Sync {
        applied,
        head,
        behind_secs,
        broken: shared.broken.lock().expect("broken lock").clone(),
    })
}
