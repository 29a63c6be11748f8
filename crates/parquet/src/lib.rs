//! # chronomap-parquet
//!
//! Apache Parquet tables of a fleet's observations and predictions, for DataFusion, DuckDB,
//! pandas and Polars (`chronomap export parquet`).
//!
//! Two tables, each written by a streaming writer that buffers at most one row group
//! ([`DEFAULT_ROW_GROUP_ROWS`] rows, about 36 bytes a row plus each distinct model id of the
//! group once) and writes it, Snappy-compressed, when full:
//!
//! * [`ObservationsWriter`]: `namespace`, `model_id`, `time`, `time_s`, `value`, `seq`;
//! * [`PredictionsWriter`]: `namespace`, `model_id`, `time`, `time_s`, `probability`, `value`.
//!
//! `namespace` is the model id up to its first `/` (a robot, a site), or the whole id
//! ([`namespace_of`]). `time` is a `TIMESTAMP(MICROS, UTC)` (the seconds rounded to the
//! nearest microsecond) and `time_s` the exact seconds as a `DOUBLE`. Every column is
//! `REQUIRED` except the `value` of predictions, which is null for a model without a range.
//! `time` is delta-encoded and `time_s` split into byte streams (both read by every Parquet
//! reader of the last years); the other columns are dictionary-encoded.
//!
//! ```
//! use chronomap_parquet::{ObservationRow, ObservationsWriter};
//!
//! let mut writer = ObservationsWriter::new("memory", Vec::new())?;
//! writer.write(&[
//!     ObservationRow { model_id: "robot1/door", time_s: 1_458_561_600.5, value: 1.0, seq: 3 },
//!     ObservationRow { model_id: "robot2/door", time_s: 1_458_561_660.0, value: 0.0, seq: 4 },
//! ])?;
//! assert_eq!(writer.rows(), 2);
//! let bytes = writer.finish()?;
//! assert_eq!(&bytes[..4], b"PAR1");
//!
//! // A time that is not a finite number of seconds is refused, naming the file, row and column.
//! let mut writer = ObservationsWriter::new("obs.parquet", Vec::new())?;
//! let bad = ObservationRow { model_id: "door", time_s: f64::NAN, value: 1.0, seq: 1 };
//! let error = writer.write(&[bad]).unwrap_err();
//! assert_eq!(
//!     error.to_string(),
//!     "obs.parquet: row 1: column time: NaN s is not a time (finite seconds within ±292,000 years of 1970)"
//! );
//! # Ok::<(), chronomap_parquet::ParquetWriteError>(())
//! ```

#![deny(missing_docs)]

use std::collections::HashMap;
use std::fmt;
use std::io::{self, Write};
use std::path::Path;
use std::sync::Arc;

use parquet::basic::{Compression, Encoding};
use parquet::data_type::{ByteArray, ByteArrayType, DoubleType, Int64Type};
use parquet::errors::ParquetError;
use parquet::file::metadata::KeyValue;
use parquet::file::properties::WriterProperties;
use parquet::file::writer::{SerializedFileWriter, SerializedRowGroupWriter};
use parquet::schema::parser::parse_message_type;
use parquet::schema::types::ColumnPath;

/// Rows of a row group unless [`ObservationsWriter::with_row_group_rows`] says otherwise
/// (2^20: large enough for DuckDB and DataFusion to read in parallel, small enough to buffer).
pub const DEFAULT_ROW_GROUP_ROWS: usize = 1 << 20;

/// Schema of the observations table.
pub const OBSERVATIONS_SCHEMA: &str = "message observations {
  REQUIRED BYTE_ARRAY namespace (STRING);
  REQUIRED BYTE_ARRAY model_id (STRING);
  REQUIRED INT64 time (TIMESTAMP(MICROS,true));
  REQUIRED DOUBLE time_s;
  REQUIRED DOUBLE value;
  REQUIRED INT64 seq;
}";

/// Schema of the predictions table.
pub const PREDICTIONS_SCHEMA: &str = "message predictions {
  REQUIRED BYTE_ARRAY namespace (STRING);
  REQUIRED BYTE_ARRAY model_id (STRING);
  REQUIRED INT64 time (TIMESTAMP(MICROS,true));
  REQUIRED DOUBLE time_s;
  REQUIRED DOUBLE probability;
  OPTIONAL DOUBLE value;
}";

