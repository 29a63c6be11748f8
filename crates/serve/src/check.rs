//! Verifying a store and salvaging what is intact in a damaged one.
//!
//! [`verify`] reads everything a store holds: every snapshot (decoded and checked), every log
//! entry from the first (its format, position and CRC-32, and its records), and replays the
//! entries after the checkpoint onto the snapshots. The service runs it at every start and
//! stops on any damage (a damaged entry behind the checkpoint would otherwise only show when
//! the observations of a model are exported); `chronomap serve --check` prints its report.
//!
//! [`salvage`] rebuilds a store from every intact log entry — the log holds every change since
//! the store was created, so the snapshots are not needed: entries are replayed from the first,
//! a record that no longer applies (its model was created by a lost entry, or its times
//! precede what the model has now) is dropped and reported by model, and the new store gets
//! the kept records, renumbered without gaps, and a snapshot of every model.
//!
//! [`check_store`] and [`salvage_store`] do either for a store where the flags of `chronomap
//! serve` name it (a redb file, or a PostgreSQL schema salvaged into a new one); [`open_reader`]
//! and [`scan_records`] read a store beside a running service (`chronomap export parquet`).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use chronomap_core::progress::Progress;

use crate::log::{LogRecord, decode_group, encode_group, ids_of_damaged};
use crate::registry::Registry;
use crate::startup::StoreLocation;
use crate::store::{Checkpoint, Store, StoreError, decode_snapshot, encode_snapshot};

/// At most this many problems are listed in a message (all are counted).
const LISTED: usize = 20;

/// What [`verify`] found.
#[derive(Debug, Default)]
pub struct Report {
    /// What and where the store is.
    pub store: String,
    /// The log position the snapshots cover.
    pub checkpoint: u64,
    /// Snapshots read.
    pub snapshots: usize,
    /// Log entries read.
    pub entries: u64,
    /// Last log position.
    pub last_seq: u64,
    /// Observations in the log.
    pub observations: u64,
    /// Every damaged snapshot or entry, one sentence each.
    pub damage: Vec<String>,
    /// What was found that is not damage (a file not closed cleanly), one sentence each.
    pub notes: Vec<String>,
}

impl Report {
    /// The report as lines for people (`chronomap serve --check`).
    pub fn text(&self, models: usize) -> String {
        let mut text = String::new();
        let _ = writeln!(text, "store: {}", self.store);
        for note in &self.notes {
            let _ = writeln!(text, "note: {note}");
        }
        let _ = writeln!(
            text,
            "log: {} entries ({} observations), last position {}; checkpoint at {}, {} snapshots; {models} models",
            self.entries, self.observations, self.last_seq, self.checkpoint, self.snapshots
        );
        if self.damage.is_empty() {
            let _ = writeln!(text, "ok: every snapshot and log entry is intact");
        } else {
            let _ = writeln!(text, "damaged: {} problems", self.damage.len());
            for line in self.damage.iter().take(LISTED) {
                let _ = writeln!(text, "  {line}");
            }
            if self.damage.len() > LISTED {
                let _ = writeln!(text, "  ... and {} more", self.damage.len() - LISTED);
            }
        }
        text
    }

    /// Why the service does not start, and what to do.
    pub fn failure(&self) -> String {
        let mut text = format!(
            "{}: the store is damaged ({} problems); nothing was changed:",
            self.store,
            self.damage.len()
        );
        for line in self.damage.iter().take(LISTED) {
            let _ = write!(text, "\n  {line}");
        }
        if self.damage.len() > LISTED {
            let _ = write!(text, "\n  ... and {} more", self.damage.len() - LISTED);
        }
        text.push('\n');
        text.push_str(RECOVERY_HINT);
        text
    }
}

/// What to do with a damaged store (the flags of `chronomap serve`).
pub const RECOVERY_HINT: &str = "To recover: `chronomap serve --check` (with the same --data and \
     --postgres flags) lists the damage; `chronomap serve --salvage` rebuilds the store from every \
     intact log entry and reports what was lost (the damaged redb file is kept beside it as \
     chronomap.redb.damaged-TIME; with --postgres the salvaged store is written to the schema \
     SCHEMA_salvaged). See docs/service.md, \"Security model\".";

