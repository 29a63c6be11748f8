//! A service store's observations and predictions as Parquet tables (`chronomap export
//! parquet`, docs/parquet.md), for DuckDB, DataFusion and pandas.
//!
//! The log is read twice, one commit group at a time, up to the position it had when the export
//! began (a PostgreSQL store may grow meanwhile): first to find where each exported model was
//! last created, then to write its observations since, in log order. Nothing is buffered per
//! model, so memory is one decoded group, one row group of the table being written (see
//! `chronomap_parquet`) and a map of the exported ids, however long the log.

use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::TemporalModel;
use chronomap_core::progress::Progress;
use chronomap_parquet::{
    ObservationRow, ObservationsWriter, ParquetWriteError, PendingFile, PredictionRow,
    PredictionsWriter,
};
use serde::Serialize;

use crate::check::{self, open_reader, scan_failure, scan_records};
use crate::log::LogRecord;
use crate::registry::Registry;
use crate::startup::StoreLocation;
use crate::store::{Store, StoreError};

/// Most predictions (models × grid times) one export writes.
pub const MAX_PREDICTIONS: u64 = 100_000_000;

/// Rows handed to a table writer at once (and predictions computed at once per model).
const BATCH: usize = 1 << 16;

/// Why an export failed. [`ExportError::is_usage`] tells the errors of what was asked
/// (the flags) from those of the store and the files.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The prediction grid cannot be written as asked.
    #[error("{0}")]
    Grid(String),
    /// The grid times every exported model are more than [`MAX_PREDICTIONS`].
    #[error(
        "{models} models × {times} times is {cells} predictions; at most {MAX_PREDICTIONS} are \
         written (raise --step, narrow --from/--to, choose models with --prefix, or \
         --no-predictions)"
    )]
    TooManyPredictions {
        /// Models exported.
        models: usize,
        /// Times of the grid.
        times: u64,
        /// Their product.
        cells: u64,
    },
    /// The store is damaged (nothing was written).
    #[error("{0}")]
    Damaged(String),
    /// The store cannot be read.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A table cannot be written.
    #[error(transparent)]
    Write(#[from] ParquetWriteError),
    /// The output folder cannot be created.
    #[error("cannot create the directory {}", .path.display())]
    Directory {
        /// The folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The output path is not a folder.
    #[error("{}: not a directory (-o names the folder of the tables)", .path.display())]
    NotADirectory {
        /// The path.
        path: PathBuf,
    },
    /// A model of the snapshots is never created in the log.
    #[error(
        "{store}: the log up to position {last_seq} never creates the model {id:?} its \
         snapshots hold: its observations cannot be exported"
    )]
    NeverCreated {
        /// The store.
        store: String,
        /// The log position of the export.
        last_seq: u64,
        /// The model.
        id: String,
    },
}

impl ExportError {
    /// Whether the request itself is at fault (the prediction grid), not the store or files.
    pub fn is_usage(&self) -> bool {
        matches!(
            self,
            ExportError::Grid(_) | ExportError::TooManyPredictions { .. }
        )
    }
}

/// The prediction grid: `points` times from `from`, `step` apart, up to `to`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictionGrid {
    /// First time (unix seconds).
    pub from: f64,
    /// Last time asked for.
    pub to: f64,
    /// Seconds between times.
    pub step: f64,
    /// Times.
    pub points: u64,
}