/// Rows are handed to the column writers in slices of this many (the string columns are
/// materialised one slice at a time).
const CHUNK: usize = 1 << 16;

/// Why a table cannot be written: the file (or the name given for a stream), and the row
/// and column when one value is at fault.
#[derive(Debug)]
pub struct ParquetWriteError {
    /// The file or stream name.
    pub file: String,
    /// The row (counted from 1 in the table) whose value is refused.
    pub row: Option<u64>,
    /// The column at fault.
    pub column: Option<&'static str>,
    /// What went wrong.
    pub reason: String,
}

impl fmt::Display for ParquetWriteError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(row) = self.row {
            write!(f, ": row {row}")?;
        }
        if let Some(column) = self.column {
            write!(f, ": column {column}")?;
        }
        write!(f, ": {}", self.reason)
    }
}

impl std::error::Error for ParquetWriteError {}

/// The namespace of a model id: up to its first `/`, or the whole id.
pub fn namespace_of(id: &str) -> &str {
    id.split_once('/').map_or(id, |(namespace, _)| namespace)
}

/// Microseconds since 1970 of `seconds`, rounded to the nearest; `None` unless finite and
/// within the range of an `INT64` of microseconds.
pub fn micros_of(seconds: f64) -> Option<i64> {
    let micros = (seconds * 1e6).round();
    // i64::MAX as f64 is 2^63, itself out of range.
    (micros.is_finite() && micros >= i64::MIN as f64 && micros < i64::MAX as f64)
        .then_some(micros as i64)
}

/// `t` for a message: plain digits, or with an exponent when those would be many.
fn seconds(t: f64) -> String {
    if t.abs() < 1e16 {
        t.to_string()
    } else {
        format!("{t:e}")
    }
}

/// One observation: a value a model was given at a time, at a log position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObservationRow<'a> {
    /// The model.
    pub model_id: &'a str,
    /// Time (s since 1970, or relative).
    pub time_s: f64,
    /// The value as given (in the model's range).
    pub value: f64,
    /// The log position that added it.
    pub seq: u64,
}

/// One prediction of a model at a time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictionRow<'a> {
    /// The model.
    pub model_id: &'a str,
    /// Time (s).
    pub time_s: f64,
    /// Probability of the state in `[0, 1]`.
    pub probability: f64,
    /// The probability mapped onto the model's range; `None` for a model without one.
    pub value: Option<f64>,
}

/// The model ids of the rows of one row group: each distinct id once, and its index per row.
#[derive(Default)]
struct Ids {
    ids: Vec<String>,
    index: HashMap<String, u32>,
    of_row: Vec<u32>,
}

impl Ids {
    fn push(&mut self, id: &str) {
        let i = match self.of_row.last() {
            Some(&last) if self.ids[last as usize] == id => last,
            _ => match self.index.get(id) {
                Some(&i) => i,
                None => {
                    let i = self.ids.len() as u32;
                    self.ids.push(id.to_owned());
                    self.index.insert(id.to_owned(), i);
                    i
                }
            },
        };
        self.of_row.push(i);
    }

    fn clear(&mut self) {
        self.ids.clear();
        self.index.clear();
        self.of_row.clear();
    }
}

/// What both tables share: the file writer, the row-group buffer of ids and times, counts.
struct Table<W: Write + Send> {
    name: String,
    file: SerializedFileWriter<W>,
    row_group_rows: usize,
    rows: u64,
    row_groups: usize,
    ids: Ids,
    time: Vec<i64>,
    time_s: Vec<f64>,
}

impl<W: Write + Send> Table<W> {
    fn new(name: String, writer: W, schema: &str) -> Result<Self, ParquetWriteError> {
        let schema = parse_message_type(schema).expect("the table schemas parse");
        // Times are mostly increasing and often regular: deltas of `time` and the byte planes of
        // `time_s` compress to a tenth of what dictionaries do (measured on the greg door,
        // sampled every minute: 6.0 MB instead of 60.6 MB for 11.6 M observations).
        let properties = WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .set_column_dictionary_enabled(ColumnPath::from("time"), false)
            .set_column_encoding(ColumnPath::from("time"), Encoding::DELTA_BINARY_PACKED)
            .set_column_dictionary_enabled(ColumnPath::from("time_s"), false)
            .set_column_encoding(ColumnPath::from("time_s"), Encoding::BYTE_STREAM_SPLIT)
            .build();
        let file = SerializedFileWriter::new(writer, Arc::new(schema), Arc::new(properties))
            .map_err(|e| fail(&name, None, e))?;
        Ok(Table {
            name,
            file,
            row_group_rows: DEFAULT_ROW_GROUP_ROWS,
            rows: 0,
            row_groups: 0,
            ids: Ids::default(),
            time: Vec::new(),
            time_s: Vec::new(),
        })
    }