/// A verified store: its models, last position and the report.
pub struct Verified {
    /// The models after the checkpoint's snapshots and the replay (complete only without damage).
    pub registry: Registry,
    /// Last log position.
    pub last_seq: u64,
    /// The ids the replay after the checkpoint touched: their snapshots are older than the
    /// models, so the next checkpoint must write (or delete) them.
    pub replayed: std::collections::BTreeSet<String>,
    /// What was found.
    pub report: Report,
}

/// Reads and checks everything `store` holds (see the module documentation).
///
/// # Errors
/// The store cannot be read at all (damage it can read past is in the report).
pub fn verify(store: &dyn Store) -> Result<Verified, StoreError> {
    let recovered = store.recover()?;
    let mut report = Report {
        store: store.describe(),
        checkpoint: recovered.checkpoint,
        snapshots: recovered.snapshots.len(),
        ..Report::default()
    };
    let mut registry = Registry::new();
    for (id, bytes) in &recovered.snapshots {
        match decode_snapshot(id, bytes) {
            Ok(entry) => registry.put(id.clone(), Some(entry)),
            Err(e) => report.damage.push(e),
        }
    }
    // Positions up to `compacted` were folded into the snapshots and live in the archive.
    let mut previous = recovered.compacted;
    let mut replaying = report.damage.is_empty();
    let mut replayed = std::collections::BTreeSet::new();
    let scanned = store.scan(recovered.compacted + 1, &mut |seq, bytes| {
        report.entries += 1;
        if seq != previous + 1 {
            report.damage.push(format!(
                "log entries {}..={} are missing",
                previous + 1,
                seq - 1
            ));
            replaying &= seq <= recovered.checkpoint;
        }
        previous = seq;
        match decode_group(seq, bytes) {
            Ok(records) => {
                report.observations += records.iter().map(|r| r.observations() as u64).sum::<u64>();
                if seq > recovered.checkpoint && replaying {
                    for record in &records {
                        replayed.insert(record.id().to_owned());
                        if let Err(e) = registry.apply(record) {
                            report.damage.push(format!(
                                "log entry {seq} cannot be replayed onto model {:?}: {e}",
                                record.id()
                            ));
                            replaying = false;
                            break;
                        }
                    }
                }
            }
            Err(e) => {
                report.damage.push(format!("{e}{}", naming(bytes)));
                replaying &= seq <= recovered.checkpoint;
            }
        }
        Ok(())
    });
    if let Err(e) = scanned {
        report.damage.push(format!(
            "the log cannot be read after position {previous}: {}",
            e.reason
        ));
    }
    report.last_seq = previous.max(recovered.last_seq);
    if report.last_seq < recovered.checkpoint {
        report.damage.push(format!(
            "the checkpoint covers position {} but the log ends at {}",
            recovered.checkpoint, report.last_seq
        ));
    }
    Ok(Verified {
        registry,
        last_seq: report.last_seq,
        replayed,
        report,
    })
}

