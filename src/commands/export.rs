//! `chronomap export parquet`: a service store's observations and predictions as Parquet.
//!
//! The log is read twice, one commit group at a time, up to the position it had when the export
//! began (a PostgreSQL store may grow meanwhile): first to find where each exported model was
//! last created, then to write its observations since, in log order. Nothing is buffered per
//! model, so memory is one decoded group, one row group of the table being written (see
//! `chronomap_parquet`) and a map of the exported ids, however long the log.

use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result, bail};
use chronomap_core::TemporalModel;
use chronomap_core::progress::Progress;
use chronomap_parquet::{
    ObservationRow, ObservationsWriter, PendingFile, PredictionRow, PredictionsWriter,
};
use chronomap_serve::check;
use chronomap_serve::log::{LogRecord, decode_group};
use chronomap_serve::store::{PostgresStore, RedbStore, Store, StoreError};
use serde_json::json;

use crate::cli::ExportParquetArgs;
use crate::outln;
use crate::output::{ProgressBar, print_json, usage};

/// Most predictions (models × grid times) one export writes.
pub const MAX_PREDICTIONS: u64 = 100_000_000;

/// Rows handed to a table writer at once (and predictions computed at once per model).
const BATCH: usize = 1 << 16;

/// The prediction grid: `points` times from `from`, `step` apart.
#[derive(Clone, Copy, Debug)]
struct Grid {
    from: f64,
    to: f64,
    step: f64,
    points: u64,
}

impl Grid {
    fn new(from: f64, to: f64, step: f64) -> Result<Grid> {
        if to < from {
            return Err(usage(format!(
                "--to {to} is before --from {from}: the prediction grid is empty"
            )));
        }
        let steps = ((to - from) / step).floor();
        // Beyond 2^53 steps, grid times would no longer be distinct doubles.
        if !steps.is_finite() || steps >= 9.0e15 {
            return Err(usage(format!(
                "--from {from} --to {to} --step {step} makes {steps:e} times; at most \
                 {MAX_PREDICTIONS} predictions are written (raise --step or narrow --from/--to)"
            )));
        }
        // Grid times are Parquet timestamps in microseconds: checked before anything is read
        // or written.
        for (flag, t) in [("--from", from), ("--to", to)] {
            if chronomap_parquet::micros_of(t).is_none() {
                let t = if t.abs() < 1e16 {
                    t.to_string()
                } else {
                    format!("{t:e}")
                };
                return Err(usage(format!(
                    "{flag} {t}: a prediction time must be within about 292,000 years of \
                     1970 (a Parquet timestamp counts microseconds in 64 bits)"
                )));
            }
        }
        Ok(Grid {
            from,
            to,
            step,
            points: steps as u64 + 1,
        })
    }

    fn time(&self, k: u64) -> f64 {
        self.from + k as f64 * self.step
    }
}

/// `chronomap export parquet`.
pub fn parquet(args: &ExportParquetArgs) -> Result<()> {
    let started = Instant::now();
    let grid = match (args.from, args.to) {
        (Some(from), Some(to)) if !args.no_predictions => Some(Grid::new(from, to, args.step)?),
        _ => None,
    };
    let store = open_store(args)?;
    let verified = check::verify(&*store)?;
    if !verified.report.damage.is_empty() {
        bail!("{}", verified.report.failure());
    }
    let last_seq = verified.last_seq;
    let registry = verified.registry;
    let prefix = args.prefix.as_deref().unwrap_or("");
    let ids: Vec<&str> = registry
        .ids()
        .into_iter()
        .filter(|id| id.starts_with(prefix))
        .collect();
    if let Some(grid) = grid {
        let cells = grid.points.saturating_mul(ids.len() as u64);
        if cells > MAX_PREDICTIONS {
            return Err(usage(format!(
                "{} models × {} times is {cells} predictions; at most {MAX_PREDICTIONS} are \
                 written (raise --step, narrow --from/--to, choose models with --prefix, or \
                 --no-predictions)",
                ids.len(),
                grid.points
            )));
        }
    }

    // What this export creates is removed again if it fails: the folders it made (when still
    // empty) and its files (never committed; a stream written through keeps what it got).
    let created = create_dirs(&args.output)?;
    let written = write_tables(args, &*store, last_seq, &registry, &ids, grid, started);
    if written.is_err() {
        for dir in created.iter().rev() {
            let _ = std::fs::remove_dir(dir);
        }
    }
    written
}

/// Creates `dir` and its missing parents; returns those it created, outermost first.
fn create_dirs(dir: &Path) -> Result<Vec<std::path::PathBuf>> {
    let mut missing = Vec::new();
    let mut at = Some(dir);
    while let Some(d) = at.filter(|d| !d.as_os_str().is_empty()) {
        if std::fs::symlink_metadata(d).is_ok() {
            break;
        }
        missing.push(d.to_path_buf());
        at = d.parent();
    }
    missing.reverse();
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create the directory {}", dir.display()))?;
    if !dir.is_dir() {
        bail!(
            "{}: not a directory (-o names the folder of the tables)",
            dir.display()
        );
    }
    Ok(missing)
}