    fn error(&self, row: u64, column: &'static str, reason: String) -> ParquetWriteError {
        ParquetWriteError {
            file: self.name.clone(),
            row: Some(row),
            column: Some(column),
            reason,
        }
    }

    /// Checks and buffers the columns every table has; `row` counts from 1.
    fn push(&mut self, row: u64, model_id: &str, time_s: f64) -> Result<(), ParquetWriteError> {
        let micros = micros_of(time_s).ok_or_else(|| {
            self.error(
                row,
                "time",
                format!(
                    "{} s is not a time (finite seconds within ±292,000 years of 1970)",
                    seconds(time_s)
                ),
            )
        })?;
        self.ids.push(model_id);
        self.time.push(micros);
        self.time_s.push(time_s);
        Ok(())
    }

    /// Writes `namespace`, `model_id`, `time` and `time_s` as the first four columns of `group`.
    fn write_common(
        name: &str,
        ids: &Ids,
        time: &[i64],
        time_s: &[f64],
        group: &mut SerializedRowGroupWriter<'_, W>,
    ) -> Result<(), ParquetWriteError> {
        let ids_bytes: Vec<ByteArray> = ids
            .ids
            .iter()
            .map(|id| ByteArray::from(id.as_bytes().to_vec()))
            .collect();
        let namespaces: Vec<ByteArray> = ids
            .ids
            .iter()
            .map(|id| ByteArray::from(namespace_of(id).as_bytes().to_vec()))
            .collect();
        for (column, values) in [("namespace", &namespaces), ("model_id", &ids_bytes)] {
            write_column::<ByteArrayType, _>(name, column, group, |writer| {
                let mut chunk = Vec::with_capacity(CHUNK.min(ids.of_row.len()));
                for rows in ids.of_row.chunks(CHUNK) {
                    chunk.clear();
                    chunk.extend(rows.iter().map(|&i| values[i as usize].clone()));
                    writer.write_batch(&chunk, None, None)?;
                }
                Ok(())
            })?;
        }
        write_column::<Int64Type, _>(name, "time", group, |w| {
            w.write_batch(time, None, None).map(drop)
        })?;
        write_column::<DoubleType, _>(name, "time_s", group, |w| {
            w.write_batch(time_s, None, None).map(drop)
        })
    }

    fn finish_group(&mut self) {
        self.rows += self.ids.of_row.len() as u64;
        self.row_groups += 1;
        self.ids.clear();
        self.time.clear();
        self.time_s.clear();
    }

    fn finish(mut self, metadata: &[(String, String)]) -> Result<W, ParquetWriteError> {
        for (key, value) in metadata {
            self.file
                .append_key_value_metadata(KeyValue::new(key.clone(), value.clone()));
        }
        self.file
            .into_inner()
            .map_err(|e| fail(&self.name, None, e))
    }
}

/// Writes one column of a row group with `write`, naming the column in errors.
fn write_column<T: ::parquet::data_type::DataType, W: Write + Send>(
    name: &str,
    column: &'static str,
    group: &mut SerializedRowGroupWriter<'_, W>,
    write: impl FnOnce(
        &mut ::parquet::column::writer::ColumnWriterImpl<'_, T>,
    ) -> Result<(), ParquetError>,
) -> Result<(), ParquetWriteError> {
    let mut writer = group
        .next_column()
        .map_err(|e| fail(name, Some(column), e))?
        .ok_or_else(|| ParquetWriteError {
            file: name.to_owned(),
            row: None,
            column: Some(column),
            reason: "the schema has no such column".into(),
        })?;
    write(writer.typed::<T>()).map_err(|e| fail(name, Some(column), e))?;
    writer.close().map_err(|e| fail(name, Some(column), e))
}

fn fail(name: &str, column: Option<&'static str>, error: ParquetError) -> ParquetWriteError {
    ParquetWriteError {
        file: name.to_owned(),
        row: None,
        column,
        reason: error.to_string(),
    }
}

