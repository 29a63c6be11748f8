//! The PostgreSQL store: the same log and snapshots as tables of one schema, for labs that
//! already run a database server. Every commit group is one transaction, durable when
//! PostgreSQL acknowledges the commit (`synchronous_commit` as the server configures it).
//!
//! One service owns a schema at a time: [`PostgresStore::connect`] takes a session-level
//! advisory lock on it and waits (up to 15 s) while another session holds it. After
//! a crash this fences the dead process out: its database session may still be finishing a
//! statement it sent (a log append, a checkpoint), and PostgreSQL releases the lock only when
//! that session has ended, so the new service never reads a state that a late commit of the
//! old one changes afterwards. Recovery then reads the checkpoint, the snapshots and the end
//! of the log in one repeatable-read transaction, so they are one consistent state.
//!
//! A *fleet* ([`PostgresStore::connect_fleet`], `chronomap serve --fleet`) is several services
//! sharing one schema. Each holds the schema's advisory lock in shared mode (so no
//! single-owner service can open it meanwhile, nor a fleet node while one runs); appends take a
//! transaction-level advisory lock, read the groups other nodes appended since this node's last
//! position, and insert at the next position, so the log stays gap-free and in commit order;
//! each commit sends a `NOTIFY` on the schema's channel that wakes the other nodes' tailers
//! (`LISTEN` on a second connection). Checkpoints only move forward: a node whose snapshots are
//! older than the stored checkpoint writes nothing. Design and guarantee: docs/fleet.md.

use std::sync::atomic::{AtomicI64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::runtime::Runtime;
use tokio_postgres::{Client, NoTls};

use super::{Build, Checkpoint, Recovered, Store, StoreError, Visit};

/// How long [`PostgresStore::connect`] waits for another session to give up the schema.
pub const OWNER_WAIT: Duration = Duration::from_secs(15);

/// The log and snapshots in tables `log`, `snapshots` and `meta` of one schema.
pub struct PostgresStore {
    describe: String,
    schema: String,
    runtime: Runtime,
    client: Mutex<Client>,
    /// Set for a fleet node.
    fleet: Option<Fleet>,
    read_only: bool,
    /// The connection string, to reconnect.
    config: String,
    mode: Access,
    /// Commit groups per partition of `log` (`None`: a plain table made before partitioning).
    segment: Option<i64>,
    /// Whether the schema has `log_archive` (where compaction moves covered partitions).
    archive: bool,
    /// The highest partition index this process knows exists.
    segments_upto: AtomicI64,
}

/// How a schema's log is laid out.
struct Layout {
    segment: Option<i64>,
    archive: bool,
}

/// Reads the layout: whether `log` is partitioned (and by how many groups), whether
/// `log_archive` exists.
async fn layout(client: &Client, schema: &str) -> Result<Layout, tokio_postgres::Error> {
    let row = client
        .query_one(
            "SELECT (SELECT c.relkind::text FROM pg_class c JOIN pg_namespace n ON n.oid = c.relnamespace
                     WHERE n.nspname = $1 AND c.relname = 'log'),
                    to_regclass($2) IS NOT NULL",
            &[&schema, &format!("{schema}.log_archive")],
        )
        .await?;
    let partitioned = row.get::<_, Option<String>>(0).as_deref() == Some("p");
    let segment = if partitioned {
        client
            .query_opt(
                &format!("SELECT value FROM {schema}.meta WHERE key = 'segment'"),
                &[],
            )
            .await?
            .map(|row| row.get::<_, i64>(0))
            .filter(|&n| n > 0)
    } else {
        None
    };
    Ok(Layout {
        segment,
        archive: row.get(1),
    })
}

/// How a store holds its schema.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// One service, exclusively ([`PostgresStore::connect`]).
    Owner,
    /// One node of a fleet: shared lock, shared log ([`PostgresStore::connect_fleet`]).
    Fleet,
    /// A reader beside the writers: no lock, writes refused ([`PostgresStore::connect_reader`]).
    Reader,
}