/// Verifies the redb store file at `path` without writing to it or beside it (`chronomap serve
/// --check`): the file is opened read-only (holding redb's shared lock, so no service writes it
/// meanwhile) and copied to a private folder of the system's temporary directory, removed
/// afterwards; redb's page check, which may repair and so writes, runs on the copy, which is
/// then [`verify`]ed (the original, read-only, if the copy fails the page check). A file that
/// was not closed cleanly (redb must repair it before it can be read) is verified on the
/// repaired copy, with a note.
///
/// # Errors
/// The file is missing, empty, not a regular file or not a redb database, another process
/// holds it, or redb cannot open even the copy (damage it cannot repair: the reason says so).
pub fn verify_redb(path: &std::path::Path) -> Result<Verified, StoreError> {
    use crate::store::{RedbStore, Unopened};
    let (original, unclean, unreadable) = match RedbStore::try_read_only(path) {
        Ok(store) => (Some(store), false, None),
        Err((_, Unopened::Unclean)) => (None, true, None),
        Err((e, Unopened::Damaged)) => (None, false, Some(e)),
        Err((e, Unopened::Refused | Unopened::Held)) => return Err(e),
    };
    let first_line = |e: &StoreError| e.reason.lines().next().unwrap_or_default().to_owned();
    let fail = |reason: String| StoreError {
        store: path.display().to_string(),
        reason,
    };
    let scratch = Scratch::new().map_err(|e| {
        fail(format!(
            "cannot make a private folder in {} for redb's page check: {e}",
            std::env::temp_dir().display()
        ))
    })?;
    let copy = scratch.0.join("chronomap.redb");
    let mut damage = Vec::new();
    let copied = match std::fs::copy(path, &copy) {
        Ok(_) => match RedbStore::open_checked(&copy) {
            Ok(mut copied) => {
                match copied.check_integrity() {
                    Ok(true) => {}
                    Ok(false) => {
                        damage.push("redb found damaged pages (it can repair them)".into())
                    }
                    Err(e) => damage.push(format!("redb's page checksums fail: {}", e.reason)),
                }
                Some(copied)
            }
            Err(e) if unclean => return Err(fail(e.reason)),
            Err(e) => {
                damage.push(format!("redb's page checksums fail: {}", e.reason));
                None
            }
        },
        Err(e) if unclean => {
            return Err(fail(format!(
                "the store was not closed cleanly and cannot be copied to {} to be repaired \
                 there: {e}",
                scratch.0.display()
            )));
        }
        Err(e) => {
            damage.push(format!("cannot copy the file for redb's page check: {e}"));
            None
        }
    };
    // The copy passed redb's page check, so reading it cannot make redb panic on an altered
    // page; the original is read (guarded) only when the copy could not be opened.
    let store: Option<&dyn Store> = match (&copied, &original) {
        (Some(copied), _) => Some(copied),
        (None, Some(original)) => Some(original),
        (None, None) => None,
    };
    let unread = |reason: String| Verified {
        registry: Registry::new(),
        last_seq: 0,
        replayed: std::collections::BTreeSet::new(),
        report: Report {
            damage: vec![format!("the store cannot be read: {reason}")],
            ..Report::default()
        },
    };
    let mut verified = match store.map(verify) {
        Some(Ok(verified)) => verified,
        // The page check failed and redb cannot read the original either: that is the damage.
        Some(Err(e)) if copied.is_none() => unread(first_line(&e)),
        Some(Err(e)) => return Err(e),
        None => unread(unreadable.as_ref().map(first_line).unwrap_or_default()),
    };
    verified.report.store = format!("redb {}", path.display());
    if unclean {
        verified.report.notes.push(
            "the file was not closed cleanly: it was verified on a repaired copy (the file is \
             unchanged; `chronomap serve` repairs it when it starts)"
                .into(),
        );
    }
    verified.report.damage.extend(damage);
    Ok(verified)
}

/// A private folder (mode 0700 on unix) in the system's temporary directory, removed with
/// everything in it when dropped.
struct Scratch(std::path::PathBuf);

