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
pub(crate) use redb_store::Unopened;

use chronomap_io::model_file::{decode_model, encode_model};
use chronomap_models::{AnyModel, Learner};

use crate::registry::{ConfigV1, Entry};

/// Kind tag of the snapshots of models with a calendar of days off (inside a versioned,
/// checksummed model-file container): version 4, an [`Entry`] whose configuration holds the
/// calendar, and the count of observations made on days off ([`Entry::skipped`]).
const SNAPSHOT_KIND: &str = "serve-snapshot-4";

/// Kind tag of version 3 snapshots, still written for models without a calendar (so that
/// their snapshots are those services before calendars wrote and read): an entry with the
/// learner of the second moment of a model of continuous values ([`Entry::spread`]), its
/// configuration a [`ConfigV1`].
const SNAPSHOT_KIND_3: &str = "serve-snapshot-3";

/// Kind tag of version 2 snapshots (still read): an entry whose model is a [`Learner`] (the
/// online model, or the kept observations and last fit of a model fitted on a whole series),
/// without the second moment. Its models of continuous values load without one: they have no
/// prediction intervals until they are created again.
const SNAPSHOT_KIND_2: &str = "serve-snapshot-2";

/// Kind tag of version 1 snapshots (still read): an entry whose model is an [`AnyModel`] that
/// learns online.
const SNAPSHOT_KIND_1: &str = "serve-snapshot";

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

/// Encodes a model entry as a snapshot (versioned, CRC-32-checked container): version 4 for a
/// model with a calendar of days off, version 3 for the others.
pub fn encode_snapshot(entry: &Entry) -> Vec<u8> {
    if entry.config.days_off.is_empty() && entry.skipped == 0 {
        let old = Entry3 {
            config: ConfigV1 {
                spec: entry.config.spec.clone(),
                range: entry.config.range,
            },
            model: &entry.model,
            spread: entry.spread.as_ref(),
        };
        return encode_model(SNAPSHOT_KIND_3, &old).expect("entries always serialise");
    }
    encode_model(SNAPSHOT_KIND, entry).expect("entries always serialise")
}

/// A version 1 snapshot.
#[derive(serde::Deserialize)]
struct Entry1 {
    config: ConfigV1,
    model: AnyModel,
}

/// A version 2 snapshot.
#[derive(serde::Deserialize)]
struct Entry2 {
    config: ConfigV1,
    model: Learner,
}

/// A version 3 snapshot (`M` is the learner, borrowed to write, owned to read).
#[derive(serde::Serialize, serde::Deserialize)]
struct Entry3<M> {
    config: ConfigV1,
    model: M,
    spread: Option<M>,
}

/// The kind a model-file container's header names (` kind=KIND ` in its first line), to choose
/// the type its payload is decoded as; the container itself is checked by [`decode_model`].
fn container_kind(bytes: &[u8]) -> Option<&str> {
    let line = bytes.get(..bytes.len().min(200))?;
    let line = &line[..line.iter().position(|&b| b == b'\n')?];
    std::str::from_utf8(line)
        .ok()?
        .split(' ')
        .find_map(|word| word.strip_prefix("kind="))
}