impl PredictionGrid {
    /// The grid from `from` to `to` every `step` seconds (`step` is positive).
    ///
    /// # Errors
    /// `to` is before `from`, the grid has 2^53 times or more, or a time is not a Parquet
    /// timestamp (microseconds in 64 bits).
    pub fn new(from: f64, to: f64, step: f64) -> Result<PredictionGrid, ExportError> {
        if to < from {
            return Err(ExportError::Grid(format!(
                "--to {to} is before --from {from}: the prediction grid is empty"
            )));
        }
        let steps = ((to - from) / step).floor();
        // Beyond 2^53 steps, grid times would no longer be distinct doubles.
        if !steps.is_finite() || steps >= 9.0e15 {
            return Err(ExportError::Grid(format!(
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
                return Err(ExportError::Grid(format!(
                    "{flag} {t}: a prediction time must be within about 292,000 years of \
                     1970 (a Parquet timestamp counts microseconds in 64 bits)"
                )));
            }
        }
        Ok(PredictionGrid {
            from,
            to,
            step,
            points: steps as u64 + 1,
        })
    }

    /// The `k`-th time.
    pub fn time(&self, k: u64) -> f64 {
        self.from + k as f64 * self.step
    }
}

/// What to export.
#[derive(Clone, Debug)]
pub struct ExportSpec {
    /// The store, read beside the service ([`check::open_reader`]).
    pub store: StoreLocation,
    /// The folder of the tables (created with its parents if missing).
    pub output: PathBuf,
    /// Replace tables that exist.
    pub force: bool,
    /// Only the models whose ids begin with this.
    pub prefix: Option<String>,
    /// Where the predictions table samples each model; `None` writes no predictions table.
    pub grid: Option<PredictionGrid>,
}

/// One table written.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct TableReport {
    /// The file.
    pub path: PathBuf,
    /// Rows.
    pub rows: u64,
    /// Row groups.
    pub row_groups: usize,
    /// Bytes.
    pub bytes: u64,
}

/// The predictions table and its grid.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct PredictionsReport {
    /// The file.
    #[serde(flatten)]
    pub table: TableReport,
    /// First time.
    pub from: f64,
    /// Last time asked for.
    pub to: f64,
    /// Seconds between times.
    pub step: f64,
    /// Times per model.
    pub times: u64,
}

/// What an export wrote (`chronomap export parquet`; its `--json` has these keys).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ExportReport {
    /// What and where the store is.
    pub store: String,
    /// The log position exported up to.
    pub last_seq: u64,
    /// Models exported.
    pub models: usize,
    /// Models the store holds.
    #[serde(skip)]
    pub store_models: usize,
    /// The id prefix asked for.
    pub prefix: Option<String>,
    /// The observations table.
    pub observations: TableReport,
    /// The predictions table.
    pub predictions: Option<PredictionsReport>,
    /// Seconds the export took (it times itself for this report).
    pub seconds: f64,
}

impl ExportReport {
    /// The report as `chronomap export parquet` prints it.
    pub fn text(&self) -> String {
        let mut text = String::new();
        let o = &self.observations;
        let _ = writeln!(
            text,
            "store: {}, log up to position {}; {} of {} models exported",
            self.store, self.last_seq, self.models, self.store_models
        );
        let _ = writeln!(
            text,
            "{}: {} observations, {} row groups, {} bytes",
            o.path.display(),
            o.rows,
            o.row_groups,
            o.bytes
        );
        if let Some(p) = &self.predictions {
            let _ = writeln!(
                text,
                "{}: {} predictions ({} models × {} times from {} to {} every {} s), {} bytes",
                p.table.path.display(),
                p.table.rows,
                self.models,
                p.times,
                p.from,
                p.from + (p.times - 1) as f64 * p.step,
                p.step,
                p.table.bytes
            );
        }
        let total = o.rows + self.predictions.as_ref().map_or(0, |p| p.table.rows);
        let _ = writeln!(
            text,
            "{total} rows in {:.2} s ({:.0} rows/s)",
            self.seconds,
            total as f64 / self.seconds.max(1e-9)
        );
        text
    }
}

/// Exports the store of `spec` (see the module documentation): verifies it (a damaged store is
/// refused before anything is written), then writes `observations.parquet` and, with a grid,
/// `predictions.parquet` into `spec.output`. What the export creates is removed again if it
/// fails: the folders it made (when still empty) and its files (never committed; a stream
/// written through keeps what it got). Timed for the report.
///
/// # Errors
/// See [`ExportError`].
pub fn export_parquet(
    spec: &ExportSpec,
    progress: &dyn Progress,
) -> Result<ExportReport, ExportError> {
    let started = Instant::now();
    let store = open_reader(&spec.store)?;
    let verified = check::verify(&*store)?;
    if !verified.report.damage.is_empty() {
        return Err(ExportError::Damaged(verified.report.failure()));
    }
    let last_seq = verified.last_seq;
    let registry = verified.registry;
    let prefix = spec.prefix.as_deref().unwrap_or("");
    let ids: Vec<&str> = registry
        .ids()
        .into_iter()
        .filter(|id| id.starts_with(prefix))
        .collect();
    if let Some(grid) = spec.grid {
        let cells = grid.points.saturating_mul(ids.len() as u64);
        if cells > MAX_PREDICTIONS {
            return Err(ExportError::TooManyPredictions {
                models: ids.len(),
                times: grid.points,
                cells,
            });
        }
    }
    let created = create_dirs(&spec.output)?;
    let export = Export {
        spec,
        store: &*store,
        last_seq,
        registry: &registry,
        ids: &ids,
        progress,
    };
    match export.write_tables() {
        Ok((observations, predictions)) => Ok(ExportReport {
            store: store.describe(),
            last_seq,
            models: ids.len(),
            store_models: registry.len(),
            prefix: spec.prefix.clone(),
            observations,
            predictions,
            seconds: started.elapsed().as_secs_f64(),
        }),
        Err(e) => {
            for dir in created.iter().rev() {
                let _ = std::fs::remove_dir(dir);
            }
            Err(e)
        }
    }
}

