//! The single writer: group commit of every change.
//!
//! Requests hand their writes to one thread. It takes every write waiting, checks each
//! request's writes on copies of the models they touch (a request is accepted whole or
//! rejected whole), appends the accepted ones as one commit group to the store, and only
//! once the store says the group is durable does it publish the new models and acknowledge
//! the requests. Readers therefore never see an observation that a crash could lose, and
//! the log order is the order the models saw their observations in, which is what recovery
//! replays.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, RwLock};
use std::time::{Duration, Instant};

use tokio::sync::{mpsc, oneshot};

use crate::log::{LogRecord, decode_group, encode_group};
use crate::registry::{ApplyError, Entry, ModelConfig, Registry, apply_to};
use crate::store::{Checkpoint, Store, StoreError, encode_snapshot};

/// One change a request asks for: a log record, and for observations of a model that may not
/// exist yet, the configuration to create it with.
#[derive(Clone, Debug)]
pub struct WriteOp {
    /// The change. A [`LogRecord::Create`] is no change if the model exists with the same
    /// configuration.
    pub record: LogRecord,
    /// With a [`LogRecord::Observe`]: configuration of the model to create if missing.
    pub create: Option<ModelConfig>,
}

impl WriteOp {
    /// Create a model (no change if it exists with the same configuration).
    pub fn create(id: String, config: ModelConfig) -> Self {
        WriteOp {
            record: LogRecord::Create { id, config },
            create: None,
        }
    }

    /// Add observations (values as given), creating the model with `create` if it does not
    /// exist.
    pub fn observe(
        id: String,
        times: Vec<f64>,
        values: Vec<f64>,
        create: Option<ModelConfig>,
    ) -> Self {
        WriteOp {
            record: LogRecord::Observe { id, times, values },
            create,
        }
    }

    /// Remove a model.
    pub fn remove(id: String) -> Self {
        WriteOp {
            record: LogRecord::Remove { id },
            create: None,
        }
    }

    /// Put a fit of a model's kept observations in place (and of their squares, for a model
    /// with a second moment).
    pub fn refit(
        id: String,
        refit: chronomap_models::learner::Refit,
        spread: Option<chronomap_models::learner::Refit>,
    ) -> Self {
        WriteOp {
            record: LogRecord::Refit {
                id,
                refit: Box::new(refit),
                spread: spread.map(Box::new),
            },
            create: None,
        }
    }
}

/// Why a write was not made.
#[derive(Clone, Debug)]
pub enum WriteError {
    /// The request is wrong (nothing was written).
    Apply(ApplyError),
    /// The store failed; the service accepts no more writes.
    Store(String),
}

/// A successful write.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Written {
    /// Observations added.
    pub observations: u64,
    /// Log position of the commit group.
    pub seq: u64,
}

/// Writes of one request and where to send the outcome.
pub struct WriteCommand {
    /// The writes, applied in order, all or none.
    pub ops: Vec<WriteOp>,
    /// Outcome.
    pub reply: oneshot::Sender<Result<Written, WriteError>>,
}

/// When the writer snapshots the models that changed.
#[derive(Clone, Copy, Debug)]
pub struct CheckpointPolicy {
    /// After this many observations since the last checkpoint.
    pub every_observations: u64,
    /// After this much time with changes since the last checkpoint.
    pub every: Duration,
}

impl Default for CheckpointPolicy {
    fn default() -> Self {
        CheckpointPolicy {
            every_observations: 1_000_000,
            every: Duration::from_secs(60),
        }
    }
}