/// Writes the observations table ([`OBSERVATIONS_SCHEMA`]) to `W`, one row group at a time.
pub struct ObservationsWriter<W: Write + Send> {
    table: Table<W>,
    value: Vec<f64>,
    seq: Vec<i64>,
    metadata: Vec<(String, String)>,
}

impl<W: Write + Send> ObservationsWriter<W> {
    /// Starts the table on `writer`; `name` (the file) is what errors name.
    ///
    /// # Errors
    /// The header cannot be written.
    pub fn new(name: impl Into<String>, writer: W) -> Result<Self, ParquetWriteError> {
        Ok(ObservationsWriter {
            table: Table::new(name.into(), writer, OBSERVATIONS_SCHEMA)?,
            value: Vec::new(),
            seq: Vec::new(),
            metadata: Vec::new(),
        })
    }

    /// Writes row groups of `rows` rows (at least 1) instead of [`DEFAULT_ROW_GROUP_ROWS`].
    pub fn with_row_group_rows(mut self, rows: usize) -> Self {
        self.table.row_group_rows = rows.max(1);
        self
    }

    /// Adds a key-value pair to the file's metadata (written at [`Self::finish`]).
    pub fn metadata(&mut self, key: impl Into<String>, value: impl Into<String>) {
        self.metadata.push((key.into(), value.into()));
    }

    /// Appends `rows`, writing a row group whenever one is full.
    ///
    /// # Errors
    /// A time that is not finite seconds within the range of microseconds in an `INT64`, a
    /// `seq` above `i64::MAX`, or the sink fails (the file is then unusable). Rows before
    /// the refused one are kept.
    pub fn write(&mut self, rows: &[ObservationRow<'_>]) -> Result<(), ParquetWriteError> {
        for row in rows {
            let number = self.rows() + 1;
            let seq = i64::try_from(row.seq).map_err(|_| {
                self.table
                    .error(number, "seq", format!("{} is above 2^63 - 1", row.seq))
            })?;
            self.table.push(number, row.model_id, row.time_s)?;
            self.value.push(row.value);
            self.seq.push(seq);
            if self.value.len() >= self.table.row_group_rows {
                self.flush()?;
            }
        }
        Ok(())
    }

    /// Rows written so far (including those buffered).
    pub fn rows(&self) -> u64 {
        self.table.rows + self.value.len() as u64
    }

    /// Row groups written so far.
    pub fn row_groups(&self) -> usize {
        self.table.row_groups
    }

    fn flush(&mut self) -> Result<(), ParquetWriteError> {
        if self.value.is_empty() {
            return Ok(());
        }
        let table = &mut self.table;
        let name = table.name.as_str();
        let mut group = table
            .file
            .next_row_group()
            .map_err(|e| fail(name, None, e))?;
        Table::write_common(name, &table.ids, &table.time, &table.time_s, &mut group)?;
        write_column::<DoubleType, _>(name, "value", &mut group, |w| {
            w.write_batch(&self.value, None, None).map(drop)
        })?;
        write_column::<Int64Type, _>(name, "seq", &mut group, |w| {
            w.write_batch(&self.seq, None, None).map(drop)
        })?;
        group.close().map_err(|e| fail(name, None, e))?;
        table.finish_group();
        self.value.clear();
        self.seq.clear();
        Ok(())
    }

    /// Writes the last row group and the footer; returns the sink.
    ///
    /// # Errors
    /// The sink fails.
    pub fn finish(mut self) -> Result<W, ParquetWriteError> {
        self.flush()?;
        self.table.finish(&self.metadata)
    }
}

/// Writes the predictions table ([`PREDICTIONS_SCHEMA`]) to `W`, one row group at a time.
pub struct PredictionsWriter<W: Write + Send> {
    table: Table<W>,
    probability: Vec<f64>,
    /// The values present (nulls have none).
    value: Vec<f64>,
    /// Definition level of `value` per row: 1 present, 0 null.
    defined: Vec<i16>,
    metadata: Vec<(String, String)>,
}

impl<W: Write + Send> PredictionsWriter<W> {
    /// Starts the table on `writer`; `name` (the file) is what errors name.
    ///
    /// # Errors
    /// The header cannot be written.
    pub fn new(name: impl Into<String>, writer: W) -> Result<Self, ParquetWriteError> {
        Ok(PredictionsWriter {
            table: Table::new(name.into(), writer, PREDICTIONS_SCHEMA)?,
            probability: Vec::new(),
            value: Vec::new(),
            defined: Vec::new(),
            metadata: Vec::new(),
        })
    }