/// Decodes a snapshot (version 4 of a model with a calendar of days off; version 3 of one
/// without, and of services before calendars; version 2 of services before prediction intervals were
/// served, whose models of continuous values then have no learner of the second moment; or
/// version 1 of services before models fitted on a whole series were served).
///
/// # Errors
/// A damaged or foreign snapshot, naming the id.
pub fn decode_snapshot(id: &str, bytes: &[u8]) -> Result<Entry, String> {
    let damaged = |e: chronomap_io::ModelFileError| format!("snapshot of {id:?}: {e}");
    let (kind, entry): (String, Entry) = match container_kind(bytes) {
        Some(SNAPSHOT_KIND_1) => {
            let (kind, old): (String, Entry1) = decode_model(bytes).map_err(damaged)?;
            let entry = Entry {
                config: old.config.into(),
                model: Learner::Online(old.model),
                spread: None,
                skipped: 0,
            };
            (kind, entry)
        }
        Some(SNAPSHOT_KIND_2) => {
            let (kind, old): (String, Entry2) = decode_model(bytes).map_err(damaged)?;
            let entry = Entry {
                config: old.config.into(),
                model: old.model,
                spread: None,
                skipped: 0,
            };
            (kind, entry)
        }
        Some(SNAPSHOT_KIND_3) => {
            let (kind, old): (String, Entry3<Learner>) = decode_model(bytes).map_err(damaged)?;
            let entry = Entry {
                config: old.config.into(),
                model: old.model,
                spread: old.spread,
                skipped: 0,
            };
            (kind, entry)
        }
        _ => decode_model(bytes).map_err(damaged)?,
    };
    if ![
        SNAPSHOT_KIND,
        SNAPSHOT_KIND_3,
        SNAPSHOT_KIND_2,
        SNAPSHOT_KIND_1,
    ]
    .contains(&kind.as_str())
    {
        return Err(format!(
            "snapshot of {id:?}: a {kind:?} container, not a model snapshot"
        ));
    }
    if !entry.model.is_consistent() || entry.spread.as_ref().is_some_and(|s| !s.is_consistent()) {
        return Err(format!("snapshot of {id:?}: inconsistent model parameters"));
    }
    // A model of continuous values may lack one (restored from version 2 and snapshotted
    // again); a binary model, or one fitted on a whole series other than `auto`, never has
    // one, and it learns as the model does.
    if let Some(spread) = &entry.spread
        && (!entry.config.has_second_moment()
            || spread.is_refitting() != entry.model.is_refitting())
    {
        return Err(format!(
            "snapshot of {id:?}: a learner of the second moment for a model of binary states \
             or one fitted on a whole series other than `auto`"
        ));
    }
    Ok(entry)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registry::ModelConfig;
    use chronomap_core::TemporalModel;

    /// A configuration as snapshots before calendars wrote it.
    fn v1(config: &ModelConfig) -> ConfigV1 {
        assert!(config.days_off.is_empty());
        ConfigV1 {
            spec: config.spec.clone(),
            range: config.range,
        }
    }

    #[test]
    fn version_1_snapshots_still_load_as_online_learners() {
        // What services wrote before version 2: the entry with its model as an `AnyModel`.
        #[derive(serde::Serialize)]
        struct Version1<'a> {
            config: ConfigV1,
            model: &'a AnyModel,
        }
        let config = ModelConfig::parse(Some("fremen:2"), None).unwrap();
        let mut model = config.spec.online_model().unwrap();
        let times: Vec<f64> = (0..500).map(|i| 600.0 * f64::from(i)).collect();
        let values: Vec<f64> = times
            .iter()
            .map(|t| f64::from(u8::from(t % 86_400.0 > 30_000.0)))
            .collect();
        model.observe(&times, &values).unwrap();
        let old = encode_model(
            SNAPSHOT_KIND_1,
            &Version1 {
                config: v1(&config),
                model: &model,
            },
        )
        .unwrap();
        assert!(old.starts_with(b"chronomap-model 1 kind=serve-snapshot encoding=postcard "));
        let entry = decode_snapshot("door", &old).unwrap();
        assert_eq!(entry.config, config);
        assert!(matches!(entry.model, Learner::Online(_)));
        for t in [0.0, 4e4, 3e5, 1e6] {
            assert_eq!(entry.model.predict(t).to_bits(), model.predict(t).to_bits());
        }
        // Written again, it is version 2 and reads back the same.
        let new = encode_snapshot(&entry);
        assert!(new.starts_with(b"chronomap-model 1 kind=serve-snapshot-3 encoding=postcard "));
        let again = decode_snapshot("door", &new).unwrap();
        assert_eq!(encode_snapshot(&again), new);
        // Damage is still found, in both versions, naming the id.
        for mut bytes in [old, new] {
            *bytes.last_mut().unwrap() ^= 1;
            let error = decode_snapshot("door", &bytes).unwrap_err();
            assert!(
                error.starts_with("snapshot of \"door\": ") && error.contains("checksum"),
                "{error}"
            );
        }
        assert_eq!(
            container_kind(b"chronomap-model 1 kind=x encoding=postcard\n"),
            Some("x")
        );
        assert_eq!(container_kind(b"no header line"), None);
    }

    #[test]
    fn version_2_snapshots_load_without_a_second_moment_and_stay_so() {
        // What services wrote before prediction intervals: the entry without `spread`.
        #[derive(serde::Serialize)]
        struct Version2<'a> {
            config: ConfigV1,
            model: &'a Learner,
        }
        let config = ModelConfig::parse(Some("fremen:2"), Some([10.0, 30.0])).unwrap();
        let mut live = Entry::new(config.clone()).unwrap();
        let times: Vec<f64> = (0..500).map(|i| 600.0 * f64::from(i)).collect();
        let values: Vec<f64> = times
            .iter()
            .map(|t| 20.0 + 8.0 * (t / 86_400.0 * std::f64::consts::TAU).sin())
            .collect();
        live.observe("temp", &times, &values).unwrap();
        assert!(live.spread_with_order(None).is_some());
        let old = encode_model(
            SNAPSHOT_KIND_2,
            &Version2 {
                config: v1(&config),
                model: &live.model,
            },
        )
        .unwrap();
        assert!(old.starts_with(b"chronomap-model 1 kind=serve-snapshot-2 encoding=postcard "));
        let mut entry = decode_snapshot("temp", &old).unwrap();
        assert_eq!(entry.config, config);
        assert!(entry.spread.is_none() && entry.spread_with_order(None).is_none());
        for t in [0.0, 4e4, 3e5, 1e6] {
            assert_eq!(
                entry.model.predict(t).to_bits(),
                live.model.predict(t).to_bits()
            );
        }
        // It goes on learning its mean, still without intervals, and is written as version 3
        // without a second moment, which reads back the same.
        entry.observe("temp", &[4e5], &[25.0]).unwrap();
        assert!(entry.spread.is_none());
        let new = encode_snapshot(&entry);
        assert!(new.starts_with(b"chronomap-model 1 kind=serve-snapshot-3 encoding=postcard "));
        let again = decode_snapshot("temp", &new).unwrap();
        assert!(again.spread.is_none());
        assert_eq!(encode_snapshot(&again), new);
        // A version 3 snapshot keeps the second moment bit for bit.
        let with = encode_snapshot(&live);
        let back = decode_snapshot("temp", &with).unwrap();
        for t in [0.0, 4e4, 3e5] {
            assert_eq!(
                back.spread_with_order(None).unwrap().predict(t).to_bits(),
                live.spread_with_order(None).unwrap().predict(t).to_bits()
            );
        }
        // A binary model with a second moment is refused.
        let binary = Entry {
            config: ModelConfig::parse(Some("fremen:2"), None).unwrap(),
            ..live
        };
        let error = decode_snapshot("door", &encode_snapshot(&binary)).unwrap_err();
        assert!(error.contains("second moment"), "{error}");
    }
}