/// State shared by the writer and the request handlers.
pub struct Shared {
    /// The published models (readers take the read lock).
    pub registry: RwLock<Registry>,
    /// The store.
    pub store: Arc<dyn Store>,
    /// Last durable log position applied to `registry` (changed only under its write lock).
    pub seq: AtomicU64,
    /// Models changed since the last checkpoint: by this service's writes and, in a fleet, by
    /// the groups other nodes appended. Locked after `registry`, never before.
    changes: Mutex<Changes>,
    /// Held by whoever applies log groups to `registry` (the writer; in a fleet also the
    /// tailer), so that each group is applied once and in order.
    pub(crate) applying: Mutex<()>,
    /// When this service last knew it had applied the whole log (see [`crate::fleet`]).
    pub(crate) synced: Mutex<Instant>,
    /// Why this service stopped applying the log, if it did (a group that cannot be applied).
    pub(crate) broken: Mutex<Option<String>>,
    /// The refit queue of a running service: the writer queues the models its commits made
    /// due (none in tools that only recover or check a store).
    pub(crate) refits: std::sync::OnceLock<Arc<crate::refit::Refits>>,
}

/// Models changed since the last checkpoint.
#[derive(Default)]
struct Changes {
    dirty: HashSet<String>,
    removed: HashSet<String>,
    observations: u64,
}

impl Changes {
    fn touched(&mut self, id: &str, exists: bool) {
        if exists {
            self.removed.remove(id);
            self.dirty.insert(id.to_owned());
        } else {
            self.dirty.remove(id);
            self.removed.insert(id.to_owned());
        }
    }
}

impl Shared {
    /// A service state holding `registry` at log position `seq`.
    pub fn new(store: Arc<dyn Store>, registry: Registry, seq: u64) -> Self {
        Shared {
            registry: RwLock::new(registry),
            store,
            seq: AtomicU64::new(seq),
            changes: Mutex::new(Changes::default()),
            applying: Mutex::new(()),
            synced: Mutex::new(Instant::now()),
            broken: Mutex::new(None),
            refits: std::sync::OnceLock::new(),
        }
    }

    /// Applies the commit group another node appended at `seq` (the next position after
    /// [`Shared::seq`]). Call with [`Shared::applying`] held.
    ///
    /// # Errors
    /// A gap before `seq`, a damaged group, or a record that cannot be applied: the registry
    /// may then hold part of the group, so [`Shared::broken`] is set and nothing is applied
    /// after it (the writer refuses writes, readers get the last state, health says `failed`).
    pub(crate) fn apply_logged(&self, seq: u64, bytes: &[u8]) -> Result<(), StoreError> {
        // Whatever goes wrong here, this node must not apply anything after it.
        let error = |reason: String| {
            *self.broken.lock().expect("broken lock") = Some(format!(
                "this node stopped applying the shared log: {reason}"
            ));
            StoreError {
                store: self.store.describe(),
                reason,
            }
        };
        if let Some(reason) = self.broken.lock().expect("broken lock").clone() {
            return Err(StoreError {
                store: self.store.describe(),
                reason,
            });
        }
        let known = self.seq.load(Ordering::Acquire);
        if seq <= known {
            return Ok(());
        }
        if seq != known + 1 {
            return Err(error(format!(
                "log entry {} is missing (the next entry is {seq})",
                known + 1
            )));
        }
        let records = decode_group(seq, bytes).map_err(|e| error(e.to_string()))?;
        let mut registry = self.registry.write().expect("registry lock");
        let mut changes = self.changes.lock().expect("changes lock");
        for record in &records {
            registry.apply(record).map_err(|e| {
                error(format!(
                    "log entry {seq} cannot be applied to model {:?}: {e}",
                    record.id()
                ))
            })?;
            changes.touched(record.id(), registry.get(record.id()).is_some());
        }
        changes.observations += records.iter().map(|r| r.observations() as u64).sum::<u64>();
        self.seq.store(seq, Ordering::Release);
        Ok(())
    }
}

