//! Loaders of whole datasets from a directory, for experiments that span several files
//! (exploration of the Aruba apartment and the Brayford office, [Santos 2017] §6). Each loader takes
//! a directory so that the same command runs on any period published in the same format.

use std::path::{Path, PathBuf};

use chronomap_explore::World;
use thiserror::Error;

use chronomap_io::text::{DataError, Field, read_column, read_pairs};

/// Why a dataset directory could not be loaded.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum DatasetError {
    /// A file of the dataset is malformed.
    #[error(transparent)]
    Data(#[from] DataError),
    /// The directory does not hold the dataset's files.
    #[error("{dir}: {reason}")]
    Layout {
        /// The directory.
        dir: PathBuf,
        /// What is missing or inconsistent.
        reason: String,
    },
}

/// Files `<prefix><n>.txt` (or `.txt.xz`, `.txt.gz`) in `dir`, numbered 0, 1, … without gaps.
fn numbered_files(dir: &Path, prefix: &str) -> Result<Vec<PathBuf>, DatasetError> {
    let mut files = Vec::new();
    for n in 0.. {
        let found = ["txt", "txt.xz", "txt.gz"]
            .iter()
            .map(|ext| dir.join(format!("{prefix}{n}.{ext}")))
            .find(|p| p.is_file());
        match found {
            Some(path) => files.push(path),
            None => break,
        }
    }
    if files.is_empty() {
        return Err(DatasetError::Layout {
            dir: dir.to_path_buf(),
            reason: format!("no {prefix}0.txt (or .txt.xz / .txt.gz) here"),
        });
    }
    Ok(files)
}

fn binary(values: &[f64], file: &Path) -> Result<Vec<u8>, DatasetError> {
    match values.iter().position(|&v| v != 0.0 && v != 1.0) {
        Some(i) => Err(DatasetError::Layout {
            dir: file.to_path_buf(),
            reason: format!("observation {} is {}, not 0 or 1", i + 1, values[i]),
        }),
        None => Ok(values.iter().map(|&v| v as u8).collect()),
    }
}

/// The CASAS Aruba apartment ([Santos 2017] §6.1): `presence_minutes_R.txt` (`t value` lines, one
/// file per area R = 0, 1, …, the same times in every file, one step per minute). Every area
/// is its own location.
///
/// # Errors
/// Missing files, malformed lines (naming file and line), files with different times, uneven
/// steps or non-binary values.
pub fn load_aruba(dir: &Path) -> Result<World, DatasetError> {
    let files = numbered_files(dir, "presence_minutes_")?;
    let series = files
        .iter()
        .map(read_pairs)
        .collect::<Result<Vec<_>, _>>()?;
    let times = &series[0].times;
    for (s, file) in series.iter().zip(&files).skip(1) {
        if &s.times != times {
            return Err(DatasetError::Layout {
                dir: file.clone(),
                reason: format!("its times differ from those of {}", files[0].display()),
            });
        }
    }
    let step = if times.len() > 1 {
        times[1] - times[0]
    } else {
        60.0
    };
    if let Some(i) = times
        .windows(2)
        .position(|w| (w[1] - w[0] - step).abs() > 1e-6)
    {
        return Err(DatasetError::Layout {
            dir: files[0].clone(),
            reason: format!("observation {} breaks the {step} s step", i + 2),
        });
    }
    let truth = series
        .iter()
        .zip(&files)
        .map(|(s, f)| binary(&s.values, f))
        .collect::<Result<Vec<_>, _>>()?;
    let names = (0..truth.len()).map(|r| format!("area {r}")).collect();
    Ok(World::one_state_per_location(times[0], step, truth, names))
}

/// The Brayford office ([Santos 2017] §6.2): `presence_L.txt` (one 0/1 value per line, line k is
/// the k-th 10-minute slot of the week from its start, taken as time 0), one file per place.
///
/// # Errors
/// Missing files, malformed lines, files of different lengths or non-binary values.
pub fn load_brayford(dir: &Path) -> Result<World, DatasetError> {
    let files = numbered_files(dir, "presence_")?;
    let columns = files
        .iter()
        .map(|f| read_column(f, Field::Value))
        .collect::<Result<Vec<_>, _>>()?;
    for (c, file) in columns.iter().zip(&files).skip(1) {
        if c.len() != columns[0].len() {
            return Err(DatasetError::Layout {
                dir: file.clone(),
                reason: format!(
                    "{} lines but {} has {}",
                    c.len(),
                    files[0].display(),
                    columns[0].len()
                ),
            });
        }
    }
    let truth = columns
        .iter()
        .zip(&files)
        .map(|(c, f)| binary(c, f))
        .collect::<Result<Vec<_>, _>>()?;
    let names = (0..truth.len()).map(|l| format!("place {l}")).collect();
    Ok(World::one_state_per_location(0.0, 600.0, truth, names))
}
