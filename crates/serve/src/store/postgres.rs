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

use std::sync::Mutex;
use std::time::{Duration, Instant};

use tokio::runtime::Runtime;
use tokio_postgres::{Client, NoTls};

use super::{Checkpoint, Recovered, Store, StoreError, Visit};

/// How long [`PostgresStore::connect`] waits for another session to give up the schema.
const OWNER_WAIT: Duration = Duration::from_secs(15);

/// The log and snapshots in tables `log`, `snapshots` and `meta` of one schema.
pub struct PostgresStore {
    describe: String,
    schema: String,
    runtime: Runtime,
    client: Mutex<Client>,
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
        let describe = format!("postgres schema {schema}");
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
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .thread_name("chronomap-postgres")
            .enable_all()
            .build()
            .map_err(|e| error(e.to_string()))?;
        let client = runtime.block_on(async {
            let (client, connection) = tokio_postgres::connect(config, NoTls)
                .await
                .map_err(|e| error(format!("cannot connect: {e}")))?;
            tokio::spawn(async move {
                // The connection ends with an error when the server goes away; every later
                // query then fails and the writer stops.
                let _ = connection.await;
            });
            client
                .batch_execute(&format!(
                    "CREATE SCHEMA IF NOT EXISTS {schema};
                     CREATE TABLE IF NOT EXISTS {schema}.log (seq BIGINT PRIMARY KEY, grp BYTEA NOT NULL);
                     CREATE TABLE IF NOT EXISTS {schema}.snapshots (id TEXT PRIMARY KEY, bytes BYTEA NOT NULL);
                     CREATE TABLE IF NOT EXISTS {schema}.meta (key TEXT PRIMARY KEY, value BIGINT NOT NULL);"
                ))
                .await
                .map_err(|e| error(format!("cannot create tables: {e}")))?;
            let lock = format!("chronomap serve: {schema}");
            let start = Instant::now();
            loop {
                let owned: bool = client
                    .query_one(
                        "SELECT pg_try_advisory_lock(hashtextextended($1, 0))",
                        &[&lock],
                    )
                    .await
                    .map_err(|e| error(format!("cannot lock the schema: {e}")))?
                    .get(0);
                if owned {
                    break;
                }
                if start.elapsed() >= wait {
                    return Err(error(format!(
                        "another session (a running chronomap serve?) has held the schema for {:.1} s; \
                         one service per schema",
                        wait.as_secs_f64()
                    )));
                }
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
            Ok::<_, StoreError>(client)
        })?;
        Ok(PostgresStore {
            describe,
            schema: schema.to_owned(),
            runtime,
            client: Mutex::new(client),
        })
    }

    fn error(&self, e: impl std::fmt::Display) -> StoreError {
        StoreError {
            store: self.describe.clone(),
            reason: e.to_string(),
        }
    }

    fn seq_param(&self, seq: u64) -> Result<i64, StoreError> {
        i64::try_from(seq).map_err(|_| self.error(format!("log position {seq} exceeds BIGINT")))
    }
}

impl Store for PostgresStore {
    fn describe(&self) -> String {
        self.describe.clone()
    }

    fn recover(&self) -> Result<Recovered, StoreError> {
        let s = &self.schema;
        let mut client = self.client.lock().expect("postgres client lock");
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
            let last_seq = client
                .query_one(&format!("SELECT COALESCE(MAX(seq), 0) FROM {s}.log"), &[])
                .await
                .map_err(|e| self.error(e))?
                .get::<_, i64>(0) as u64;
            client.commit().await.map_err(|e| self.error(e))?;
            Ok(Recovered {
                checkpoint,
                snapshots,
                last_seq,
            })
        })
    }

    fn append(&self, seq: u64, group: &[u8]) -> Result<(), StoreError> {
        let seq = self.seq_param(seq)?;
        let client = self.client.lock().expect("postgres client lock");
        self.runtime.block_on(async {
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
        let seq = self.seq_param(checkpoint.seq)?;
        let s = &self.schema;
        let mut client = self.client.lock().expect("postgres client lock");
        self.runtime.block_on(async {
            let txn = client.transaction().await.map_err(|e| self.error(e))?;
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
            txn.execute(
                &format!(
                    "INSERT INTO {s}.meta (key, value) VALUES ('checkpoint', $1)
                     ON CONFLICT (key) DO UPDATE SET value = EXCLUDED.value"
                ),
                &[&seq],
            )
            .await
            .map_err(|e| self.error(e))?;
            txn.commit().await.map_err(|e| self.error(e))
        })
    }

    fn scan(&self, from: u64, visit: &mut Visit<'_>) -> Result<(), StoreError> {
        let from = self.seq_param(from)?;
        // Pages of groups, so that a long log is never held in memory at once.
        const PAGE: i64 = 256;
        let mut next = from;
        loop {
            let rows = {
                let client = self.client.lock().expect("postgres client lock");
                self.runtime.block_on(async {
                    client
                        .query(
                            &format!(
                                "SELECT seq, grp FROM {}.log WHERE seq >= $1 ORDER BY seq LIMIT $2",
                                self.schema
                            ),
                            &[&next, &PAGE],
                        )
                        .await
                        .map_err(|e| self.error(e))
                })?
            };
            let count = rows.len();
            for row in rows {
                let seq: i64 = row.get(0);
                let bytes: &[u8] = row.get(1);
                visit(seq as u64, bytes)?;
                next = seq + 1;
            }
            if (count as i64) < PAGE {
                return Ok(());
            }
        }
    }
}