/// Loads the last checkpoint and replays the log after it, having verified every snapshot
/// and every log entry ([`crate::check::verify`]).
///
/// # Errors
/// The store cannot be read, or a snapshot or log entry is damaged: the message names each
/// (and the models a damaged entry still names) and says how to recover.
pub fn recover(store: Arc<dyn Store>) -> Result<Shared, String> {
    let verified = crate::check::verify(&*store)
        .map_err(|e| format!("{e}\n{}", crate::check::RECOVERY_HINT))?;
    if !verified.report.damage.is_empty() {
        return Err(verified.report.failure());
    }
    let shared = Shared::new(store, verified.registry, verified.last_seq);
    {
        // The models the replay changed are newer than their snapshots: the next checkpoint,
        // which will claim to cover the replayed positions, must write them (without this, a
        // model changed only before a crash kept its older snapshot under a newer checkpoint,
        // and the recovery after the next crash replayed too little).
        let registry = shared.registry.read().expect("registry lock");
        let mut changes = shared.changes.lock().expect("changes lock");
        for id in &verified.replayed {
            changes.touched(id, registry.get(id).is_some());
        }
    }
    Ok(shared)
}

/// Every observation of `id` since it was last created, from the durable log.
///
/// # Errors
/// The store cannot be read or an entry is damaged.
pub fn observations_of(store: &dyn Store, id: &str) -> Result<(Vec<f64>, Vec<f64>), String> {
    let mut times = Vec::new();
    let mut values = Vec::new();
    store
        .scan(1, &mut |seq, bytes| {
            let records = decode_group(seq, bytes).map_err(|e| StoreError {
                store: store.describe(),
                reason: e.to_string(),
            })?;
            for record in records.iter().filter(|r| r.id() == id) {
                match record {
                    LogRecord::Observe {
                        times: t,
                        values: v,
                        ..
                    } => {
                        times.extend_from_slice(t);
                        values.extend_from_slice(v);
                    }
                    LogRecord::Create { .. } | LogRecord::Remove { .. } => {
                        times.clear();
                        values.clear();
                    }
                    LogRecord::Refit { .. } => {}
                }
            }
            Ok(())
        })
        .map_err(|e| e.to_string())?;
    Ok((times, values))
}

/// Most observations gathered into one commit group.
const MAX_GROUP_OBSERVATIONS: usize = 4_000_000;

/// Runs the writer until every sender is dropped, then writes a final checkpoint.
pub fn run(
    shared: Arc<Shared>,
    mut commands: mpsc::Receiver<WriteCommand>,
    policy: CheckpointPolicy,
) {
    let mut failed: Option<String> = None;
    let mut checkpoints = Checkpoints::new(policy);
    while let Some(first) = commands.blocking_recv() {
        let mut group = vec![first];
        let mut pending: usize = group[0].ops.iter().map(|op| op.record.observations()).sum();
        while pending < MAX_GROUP_OBSERVATIONS {
            match commands.try_recv() {
                Ok(command) => {
                    pending += command
                        .ops
                        .iter()
                        .map(|op| op.record.observations())
                        .sum::<usize>();
                    group.push(command);
                }
                Err(_) => break,
            }
        }
        if let Some(reason) = &failed {
            for command in group {
                let _ = command.reply.send(Err(WriteError::Store(reason.clone())));
            }
            continue;
        }
        if let Some(reason) = shared.broken.lock().expect("broken lock").clone() {
            for command in group {
                let _ = command.reply.send(Err(WriteError::Store(reason.clone())));
            }
            continue;
        }
        if let Err(reason) = commit_group(&shared, group)
            && !shared.store.is_shared()
        {
            // A shared log needs no stop: the next append reads the log from the last
            // position applied, so a group that did commit is applied then, once.
            failed = Some(reason);
        }
        checkpoints.maybe_write(&shared, false);
    }
    if failed.is_none() {
        checkpoints.maybe_write(&shared, true);
    }
}

