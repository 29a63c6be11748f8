//! The embedded default store: one redb file (ACID, copy-on-write B-trees, fsync on commit).

use std::path::{Path, PathBuf};

use redb::{Database, ReadOnlyDatabase, ReadableDatabase, ReadableTable, TableDefinition};

use super::{Checkpoint, Recovered, Store, StoreError, Visit};

const LOG: TableDefinition<u64, &[u8]> = TableDefinition::new("log");
const SNAPSHOTS: TableDefinition<&str, &[u8]> = TableDefinition::new("snapshots");
const META: TableDefinition<&str, u64> = TableDefinition::new("meta");
const CHECKPOINT: &str = "checkpoint";

/// The log and snapshots in one redb database file.
pub struct RedbStore {
    path: PathBuf,
    db: Db,
}

/// Why [`RedbStore::try_read_only`] did not open a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Unopened {
    /// It is no store (missing, empty, not a regular file, not a redb file).
    Refused,
    /// Another process (a running service) holds it.
    Held,
    /// It was not closed cleanly: redb must repair it before it can be read.
    Unclean,
    /// redb found it damaged, or stopped reading it.
    Damaged,
}

/// The database, opened to read and write (the service) or only to read (an export).
enum Db {
    Write(Database),
    Read(ReadOnlyDatabase),
}

impl Db {
    fn begin_read(&self) -> Result<redb::ReadTransaction, redb::TransactionError> {
        match self {
            Db::Write(db) => db.begin_read(),
            Db::Read(db) => db.begin_read(),
        }
    }
}

impl RedbStore {
    /// Opens (or creates, readable by its owner only on unix: mode 0600) the database at
    /// `path`.
    ///
    /// # Errors
    /// The file cannot be opened, is not a redb database, or another process holds it; a
    /// file redb finds corrupted says how to recover ([`crate::check::RECOVERY_HINT`]).
    pub fn open(path: impl AsRef<Path>) -> Result<Self, StoreError> {
        Self::open_with(path.as_ref(), false)
    }

    /// [`RedbStore::open`] with redb's page check on open: a file altered since redb wrote it
    /// is refused as damaged instead of read (where reading could make redb panic). The check
    /// reads the whole file and may write (repair, commit): `chronomap serve --check` runs it
    /// on a copy.
    pub(crate) fn open_checked(path: &Path) -> Result<Self, StoreError> {
        Self::open_with(path, true)
    }

    fn open_with(path: &Path, check: bool) -> Result<Self, StoreError> {
        let path = path.to_path_buf();
        let fail = |reason: String| StoreError {
            store: path.display().to_string(),
            reason,
        };
        let mut options = std::fs::OpenOptions::new();
        options.read(true).write(true).create(true).truncate(false);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
        options
            .open(&path)
            .map_err(|e| fail(format!("cannot open or create the file: {e}")))?;
        let created = guarded(&path, || {
            Ok(redb::Builder::new()
                .set_check_integrity_on_open(check)
                .create(&path))
        })?;
        let db = created.map_err(|e| match e {
            redb::DatabaseError::Storage(redb::StorageError::Corrupted(_)) => fail(format!(
                "the file is damaged and redb cannot repair it ({e}); nothing was changed.\n{}",
                crate::check::RECOVERY_HINT
            )),
            redb::DatabaseError::DatabaseAlreadyOpen => fail(e.to_string()),
            e => fail(format!(
                "{e} (if the file is damaged: {})",
                crate::check::RECOVERY_HINT
            )),
        })?;
        let store = RedbStore {
            path,
            db: Db::Write(db),
        };
        let txn = store
            .writable()?
            .begin_write()
            .map_err(|e| store.error(e))?;
        {
            txn.open_table(LOG).map_err(|e| store.error(e))?;
            txn.open_table(SNAPSHOTS).map_err(|e| store.error(e))?;
            txn.open_table(META).map_err(|e| store.error(e))?;
        }
        txn.commit().map_err(|e| store.error(e))?;
        Ok(store)
    }

    /// Opens the database at `path` to read it only: nothing is created, repaired or written
    /// (the file is opened read-only, so its bytes and times stay as they were, and a store on
    /// a read-only file system can be read).
    ///
    /// # Errors
    /// The file does not exist, is not a regular file, is empty, is not a redb database,
    /// another process holds it (redb's message says it is open), or it was not closed cleanly
    /// (redb would have to repair it, which takes writing: opening it with `chronomap serve`
    /// does).
    pub fn open_read_only(path: impl AsRef<Path>) -> Result<Self, StoreError> {
        Self::try_read_only(path.as_ref()).map_err(|(e, _)| e)
    }