/// Writes the tables of the export into `args.output` and prints the summary.
fn write_tables(
    args: &ExportParquetArgs,
    store: &dyn Store,
    last_seq: u64,
    registry: &chronomap_serve::registry::Registry,
    ids: &[&str],
    grid: Option<Grid>,
    started: Instant,
) -> Result<()> {
    let prefix = args.prefix.as_deref().unwrap_or("");
    let observations_path = args.output.join("observations.parquet");
    let predictions_path = args.output.join("predictions.parquet");
    // Both files are refused before anything is read, when they exist and --force is not given.
    let observations_file = PendingFile::create(&observations_path, args.force)?;
    let predictions_file = grid
        .map(|_| PendingFile::create(&predictions_path, args.force))
        .transpose()?;
    let description = store.describe();
    let provenance = [
        ("chronomap.store", description.clone()),
        ("chronomap.last_seq", last_seq.to_string()),
        ("chronomap.prefix", prefix.to_owned()),
    ];

    // Pass 1: where each exported model was last created (log position, record index).
    let mut created: HashMap<&str, (u64, usize)> = HashMap::with_capacity(ids.len());
    let selected: std::collections::HashSet<&str> = ids.iter().copied().collect();
    let bar = ProgressBar::stage("reading the log", last_seq);
    scan_to(store, last_seq, &bar, &mut |seq, records| {
        for (i, record) in records.iter().enumerate() {
            if let LogRecord::Create { id, .. } = record
                && let Some(&id) = selected.get(id.as_str())
            {
                created.insert(id, (seq, i));
            }
        }
        Ok(())
    })?;
    drop(bar);
    if let Some(id) = ids.iter().find(|id| !created.contains_key(*id)) {
        bail!(
            "{description}: the log up to position {last_seq} never creates the model {id:?} \
             its snapshots hold: its observations cannot be exported"
        );
    }

    // Pass 2: the observations since then, in log order.
    let name = observations_path.display().to_string();
    let mut observations = ObservationsWriter::new(name, observations_file)?;
    for (key, value) in &provenance {
        observations.metadata(*key, value.clone());
    }
    let bar = ProgressBar::stage("observations", last_seq);
    scan_to(store, last_seq, &bar, &mut |seq, records| {
        // Borrows the group's ids: one buffer per group.
        let mut rows: Vec<ObservationRow> = Vec::new();
        for (i, record) in records.iter().enumerate() {
            let LogRecord::Observe { id, times, values } = record else {
                continue;
            };
            match created.get(id.as_str()) {
                Some(&since) if (seq, i) > since => {}
                _ => continue,
            }
            for (times, values) in times.chunks(BATCH).zip(values.chunks(BATCH)) {
                rows.clear();
                rows.extend(
                    times
                        .iter()
                        .zip(values)
                        .map(|(&time_s, &value)| ObservationRow {
                            model_id: id,
                            time_s,
                            value,
                            seq,
                        }),
                );
                observations
                    .write(&rows)
                    .map_err(|e| scan_failure(e.to_string()))?;
            }
        }
        Ok(())
    })?;
    drop(bar);
    let observation_rows = observations.rows();
    let observation_groups = observations.row_groups() + usize::from(observation_rows > 0);
    // Committed once the predictions are written too: a failure there leaves no table.
    let observations_file = observations.finish()?;

    let predictions = match (grid, predictions_file) {
        (Some(grid), Some(file)) => {
            let name = predictions_path.display().to_string();
            let mut writer = PredictionsWriter::new(name, file)?;
            for (key, value) in &provenance {
                writer.metadata(*key, value.clone());
            }
            let bar = ProgressBar::stage("predictions", grid.points * ids.len() as u64);
            let mut times = Vec::with_capacity(BATCH);
            let mut rows: Vec<PredictionRow> = Vec::with_capacity(BATCH);
            for &id in ids {
                let entry = registry.get(id).expect("the ids are the registry's");
                let mut k = 0;
                while k < grid.points {
                    let end = (k + BATCH as u64).min(grid.points);
                    times.clear();
                    times.extend((k..end).map(|k| grid.time(k)));
                    let probabilities = entry.model.predict_many(&times);
                    rows.clear();
                    rows.extend(times.iter().zip(&probabilities).map(|(&time_s, &p)| {
                        PredictionRow {
                            model_id: id,
                            time_s,
                            probability: p,
                            value: entry.config.range.map(|_| entry.config.scale(p)),
                        }
                    }));
                    writer.write(&rows)?;
                    bar.advance(end - k);
                    k = end;
                }
            }
            drop(bar);
            let rows = writer.rows();
            let groups = writer.row_groups() + usize::from(rows > 0);
            Some((grid, rows, groups, writer.finish()?))
        }
        _ => None,
    };
    let observations_stream = observations_file.is_stream();
    let observation_bytes = observations_file.commit()?;
    let predictions = match predictions {
        Some((grid, rows, groups, file)) => match file.commit() {
            Ok(bytes) => Some((grid, rows, groups, bytes)),
            Err(e) => {
                if !observations_stream {
                    let _ = std::fs::remove_file(&observations_path);
                }
                return Err(e.into());
            }
        },
        None => None,
    };

    let seconds = started.elapsed().as_secs_f64();
    let total_rows = observation_rows + predictions.map_or(0, |(_, rows, _, _)| rows);
    if args.json {
        return print_json(&json!({
            "store": description,
            "last_seq": last_seq,
            "models": ids.len(),
            "prefix": args.prefix,
            "observations": {
                "path": observations_path,
                "rows": observation_rows,
                "row_groups": observation_groups,
                "bytes": observation_bytes,
            },
            "predictions": predictions.map(|(grid, rows, groups, bytes)| json!({
                "path": predictions_path,
                "rows": rows,
                "row_groups": groups,
                "bytes": bytes,
                "from": grid.from,
                "to": grid.to,
                "step": grid.step,
                "times": grid.points,
            })),
            "seconds": seconds,
        }));
    }
    outln!(
        "store: {description}, log up to position {last_seq}; {} of {} models exported",
        ids.len(),
        registry.len()
    )?;
    outln!(
        "{}: {observation_rows} observations, {observation_groups} row groups, {observation_bytes} bytes",
        observations_path.display()
    )?;
    if let Some((grid, rows, _, bytes)) = predictions {
        outln!(
            "{}: {rows} predictions ({} models × {} times from {} to {} every {} s), {bytes} bytes",
            predictions_path.display(),
            ids.len(),
            grid.points,
            grid.from,
            grid.time(grid.points - 1),
            grid.step
        )?;
    }
    outln!(
        "{total_rows} rows in {seconds:.2} s ({:.0} rows/s)",
        total_rows as f64 / seconds.max(1e-9)
    )?;
    Ok(())
}