    /// Writes row groups of `rows` rows (at least 1) instead of [`DEFAULT_ROW_GROUP_ROWS`].
    pub fn with_row_group_rows(mut self, rows: usize) -> Self {
        self.table.row_group_rows = rows.max(1);
        self
    }

    /// Adds a key-value pair to the file's metadata (written at [`Self::finish`]).
    pub fn metadata(&mut self, key: impl Into<String>, value: impl Into<String>) {
        self.metadata.push((key.into(), value.into()));
    }

    /// Appends `rows`, writing a row group whenever one is full.
    ///
    /// # Errors
    /// As [`ObservationsWriter::write`].
    pub fn write(&mut self, rows: &[PredictionRow<'_>]) -> Result<(), ParquetWriteError> {
        for row in rows {
            let number = self.rows() + 1;
            self.table.push(number, row.model_id, row.time_s)?;
            self.probability.push(row.probability);
            match row.value {
                Some(value) => {
                    self.value.push(value);
                    self.defined.push(1);
                }
                None => self.defined.push(0),
            }
            if self.defined.len() >= self.table.row_group_rows {
                self.flush()?;
            }
        }
        Ok(())
    }

    /// Rows written so far (including those buffered).
    pub fn rows(&self) -> u64 {
        self.table.rows + self.defined.len() as u64
    }

    /// Row groups written so far.
    pub fn row_groups(&self) -> usize {
        self.table.row_groups
    }

    fn flush(&mut self) -> Result<(), ParquetWriteError> {
        if self.defined.is_empty() {
            return Ok(());
        }
        let table = &mut self.table;
        let name = table.name.as_str();
        let mut group = table
            .file
            .next_row_group()
            .map_err(|e| fail(name, None, e))?;
        Table::write_common(name, &table.ids, &table.time, &table.time_s, &mut group)?;
        write_column::<DoubleType, _>(name, "probability", &mut group, |w| {
            w.write_batch(&self.probability, None, None).map(drop)
        })?;
        write_column::<DoubleType, _>(name, "value", &mut group, |w| {
            w.write_batch(&self.value, Some(&self.defined), None)
                .map(drop)
        })?;
        group.close().map_err(|e| fail(name, None, e))?;
        table.finish_group();
        self.probability.clear();
        self.value.clear();
        self.defined.clear();
        Ok(())
    }

    /// Writes the last row group and the footer; returns the sink.
    ///
    /// # Errors
    /// The sink fails.
    pub fn finish(mut self) -> Result<W, ParquetWriteError> {
        self.flush()?;
        self.table.finish(&self.metadata)
    }
}

/// A table file being written with the one output writer (`chronomap_io::output::Output`): a
/// regular file is written under a temporary name beside its final path and
/// [`PendingFile::commit`] flushes it to disk and renames it into place (dropping it
/// uncommitted deletes it, so a failed export never leaves a truncated table behind); a
/// device or named pipe is written through; a link's file is written and the link kept; a
/// directory is refused.
pub struct PendingFile {
    output: chronomap_io::output::Output,
}

impl PendingFile {
    /// Starts `path`. With `replace` false, an existing file at `path` (or where its link
    /// points) is refused now (devices and pipes are written through).
    ///
    /// # Errors
    /// `path` exists (and `replace` is false), is a directory or another kind of file that
    /// is not written, or cannot be opened.
    pub fn create(path: &Path, replace: bool) -> Result<Self, ParquetWriteError> {
        let output =
            chronomap_io::output::Output::create_or_refuse(path, replace).map_err(|e| {
                ParquetWriteError {
                    file: path.display().to_string(),
                    row: None,
                    column: None,
                    reason: if e.io.kind() == io::ErrorKind::AlreadyExists {
                        "exists already (replace it with --force)".into()
                    } else {
                        format!("cannot {}: {}", e.action, e.io)
                    },
                }
            })?;
        Ok(PendingFile { output })
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        self.output.path()
    }

    /// Whether the file is a device or pipe written through, where nothing can be taken
    /// back.
    pub fn is_stream(&self) -> bool {
        self.output.is_stream()
    }