/// Most commit groups read in one query.
const PAGE_GROUPS: i64 = 256;
/// Bytes of commit groups after which a page ends (the group that crosses it is the last).
const PAGE_BYTES: i64 = 64 << 20;

/// Commit groups per partition of the log in a new schema, by default.
pub const DEFAULT_SEGMENT_GROUPS: u64 = 100_000;

/// What a fleet node has besides the client: the connection that listens for other nodes'
/// appends.
struct Fleet {
    /// Kept open (reopened when it died): its connection's task wakes `appended` on every
    /// notification.
    listener: Mutex<Client>,
    appended: Arc<tokio::sync::Notify>,
}

impl PostgresStore {
    /// Connects (`config` as libpq's `key=value` string or a `postgresql://` URL), creates
    /// the schema and its tables if they do not exist, and takes the schema's advisory lock
    /// (see the module documentation).
    ///
    /// # Errors
    /// The server cannot be reached, refuses the login, the schema name is not a plain
    /// identifier (`[a-z_][a-z0-9_]*`, up to 63 bytes), or another session still holds the
    /// schema after 15 s (see [`PostgresStore::connect_waiting`] for another wait).
    pub fn connect(config: &str, schema: &str) -> Result<Self, StoreError> {
        Self::connect_waiting(config, schema, OWNER_WAIT)
    }

    /// [`PostgresStore::connect`], waiting at most `wait` for the schema's lock.
    ///
    /// # Errors
    /// As [`PostgresStore::connect`].
    pub fn connect_waiting(config: &str, schema: &str, wait: Duration) -> Result<Self, StoreError> {
        Self::open(config, schema, wait, Access::Owner)
    }

    /// Connects to read an existing store beside the services that write it (an export, a
    /// report): takes no lock and refuses to append or checkpoint. Reading is safe alongside
    /// writers because the log is append-only and [`Store::recover`] reads in one snapshot.
    ///
    /// # Errors
    /// The server cannot be reached, or the schema holds no chronomap store.
    pub fn connect_reader(config: &str, schema: &str) -> Result<Self, StoreError> {
        Self::open(config, schema, Duration::ZERO, Access::Reader)
    }