/// Checks, commits and publishes one group; returns the store failure, if any.
fn commit_group(shared: &Shared, group: Vec<WriteCommand>) -> Result<(), String> {
    let _applying = shared.applying.lock().expect("applying lock");
    let mut staged: HashMap<String, Option<Entry>> = HashMap::new();
    let mut records: Vec<LogRecord> = Vec::new();
    let mut outcomes = Vec::with_capacity(group.len());
    let mut waiting = Some(group);
    let known = shared.seq.load(Ordering::Acquire);
    let appended = shared.store.append_next(
        known,
        &mut |seq, bytes| shared.apply_logged(seq, bytes),
        &mut |seq| {
            // Every group before `seq` is applied now: check the requests against them.
            let registry = shared.registry.read().expect("registry lock");
            for command in waiting.take().into_iter().flatten() {
                let mut scratch: HashMap<String, Option<Entry>> = HashMap::new();
                let mut command_records = Vec::new();
                let result = stage(
                    command.ops,
                    &registry,
                    &staged,
                    &mut scratch,
                    &mut command_records,
                );
                match result {
                    Ok(observations) => {
                        staged.extend(scratch);
                        records.append(&mut command_records);
                        outcomes.push((command.reply, Ok(observations)));
                    }
                    Err(e) => outcomes.push((command.reply, Err(e))),
                }
            }
            (!records.is_empty()).then(|| encode_group(seq, &records))
        },
    );
    let mut store_failure = None;
    let committed_seq = match appended {
        Ok(Some(seq)) => {
            let mut registry = shared.registry.write().expect("registry lock");
            let mut changes = shared.changes.lock().expect("changes lock");
            let ids: Vec<String> = staged.keys().cloned().collect();
            for (id, slot) in staged {
                changes.touched(&id, slot.is_some());
                registry.put(id, slot);
            }
            changes.observations += records.iter().map(|r| r.observations() as u64).sum::<u64>();
            shared.seq.store(seq, Ordering::Release);
            if let Some(refits) = shared.refits.get() {
                refits.schedule_due(&registry, ids.iter().map(String::as_str));
            }
            seq
        }
        Ok(None) => shared.seq.load(Ordering::Acquire),
        Err(e) => {
            let reason = if shared.store.is_shared() {
                format!(
                    "the store failed ({e}); the write may or may not be in the log: read the \
                     model before sending it again"
                )
            } else {
                format!("the store failed ({e}); writes are refused until the service is restarted")
            };
            store_failure = Some(reason);
            shared.seq.load(Ordering::Acquire)
        }
    };
    // Requests never checked (the store failed before): the store's error.
    for command in waiting.into_iter().flatten() {
        let reason = store_failure.clone().unwrap_or_default();
        let _ = command.reply.send(Err(WriteError::Store(reason)));
    }
    for (reply, outcome) in outcomes {
        let outcome = match (&store_failure, outcome) {
            (_, Err(e)) => Err(WriteError::Apply(e)),
            (Some(reason), Ok(_)) => Err(WriteError::Store(reason.clone())),
            (None, Ok(observations)) => Ok(Written {
                observations,
                seq: committed_seq,
            }),
        };
        let _ = reply.send(outcome);
    }
    store_failure.map_or(Ok(()), Err)
}

/// Turns a request's ops into records, applying them to copies of the models.
fn stage(
    ops: Vec<WriteOp>,
    registry: &Registry,
    staged: &HashMap<String, Option<Entry>>,
    scratch: &mut HashMap<String, Option<Entry>>,
    records: &mut Vec<LogRecord>,
) -> Result<u64, ApplyError> {
    let mut observations = 0;
    for WriteOp { record, create } in ops {
        let id = record.id().to_owned();
        let slot = scratch
            .entry(id.clone())
            .or_insert_with(|| match staged.get(&id) {
                Some(slot) => slot.clone(),
                None => registry.get(&id).cloned(),
            });
        let mut push = |record: LogRecord, slot: &mut Option<Entry>| {
            apply_to(slot, &record)?;
            records.push(record);
            Ok::<(), ApplyError>(())
        };
        match &record {
            LogRecord::Create { config, .. } => {
                if slot.as_ref().is_some_and(|e| e.config == *config) {
                    continue;
                }
            }
            LogRecord::Observe { .. } => {
                if slot.is_none()
                    && let Some(config) = create
                {
                    push(LogRecord::Create { id, config }, slot)?;
                }
            }
            LogRecord::Remove { .. } | LogRecord::Refit { .. } => {}
        }
        observations += record.observations() as u64;
        push(record, slot)?;
    }
    Ok(observations)
}