/// Creates `dir` and its missing parents; returns those it created, outermost first.
fn create_dirs(dir: &Path) -> Result<Vec<PathBuf>, ExportError> {
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
    std::fs::create_dir_all(dir).map_err(|source| ExportError::Directory {
        path: dir.to_path_buf(),
        source,
    })?;
    if !dir.is_dir() {
        return Err(ExportError::NotADirectory {
            path: dir.to_path_buf(),
        });
    }
    Ok(missing)
}

/// One export's store, models and output.
struct Export<'a> {
    spec: &'a ExportSpec,
    store: &'a dyn Store,
    last_seq: u64,
    registry: &'a Registry,
    ids: &'a [&'a str],
    progress: &'a dyn Progress,
}

impl Export<'_> {
    /// Writes the tables; both are committed only once both are written.
    fn write_tables(&self) -> Result<(TableReport, Option<PredictionsReport>), ExportError> {
        let (store, last_seq, ids) = (self.store, self.last_seq, self.ids);
        let observations_path = self.spec.output.join("observations.parquet");
        let predictions_path = self.spec.output.join("predictions.parquet");
        // Both files are refused before anything is read, when they exist and force is not
        // given.
        let observations_file = PendingFile::create(&observations_path, self.spec.force)?;
        let predictions_file = self
            .spec
            .grid
            .map(|_| PendingFile::create(&predictions_path, self.spec.force))
            .transpose()?;
        let description = store.describe();
        let provenance = [
            ("chronomap.store", description.clone()),
            ("chronomap.last_seq", last_seq.to_string()),
            (
                "chronomap.prefix",
                self.spec.prefix.clone().unwrap_or_default(),
            ),
        ];

        // Pass 1: where each exported model was last created (log position, record index).
        let mut created: HashMap<&str, (u64, usize)> = HashMap::with_capacity(ids.len());
        let selected: HashSet<&str> = ids.iter().copied().collect();
        self.progress.stage("reading the log", last_seq);
        scan_records(store, last_seq, self.progress, &mut |seq, records| {
            for (i, record) in records.iter().enumerate() {
                if let LogRecord::Create { id, .. } = record
                    && let Some(&id) = selected.get(id.as_str())
                {
                    created.insert(id, (seq, i));
                }
            }
            Ok(())
        })?;
        if let Some(id) = ids.iter().find(|id| !created.contains_key(*id)) {
            return Err(ExportError::NeverCreated {
                store: description,
                last_seq,
                id: (*id).to_owned(),
            });
        }

        // Pass 2: the observations since then, in log order.
        let name = observations_path.display().to_string();
        let mut observations = ObservationsWriter::new(name, observations_file)?;
        for (key, value) in &provenance {
            observations.metadata(*key, value.clone());
        }
        self.progress.stage("observations", last_seq);
        scan_records(store, last_seq, self.progress, &mut |seq, records| {
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
        let observation_rows = observations.rows();
        let observation_groups = observations.row_groups() + usize::from(observation_rows > 0);
        // Committed once the predictions are written too: a failure there leaves no table.
        let observations_file = observations.finish()?;

        let predictions = match (self.spec.grid, predictions_file) {
            (Some(grid), Some(file)) => {
                let name = predictions_path.display().to_string();
                let mut writer = PredictionsWriter::new(name, file)?;
                for (key, value) in &provenance {
                    writer.metadata(*key, value.clone());
                }
                self.write_predictions(grid, &mut writer)?;
                let rows = writer.rows();
                let groups = writer.row_groups() + usize::from(rows > 0);
                Some((grid, rows, groups, writer.finish()?))
            }
            _ => None,
        };
        let observations_stream = observations_file.is_stream();
        let observation_bytes = observations_file.commit()?;
        let predictions = match predictions {
            Some((grid, rows, row_groups, file)) => match file.commit() {
                Ok(bytes) => Some(PredictionsReport {
                    table: TableReport {
                        path: predictions_path,
                        rows,
                        row_groups,
                        bytes,
                    },
                    from: grid.from,
                    to: grid.to,
                    step: grid.step,
                    times: grid.points,
                }),
                Err(e) => {
                    if !observations_stream {
                        let _ = std::fs::remove_file(&observations_path);
                    }
                    return Err(e.into());
                }
            },
            None => None,
        };
        let observations = TableReport {
            path: observations_path,
            rows: observation_rows,
            row_groups: observation_groups,
            bytes: observation_bytes,
        };
        Ok((observations, predictions))
    }

    /// Every exported model's predictions at every time of `grid`, model by model.
    fn write_predictions(
        &self,
        grid: PredictionGrid,
        writer: &mut PredictionsWriter<PendingFile>,
    ) -> Result<(), ExportError> {
        self.progress
            .stage("predictions", grid.points * self.ids.len() as u64);
        let mut times = Vec::with_capacity(BATCH);
        let mut rows: Vec<PredictionRow> = Vec::with_capacity(BATCH);
        for &id in self.ids {
            let entry = self.registry.get(id).expect("the ids are the registry's");
            let mut k = 0;
            while k < grid.points {
                let end = (k + BATCH as u64).min(grid.points);
                times.clear();
                times.extend((k..end).map(|k| grid.time(k)));
                // A day off of the model's calendar is predicted at its stand-in.
                let probabilities = entry
                    .model
                    .predict_many(&entry.config.days_off.stand_ins(&times));
                rows.clear();
                rows.extend(
                    times
                        .iter()
                        .zip(&probabilities)
                        .map(|(&time_s, &p)| PredictionRow {
                            model_id: id,
                            time_s,
                            probability: p,
                            value: entry.config.range.map(|_| entry.config.scale(p)),
                        }),
                );
                writer.write(&rows)?;
                self.progress.advance(end - k);
                k = end;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_prediction_grid_counts_its_times_and_refuses_what_parquet_cannot_hold() {
        let grid = PredictionGrid::new(0.0, 3600.0, 600.0).unwrap();
        assert_eq!(grid.points, 7);
        assert_eq!(grid.time(6), 3600.0);
        // A step that does not divide the span: the last time is before `to`.
        let grid = PredictionGrid::new(100.0, 1000.0, 400.0).unwrap();
        assert_eq!((grid.points, grid.time(2)), (3, 900.0));
        let e = PredictionGrid::new(10.0, 5.0, 1.0).unwrap_err();
        assert!(e.is_usage());
        assert_eq!(
            e.to_string(),
            "--to 5 is before --from 10: the prediction grid is empty"
        );
        let e = PredictionGrid::new(0.0, 1e16, 1.0).unwrap_err();
        assert!(e.to_string().contains("makes 1e16 times"), "{e}");
        // 2^63 µs is about 292,471 years.
        let e = PredictionGrid::new(0.0, 1e13, 1e12).unwrap_err();
        assert!(e.to_string().starts_with("--to 10000000000000: "), "{e}");
    }

    #[test]
    fn the_report_prints_the_last_grid_time_and_the_rate() {
        let table = |path: &str, rows| TableReport {
            path: PathBuf::from(path),
            rows,
            row_groups: 1,
            bytes: 1000,
        };
        let report = ExportReport {
            store: "redb x".into(),
            last_seq: 4,
            models: 2,
            store_models: 3,
            prefix: None,
            observations: table("o.parquet", 30),
            predictions: Some(PredictionsReport {
                table: table("p.parquet", 10),
                from: 0.0,
                to: 10.0,
                step: 2.5,
                times: 5,
            }),
            seconds: 2.0,
        };
        assert_eq!(
            report.text(),
            "store: redb x, log up to position 4; 2 of 3 models exported\n\
             o.parquet: 30 observations, 1 row groups, 1000 bytes\n\
             p.parquet: 10 predictions (2 models × 5 times from 0 to 10 every 2.5 s), 1000 bytes\n\
             40 rows in 2.00 s (20 rows/s)\n"
        );
        let json = serde_json::to_value(&report).unwrap();
        assert_eq!(json["predictions"]["rows"], 10);
        assert_eq!(json["predictions"]["times"], 5);
        assert!(json.get("store_models").is_none());
    }
}