    /// Connects to check or salvage an existing store (`chronomap serve --check`,
    /// `--salvage`'s source): nothing is created or written, as with
    /// [`PostgresStore::connect_reader`], but the schema's advisory lock is held in shared mode,
    /// so that no single-owner service writes (or compacts) the store while it is read; nodes
    /// of a fleet, which hold it shared too, may.
    ///
    /// # Errors
    /// As [`PostgresStore::connect_reader`]; a single-owner service still holds the schema
    /// after 15 s.
    pub fn connect_checker(config: &str, schema: &str) -> Result<Self, StoreError> {
        let store = Self::connect_reader(config, schema)?;
        let lock = format!("chronomap serve: {schema}");
        let start = Instant::now();
        loop {
            let owned: bool = {
                let client = store.connection()?;
                store
                    .runtime
                    .block_on(client.query_one(
                        "SELECT pg_try_advisory_lock_shared(hashtextextended($1, 0))",
                        &[&lock],
                    ))
                    .map_err(|e| store.error(e))?
                    .get(0)
            };
            if owned {
                return Ok(store);
            }
            if start.elapsed() >= OWNER_WAIT {
                return Err(StoreError {
                    store: store.describe.clone(),
                    reason: format!(
                        "another session (a running chronomap serve?) has held the schema for \
                         {:.1} s; stop it to check the store",
                        OWNER_WAIT.as_secs_f64()
                    ),
                });
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Connects as one node of a fleet sharing the schema (see the module documentation):
    /// creates the tables if missing, takes the schema's advisory lock in shared mode and
    /// listens for the other nodes' appends.
    ///
    /// # Errors
    /// As [`PostgresStore::connect`]; a single-owner service holds the schema.
    pub fn connect_fleet(config: &str, schema: &str) -> Result<Self, StoreError> {
        Self::open(config, schema, OWNER_WAIT, Access::Fleet)
    }

    fn open(config: &str, schema: &str, wait: Duration, mode: Access) -> Result<Self, StoreError> {
        Self::connect_with(config, schema, mode, wait, DEFAULT_SEGMENT_GROUPS)
    }

    /// Connects with every choice explicit: how the schema is held, how long to wait for its
    /// lock, and the commit groups per partition of the log if the schema is new (an existing
    /// schema keeps its own; a schema made before partitioning keeps one plain log table and
    /// is never compacted).
    ///
    /// # Errors
    /// As [`PostgresStore::connect`]; `segment_groups` is 0.
    pub fn connect_with(
        config: &str,
        schema: &str,
        mode: Access,
        wait: Duration,
        segment_groups: u64,
    ) -> Result<Self, StoreError> {
        let fleet = mode == Access::Fleet;
        let describe = match mode {
            Access::Owner => format!("postgres schema {schema}"),
            Access::Fleet => format!("postgres schema {schema} (fleet)"),
            Access::Reader => format!("postgres schema {schema} (read-only)"),
        };
        let error = |reason: String| StoreError {
            store: describe.clone(),
            reason,
        };
        let plain = schema.len() <= 63
            && schema.starts_with(|c: char| c.is_ascii_lowercase() || c == '_')
            && schema
                .bytes()
                .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_');
        if !plain {
            return Err(error(format!(
                "schema name {schema:?} is not a plain identifier [a-z_][a-z0-9_]*"
            )));
        }
        let Some(segment_groups) = i64::try_from(segment_groups).ok().filter(|&n| n > 0) else {
            return Err(error(format!(
                "{segment_groups} commit groups per log partition: must be 1 to 2^63 - 1"
            )));
        };
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("chronomap-postgres")
            .enable_all()
            .build()
            .map_err(|e| error(e.to_string()))?;
        let client = runtime.block_on(async {
            let (client, connection) = tokio_postgres::connect(config, NoTls)
                .await
                .map_err(|e| error(format!("cannot connect: {}", db_message(&e))))?;
            tokio::spawn(async move {
                // The connection ends with an error when the server goes away; every later
                // query then fails and the writer stops.
                let _ = connection.await;
            });
            if mode == Access::Reader {
                let exists: bool = client
                    .query_one(
                        "SELECT to_regclass($1) IS NOT NULL AND to_regclass($2) IS NOT NULL",
                        &[&format!("{schema}.log"), &format!("{schema}.snapshots")],
                    )
                    .await
                    .map_err(|e| error(db_message(&e)))?
                    .get(0);
                if !exists {
                    return Err(error("holds no chronomap store (no tables log and snapshots)".into()));
                }
                let layout = layout(&client, schema).await.map_err(|e| error(db_message(&e)))?;
                return Ok((client, None, layout));
            }
            // Nodes of a fleet start at once: `IF NOT EXISTS` is not safe against a concurrent
            // creation, so creation is serialised by a transaction-level advisory lock.
            client
                .batch_execute(&format!(
                    "BEGIN;
                     SELECT pg_advisory_xact_lock(hashtextextended('chronomap serve: {schema}', 2));
                     CREATE SCHEMA IF NOT EXISTS {schema};
                     CREATE TABLE IF NOT EXISTS {schema}.log (seq BIGINT PRIMARY KEY, grp BYTEA NOT NULL)
                         PARTITION BY RANGE (seq);
                     CREATE TABLE IF NOT EXISTS {schema}.log_archive (seq BIGINT PRIMARY KEY, grp BYTEA NOT NULL)
                         PARTITION BY RANGE (seq);
                     CREATE TABLE IF NOT EXISTS {schema}.snapshots (id TEXT PRIMARY KEY, bytes BYTEA NOT NULL);
                     CREATE TABLE IF NOT EXISTS {schema}.meta (key TEXT PRIMARY KEY, value BIGINT NOT NULL);
                     INSERT INTO {schema}.meta (key, value) VALUES ('segment', {segment_groups})
                         ON CONFLICT (key) DO NOTHING;
                     COMMIT;"
                ))
                .await
                .map_err(|e| error(format!("cannot create tables: {}", db_message(&e))))?;
            let lock = format!("chronomap serve: {schema}");
            let start = Instant::now();
            let try_lock = if fleet {
                "SELECT pg_try_advisory_lock_shared(hashtextextended($1, 0))"
            } else {
                "SELECT pg_try_advisory_lock(hashtextextended($1, 0))"
            };
            loop {
                let owned: bool = client
                    .query_one(try_lock, &[&lock])
                    .await
                    .map_err(|e| error(format!("cannot lock the schema: {}", db_message(&e))))?
                    .get(0);
                if owned {
                    break;
                }
                if start.elapsed() >= wait {
                    return Err(error(if fleet {
                        format!(
                            "a single-owner service (chronomap serve without --fleet?) has held \
                             the schema for {:.1} s; stop it, or start every service on this \
                             schema with --fleet",
                            wait.as_secs_f64()
                        )
                    } else {
                        format!(
                            "another session (a running chronomap serve?) has held the schema \
                             for {:.1} s; one service per schema, or start every service on it \
                             with --fleet",
                            wait.as_secs_f64()
                        )
                    }));
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            let fleet = if fleet {
                let appended = Arc::new(tokio::sync::Notify::new());
                let listener = listen(config, schema, &appended).await.map_err(|e| {
                    error(format!("cannot listen for the other nodes' appends: {e}"))
                })?;
                Some(Fleet {
                    listener: Mutex::new(listener),
                    appended,
                })
            } else {
                None
            };
            let layout = layout(&client, schema).await.map_err(|e| error(db_message(&e)))?;
            Ok::<_, StoreError>((client, fleet, layout))
        })?;
        let (client, fleet, layout) = client;
        Ok(PostgresStore {
            describe,
            schema: schema.to_owned(),
            config: config.to_owned(),
            mode,
            runtime,
            client: Mutex::new(client),
            fleet,
            read_only: mode == Access::Reader,
            segment: layout.segment,
            archive: layout.archive,
            segments_upto: AtomicI64::new(-1),
        })
    }

    fn error(&self, e: tokio_postgres::Error) -> StoreError {
        StoreError {
            store: self.describe.clone(),
            reason: db_message(&e),
        }
    }

    /// The statements that make the partitions of `log` for position `seq` and the segment
    /// after it, if this process has not seen them yet; run them with the append.
    fn segment_ddl(&self, seq: i64) -> Option<(String, i64)> {
        let segment = self.segment?;
        let index = (seq - 1) / segment;
        if index < self.segments_upto.load(Ordering::Acquire) {
            return None;
        }
        let s = &self.schema;
        let ddl = (index..=index + 1)
            .map(|i| {
                let from = i.saturating_mul(segment).saturating_add(1);
                let to = from.saturating_add(segment);
                format!(
                    "CREATE TABLE IF NOT EXISTS {s}.log_{i} PARTITION OF {s}.log \
                     FOR VALUES FROM ({from}) TO ({to});"
                )
            })
            .collect();
        Some((ddl, index + 1))
    }

    /// The client, reconnected first if its connection died (a fleet node or a reader: the
    /// server restarted, or ended the session). A fleet node takes the schema's shared lock again;
    /// a single owner never reconnects, because another service may have taken the schema
    /// meanwhile — its store stays failed until it is restarted.
    fn connection(&self) -> Result<std::sync::MutexGuard<'_, Client>, StoreError> {
        let mut client = self.client.lock().expect("postgres client lock");
        if client.is_closed() && self.mode != Access::Owner {
            *client = self.runtime.block_on(self.reconnect())?;
        }
        if let Some(fleet) = &self.fleet {
            let mut listener = fleet.listener.lock().expect("postgres listener lock");
            if listener.is_closed() {
                // Without it the tailer still polls; try again at the next use if this fails.
                if let Ok(fresh) =
                    self.runtime
                        .block_on(listen(&self.config, &self.schema, &fleet.appended))
                {
                    *listener = fresh;
                }
            }
        }
        Ok(client)
    }

    async fn reconnect(&self) -> Result<Client, StoreError> {
        let (client, connection) =
            tokio_postgres::connect(&self.config, NoTls)
                .await
                .map_err(|e| StoreError {
                    store: self.describe.clone(),
                    reason: format!(
                        "the connection was lost and cannot be made again: {}",
                        db_message(&e)
                    ),
                })?;
        tokio::spawn(async move {
            let _ = connection.await;
        });
        if self.mode == Access::Fleet {
            let shared: bool = client
                .query_one(
                    "SELECT pg_try_advisory_lock_shared(hashtextextended($1, 0))",
                    &[&format!("chronomap serve: {}", self.schema)],
                )
                .await
                .map_err(|e| self.error(e))?
                .get(0);
            if !shared {
                return Err(StoreError {
                    store: self.describe.clone(),
                    reason: "reconnected, but a single-owner service now holds the schema".into(),
                });
            }
        }
        Ok(client)
    }

    /// Takes the fleet's append lock for the rest of `txn` (released by commit or rollback, and
    /// by the server when the session dies).
    async fn take_append_lock(
        &self,
        txn: &tokio_postgres::Transaction<'_>,
    ) -> Result<(), StoreError> {
        txn.execute(
            "SELECT pg_advisory_xact_lock(hashtextextended($1, 1))",
            &[&format!("chronomap serve: {}", self.schema)],
        )
        .await
        .map_err(|e| self.error(e))?;
        Ok(())
    }

    /// Sets `meta.key` to `value` within `txn`.
    async fn set_meta(
        &self,
        txn: &tokio_postgres::Transaction<'_>,
        key: &str,
        value: i64,
    ) -> Result<(), StoreError> {
        txn.execute(
            &format!(
                "INSERT INTO {}.meta (key, value) VALUES ($1, $2)
                 ON CONFLICT (key) DO UPDATE SET value = EXCLUDED.value",
                self.schema
            ),
            &[&key, &value],
        )
        .await
        .map_err(|e| self.error(e))?;
        Ok(())
    }

    /// The last position of the log and the last compacted one.
    fn head_query(&self) -> String {
        let s = &self.schema;
        format!(
            "SELECT GREATEST(COALESCE((SELECT MAX(seq) FROM {s}.log), 0), c.value), c.value
             FROM (SELECT COALESCE((SELECT value FROM {s}.meta WHERE key = 'compacted'), 0) AS value) AS c"
        )
    }

    /// One page of the log from position `$1`: at most `$2` groups, and only as many as start
    /// within the first `$3` bytes (at least one), so that a page of large groups stays
    /// bounded. `octet_length` reads the stored size without fetching the value.
    fn page_query(&self) -> String {
        format!(
            "SELECT seq, grp FROM (
                 SELECT seq, grp, sum(octet_length(grp)) OVER (ORDER BY seq) - octet_length(grp) AS before
                 FROM (SELECT seq, grp FROM {} WHERE seq >= $1 ORDER BY seq LIMIT $2) AS page
             ) AS sized
             WHERE before < $3
             ORDER BY seq",
            self.entries()
        )
    }

    /// The log as one relation: archive and live log, or the live log alone.
    fn entries(&self) -> String {
        let s = &self.schema;
        if self.archive {
            format!(
                "(SELECT seq, grp FROM {s}.log_archive UNION ALL SELECT seq, grp FROM {s}.log) AS entries"
            )
        } else {
            format!("{s}.log")
        }
    }

    fn writable(&self) -> Result<(), StoreError> {
        if self.read_only {
            return Err(StoreError {
                store: self.describe.clone(),
                reason: "opened read-only".into(),
            });
        }
        Ok(())
    }

    fn seq_param(&self, seq: u64) -> Result<i64, StoreError> {
        i64::try_from(seq).map_err(|_| StoreError {
            store: self.describe.clone(),
            reason: format!("log position {seq} exceeds BIGINT"),
        })
    }
}

/// The server's own message of a database error (tokio-postgres displays only "db error").
fn db_message(e: &tokio_postgres::Error) -> String {
    match (e.as_db_error(), std::error::Error::source(e)) {
        (Some(db), _) => format!("{e}: {}", db.message()),
        (None, Some(cause)) => format!("{e}: {cause}"),
        (None, None) => e.to_string(),
    }
}

/// A second connection that `LISTEN`s on the schema's channel; every notification (an append
/// by any node) wakes the returned [`Fleet::appended`].
async fn listen(
    config: &str,
    schema: &str,
    appended: &Arc<tokio::sync::Notify>,
) -> Result<Client, tokio_postgres::Error> {
    let (listener, mut connection) = tokio_postgres::connect(config, NoTls).await?;
    let wake = Arc::clone(appended);
    tokio::spawn(async move {
        // Drives the connection; ends when the server goes away (the tailer then polls).
        while let Some(Ok(message)) = std::future::poll_fn(|cx| connection.poll_message(cx)).await {
            if matches!(message, tokio_postgres::AsyncMessage::Notification(_)) {
                wake.notify_one();
            }
        }
    });
    listener.batch_execute(&format!("LISTEN {schema}")).await?;
    // A reconnected listener may have missed notifications: wake the tailer once.
    appended.notify_one();
    Ok(listener)
}

impl Store for PostgresStore {
    fn describe(&self) -> String {
        self.describe.clone()
    }

    fn recover(&self) -> Result<Recovered, StoreError> {
        let s = &self.schema;
        let mut client = self.connection()?;
        self.runtime.block_on(async {
            // One snapshot of the database for all three reads.
            let client = client
                .build_transaction()
                .isolation_level(tokio_postgres::IsolationLevel::RepeatableRead)
                .read_only(true)
                .start()
                .await
                .map_err(|e| self.error(e))?;
            let checkpoint = client
                .query_opt(
                    &format!("SELECT value FROM {s}.meta WHERE key = 'checkpoint'"),
                    &[],
                )
                .await
                .map_err(|e| self.error(e))?
                .map_or(0, |row| row.get::<_, i64>(0) as u64);
            let snapshots = client
                .query(&format!("SELECT id, bytes FROM {s}.snapshots"), &[])
                .await
                .map_err(|e| self.error(e))?
                .into_iter()
                .map(|row| (row.get::<_, String>(0), row.get::<_, Vec<u8>>(1)))
                .collect();
            let row = client
                .query_one(&self.head_query(), &[])
                .await
                .map_err(|e| self.error(e))?;
            let (last_seq, compacted) = (row.get::<_, i64>(0) as u64, row.get::<_, i64>(1) as u64);
            client.commit().await.map_err(|e| self.error(e))?;
            Ok(Recovered {
                checkpoint,
                snapshots,
                last_seq,
                compacted,
            })
        })
    }

    fn append(&self, seq: u64, group: &[u8]) -> Result<(), StoreError> {
        self.writable()?;
        let seq = self.seq_param(seq)?;
        let client = self.connection()?;
        self.runtime.block_on(async {
            if let Some((ddl, upto)) = self.segment_ddl(seq) {
                client
                    .batch_execute(&ddl)
                    .await
                    .map_err(|e| self.error(e))?;
                self.segments_upto.fetch_max(upto, Ordering::AcqRel);
            }
            client
                .execute(
                    &format!("INSERT INTO {}.log (seq, grp) VALUES ($1, $2)", self.schema),
                    &[&seq, &group],
                )
                .await
                .map_err(|e| self.error(e))?;
            Ok(())
        })
    }

    fn checkpoint(&self, checkpoint: &Checkpoint<'_>) -> Result<(), StoreError> {
        self.writable()?;
        let seq = self.seq_param(checkpoint.seq)?;
        let s = &self.schema;
        let mut client = self.connection()?;
        self.runtime.block_on(async {
            let txn = client.transaction().await.map_err(|e| self.error(e))?;
            if self.fleet.is_some() {
                // Checkpoints only move forward: another node may have written a later one.
                txn.execute(
                    &format!(
                        "INSERT INTO {s}.meta (key, value) VALUES ('checkpoint', 0)
                         ON CONFLICT (key) DO NOTHING"
                    ),
                    &[],
                )
                .await
                .map_err(|e| self.error(e))?;
                let current: i64 = txn
                    .query_one(
                        &format!("SELECT value FROM {s}.meta WHERE key = 'checkpoint' FOR UPDATE"),
                        &[],
                    )
                    .await
                    .map_err(|e| self.error(e))?
                    .get(0);
                if current >= seq {
                    return txn.rollback().await.map_err(|e| self.error(e));
                }
            }
            let upsert = txn
                .prepare(&format!(
                    "INSERT INTO {s}.snapshots (id, bytes) VALUES ($1, $2)
                     ON CONFLICT (id) DO UPDATE SET bytes = EXCLUDED.bytes"
                ))
                .await
                .map_err(|e| self.error(e))?;
            for (id, bytes) in checkpoint.snapshots {
                txn.execute(&upsert, &[id, bytes])
                    .await
                    .map_err(|e| self.error(e))?;
            }
            for id in checkpoint.removed {
                txn.execute(&format!("DELETE FROM {s}.snapshots WHERE id = $1"), &[id])
                    .await
                    .map_err(|e| self.error(e))?;
            }
            self.set_meta(&txn, "checkpoint", seq).await?;
            txn.commit().await.map_err(|e| self.error(e))
        })
    }

    fn scan(&self, from: u64, visit: &mut Visit<'_>) -> Result<(), StoreError> {
        let from = self.seq_param(from)?;
        // Bounded pages of groups, so that a long log is never held in memory at once.
        let mut next = from;
        loop {
            let rows = {
                let client = self.connection()?;
                self.runtime.block_on(async {
                    client
                        .query(&self.page_query(), &[&next, &PAGE_GROUPS, &PAGE_BYTES])
                        .await
                        .map_err(|e| self.error(e))
                })?
            };
            if rows.is_empty() {
                return Ok(());
            }
            for row in rows {
                let seq: i64 = row.get(0);
                let bytes: &[u8] = row.get(1);
                visit(seq as u64, bytes)?;
                next = seq + 1;
            }
        }
    }

    fn append_next(
        &self,
        known: u64,
        catch_up: &mut Visit<'_>,
        build: &mut Build<'_>,
    ) -> Result<Option<u64>, StoreError> {
        self.writable()?;
        if self.fleet.is_none() {
            let Some(group) = build(known + 1) else {
                return Ok(None);
            };
            self.append(known + 1, &group)?;
            return Ok(Some(known + 1));
        }
        let s = &self.schema;
        let mut client = self.connection()?;
        self.runtime.block_on(async {
            let txn = client.transaction().await.map_err(|e| self.error(e))?;
            // One appender at a time in the whole fleet; released by commit or rollback (and by
            // the server when a node dies mid-transaction).
            self.take_append_lock(&txn).await?;
            // What the others appended since `known` (also from the archive, for a node that
            // fell behind a compaction), in bounded pages.
            let mut last = self.seq_param(known)?;
            loop {
                let rows = txn
                    .query(
                        &self.page_query(),
                        &[&(last + 1), &PAGE_GROUPS, &PAGE_BYTES],
                    )
                    .await
                    .map_err(|e| self.error(e))?;
                if rows.is_empty() {
                    break;
                }
                for row in rows {
                    let seq: i64 = row.get(0);
                    catch_up(seq as u64, row.get(1))?;
                    last = seq;
                }
            }
            let next = last + 1;
            let Some(group) = build(next as u64) else {
                txn.rollback().await.map_err(|e| self.error(e))?;
                return Ok(None);
            };
            let segments = self.segment_ddl(next);
            if let Some((ddl, _)) = &segments {
                txn.batch_execute(ddl).await.map_err(|e| self.error(e))?;
            }
            txn.execute(
                &format!("INSERT INTO {s}.log (seq, grp) VALUES ($1, $2)"),
                &[&next, &group],
            )
            .await
            .map_err(|e| self.error(e))?;
            // Delivered at commit, to every node listening.
            txn.execute("SELECT pg_notify($1, $2)", &[s, &next.to_string()])
                .await
                .map_err(|e| self.error(e))?;
            txn.commit().await.map_err(|e| self.error(e))?;
            if let Some((_, upto)) = segments {
                self.segments_upto.fetch_max(upto, Ordering::AcqRel);
            }
            Ok(Some(next as u64))
        })
    }

    fn is_shared(&self) -> bool {
        self.fleet.is_some()
    }

    fn compact(&self) -> Result<u64, StoreError> {
        self.writable()?;
        let (Some(segment), true) = (self.segment, self.archive) else {
            return Ok(0);
        };
        let s = &self.schema;
        let mut client = self.connection()?;
        self.runtime.block_on(async {
            let txn = client.transaction().await.map_err(|e| self.error(e))?;
            if self.fleet.is_some() {
                // No append of another node between reading the checkpoint and moving.
                self.take_append_lock(&txn).await?;
            }
            let row = txn
                .query_one(
                    &format!(
                        "SELECT COALESCE((SELECT value FROM {s}.meta WHERE key = 'checkpoint'), 0),
                                COALESCE((SELECT value FROM {s}.meta WHERE key = 'compacted'), 0)"
                    ),
                    &[],
                )
                .await
                .map_err(|e| self.error(e))?;
            let (checkpoint, compacted): (i64, i64) = (row.get(0), row.get(1));
            let (mut upto, mut moved) = (compacted, 0);
            // Whole segments only: the next one starts right after `upto`.
            while let Some(to) = upto.checked_add(segment).filter(|&to| to <= checkpoint) {
                let index = upto / segment;
                let attached: bool = txn
                    .query_one(
                        "SELECT EXISTS (SELECT 1 FROM pg_inherits i
                           JOIN pg_class c ON c.oid = i.inhrelid
                           JOIN pg_class p ON p.oid = i.inhparent
                           JOIN pg_namespace n ON n.oid = p.relnamespace
                         WHERE n.nspname = $1 AND p.relname = 'log' AND c.relname = $2)",
                        &[s, &format!("log_{index}")],
                    )
                    .await
                    .map_err(|e| self.error(e))?
                    .get(0);
                if attached {
                    txn.batch_execute(&format!(
                        "ALTER TABLE {s}.log DETACH PARTITION {s}.log_{index};
                         ALTER TABLE {s}.log_archive ATTACH PARTITION {s}.log_{index}
                             FOR VALUES FROM ({}) TO ({});",
                        upto + 1,
                        to + 1
                    ))
                    .await
                    .map_err(|e| self.error(e))?;
                    moved += 1;
                }
                upto = to;
            }
            if upto > compacted {
                self.set_meta(&txn, "compacted", upto).await?;
            }
            txn.commit().await.map_err(|e| self.error(e))?;
            Ok(moved)
        })
    }

    fn head(&self) -> Result<Option<u64>, StoreError> {
        if self.fleet.is_none() {
            return Ok(None);
        }
        let client = self.connection()?;
        self.runtime.block_on(async {
            let head: i64 = client
                .query_one(&self.head_query(), &[])
                .await
                .map_err(|e| self.error(e))?
                .get(0);
            Ok(Some(head as u64))
        })
    }

    fn wait_for_appends(&self, timeout: Duration) {
        match &self.fleet {
            Some(fleet) => {
                let appended = Arc::clone(&fleet.appended);
                let _ = self
                    .runtime
                    .block_on(async { tokio::time::timeout(timeout, appended.notified()).await });
            }
            None => std::thread::sleep(timeout),
        }
    }
}