    /// Flushes the file to disk and renames it to its final path (a device or pipe: flushes
    /// it); returns the number of bytes written.
    ///
    /// # Errors
    /// The file cannot be written or renamed (it is then deleted).
    pub fn commit(self) -> Result<u64, ParquetWriteError> {
        let file = self.output.path().display().to_string();
        self.output.commit().map_err(|e| ParquetWriteError {
            file,
            row: None,
            column: None,
            reason: format!("cannot {}: {}", e.action, e.io),
        })
    }
}

impl Write for PendingFile {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.output.write(buf)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.output.flush()
    }
}

#[cfg(test)]
mod tests {
    use parquet::basic::{LogicalType, Repetition, TimeUnit, Type as Physical};
    use parquet::file::reader::{FileReader, SerializedFileReader};
    use parquet::record::{Field, Row, RowAccessor};
    use std::fs::{self, File};
    use std::path::PathBuf;

    use super::*;

    /// A directory of its own for each test, under the system's temporary directory.
    fn scratch(test: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "chronomap-io-parquet-{}-{test}",
            std::process::id()
        ));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn read_rows(path: &Path) -> (SerializedFileReader<File>, Vec<Row>) {
        let reader = SerializedFileReader::new(File::open(path).unwrap()).unwrap();
        let rows = reader
            .get_row_iter(None)
            .unwrap()
            .collect::<Result<Vec<_>, _>>()
            .unwrap();
        (reader, rows)
    }

    const IDS: [&str; 5] = [
        "robot1/door",
        "robot1/door/left",
        "robot2/door",
        "lab",
        "robot2/kitchen",
    ];

