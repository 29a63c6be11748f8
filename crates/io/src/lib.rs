//! # chronomap-io
//!
//! File formats, dataset readers, model files and plots of chronomap (overview to follow).
#![deny(missing_docs)]

pub mod model_file;
pub mod plot;
pub mod text;

pub use model_file::{
    ModelFileError, ModelFileErrorKind, decode_model, encode_model, read_model_file,
    write_model_file,
};
pub use text::{
    DataError, DataErrorKind, Field, TimeSeries, read_column, read_column_from, read_pairs,
    read_pairs_from, read_test_set, read_test_set_from,
};