    /// [`RedbStore::open_read_only`], saying with an error why it could not be opened.
    pub(crate) fn try_read_only(path: &Path) -> Result<Self, (StoreError, Unopened)> {
        let path = path.to_path_buf();
        let fail = |reason: String| StoreError {
            store: path.display().to_string(),
            reason,
        };
        let metadata = std::fs::metadata(&path).map_err(|e| {
            (
                fail(format!("cannot open the file: {e}")),
                Unopened::Refused,
            )
        })?;
        if !metadata.is_file() {
            return Err((
                fail(
                    "not a regular file: not a store (a store is made by `chronomap serve`)".into(),
                ),
                Unopened::Refused,
            ));
        }
        if metadata.len() == 0 {
            return Err((
                fail(
                    "the file is empty: not a store (a store is made by `chronomap serve`)".into(),
                ),
                Unopened::Refused,
            ));
        }
        let opened = guarded(&path, || Ok(ReadOnlyDatabase::open(&path)))
            .map_err(|e| (e, Unopened::Damaged))?;
        let db = opened.map_err(|e| match e {
            redb::DatabaseError::RepairAborted => (
                fail(format!(
                    "the store was not closed cleanly and redb must repair it before it can be \
                     read, which takes writing; start and stop `chronomap serve` on it once (it \
                     repairs the file), then read it again ({e})"
                )),
                Unopened::Unclean,
            ),
            redb::DatabaseError::DatabaseAlreadyOpen => (fail(e.to_string()), Unopened::Held),
            redb::DatabaseError::Storage(redb::StorageError::Corrupted(_)) => (
                fail(format!(
                    "the file is damaged ({e}); nothing was changed.\n{}",
                    crate::check::RECOVERY_HINT
                )),
                Unopened::Damaged,
            ),
            e => (
                fail(format!(
                    "{e} (if the file is damaged: {})",
                    crate::check::RECOVERY_HINT
                )),
                Unopened::Refused,
            ),
        })?;
        Ok(RedbStore {
            path,
            db: Db::Read(db),
        })
    }

    /// Checks every page checksum of the file (redb's own integrity check).
    ///
    /// # Errors
    /// The check fails and redb cannot repair the file, or the store was opened read-only.
    pub fn check_integrity(&mut self) -> Result<bool, StoreError> {
        let path = self.path.display().to_string();
        match &mut self.db {
            Db::Write(db) => db.check_integrity().map_err(|e| StoreError {
                store: path,
                reason: e.to_string(),
            }),
            Db::Read(_) => Err(StoreError {
                store: path,
                reason: "opened read-only: the integrity check may repair, which writes".into(),
            }),
        }
    }

    /// Runs `read` (redb reading the file), turning a panic of redb into an error naming the
    /// file. redb checks page checksums only when it repairs or checks a file it may write
    /// (`Builder::set_check_integrity_on_open` "does not apply to read-only opens"), and
    /// otherwise may panic on pages altered since it wrote them ("where a plain open may
    /// panic"): a read-only reader (an export, `--check`) has no other way to refuse such a
    /// file. The panic's message is kept for the error instead of printed.
    fn guarded<T>(&self, read: impl FnOnce() -> Result<T, StoreError>) -> Result<T, StoreError> {
        guarded(&self.path, read)
    }

    /// The database to write, or an error for a store opened read-only.
    fn writable(&self) -> Result<&Database, StoreError> {
        match &self.db {
            Db::Write(db) => Ok(db),
            Db::Read(_) => Err(self.error("opened read-only: nothing can be written")),
        }
    }

    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn error(&self, e: impl std::fmt::Display) -> StoreError {
        StoreError {
            store: self.path.display().to_string(),
            reason: e.to_string(),
        }
    }
}

impl Store for RedbStore {
    fn describe(&self) -> String {
        format!("redb {}", self.path.display())
    }

    fn recover(&self) -> Result<Recovered, StoreError> {
        self.guarded(|| self.recover_unguarded())
    }

    fn append(&self, seq: u64, group: &[u8]) -> Result<(), StoreError> {
        let txn = self.writable()?.begin_write().map_err(|e| self.error(e))?;
        {
            let mut log = txn.open_table(LOG).map_err(|e| self.error(e))?;
            log.insert(seq, group).map_err(|e| self.error(e))?;
        }
        txn.commit().map_err(|e| self.error(e))
    }