/// When to write the next checkpoint.
struct Checkpoints {
    policy: CheckpointPolicy,
    last: Instant,
}

impl Checkpoints {
    fn new(policy: CheckpointPolicy) -> Self {
        Checkpoints {
            policy,
            last: Instant::now(),
        }
    }

    /// Snapshots every changed model if the policy (or `force`) says so.
    fn maybe_write(&mut self, shared: &Shared, force: bool) {
        let (seq, snapshots, taken) = {
            let registry = shared.registry.read().expect("registry lock");
            let mut changes = shared.changes.lock().expect("changes lock");
            let changed = !changes.dirty.is_empty() || !changes.removed.is_empty();
            let due = changes.observations >= self.policy.every_observations
                || self.last.elapsed() >= self.policy.every;
            if !changed || !(due || force) {
                return;
            }
            let taken = std::mem::take(&mut *changes);
            let snapshots: Vec<(String, Vec<u8>)> = taken
                .dirty
                .iter()
                .filter_map(|id| registry.get(id).map(|e| (id.clone(), encode_snapshot(e))))
                .collect();
            (shared.seq.load(Ordering::Acquire), snapshots, taken)
        };
        let removed: Vec<String> = taken.removed.iter().cloned().collect();
        let checkpoint = Checkpoint {
            seq,
            snapshots: &snapshots,
            removed: &removed,
        };
        match shared.store.checkpoint(&checkpoint) {
            Ok(()) => {
                self.last = Instant::now();
                // The log the checkpoint covers is no longer needed for recovery.
                if let Err(e) = shared.store.compact() {
                    eprintln!("warning: compaction after log position {seq} failed: {e}");
                }
            }
            Err(e) => {
                // The log still holds everything; the next checkpoint tries again.
                eprintln!("warning: checkpoint at log position {seq} failed: {e}");
                let mut changes = shared.changes.lock().expect("changes lock");
                for id in taken.dirty {
                    if !changes.removed.contains(&id) {
                        changes.dirty.insert(id);
                    }
                }
                for id in taken.removed {
                    if !changes.dirty.contains(&id) {
                        changes.removed.insert(id);
                    }
                }
                changes.observations += taken.observations;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::store::RedbStore;
    use chronomap_core::TemporalModel;

    fn scratch(name: &str) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(format!("chronomap-writer-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn config(spec: &str) -> ModelConfig {
        ModelConfig::parse(Some(spec), None).unwrap()
    }

    fn observe(id: &str, t0: f64, n: usize) -> WriteOp {
        let times: Vec<f64> = (0..n).map(|k| t0 + k as f64 * 600.0).collect();
        let values = times
            .iter()
            .map(|t| f64::from(u8::from((t % 86_400.0) > 30_000.0)))
            .collect();
        WriteOp::observe(id.into(), times, values, Some(config("fremen:2")))
    }

    /// Runs a writer over `store`, sends every request of `requests` as one channel burst
    /// (so that they share commit groups), returns the outcomes and the registry.
    fn run_writer(
        store: Arc<dyn Store>,
        requests: Vec<Vec<WriteOp>>,
        policy: CheckpointPolicy,
    ) -> (Vec<Result<Written, WriteError>>, Arc<Shared>) {
        let shared = Arc::new(recover(store).unwrap());
        let (sender, receiver) = mpsc::channel(1024);
        let mut replies = Vec::new();
        for ops in requests {
            let (reply, outcome) = oneshot::channel();
            sender.try_send(WriteCommand { ops, reply }).unwrap();
            replies.push(outcome);
        }
        drop(sender);
        let writer_shared = Arc::clone(&shared);
        std::thread::spawn(move || run(writer_shared, receiver, policy))
            .join()
            .unwrap();
        let outcomes = replies
            .into_iter()
            .map(|r| r.blocking_recv().unwrap())
            .collect();
        (outcomes, shared)
    }

    fn models(shared: &Shared) -> Vec<(String, Vec<u8>)> {
        let registry = shared.registry.read().unwrap();
        registry
            .ids()
            .into_iter()
            .map(|id| (id.to_owned(), encode_snapshot(registry.get(id).unwrap())))
            .collect()
    }

    #[test]
    fn a_request_is_accepted_whole_or_rejected_whole() {
        let dir = scratch("atomic");
        let store: Arc<dyn Store> = Arc::new(RedbStore::open(dir.join("db")).unwrap());
        let requests = vec![
            vec![observe("a", 0.0, 10)],
            // Valid for "b", then a time before a's last one: nothing of it may stay.
            vec![observe("b", 0.0, 5), observe("a", 100.0, 3)],
            vec![observe("b", 0.0, 7)],
            vec![WriteOp::remove("nope".into())],
        ];
        let (outcomes, shared) =
            run_writer(Arc::clone(&store), requests, CheckpointPolicy::default());
        assert_eq!(outcomes[0].as_ref().unwrap().observations, 10);
        assert!(matches!(
            &outcomes[1],
            Err(WriteError::Apply(ApplyError::Observation(id, _))) if id == "a"
        ));
        assert_eq!(outcomes[2].as_ref().unwrap().observations, 7);
        assert!(matches!(
            &outcomes[3],
            Err(WriteError::Apply(ApplyError::NotFound(_)))
        ));
        let registry = shared.registry.read().unwrap();
        assert_eq!(registry.get("a").unwrap().model.span().count, 10);
        assert_eq!(registry.get("b").unwrap().model.span().count, 7);
        // All three accepted requests went into one commit group.
        assert_eq!(shared.seq.load(Ordering::Acquire), 1);
    }

    #[test]
    fn recovery_from_checkpoints_and_log_equals_the_live_models() {
        for (name, every) in [("checkpoint-at-exit-only", u64::MAX), ("checkpoints", 25)] {
            let dir = scratch(name);
            let store: Arc<dyn Store> = Arc::new(RedbStore::open(dir.join("db")).unwrap());
            let policy = CheckpointPolicy {
                every_observations: every,
                every: Duration::from_secs(3600),
            };
            let mut live = Vec::new();
            // Three runs of the writer over the same store, as three service lifetimes.
            for round in 0..3 {
                let t0 = round as f64 * 1e6;
                let requests = vec![
                    vec![observe("door", t0, 40)],
                    vec![
                        observe("lab", t0, 15),
                        observe("door", t0 + 40.0 * 600.0, 9),
                    ],
                    vec![WriteOp::remove("lab".into())],
                    vec![WriteOp::create("lab".into(), config("hist:24"))],
                    vec![observe("lab", t0 + 1.0, 30)],
                ];
                let (outcomes, shared) = run_writer(Arc::clone(&store), requests, policy);
                assert!(outcomes.iter().all(Result::is_ok), "{outcomes:?}");
                live = models(&shared);
            }
            let recovered = recover(Arc::clone(&store)).unwrap();
            assert_eq!(models(&recovered), live, "{name}");
            // The continuous times of "door" across lifetimes: 3 × 49 observations.
            let registry = recovered.registry.read().unwrap();
            assert_eq!(registry.get("door").unwrap().model.span().count, 147);
            assert_eq!(registry.get("lab").unwrap().config, config("hist:24"));
            drop(registry);
            let (times, _) = observations_of(&*store, "lab").unwrap();
            assert_eq!(times.len(), 30, "observations since the last create");
        }
    }

    #[test]
    fn models_replayed_after_a_crash_are_in_the_next_checkpoint() {
        let dir = scratch("replayed");
        let store: Arc<dyn Store> = Arc::new(RedbStore::open(dir.join("db")).unwrap());
        let every = CheckpointPolicy {
            every_observations: 1,
            every: Duration::from_secs(3600),
        };
        let (outcomes, _) = run_writer(
            Arc::clone(&store),
            vec![vec![observe("a", 0.0, 10)], vec![observe("b", 0.0, 10)]],
            every,
        );
        assert!(outcomes.iter().all(Result::is_ok));
        // A lifetime that committed a group for "a" and was killed before its checkpoint.
        let WriteOp { record, .. } = observe("a", 6_000.0, 10);
        store.append(2, &encode_group(2, &[record])).unwrap();
        // The next lifetime writes only "b" and checkpoints after it.
        let (outcomes, _) = run_writer(
            Arc::clone(&store),
            vec![vec![observe("b", 6_000.0, 5)]],
            every,
        );
        assert!(outcomes.iter().all(Result::is_ok));
        // The checkpoint now covers position 3: "a" must have been written with it.
        assert_eq!(store.recover().unwrap().checkpoint, 3);
        let recovered = recover(Arc::clone(&store)).unwrap();
        let registry = recovered.registry.read().unwrap();
        assert_eq!(registry.get("a").unwrap().model.span().count, 20);
        assert_eq!(registry.get("b").unwrap().model.span().count, 15);
    }

    /// Observations of a door open from 8:20 every day, every 10 minutes from `t0`, for a
    /// model created as `spec` if missing.
    fn observe_as(spec: &str, id: &str, t0: f64, n: usize) -> WriteOp {
        let WriteOp { record, .. } = observe(id, t0, n);
        WriteOp {
            record,
            create: Some(config(spec)),
        }
    }

    fn refit_of(shared: &Shared, id: &str) -> chronomap_models::learner::Refit {
        let job = shared
            .registry
            .read()
            .unwrap()
            .get(id)
            .unwrap()
            .model
            .refit_job()
            .unwrap();
        job.run(&crate::refit::fit_options()).unwrap()
    }

    #[test]
    fn refits_are_logged_and_recovery_installs_them_where_they_were() {
        let options = crate::refit::fit_options();
        for (name, every) in [("refit-replayed", u64::MAX), ("refit-snapshotted", 100)] {
            let dir = scratch(name);
            let store: Arc<dyn Store> = Arc::new(RedbStore::open(dir.join("db")).unwrap());
            let policy = CheckpointPolicy {
                every_observations: every,
                every: Duration::from_secs(3600),
            };
            // Two weeks of an `auto` and a `fremen:auto` model; the fits are made of them...
            let two_weeks = 2 * 7 * 144;
            let (outcomes, shared) = run_writer(
                Arc::clone(&store),
                vec![vec![
                    observe_as("auto", "door", 0.0, two_weeks),
                    observe_as("fremen:auto", "lab", 0.0, two_weeks),
                ]],
                policy,
            );
            assert!(outcomes.iter().all(Result::is_ok), "{outcomes:?}");
            let (door, lab) = (refit_of(&shared, "door"), refit_of(&shared, "lab"));
            // ... and put in place after more observations arrived (in the next lifetime).
            let t1 = two_weeks as f64 * 600.0;
            let (outcomes, shared) = run_writer(
                Arc::clone(&store),
                vec![
                    vec![observe_as("auto", "door", t1, 100)],
                    vec![WriteOp::refit("door".into(), door, None)],
                    vec![WriteOp::refit("lab".into(), lab.clone(), None)],
                    vec![observe_as("auto", "door", t1 + 100.0 * 600.0, 50)],
                ],
                policy,
            );
            assert!(outcomes.iter().all(Result::is_ok), "{outcomes:?}");
            let live = models(&shared);
            // The fit of the first two weeks, having learned the 150 later observations online.
            let all = match &observe_as("auto", "door", 0.0, two_weeks + 150).record {
                LogRecord::Observe { times, values, .. } => (times.clone(), values.clone()),
                _ => unreachable!(),
            };
            let mut expected = "auto"
                .parse::<chronomap_models::ModelSpec>()
                .unwrap()
                .fit(&all.0[..two_weeks], &all.1[..two_weeks], &options)
                .unwrap()
                .model;
            expected
                .observe(&all.0[two_weeks..], &all.1[two_weeks..])
                .unwrap();
            {
                let registry = shared.registry.read().unwrap();
                let door = &registry.get("door").unwrap().model;
                assert_eq!(
                    postcard::to_allocvec(door.model().unwrap()).unwrap(),
                    postcard::to_allocvec(&expected).unwrap(),
                    "{name}"
                );
                assert_eq!(door.last_fit().unwrap().through, two_weeks as u64);
                assert_eq!(door.span().count, two_weeks as u64 + 150);
            }
            let recovered = recover(Arc::clone(&store)).unwrap();
            assert_eq!(models(&recovered), live, "{name}");
            // A lifetime killed after committing observations and a refit, before any
            // checkpoint: recovery replays both and installs the logged fit.
            let records = [
                observe_as("auto", "door", t1 + 150.0 * 600.0, 10).record,
                LogRecord::Refit {
                    id: "door".into(),
                    refit: Box::new(refit_of(&shared, "door")),
                    spread: None,
                },
            ];
            let seq = shared.seq.load(Ordering::Acquire) + 1;
            store.append(seq, &encode_group(seq, &records)).unwrap();
            let mut registry = shared.registry.read().unwrap().clone();
            for record in &records {
                registry.apply(record).unwrap();
            }
            let live = Shared::new(Arc::clone(&store), registry, seq);
            let recovered = recover(Arc::clone(&store)).unwrap();
            assert_eq!(models(&recovered), models(&live), "{name}");
            {
                let registry = recovered.registry.read().unwrap();
                let door = &registry.get("door").unwrap().model;
                assert_eq!(door.last_fit().unwrap().through, two_weeks as u64 + 150);
                assert_eq!(door.since_fit().0, 10);
            }
            let shared = recovered;
            // The same fit again is accepted; a fit of another spec's model, or of a removed
            // model, is refused whole and not logged.
            let before = shared.seq.load(Ordering::Acquire);
            let stale = lab;
            let (outcomes, shared) = run_writer(
                Arc::clone(&store),
                vec![
                    vec![WriteOp::refit("lab".into(), stale.clone(), None)],
                    vec![WriteOp::refit("door".into(), stale.clone(), None)],
                    vec![WriteOp::remove("lab".into())],
                    vec![WriteOp::refit("lab".into(), stale, None)],
                ],
                policy,
            );
            assert!(outcomes[0].is_ok());
            assert!(
                matches!(&outcomes[1], Err(WriteError::Apply(ApplyError::Refit(id, _))) if id == "door"),
                "{:?}",
                outcomes[1]
            );
            assert!(matches!(
                &outcomes[3],
                Err(WriteError::Apply(ApplyError::NotFound(_)))
            ));
            assert_eq!(shared.seq.load(Ordering::Acquire), before + 1);
        }
    }

    #[test]
    fn damaged_snapshots_and_log_entries_stop_recovery_with_their_name() {
        let dir = scratch("damaged");
        let path = dir.join("db");
        {
            let store: Arc<dyn Store> = Arc::new(RedbStore::open(&path).unwrap());
            let (outcomes, _) = run_writer(
                Arc::clone(&store),
                vec![vec![observe("door", 0.0, 20)]],
                CheckpointPolicy::default(),
            );
            assert!(outcomes[0].is_ok());
            let mut snapshot = encode_snapshot(&Entry::new(config("fremen:2")).unwrap());
            *snapshot.last_mut().unwrap() ^= 0x40;
            let snapshots = [("door".into(), snapshot)];
            store
                .checkpoint(&Checkpoint {
                    seq: 0,
                    snapshots: &snapshots,
                    removed: &[],
                })
                .unwrap();
        }
        let store: Arc<dyn Store> = Arc::new(RedbStore::open(&path).unwrap());
        let error = recover(Arc::clone(&store)).err().unwrap();
        assert!(
            error.contains("snapshot of \"door\"") && error.contains("checksum"),
            "{error}"
        );
        store
            .checkpoint(&Checkpoint {
                seq: 0,
                snapshots: &[],
                removed: &["door".into()],
            })
            .unwrap();
        store.append(2, b"CMLOG\x001\nxxxx garbage").unwrap();
        let error = recover(store).err().unwrap();
        assert!(
            error.contains("log entry 2") && error.contains("checksum"),
            "{error}"
        );
    }
}