impl Scratch {
    fn new() -> std::io::Result<Self> {
        let nanos = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let dir =
            std::env::temp_dir().join(format!("chronomap-check-{}-{nanos}", std::process::id()));
        let mut builder = std::fs::DirBuilder::new();
        #[cfg(unix)]
        std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
        builder.create(&dir)?;
        Ok(Scratch(dir))
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// ` (it names the model "door")`, when a damaged entry still decodes.
fn naming(bytes: &[u8]) -> String {
    let ids = ids_of_damaged(bytes);
    if ids.is_empty() {
        return "; the models it changed cannot be read".into();
    }
    let list: Vec<String> = ids.iter().take(10).map(|id| format!("{id:?}")).collect();
    format!(
        "; it names the model{} {}{} (read despite the damage)",
        if ids.len() == 1 { "" } else { "s" },
        list.join(", "),
        if ids.len() > 10 { ", ..." } else { "" }
    )
}

/// The log entries a salvage reads: per position, the candidate entries (one from a readable
/// store; copies found in the raw bytes of a file may add others).
pub type Candidates = BTreeMap<u64, Vec<Vec<u8>>>;

/// What [`salvage`] kept and lost.
#[derive(Debug, Default)]
pub struct SalvageReport {
    /// Log entries written to the new store.
    pub entries: u64,
    /// Observations kept.
    pub observations: u64,
    /// Models in the new store.
    pub models: usize,
    /// Everything lost, one sentence each.
    pub lost: Vec<String>,
}

impl SalvageReport {
    /// The report as lines for people.
    pub fn text(&self) -> String {
        let mut text = format!(
            "kept: {} models, {} observations in {} log entries\n",
            self.models, self.observations, self.entries
        );
        if self.lost.is_empty() {
            text.push_str("lost: nothing\n");
        } else {
            let _ = writeln!(text, "lost ({}):", self.lost.len());
            for line in &self.lost {
                let _ = writeln!(text, "  {line}");
            }
        }
        text
    }
}

/// Replays every intact entry of `candidates` from the first and writes what applies to the
/// empty store `into` (see the module documentation).
///
/// # Errors
/// `into` cannot be written.
pub fn salvage(candidates: &Candidates, into: &dyn Store) -> Result<SalvageReport, StoreError> {
    let mut report = SalvageReport::default();
    let mut registry = Registry::new();
    let mut previous = 0;
    for (&seq, versions) in candidates {
        if seq == previous + 2 {
            report
                .lost
                .push(format!("log entry {}: no intact copy found", seq - 1));
        } else if seq != previous + 1 {
            report.lost.push(format!(
                "log entries {}..={}: no intact copy found",
                previous + 1,
                seq - 1
            ));
        }
        previous = seq;
        let intact: Vec<Vec<LogRecord>> = versions
            .iter()
            .filter_map(|bytes| decode_group(seq, bytes).ok())
            .collect();
        let Some(first) = intact.first() else {
            let bytes = versions.first().map_or(&[][..], Vec::as_slice);
            let reason = decode_group(seq, bytes)
                .err()
                .map_or_else(|| "damaged".into(), |e| e.to_string());
            report.lost.push(format!("{reason}{}", naming(bytes)));
            continue;
        };
        // Two different intact entries at one position: one was written by a transaction
        // that never committed. Keep the one that applies whole, else the first.
        let records = if intact.len() > 1 {
            let whole = intact.iter().find(|records| {
                let mut trial = registry.clone();
                records.iter().all(|r| trial.apply(r).is_ok())
            });
            report.lost.push(format!(
                "log entry {seq}: {} different intact copies; kept the one that applies",
                intact.len()
            ));
            whole.unwrap_or(first)
        } else {
            first
        };
        let mut kept = Vec::with_capacity(records.len());
        for record in records {
            match registry.apply(record) {
                Ok(()) => kept.push(record.clone()),
                Err(e) => report.lost.push(format!(
                    "log entry {seq}, model {:?}: dropped a {} ({e})",
                    record.id(),
                    describe(record)
                )),
            }
        }
        if !kept.is_empty() {
            report.entries += 1;
            report.observations += kept.iter().map(|r| r.observations() as u64).sum::<u64>();
            into.append(report.entries, &encode_group(report.entries, &kept))?;
        }
    }
    let snapshots: Vec<(String, Vec<u8>)> = registry
        .ids()
        .into_iter()
        .map(|id| {
            let entry = registry.get(id).expect("listed id");
            (id.to_owned(), encode_snapshot(entry))
        })
        .collect();
    into.checkpoint(&Checkpoint {
        seq: report.entries,
        snapshots: &snapshots,
        removed: &[],
    })?;
    report.models = registry.len();
    Ok(report)
}

fn describe(record: &LogRecord) -> String {
    match record {
        LogRecord::Create { .. } => "creation".into(),
        LogRecord::Observe { times, .. } => format!("batch of {} observations", times.len()),
        LogRecord::Remove { .. } => "removal".into(),
        LogRecord::Refit { refit, spread, .. } => format!(
            "refit on {} observations{}",
            refit.record.observations,
            if spread.is_some() {
                " (and of their second moment)"
            } else {
                ""
            }
        ),
    }
}

/// The candidates of a readable store: every entry its log holds.
///
/// # Errors
/// The log cannot be read from position `from` on; the entries read before are returned
/// with the error, so that the caller can look for the rest elsewhere.
pub fn candidates_of(store: &dyn Store) -> (Candidates, Option<StoreError>) {
    let mut candidates = Candidates::new();
    let scanned = store.scan(1, &mut |seq, bytes| {
        candidates.entry(seq).or_default().push(bytes.to_vec());
        Ok(())
    });
    (candidates, scanned.err())
}

/// Salvages the redb store file at `path` (see the module documentation): the entries come from
/// the file as redb reads it, and — where redb cannot open the file, cannot read its log to the
/// end, or an entry is damaged — from intact copies found in the raw bytes (format 2 entries
/// carry their position). The damaged file is renamed to `NAME.damaged-UNIXTIME` beside it and
/// the new store takes its place; returns the report and the kept file.
///
/// # Errors
/// The file cannot be read, or the new store cannot be written (the old file is then where
/// it was).
pub fn salvage_redb(
    path: &std::path::Path,
) -> Result<(SalvageReport, std::path::PathBuf), StoreError> {
    use crate::store::{RedbStore, Unopened};
    let fail = |reason: String| StoreError {
        store: path.display().to_string(),
        reason,
    };
    let metadata =
        std::fs::metadata(path).map_err(|e| fail(format!("cannot read the file: {e}")))?;
    if !metadata.is_file() || metadata.len() == 0 {
        return Err(fail(format!(
            "{}: not a store, nothing to salvage; nothing was changed",
            if metadata.is_file() {
                "the file is empty"
            } else {
                "not a regular file"
            }
        )));
    }
    let raw = std::fs::read(path).map_err(|e| fail(format!("cannot read the file: {e}")))?;
    let mut copies: Candidates = Candidates::new();
    for (seq, bytes) in crate::log::scan_raw(&raw) {
        let versions = copies.entry(seq).or_default();
        if !versions.contains(&bytes) {
            versions.push(bytes);
        }
    }
    drop(raw);
    let mut notes = Vec::new();
    // redb may repair the file it opens: it reads a copy, so that the damaged file is kept
    // exactly as it was; the file itself is held open read-only meanwhile (redb's shared lock)
    // when it can be, and never salvaged while a service holds it.
    let _held = match RedbStore::try_read_only(path) {
        Ok(store) => Some(store),
        Err((e, Unopened::Held)) => {
            return Err(fail(format!(
                "{}; stop the service that holds it before salvaging",
                e.reason
            )));
        }
        Err(_) => None,
    };
    let scratch = Scratch::new().map_err(|e| {
        fail(format!(
            "cannot make a private folder in {} to read a copy of the file: {e}",
            std::env::temp_dir().display()
        ))
    })?;
    let copy = scratch.0.join("chronomap.redb");
    std::fs::copy(path, &copy).map_err(|e| {
        fail(format!(
            "cannot copy the file to {} to read it: {e}",
            copy.display()
        ))
    })?;
    let (mut candidates, unread) = match RedbStore::open(&copy) {
        Ok(store) => candidates_of(&store),
        Err(_) if copies.is_empty() => {
            return Err(fail(
                "redb cannot open the file and no log entry was found in its bytes: not a \
                 chronomap store, or nothing of it is left; nothing was changed"
                    .into(),
            ));
        }
        Err(e) => (Candidates::new(), Some(e)),
    };
    for (seq, versions) in &mut candidates {
        if versions.iter().all(|b| decode_group(*seq, b).is_err())
            && let Some(others) = copies.get(seq)
        {
            versions.extend(others.iter().cloned());
        }
    }
    if let Some(e) = unread {
        let last = candidates.keys().last().copied().unwrap_or(0);
        let found: Vec<_> = copies.range(last + 1..).collect();
        notes.push(format!(
            "redb could not read the log past position {last} ({}); {} later positions were \
             found in the raw file (the last of them may be writes that never committed, so \
             were never acknowledged)",
            e.reason,
            found.len()
        ));
        for (seq, versions) in found {
            candidates.insert(*seq, versions.clone());
        }
    }
    let name = path
        .file_name()
        .map_or_else(|| "store".into(), |n| n.to_string_lossy().into_owned());
    let fresh = path.with_file_name(format!("{name}.salvage"));
    let _ = std::fs::remove_file(&fresh);
    let mut report = {
        let store = RedbStore::open(&fresh)?;
        salvage(&candidates, &store)?
    };
    let seconds = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let kept = path.with_file_name(format!("{name}.damaged-{seconds}"));
    std::fs::rename(path, &kept)
        .map_err(|e| fail(format!("cannot rename it to {}: {e}", kept.display())))?;
    std::fs::rename(&fresh, path).map_err(|e| {
        fail(format!(
            "cannot move the salvaged store {} into place: {e}",
            fresh.display()
        ))
    })?;
    notes.append(&mut report.lost);
    report.lost = notes;
    Ok((report, kept))
}

/// What `chronomap serve --check` found: the verified store, or a redb file that cannot be read.
pub enum StoreCheck {
    /// The store was read to its end (it may still be damaged: see [`StoreCheck::failure`]).
    Verified(Box<Verified>),
    /// redb cannot read the file.
    Unreadable {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

impl StoreCheck {
    /// The report as lines for people.
    pub fn text(&self) -> String {
        match self {
            StoreCheck::Verified(verified) => verified.report.text(verified.registry.len()),
            StoreCheck::Unreadable { path, reason } => {
                format!("store: redb {}\ncannot be read: {reason}\n", path.display())
            }
        }
    }

    /// Why the check fails (the command's error), `None` for an intact store.
    pub fn failure(&self) -> Option<String> {
        match self {
            StoreCheck::Verified(verified) if verified.report.damage.is_empty() => None,
            StoreCheck::Verified(verified) => Some(format!(
                "the store is damaged ({} problems); `chronomap serve --salvage` with the same \
                 flags rebuilds it from every intact log entry",
                verified.report.damage.len()
            )),
            StoreCheck::Unreadable { path, .. } => Some(format!(
                "{}: the store cannot be read; nothing was changed",
                path.display()
            )),
        }
    }
}

/// The redb file of `data`, which must exist to be checked or salvaged.
fn existing_redb(data: &Path) -> Result<PathBuf, StoreError> {
    let path = StoreLocation::redb_file(data);
    if !path.exists() {
        return Err(StoreError {
            store: path.display().to_string(),
            reason: "no store to check or salvage".into(),
        });
    }
    Ok(path)
}

/// Checks the store at `at` without writing anything (`chronomap serve --check`): a redb file
/// by [`verify_redb`], a PostgreSQL schema by [`verify`] under no lock (a schema without a
/// store is not created).
///
/// # Errors
/// There is no redb file, or the store cannot be opened or read at all.
pub fn check_store(at: &StoreLocation) -> Result<StoreCheck, StoreError> {
    Ok(match at {
        StoreLocation::Redb { data } => {
            let path = existing_redb(data)?;
            match verify_redb(&path) {
                Ok(verified) => StoreCheck::Verified(Box::new(verified)),
                Err(e) => StoreCheck::Unreadable {
                    path,
                    reason: e.reason,
                },
            }
        }
        #[cfg(feature = "postgres")]
        StoreLocation::Postgres { config, schema } => {
            let store = crate::store::PostgresStore::connect_checker(config, schema)?;
            StoreCheck::Verified(Box::new(verify(&store)?))
        }
    })
}

/// What a salvage kept and lost, and where the damaged store is.
#[derive(Debug)]
pub struct Salvaged {
    /// Kept and lost.
    pub report: SalvageReport,
    /// The damaged store, kept, and where the salvaged one is.
    pub kept: String,
}

impl Salvaged {
    /// The report as lines for people (`chronomap serve --salvage`).
    pub fn text(&self) -> String {
        format!(
            "{}\nthe damaged store is kept: {}\n",
            self.report.text().trim_end(),
            self.kept
        )
    }
}

/// Why a salvage did not happen.
#[derive(Debug, thiserror::Error)]
pub enum SalvageError {
    /// A store cannot be read or written.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// The schema a PostgreSQL store is salvaged into is not empty.
    #[error(
        "postgres schema {schema} already holds a store; drop it (DROP SCHEMA {schema} CASCADE) \
         or salvage into another --postgres-schema"
    )]
    Occupied {
        /// The schema.
        schema: String,
    },
}

/// Salvages the store at `at` (`chronomap serve --salvage`): a redb file by [`salvage_redb`],
/// which keeps the damaged file beside the new one; a PostgreSQL schema `S` into the new
/// schema `S_salvaged`, leaving `S` unchanged.
///
/// # Errors
/// There is no redb file; a store cannot be read or written; `S_salvaged` holds a store.
pub fn salvage_store(at: &StoreLocation) -> Result<Salvaged, SalvageError> {
    match at {
        StoreLocation::Redb { data } => {
            let (report, kept) = salvage_redb(&existing_redb(data)?)?;
            Ok(Salvaged {
                report,
                kept: kept.display().to_string(),
            })
        }
        #[cfg(feature = "postgres")]
        StoreLocation::Postgres { config, schema } => salvage_postgres(config, schema),
    }
}

/// Salvages the PostgreSQL store in `schema` into the schema `{schema}_salvaged`, which must
/// not hold a store: every entry the log holds, up to where it can be read.
///
/// # Errors
/// A store cannot be read or written; the target schema holds a store.
#[cfg(feature = "postgres")]
pub fn salvage_postgres(config: &str, schema: &str) -> Result<Salvaged, SalvageError> {
    use crate::store::PostgresStore;
    let source = PostgresStore::connect_checker(config, schema)?;
    let target = format!("{schema}_salvaged");
    let into = PostgresStore::connect(config, &target)?;
    let held = into.recover()?;
    if held.last_seq > 0 || !held.snapshots.is_empty() {
        return Err(SalvageError::Occupied { schema: target });
    }
    let (candidates, unread) = candidates_of(&source);
    let mut report = salvage(&candidates, &into)?;
    if let Some(e) = unread {
        report
            .lost
            .insert(0, format!("the log cannot be read to its end: {e}"));
    }
    Ok(Salvaged {
        report,
        kept: format!(
            "schema {schema} (unchanged); the salvaged store is the schema {target}: serve it \
             with --postgres-schema {target}"
        ),
    })
}

/// Opens the store at `at` to read it beside (never instead of) the service: the redb file,
/// which must exist, read-only (the service must not hold it: redb lets one process open a
/// file); a PostgreSQL schema without a lock.
///
/// # Errors
/// There is no redb file, another process holds it (the message says what to do), or the
/// store cannot be opened.
pub fn open_reader(at: &StoreLocation) -> Result<Box<dyn Store>, StoreError> {
    match at {
        #[cfg(feature = "postgres")]
        StoreLocation::Postgres { config, schema } => Ok(Box::new(
            crate::store::PostgresStore::connect_reader(config, schema)?,
        )),
        StoreLocation::Redb { data } => {
            let path = StoreLocation::redb_file(data);
            if !path.is_file() {
                return Err(StoreError {
                    store: path.display().to_string(),
                    reason: format!(
                        "no store (a `chronomap serve --data {}` keeps its models there)",
                        data.display()
                    ),
                });
            }
            crate::store::RedbStore::open_read_only(&path)
                .map(|store| Box::new(store) as Box<dyn Store>)
                .map_err(|e| in_use(e, data))
        }
    }
}

/// A redb open error, explained when another process (a running service) holds the file.
fn in_use(error: StoreError, data: &Path) -> StoreError {
    if error.reason.to_lowercase().contains("already open") {
        StoreError {
            reason: format!(
                "the store is in use ({}): is `chronomap serve --data {}` running? redb lets \
                 one process open the file; stop the service and export again, or keep the \
                 store in PostgreSQL (`serve --postgres`), which `export parquet --postgres` \
                 reads beside running services",
                error.reason,
                data.display()
            ),
            store: error.store,
        }
    } else {
        error
    }
}

/// A failure inside a scan, carried out of the store's callback (the store is named once the
/// scan has returned).
pub fn scan_failure(reason: String) -> StoreError {
    StoreError {
        store: String::new(),
        reason,
    }
}

/// What [`scan_records`] calls with each commit group: its position and records.
pub type VisitRecords<'a> = dyn FnMut(u64, &[LogRecord]) -> Result<(), StoreError> + 'a;

/// Calls `visit` with the decoded records of every commit group from position 1 to
/// `last_seq`, advancing `progress` by one per group; stops at `last_seq` (a shared store may
/// have grown since it was verified). A [`scan_failure`] of `visit` is reported naming the
/// store.
///
/// # Errors
/// The log cannot be read, an entry is missing or damaged, the log ends before `last_seq`, or
/// `visit` failed.
pub fn scan_records(
    store: &dyn Store,
    last_seq: u64,
    progress: &dyn Progress,
    visit: &mut VisitRecords<'_>,
) -> Result<(), StoreError> {
    let mut previous = 0;
    let mut stopped = false;
    let scanned = store.scan(1, &mut |seq, bytes| {
        if seq > last_seq {
            stopped = true;
            return Err(scan_failure(String::new()));
        }
        if seq != previous + 1 {
            return Err(scan_failure(format!(
                "log entries {}..={} are missing: the observations cannot be exported complete",
                previous + 1,
                seq - 1
            )));
        }
        previous = seq;
        let records = decode_group(seq, bytes).map_err(|e| scan_failure(e.to_string()))?;
        visit(seq, &records)?;
        progress.advance(1);
        Ok(())
    });
    match scanned {
        Err(_) if stopped => {}
        Ok(()) => {}
        Err(e) if e.store.is_empty() => {
            return Err(StoreError {
                store: store.describe(),
                reason: e.reason,
            });
        }
        Err(e) => return Err(e),
    }
    if previous < last_seq {
        return Err(StoreError {
            store: store.describe(),
            reason: format!(
                "the log ends at position {previous}, before {last_seq} where it ended when \
                 the export began"
            ),
        });
    }
    Ok(())
}

#[cfg(test)]
#[path = "check_tests.rs"]
mod tests;