/// The store the flags name: DATA/chronomap.redb (which must exist; the service must not hold
/// it) or a PostgreSQL schema, read without a lock.
fn open_store(args: &ExportParquetArgs) -> Result<Box<dyn Store>> {
    if let Some(config) = &args.postgres {
        return Ok(Box::new(PostgresStore::connect_reader(
            config,
            &args.postgres_schema,
        )?));
    }
    let data = args
        .data
        .as_deref()
        .expect("clap requires --data without --postgres");
    let path = data.join("chronomap.redb");
    if !path.is_file() {
        bail!(
            "{}: no store (a `chronomap serve --data {}` keeps its models there)",
            path.display(),
            data.display()
        );
    }
    // Read-only: an export never creates, repairs or writes the store.
    RedbStore::open_read_only(&path)
        .map(|store| Box::new(store) as Box<dyn Store>)
        .map_err(|e| in_use(e, data))
}

/// A redb open error, explained when another process (a running service) holds the file.
fn in_use(error: StoreError, data: &Path) -> anyhow::Error {
    if error.reason.to_lowercase().contains("already open") {
        anyhow::anyhow!(
            "{}: the store is in use ({}): is `chronomap serve --data {}` running? redb lets \
             one process open the file; stop the service and export again, or keep the store \
             in PostgreSQL (`serve --postgres`), which `export parquet --postgres` reads \
             beside running services",
            error.store,
            error.reason,
            data.display()
        )
    } else {
        error.into()
    }
}

/// A failure inside a scan, carried out of the store's callback.
fn scan_failure(reason: String) -> StoreError {
    StoreError {
        store: String::new(),
        reason,
    }
}

/// What [`scan_to`] calls with each commit group: its position and records.
type VisitRecords<'a> = dyn FnMut(u64, &[LogRecord]) -> Result<(), StoreError> + 'a;

/// Calls `visit` with the decoded records of every commit group from position 1 to
/// `last_seq`, advancing `bar` by one per group; stops at `last_seq` (a shared store may have
/// grown since it was verified).
fn scan_to(
    store: &dyn Store,
    last_seq: u64,
    bar: &ProgressBar,
    visit: &mut VisitRecords<'_>,
) -> Result<()> {
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
        bar.advance(1);
        Ok(())
    });
    match scanned {
        Err(_) if stopped => {}
        Ok(()) => {}
        Err(e) if e.store.is_empty() => bail!("{}: {}", store.describe(), e.reason),
        Err(e) => return Err(e.into()),
    }
    if previous < last_seq {
        bail!(
            "{}: the log ends at position {previous}, before {last_seq} where it ended when the \
             export began",
            store.describe()
        );
    }
    Ok(())
}
