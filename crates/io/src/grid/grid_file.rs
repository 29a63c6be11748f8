//! Grid files: the learning state of a [`FremenGrid`], its compact ("lossy") model or its
//! lossless model ([`AnyGrid`] of `chronomap-grid`), in the versioned, checksummed container
//! of [`crate::model_file`].
//!
//! # Formats of the learning state (`grid-state`)
//! The payload starts with the index of what it holds: 1 is a compact model, 2 a lossless
//! one, and the learning state has the format version in its index:
//!
//! * **format 1** (index 0, read only): every changing cell with its own 128-bit sums for every
//!   period (about `64 K` bytes a changing cell for `K` periods), and the slot index of every
//!   cell. Read into the current representation ([`chronomap_grid::format1`]), exactly.
//! * **format 2** (index 3, [`GRID_STATE_FORMAT`], written): the grid as it is held in memory
//!   (see "Memory" in [`chronomap_grid`]): cells that changed a few times as their slots with
//!   inline edges, shared frame prefixes, blocks of 64-bit sums (128-bit once a sum needed
//!   more), no slot index (rebuilt when read).
//!
//! A reader older than format 2 refuses a file of format 2 as a payload that does not decode.

use std::path::Path;

use chronomap_grid::format1::GridStateV1;
use chronomap_grid::{AnyGrid, FittedGrid, FremenGrid, GridStore, LosslessGrid};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::model_file::{
    CheckedPayload, ModelFileError, decode_checked, encode_model, read_checked, write_model_file,
};

/// The format version of the learning state this build writes (see the [module docs](self)).
pub const GRID_STATE_FORMAT: u32 = 2;

/// The kind in the header of a file of a learning state.
const STATE_KIND: &str = "grid-state";

/// An [`AnyGrid`] as the payload of a grid file (the serde forms are this format's).
struct GridPayload(AnyGrid);

/// The payload as stored: postcard writes the variant index first.
#[derive(Deserialize)]
enum StoredGridFile {
    /// A learning state of format 1.
    StateV1(Box<GridStateV1>),
    Lossy(Box<FittedGrid>),
    Lossless(Box<LosslessGrid>),
    /// A learning state of format 2.
    State(Box<FremenGrid>),
}

/// Index of the learning state of format 2 in the payload.
const STATE_INDEX: u32 = 3;

/// An [`AnyGrid`] serialised where it is.
struct GridRef<'a>(&'a AnyGrid);

impl Serialize for GridRef<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        match self.0 {
            AnyGrid::State(grid) => StateRef(grid).serialize(serializer),
            AnyGrid::Lossy(grid) => {
                serializer.serialize_newtype_variant("GridFile", 1, "Lossy", grid.as_ref())
            }
            AnyGrid::Lossless(grid) => {
                serializer.serialize_newtype_variant("GridFile", 2, "Lossless", grid.as_ref())
            }
        }
    }
}

impl<'de> Deserialize<'de> for GridPayload {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        Ok(GridPayload(
            match StoredGridFile::deserialize(deserializer)? {
                StoredGridFile::StateV1(v1) => AnyGrid::State(Box::new(
                    FremenGrid::try_from(*v1).map_err(serde::de::Error::custom)?,
                )),
                StoredGridFile::Lossy(grid) => AnyGrid::Lossy(grid),
                StoredGridFile::Lossless(grid) => AnyGrid::Lossless(grid),
                StoredGridFile::State(grid) => AnyGrid::State(grid),
            },
        ))
    }
}

/// A learning state serialised where it is, as [`AnyGrid::State`] is.
struct StateRef<'a>(&'a FremenGrid);

impl Serialize for StateRef<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_newtype_variant("GridFile", STATE_INDEX, "State", self.0)
    }
}

/// The kind written in the header of a file of `grid`: `grid-state`, `grid-lossy` or
/// `grid-lossless`.
pub fn grid_kind(grid: &AnyGrid) -> &'static str {
    match grid.form() {
        GridStore::State => STATE_KIND,
        GridStore::Lossy => "grid-lossy",
        GridStore::Lossless => "grid-lossless",
    }
}

impl CheckedPayload for GridPayload {
    const NOUN: &'static str = "";

    fn payload_kind(&self) -> &str {
        grid_kind(&self.0)
    }

    fn invariants_hold(&self) -> bool {
        self.0.is_consistent()
    }
}

/// Encodes a grid file in memory (its length is the file size of eq. (16)).
///
/// # Errors
/// As [`encode_model`].
pub fn encode_grid(grid: &AnyGrid) -> Result<Vec<u8>, ModelFileError> {
    encode_model(grid_kind(grid), &GridRef(grid))
}

/// Decodes a grid file, checking the kind and the grid's invariants.
///
/// # Errors
/// As [`decode_model`](crate::model_file::decode_model), or
/// [`Inconsistent`](crate::model_file::ModelFileErrorKind::Inconsistent).
pub fn decode_grid(bytes: &[u8]) -> Result<AnyGrid, ModelFileError> {
    decode_checked::<GridPayload>(bytes).map(|p| p.0)
}

/// Writes a grid file atomically.
///
/// # Errors
/// As [`write_model_file`].
pub fn write_grid_file(path: impl AsRef<Path>, grid: &AnyGrid) -> Result<(), ModelFileError> {
    write_model_file(path, grid_kind(grid), &GridRef(grid))
}

/// Reads a grid file, checking version, checksum, kind and invariants.
///
/// # Errors
/// As [`read_model_file`](crate::model_file::read_model_file), or
/// [`Inconsistent`](crate::model_file::ModelFileErrorKind::Inconsistent); errors name the path.
pub fn read_grid_file(path: impl AsRef<Path>) -> Result<AnyGrid, ModelFileError> {
    read_checked::<GridPayload>(path.as_ref()).map(|p| p.0)
}

/// Encodes the learning state of `grid` as a grid file in memory without copying the grid:
/// the bytes of [`encode_grid`]`(&AnyGrid::State(Box::new(grid.clone())))`.
///
/// # Errors
/// As [`encode_model`].
pub fn encode_grid_state(grid: &FremenGrid) -> Result<Vec<u8>, ModelFileError> {
    encode_model(STATE_KIND, &StateRef(grid))
}

/// Writes the learning state of `grid` as a grid file atomically without copying the grid
/// (a clone would double its memory while saving): the file [`write_grid_file`] writes for
/// `AnyGrid::State(Box::new(grid.clone()))`.
///
/// # Errors
/// As [`write_model_file`].
pub fn write_grid_state(path: impl AsRef<Path>, grid: &FremenGrid) -> Result<(), ModelFileError> {
    write_model_file(path, STATE_KIND, &StateRef(grid))
}