    fn checkpoint(&self, checkpoint: &Checkpoint<'_>) -> Result<(), StoreError> {
        let txn = self.writable()?.begin_write().map_err(|e| self.error(e))?;
        {
            let mut table = txn.open_table(SNAPSHOTS).map_err(|e| self.error(e))?;
            for (id, bytes) in checkpoint.snapshots {
                table
                    .insert(id.as_str(), bytes.as_slice())
                    .map_err(|e| self.error(e))?;
            }
            for id in checkpoint.removed {
                table.remove(id.as_str()).map_err(|e| self.error(e))?;
            }
            let mut meta = txn.open_table(META).map_err(|e| self.error(e))?;
            meta.insert(CHECKPOINT, checkpoint.seq)
                .map_err(|e| self.error(e))?;
        }
        txn.commit().map_err(|e| self.error(e))
    }

    fn scan(&self, from: u64, visit: &mut Visit<'_>) -> Result<(), StoreError> {
        let txn = self.guarded(|| self.db.begin_read().map_err(|e| self.error(e)))?;
        let log = self.guarded(|| txn.open_table(LOG).map_err(|e| self.error(e)))?;
        let mut rows = self.guarded(|| log.range(from..).map_err(|e| self.error(e)))?;
        // Only redb's steps are guarded: a panic of `visit` is not the file's.
        while let Some(row) = self.guarded(|| Ok(rows.next()))? {
            let (seq, bytes) = row.map_err(|e| self.error(e))?;
            visit(seq.value(), bytes.value())?;
        }
        Ok(())
    }
}

impl RedbStore {
    fn recover_unguarded(&self) -> Result<Recovered, StoreError> {
        let txn = self.db.begin_read().map_err(|e| self.error(e))?;
        let meta = txn.open_table(META).map_err(|e| self.error(e))?;
        let checkpoint = meta
            .get(CHECKPOINT)
            .map_err(|e| self.error(e))?
            .map_or(0, |v| v.value());
        let snapshots_table = txn.open_table(SNAPSHOTS).map_err(|e| self.error(e))?;
        let mut snapshots = Vec::new();
        for row in snapshots_table.iter().map_err(|e| self.error(e))? {
            let (id, bytes) = row.map_err(|e| self.error(e))?;
            snapshots.push((id.value().to_owned(), bytes.value().to_vec()));
        }
        let log = txn.open_table(LOG).map_err(|e| self.error(e))?;
        let last_seq = log
            .last()
            .map_err(|e| self.error(e))?
            .map_or(0, |(k, _)| k.value());
        Ok(Recovered {
            checkpoint,
            snapshots,
            last_seq,
            compacted: 0,
        })
    }
}

thread_local! {
    /// Whether this thread is inside [`guarded`], and the message of the panic it caught.
    static GUARD: std::cell::RefCell<Option<Option<String>>> = const { std::cell::RefCell::new(None) };
}

/// [`RedbStore::guarded`] for `path`. The process's panic hook is wrapped once: a panic on a
/// thread inside `guarded` is recorded for its error, any other goes to the previous hook.
fn guarded<T>(path: &Path, read: impl FnOnce() -> Result<T, StoreError>) -> Result<T, StoreError> {
    static HOOK: std::sync::Once = std::sync::Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let inside = GUARD.with(|g| {
                let mut g = g.borrow_mut();
                match g.as_mut() {
                    Some(message) => {
                        let payload = info
                            .payload()
                            .downcast_ref::<&str>()
                            .map(|s| (*s).to_owned())
                            .or_else(|| info.payload().downcast_ref::<String>().cloned())
                            .unwrap_or_default();
                        let at = info
                            .location()
                            .map(|l| {
                                // The source file within its crate, not where it was built.
                                let file =
                                    l.file().rsplit_once("/src/").map_or(l.file(), |(_, f)| f);
                                format!(" at {file}:{}", l.line())
                            })
                            .unwrap_or_default();
                        *message = Some(format!("{payload}{at}"));
                        true
                    }
                    None => false,
                }
            });
            if !inside {
                previous(info);
            }
        }));
    });
    let outer = GUARD.with(|g| g.borrow_mut().replace(None));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(read));
    let caught = GUARD.with(|g| std::mem::replace(&mut *g.borrow_mut(), outer));
    result.unwrap_or_else(|_| {
        let message = caught.flatten().unwrap_or_default();
        Err(StoreError {
            store: path.display().to_string(),
            reason: format!(
                "the file is damaged: redb stopped reading it ({message}); nothing was \
                 changed.\n{}",
                crate::check::RECOVERY_HINT
            ),
        })
    })
}