    /// Row `k` of the observation tests: a time on a quarter second, so that its microseconds
    /// are known exactly without floating point (`1458561600 s + k × 250000 µs`).
    fn observation(k: u64) -> ObservationRow<'static> {
        ObservationRow {
            model_id: IDS[(k / 7) as usize % IDS.len()],
            time_s: 1_458_561_600.0 + k as f64 * 0.25,
            value: (k % 3) as f64 / 2.0 - 10.0,
            seq: 1 + k / 4,
        }
    }

    #[test]
    fn observations_round_trip_exactly_through_the_reader() {
        let dir = scratch("observations");
        let path = dir.join("observations.parquet");
        let rows: Vec<ObservationRow> = (0..700).map(observation).collect();
        let sink = PendingFile::create(&path, false).unwrap();
        let mut writer = ObservationsWriter::new(path.display().to_string(), sink)
            .unwrap()
            .with_row_group_rows(128);
        // In uneven batches, so that row groups straddle them.
        for batch in rows.chunks(97) {
            writer.write(batch).unwrap();
        }
        writer.metadata("chronomap.last_seq", "175");
        assert_eq!(writer.rows(), 700);
        assert_eq!(writer.row_groups(), 5, "5 full groups of 128 before finish");
        let bytes = writer.finish().unwrap().commit().unwrap();
        assert_eq!(bytes, fs::metadata(&path).unwrap().len());

        let (reader, read) = read_rows(&path);
        let meta = reader.metadata();
        assert_eq!(meta.file_metadata().num_rows(), 700);
        assert_eq!(meta.num_row_groups(), 6, "700 rows in groups of 128");
        let kv = meta.file_metadata().key_value_metadata().unwrap();
        assert!(
            kv.iter()
                .any(|k| k.key == "chronomap.last_seq" && k.value.as_deref() == Some("175"))
        );
        // The times are stored as deltas and byte streams, the rest with dictionaries.
        let chunks = meta.row_group(0);
        let encodings = |i: usize| chunks.column(i).encodings().collect::<Vec<_>>();
        assert!(
            encodings(2).contains(&Encoding::DELTA_BINARY_PACKED),
            "{:?}",
            encodings(2)
        );
        assert!(
            encodings(3).contains(&Encoding::BYTE_STREAM_SPLIT),
            "{:?}",
            encodings(3)
        );
        for i in [0, 1, 4, 5] {
            assert!(
                encodings(i).contains(&Encoding::RLE_DICTIONARY),
                "{:?}",
                encodings(i)
            );
        }
        assert_eq!(read.len(), rows.len());
        for (k, (row, expected)) in read.iter().zip(&rows).enumerate() {
            let namespace = expected.model_id.split('/').next().unwrap();
            assert_eq!(row.get_string(0).unwrap(), namespace, "row {k}");
            assert_eq!(row.get_string(1).unwrap(), expected.model_id, "row {k}");
            assert_eq!(
                row.get_timestamp_micros(2).unwrap(),
                1_458_561_600_000_000 + k as i64 * 250_000,
                "row {k}"
            );
            assert_eq!(
                row.get_double(3).unwrap().to_bits(),
                expected.time_s.to_bits()
            );
            assert_eq!(
                row.get_double(4).unwrap().to_bits(),
                expected.value.to_bits()
            );
            assert_eq!(row.get_long(5).unwrap(), expected.seq as i64, "row {k}");
        }
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn the_schemas_carry_the_logical_types_readers_rely_on() {
        let dir = scratch("schemas");
        let observations = dir.join("o.parquet");
        let predictions = dir.join("p.parquet");
        let sink = PendingFile::create(&observations, false).unwrap();
        let mut writer = ObservationsWriter::new("o", sink).unwrap();
        writer.write(&[observation(0)]).unwrap();
        writer.finish().unwrap().commit().unwrap();
        let sink = PendingFile::create(&predictions, false).unwrap();
        PredictionsWriter::new("p", sink)
            .unwrap()
            .finish()
            .unwrap()
            .commit()
            .unwrap();

        let timestamp = LogicalType::timestamp(true, TimeUnit::MICROS);
        let expected = [
            (
                &observations,
                vec![
                    (
                        "namespace",
                        Physical::BYTE_ARRAY,
                        Some(LogicalType::String),
                        Repetition::REQUIRED,
                    ),
                    (
                        "model_id",
                        Physical::BYTE_ARRAY,
                        Some(LogicalType::String),
                        Repetition::REQUIRED,
                    ),
                    (
                        "time",
                        Physical::INT64,
                        Some(timestamp.clone()),
                        Repetition::REQUIRED,
                    ),
                    ("time_s", Physical::DOUBLE, None, Repetition::REQUIRED),
                    ("value", Physical::DOUBLE, None, Repetition::REQUIRED),
                    ("seq", Physical::INT64, None, Repetition::REQUIRED),
                ],
            ),
            (
                &predictions,
                vec![
                    (
                        "namespace",
                        Physical::BYTE_ARRAY,
                        Some(LogicalType::String),
                        Repetition::REQUIRED,
                    ),
                    (
                        "model_id",
                        Physical::BYTE_ARRAY,
                        Some(LogicalType::String),
                        Repetition::REQUIRED,
                    ),
                    (
                        "time",
                        Physical::INT64,
                        Some(timestamp),
                        Repetition::REQUIRED,
                    ),
                    ("time_s", Physical::DOUBLE, None, Repetition::REQUIRED),
                    ("probability", Physical::DOUBLE, None, Repetition::REQUIRED),
                    ("value", Physical::DOUBLE, None, Repetition::OPTIONAL),
                ],
            ),
        ];
        for (path, columns) in expected {
            let (reader, _) = read_rows(path);
            let schema = reader.metadata().file_metadata().schema_descr();
            assert_eq!(schema.num_columns(), columns.len(), "{}", path.display());
            for (i, (name, physical, logical, repetition)) in columns.into_iter().enumerate() {
                let column = schema.column(i);
                assert_eq!(column.name(), name);
                assert_eq!(column.physical_type(), physical, "{name}");
                assert_eq!(column.logical_type_ref(), logical.as_ref(), "{name}");
                assert_eq!(
                    column.self_type().get_basic_info().repetition(),
                    repetition,
                    "{name}"
                );
            }
        }
        // An empty table is a valid file with no rows.
        let (reader, rows) = read_rows(&predictions);
        assert_eq!((reader.metadata().num_row_groups(), rows.len()), (0, 0));
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn predictions_keep_nulls_where_a_model_has_no_range() {
        let dir = scratch("predictions");
        let path = dir.join("predictions.parquet");
        let rows: Vec<PredictionRow> = (0..300u32)
            .map(|k| PredictionRow {
                model_id: IDS[k as usize % IDS.len()],
                time_s: -3600.0 + f64::from(k) * 60.0,
                probability: f64::from(k) / 299.0,
                value: (k % 5 != 3).then(|| 15.0 + 10.0 * f64::from(k) / 299.0),
            })
            .collect();
        let sink = PendingFile::create(&path, false).unwrap();
        let mut writer = PredictionsWriter::new("p", sink)
            .unwrap()
            .with_row_group_rows(64);
        writer.write(&rows).unwrap();
        writer.finish().unwrap().commit().unwrap();

        let (reader, read) = read_rows(&path);
        assert_eq!(
            reader.metadata().num_row_groups(),
            5,
            "300 rows in groups of 64"
        );
        assert_eq!(read.len(), 300);
        let mut nulls = 0;
        for (k, (row, expected)) in read.iter().zip(&rows).enumerate() {
            assert_eq!(row.get_string(1).unwrap(), expected.model_id, "row {k}");
            // Before 1970: a negative timestamp, whole minutes.
            assert_eq!(
                row.get_timestamp_micros(2).unwrap(),
                (-3600 + 60 * k as i64) * 1_000_000
            );
            assert_eq!(
                row.get_double(4).unwrap().to_bits(),
                expected.probability.to_bits()
            );
            let value = row.get_column_iter().nth(5).unwrap().1;
            match (value, expected.value) {
                (Field::Double(v), Some(e)) => assert_eq!(v.to_bits(), e.to_bits(), "row {k}"),
                (Field::Null, None) => nulls += 1,
                (v, e) => panic!("row {k}: read {v:?}, wrote {e:?}"),
            }
        }
        assert_eq!(nulls, 60, "every fifth row has no value");
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn values_that_do_not_fit_are_refused_naming_file_row_and_column() {
        let mut writer = ObservationsWriter::new("fleet/observations.parquet", Vec::new()).unwrap();
        writer.write(&[observation(0), observation(1)]).unwrap();
        for (time_s, text) in [
            (1e300, "1e300"),
            (f64::INFINITY, "inf"),
            (-9.3e12, "-9300000000000"),
        ] {
            let bad = ObservationRow {
                time_s,
                ..observation(2)
            };
            let error = writer.write(&[bad]).unwrap_err();
            assert_eq!(
                error.to_string(),
                format!(
                    "fleet/observations.parquet: row 3: column time: {text} s is not a time \
                     (finite seconds within ±292,000 years of 1970)"
                )
            );
        }
        let bad = ObservationRow {
            seq: u64::MAX,
            ..observation(2)
        };
        let error = writer.write(&[bad]).unwrap_err();
        assert_eq!((error.row, error.column), (Some(3), Some("seq")));
        // The refused rows are not in the table; the good ones are.
        assert_eq!(writer.rows(), 2);
        let bytes = writer.finish().unwrap();
        assert_eq!(&bytes[bytes.len() - 4..], b"PAR1");
        // The extremes that fit are kept.
        assert_eq!(micros_of(-9.2e12), Some(-9_200_000_000_000_000_000));
        assert_eq!(
            micros_of(0.000_000_5),
            Some(1),
            "rounded to the nearest microsecond"
        );
        assert_eq!(micros_of(-0.000_000_4), Some(0));
    }

    #[test]
    fn a_pending_file_replaces_nothing_unless_asked_and_vanishes_when_dropped() {
        let dir = scratch("pending");
        let path = dir.join("observations.parquet");
        fs::write(&path, "old").unwrap();
        let error = PendingFile::create(&path, false).err().unwrap();
        assert_eq!(
            error.to_string(),
            format!(
                "{}: exists already (replace it with --force)",
                path.display()
            )
        );
        let mut pending = PendingFile::create(&path, true).unwrap();
        pending.write_all(b"half a table").unwrap();
        drop(pending);
        assert_eq!(
            fs::read(&path).unwrap(),
            b"old",
            "an uncommitted file changes nothing"
        );
        assert_eq!(
            fs::read_dir(&dir).unwrap().count(),
            1,
            "and leaves no temporary file"
        );
        let mut pending = PendingFile::create(&path, true).unwrap();
        pending.write_all(b"new").unwrap();
        assert_eq!(pending.commit().unwrap(), 3);
        assert_eq!(fs::read(&path).unwrap(), b"new");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 1);
        fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn the_namespace_is_the_id_up_to_its_first_slash() {
        assert_eq!(namespace_of("robot1/door/left"), "robot1");
        assert_eq!(namespace_of("door"), "door");
        assert_eq!(namespace_of("/door"), "");
        assert_eq!(namespace_of("robot1/"), "robot1");
    }
}
