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
        let path = path.as_ref().to_path_buf();
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
        let db = Database::create(&path).map_err(|e| match e {
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
    /// The file does not exist, is empty, is not a redb database, another process holds it
    /// (redb's message says it is open), or it was not closed cleanly (redb would have to
    /// repair it, which takes writing: opening it with `chronomap serve` does).
    pub fn open_read_only(path: impl AsRef<Path>) -> Result<Self, StoreError> {
        let path = path.as_ref().to_path_buf();
        let fail = |reason: String| StoreError {
            store: path.display().to_string(),
            reason,
        };
        let size = std::fs::metadata(&path)
            .map_err(|e| fail(format!("cannot open the file: {e}")))?
            .len();
        if size == 0 {
            return Err(fail(
                "the file is empty: not a store (a store is made by `chronomap serve`)".into(),
            ));
        }
        let db = ReadOnlyDatabase::open(&path).map_err(|e| match e {
            redb::DatabaseError::RepairAborted => fail(format!(
                "the store was not closed cleanly and redb must repair it before it can be \
                 read, which takes writing; start and stop `chronomap serve` on it once (it \
                 repairs the file), then read it again ({e})"
            )),
            redb::DatabaseError::DatabaseAlreadyOpen => fail(e.to_string()),
            e => fail(format!(
                "{e} (if the file is damaged: {})",
                crate::check::RECOVERY_HINT
            )),
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
        let txn = self.db.begin_read().map_err(|e| self.error(e))?;
        let log = txn.open_table(LOG).map_err(|e| self.error(e))?;
        for row in log.range(from..).map_err(|e| self.error(e))? {
            let (seq, bytes) = row.map_err(|e| self.error(e))?;
            visit(seq.value(), bytes.value())?;
        }
        Ok(())
    }
}
