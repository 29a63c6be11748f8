//! Grid files: the learning state of a [`FremenGrid`], its compact ("lossy") model or its
//! lossless model, in the versioned, checksummed container of [`crate::model_file`].

use std::path::Path;

use chronomap_grid::{FittedGrid, FremenGrid, LosslessGrid};
use serde::{Deserialize, Serialize};

use crate::model_file::{
    CheckedPayload, ModelFileError, decode_checked, encode_model, read_checked, write_model_file,
};

/// What a grid file holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum GridFile {
    /// Everything needed to continue learning (exact accumulators of every changing cell).
    State(Box<FremenGrid>),
    /// The compact model: predicts maps, cannot learn further ([Krajník 2017] §VI "lossy").
    Lossy(Box<FittedGrid>),
    /// The compact model and the outlier sets that reproduce every frame (§VI "lossless").
    Lossless(Box<LosslessGrid>),
}

impl GridFile {
    /// The kind written in the file header.
    pub fn kind(&self) -> &'static str {
        match self {
            GridFile::State(_) => "grid-state",
            GridFile::Lossy(_) => "grid-lossy",
            GridFile::Lossless(_) => "grid-lossless",
        }
    }
}

impl CheckedPayload for GridFile {
    const NOUN: &'static str = "";

    fn payload_kind(&self) -> &str {
        self.kind()
    }

    fn invariants_hold(&self) -> bool {
        match self {
            GridFile::State(g) => g.is_consistent(),
            GridFile::Lossy(g) => g.is_consistent(),
            GridFile::Lossless(g) => g.is_consistent(),
        }
    }
}

/// Encodes a grid file in memory (its length is the file size of eq. (16)).
///
/// # Errors
/// As [`encode_model`].
pub fn encode_grid(grid: &GridFile) -> Result<Vec<u8>, ModelFileError> {
    encode_model(grid.kind(), grid)
}

/// Decodes a grid file, checking the kind and the grid's invariants.
///
/// # Errors
/// As [`decode_model`](crate::model_file::decode_model), or
/// [`Inconsistent`](crate::model_file::ModelFileErrorKind::Inconsistent).
pub fn decode_grid(bytes: &[u8]) -> Result<GridFile, ModelFileError> {
    decode_checked(bytes)
}

/// Writes a grid file atomically.
///
/// # Errors
/// As [`write_model_file`].
pub fn write_grid_file(path: impl AsRef<Path>, grid: &GridFile) -> Result<(), ModelFileError> {
    write_model_file(path, grid.kind(), grid)
}

/// Reads a grid file, checking version, checksum, kind and invariants.
///
/// # Errors
/// As [`read_model_file`](crate::model_file::read_model_file), or
/// [`Inconsistent`](crate::model_file::ModelFileErrorKind::Inconsistent); errors name the path.
pub fn read_grid_file(path: impl AsRef<Path>) -> Result<GridFile, ModelFileError> {
    read_checked(path.as_ref())
}
