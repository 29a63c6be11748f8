//! Where the service keeps its state: an append-only log of commit groups and, at
//! checkpoints, a snapshot of every model that changed. Recovery loads the snapshots and
//! replays the log after the checkpoint.
//!
//! Two backends implement [`Store`]: [`RedbStore`], an embedded file (the default), and
//! `PostgresStore`, a PostgreSQL database (feature `postgres`, on by default).

#[cfg(feature = "postgres")]
mod postgres;
mod redb_store;

#[cfg(feature = "postgres")]
pub use postgres::{Access, DEFAULT_SEGMENT_GROUPS, OWNER_WAIT, PostgresStore};
pub use redb_store::RedbStore;

use chronomap_io::model_file::{decode_model, encode_model};

use crate::registry::Entry;

/// Kind tag of model snapshots (inside a versioned, checksummed model-file container).
const SNAPSHOT_KIND: &str = "serve-snapshot";

/// A store failure: I/O, the database, or damaged content.
#[derive(Debug, thiserror::Error)]
#[error("{store}: {reason}")]
pub struct StoreError {
    /// Which store (path or connection).
    pub store: String,
    /// What went wrong.
    pub reason: String,
}

/// What a store holds at start-up.
#[derive(Debug, Default)]
pub struct Recovered {
    /// The log position every snapshot covers.
    pub checkpoint: u64,
    /// Snapshots (id, encoded entry).
    pub snapshots: Vec<(String, Vec<u8>)>,
    /// Last log position written.
    pub last_seq: u64,
    /// Every log position up to this one was folded into the snapshots and moved out of the
    /// live log ([`Store::compact`]): recovery reads the log after it. At most `checkpoint`.
    pub compacted: u64,
}

/// What one checkpoint writes ([`Store::checkpoint`]), atomically.
#[derive(Clone, Copy, Debug)]
pub struct Checkpoint<'a> {
    /// The log position the snapshots cover.
    pub seq: u64,
    /// New or changed snapshots (id, encoded entry).
    pub snapshots: &'a [(String, Vec<u8>)],
    /// The ids whose snapshots are deleted.
    pub removed: &'a [String],
}

/// What [`Store::scan`] calls with each commit group: its log position and bytes.
pub type Visit<'a> = dyn FnMut(u64, &[u8]) -> Result<(), StoreError> + 'a;

/// What [`Store::append_next`] calls once the position of the next commit group is known: the
/// encoded group for that position, or `None` to append nothing.
pub type Build<'a> = dyn FnMut(u64) -> Option<Vec<u8>> + 'a;

/// Durable storage of the log and the snapshots.
///
/// Methods block; the service calls them from its writer thread and from blocking tasks.
pub trait Store: Send + Sync {
    /// What and where the store is, for messages.
    fn describe(&self) -> String;

    /// The checkpoint, its snapshots and the last log position.
    ///
    /// # Errors
    /// The store cannot be read.
    fn recover(&self) -> Result<Recovered, StoreError>;

    /// Appends one commit group at position `seq`; returns once it is durable.
    ///
    /// # Errors
    /// The group may or may not be durable; the caller must stop writing.
    fn append(&self, seq: u64, group: &[u8]) -> Result<(), StoreError>;

    /// Records that the snapshots cover the log up to `checkpoint.seq`: writes its
    /// `snapshots`, deletes those of its `removed` ids, atomically.
    ///
    /// # Errors
    /// The store cannot be written; the previous checkpoint stays valid.
    fn checkpoint(&self, checkpoint: &Checkpoint<'_>) -> Result<(), StoreError>;

    /// Calls `visit` with every commit group from position `from` on, in order.
    ///
    /// # Errors
    /// The store cannot be read, or `visit` failed.
    fn scan(&self, from: u64, visit: &mut Visit<'_>) -> Result<(), StoreError>;

    /// Appends the next commit group after `known`, the last position this process has
    /// applied. A store that several processes share (a fleet, [`Store::is_shared`]) first
    /// takes its global append lock and calls `catch_up` with every group after `known` that
    /// others appended, in order; then `build` makes the group for the next free position,
    /// which is appended, all under the lock, so that every group is checked against the state
    /// every earlier group made. Returns the position written (`None` when `build` made
    /// nothing).
    ///
    /// The default, for a store one process owns, is [`Store::append`] at `known + 1`.
    ///
    /// # Errors
    /// As [`Store::append`]; or `catch_up` failed (nothing was appended).
    fn append_next(
        &self,
        known: u64,
        catch_up: &mut Visit<'_>,
        build: &mut Build<'_>,
    ) -> Result<Option<u64>, StoreError> {
        let _ = catch_up;
        match build(known + 1) {
            Some(group) => {
                self.append(known + 1, &group)?;
                Ok(Some(known + 1))
            }
            None => Ok(None),
        }
    }

    /// Whether other processes append to the same log (`chronomap serve --fleet`): the service
    /// then tails the log ([`crate::fleet`]).
    fn is_shared(&self) -> bool {
        false
    }

    /// The last position of the log as the store has it now, for a shared store; `None` for a
    /// store one process owns (its own position is the head).
    ///
    /// # Errors
    /// The store cannot be read.
    fn head(&self) -> Result<Option<u64>, StoreError> {
        Ok(None)
    }

    /// Folds the log into the snapshots: moves the whole segments of the live log that the
    /// checkpoint covers out of it (into an archive that [`Store::scan`] still reads), so that
    /// recovery reads only the rest. Returns the segments moved. The default, for a store that
    /// does not segment its log, moves nothing.
    ///
    /// # Errors
    /// The store cannot be written; nothing was moved.
    fn compact(&self) -> Result<u64, StoreError> {
        Ok(0)
    }

    /// Blocks until another process may have appended (a shared store's notification) or
    /// `timeout` has passed; a store one process owns just waits.
    fn wait_for_appends(&self, timeout: std::time::Duration) {
        std::thread::sleep(timeout);
    }
}

/// Encodes a model entry as a snapshot (versioned, CRC-32-checked container).
pub fn encode_snapshot(entry: &Entry) -> Vec<u8> {
    encode_model(SNAPSHOT_KIND, entry).expect("entries always serialise")
}

/// Decodes a snapshot.
///
/// # Errors
/// A damaged or foreign snapshot, naming the id.
pub fn decode_snapshot(id: &str, bytes: &[u8]) -> Result<Entry, String> {
    let (kind, entry): (String, Entry) =
        decode_model(bytes).map_err(|e| format!("snapshot of {id:?}: {e}"))?;
    if kind != SNAPSHOT_KIND {
        return Err(format!(
            "snapshot of {id:?}: a {kind:?} container, not a model snapshot"
        ));
    }
    if !entry.model.is_consistent() {
        return Err(format!("snapshot of {id:?}: inconsistent model parameters"));
    }
    Ok(entry)
}
