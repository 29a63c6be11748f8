//! Versioned, checksummed model files.
//!
//! ```
//! use chronomap_core::{FremenModel, TemporalModel};
//! use chronomap_io::model_file::{decode_model, encode_model};
//!
//! let mut door = FremenModel::with_order(2);
//! door.observe(&[0.0, 3600.0, 7200.0], &[0.0, 1.0, 1.0])?;
//! let bytes = encode_model("fremen", &door)?;
//! assert!(bytes.starts_with(b"chronomap-model 1 kind=fremen encoding=postcard bytes="));
//!
//! let (kind, loaded): (String, FremenModel) = decode_model(&bytes)?;
//! assert_eq!(kind, "fremen");
//! assert_eq!(loaded.predict(5000.0).to_bits(), door.predict(5000.0).to_bits());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! # Layout (format version 1)
//! One ASCII header line, then the payload:
//!
//! ```text
//! chronomap-model 1 kind=<kind> encoding=postcard bytes=<payload length> crc32=<8 hex digits>\n
//! <payload: the model serialised with postcard>
//! ```
//!
//! * `<kind>` names what the payload holds (e.g. `fremen`); 1 to [`MAX_KIND_LEN`] characters
//!   from `A-Z a-z 0-9 _ - . : + /`.
//! * `bytes` is the exact payload length in decimal; a file that is shorter or longer is
//!   rejected.
//! * `crc32` (CRC-32/ISO-HDLC, lowercase hex) covers the header text before ` crc32=` **and**
//!   the payload, so a corrupted kind or length is detected as well as a corrupted payload: any
//!   single changed byte of a file is detected.
//! * The payload is [postcard](https://docs.rs/postcard) (compact, little-endian, `f64` stored
//!   bit for bit, `i128` supported). It must decode completely: unused bytes are an error.
//!
//! Readers reject a version they do not know (naming it and the versions they read) instead
//! of guessing. [`write_model_file`] writes atomically: a temporary file in the same directory,
//! flushed to disk, then renamed over the target, so a crash never leaves a half-written model.

use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

#[cfg(feature = "models")]
use chronomap_models::AnyModel;
use serde::Serialize;
use serde::de::DeserializeOwned;
use thiserror::Error;

/// First word of every model file.
pub const MAGIC: &str = "chronomap-model";

/// The format version this build writes.
pub const FORMAT_VERSION: u32 = 1;

/// The format versions this build reads.
pub const SUPPORTED_VERSIONS: &[u32] = &[1];

/// Longest accepted model kind.
pub const MAX_KIND_LEN: usize = 64;

/// Longest possible header line of version 1 (with a kind of [`MAX_KIND_LEN`] and a 20-digit
/// length), newline included; readers do not look further for the end of the header.
const MAX_HEADER_LEN: usize = 160;

/// Longest excerpt of a header quoted in an error message.
const MAX_QUOTED_CHARS: usize = 40;

/// What is wrong with a model file or model bytes.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum ModelFileErrorKind {
    /// The file could not be read or written.
    #[error("cannot {action}: {io}")]
    Io {
        /// What was being done (`"read"`, `"create a temporary file for"`, ...).
        action: &'static str,
        /// The underlying error.
        io: io::Error,
    },
    /// There are no bytes at all.
    #[error("empty (0 bytes): not a chronomap model file")]
    Empty,
    /// The bytes do not start with `chronomap-model `.
    #[error("not a chronomap model file (it starts with {start:?}, expected \"{MAGIC} \")")]
    NotAModelFile {
        /// The first bytes, as text.
        start: String,
    },
    /// The header line ends before it is complete.
    #[error("truncated: the header line is incomplete ({len} bytes)")]
    TruncatedHeader {
        /// Number of bytes present.
        len: usize,
    },
    /// The header names a format version this build cannot read.
    #[error(
        "format version {found:?} is not supported (this build reads version {})",
        Versions
    )]
    UnsupportedVersion {
        /// The version as written in the file.
        found: String,
    },
    /// The header of a supported version is malformed.
    #[error("malformed header {header:?}: {reason}")]
    MalformedHeader {
        /// The header line (shortened if long).
        header: String,
        /// What is wrong.
        reason: &'static str,
    },
    /// The payload encoding is not `postcard`.
    #[error("unsupported payload encoding {found:?} (this build reads \"postcard\")")]
    UnsupportedEncoding {
        /// The encoding named in the header.
        found: String,
    },
    /// A model kind is empty, too long or has characters outside `A-Z a-z 0-9 _ - . : + /`.
    #[error(
        "invalid model kind {kind:?} (1 to {MAX_KIND_LEN} characters from A-Z a-z 0-9 _ - . : + /)"
    )]
    InvalidKind {
        /// The kind.
        kind: String,
    },
    /// The payload is shorter than the header says.
    #[error("truncated: the header announces {declared} payload bytes but only {actual} follow")]
    Truncated {
        /// Payload length in the header.
        declared: u64,
        /// Bytes present after the header.
        actual: u64,
    },
    /// The payload is longer than the header says.
    #[error(
        "{extra} unexpected bytes after the payload (the header announces {declared} payload bytes)",
        extra = actual - declared
    )]
    TrailingBytes {
        /// Payload length in the header.
        declared: u64,
        /// Bytes present after the header.
        actual: u64,
    },
    /// The checksum does not match: the file is corrupted.
    #[error(
        "checksum mismatch (header says {stored:08x}, content has {computed:08x}): the file is corrupted"
    )]
    ChecksumMismatch {
        /// The checksum in the header.
        stored: u32,
        /// The checksum of the content.
        computed: u32,
    },
    /// The model could not be serialised.
    #[error("cannot encode a model of kind {kind:?}: {reason}")]
    Encode {
        /// The kind.
        kind: String,
        /// The serialiser's message.
        reason: String,
    },
    /// The payload passed the checksum but does not decode as the requested type (a model of
    /// another kind, or written by an incompatible build).
    #[error("the payload of kind {kind:?} does not decode as the requested model type: {reason}")]
    Decode {
        /// The kind named in the header.
        kind: String,
        /// The deserialiser's message.
        reason: String,
    },
    /// The payload decodes, but the model in it is not what the header says or breaks the
    /// model's invariants (a file written by hand or by an incompatible build).
    #[error("the model in the file is inconsistent: {reason}")]
    Inconsistent {
        /// What is wrong.
        reason: String,
    },
}

struct Versions;

impl fmt::Display for Versions {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, v) in SUPPORTED_VERSIONS.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{v}")?;
        }
        Ok(())
    }
}

/// Why a model could not be encoded, decoded, written or read.
///
/// Displays as `path: problem` for files (e.g. `door.cmm: checksum mismatch (...)`), or as
/// the problem alone for bytes in memory.
#[derive(Debug, Error)]
#[error("{}{kind}", PathPrefix(.path.as_deref()))]
pub struct ModelFileError {
    path: Option<PathBuf>,
    kind: ModelFileErrorKind,
}

struct PathPrefix<'a>(Option<&'a Path>);

impl fmt::Display for PathPrefix<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(path) => write!(f, "{}: ", path.display()),
            None => Ok(()),
        }
    }
}

impl ModelFileError {
    pub(crate) fn new(kind: ModelFileErrorKind) -> Self {
        ModelFileError { path: None, kind }
    }

    fn at(path: &Path, kind: ModelFileErrorKind) -> Self {
        ModelFileError {
            path: Some(path.to_owned()),
            kind,
        }
    }

    pub(crate) fn in_file(mut self, path: &Path) -> Self {
        self.path = Some(path.to_owned());
        self
    }

    /// The file concerned, if the error came from reading or writing a file.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// What is wrong.
    pub fn kind(&self) -> &ModelFileErrorKind {
        &self.kind
    }
}

/// Whether `kind` is a valid model kind (see the [module docs](self)).
pub fn is_valid_kind(kind: &str) -> bool {
    (1..=MAX_KIND_LEN).contains(&kind.len())
        && kind
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b"_-.:+/".contains(&b))
}

/// Serialises `model` into the bytes of a model file of the given kind.
///
/// # Errors
/// [`ModelFileErrorKind::InvalidKind`], or [`ModelFileErrorKind::Encode`] if serde fails.
pub fn encode_model<T: Serialize + ?Sized>(
    kind: &str,
    model: &T,
) -> Result<Vec<u8>, ModelFileError> {
    if !is_valid_kind(kind) {
        return Err(ModelFileError::new(ModelFileErrorKind::InvalidKind {
            kind: quote(kind.as_bytes()),
        }));
    }
    let bytes = postcard::to_allocvec(model).map_err(|e| {
        ModelFileError::new(ModelFileErrorKind::Encode {
            kind: kind.to_owned(),
            reason: e.to_string(),
        })
    })?;
    encode_payload(kind, bytes)
}

/// The file of a payload already serialised with postcard: the header (kind, length,
/// checksum) in front of `bytes`. [`encode_model`] is this after serialising; on its own it
/// rewraps a payload (for example to check that files of an older layout still read).
///
/// # Errors
/// [`ModelFileErrorKind::InvalidKind`].
pub fn encode_payload(kind: &str, mut bytes: Vec<u8>) -> Result<Vec<u8>, ModelFileError> {
    if !is_valid_kind(kind) {
        return Err(ModelFileError::new(ModelFileErrorKind::InvalidKind {
            kind: quote(kind.as_bytes()),
        }));
    }
    let covered = format!(
        "{MAGIC} {FORMAT_VERSION} kind={kind} encoding=postcard bytes={}",
        bytes.len()
    );
    let crc = checksum(covered.as_bytes(), &bytes);
    // The header goes in front of the payload where it is: a large model (a grid of millions
    // of cells) is not held twice while it is written.
    let header = format!("{covered} crc32={crc:08x}\n");
    bytes.splice(0..0, header.into_bytes());
    Ok(bytes)
}

/// Decodes the bytes of a model file: its kind and the model.
///
/// Everything is checked before the payload is deserialised: magic word, version, header
/// syntax, payload length and checksum.
///
/// # Errors
/// A [`ModelFileErrorKind`] saying what is wrong: [`Empty`](ModelFileErrorKind::Empty),
/// [`NotAModelFile`](ModelFileErrorKind::NotAModelFile),
/// [`UnsupportedVersion`](ModelFileErrorKind::UnsupportedVersion),
/// [`TruncatedHeader`](ModelFileErrorKind::TruncatedHeader) /
/// [`Truncated`](ModelFileErrorKind::Truncated) /
/// [`TrailingBytes`](ModelFileErrorKind::TrailingBytes),
/// [`ChecksumMismatch`](ModelFileErrorKind::ChecksumMismatch),
/// [`MalformedHeader`](ModelFileErrorKind::MalformedHeader) and kin, or
/// [`Decode`](ModelFileErrorKind::Decode) if the payload is not a `T`.
pub fn decode_model<T: DeserializeOwned>(bytes: &[u8]) -> Result<(String, T), ModelFileError> {
    let (kind, payload) = check_container(bytes).map_err(ModelFileError::new)?;
    let decode_error = |reason: String| {
        ModelFileError::new(ModelFileErrorKind::Decode {
            kind: kind.clone(),
            reason,
        })
    };
    let (model, unused) =
        postcard::take_from_bytes::<T>(payload).map_err(|e| decode_error(e.to_string()))?;
    if !unused.is_empty() {
        return Err(decode_error(format!(
            "{} of {} payload bytes are left over",
            unused.len(),
            payload.len()
        )));
    }
    Ok((kind, model))
}

/// Decodes a model whose layout grew a field at its end since older files were written: as
/// the current layout `T`, else as the layout before the field, `Older`, converted (for
/// example with the new field unknown). The two cannot be confused: a payload must decode
/// completely, and an older payload ends before the new field, a newer one has it left over.
///
/// # Errors
/// As [`decode_model`] for the current layout, when neither decodes.
pub fn decode_model_or_older<T, Older>(bytes: &[u8]) -> Result<(String, T), ModelFileError>
where
    T: DeserializeOwned,
    Older: DeserializeOwned + Into<T>,
{
    decode_model::<T>(bytes).or_else(|current| {
        decode_model::<Older>(bytes)
            .map(|(kind, older)| (kind, older.into()))
            .map_err(|_| current)
    })
}

/// Reads a model file as [`decode_model_or_older`] decodes it.
///
/// # Errors
/// As [`read_model_file`].
pub fn read_model_file_or_older<T, Older>(
    path: impl AsRef<Path>,
) -> Result<(String, T), ModelFileError>
where
    T: DeserializeOwned,
    Older: DeserializeOwned + Into<T>,
{
    let path = path.as_ref();
    let bytes = crate::bounded::read(path)
        .map_err(|io| ModelFileError::at(path, ModelFileErrorKind::Io { action: "read", io }))?;
    decode_model_or_older::<T, Older>(&bytes).map_err(|e| e.in_file(path))
}

/// Writes `model` to `path` as a model file of the given kind, atomically: either the complete
/// new file is at `path` afterwards, or the previous content (if any) is left untouched.
///
/// # Errors
/// As [`encode_model`], or [`ModelFileErrorKind::Io`]; all errors name `path`.
pub fn write_model_file<T: Serialize + ?Sized>(
    path: impl AsRef<Path>,
    kind: &str,
    model: &T,
) -> Result<(), ModelFileError> {
    let path = path.as_ref();
    let bytes = encode_model(kind, model).map_err(|e| e.in_file(path))?;
    write_atomically(path, &bytes)
}

/// Reads a model file written by [`write_model_file`]: its kind and the model.
///
/// # Errors
/// [`ModelFileErrorKind::Io`] if the file cannot be read, else as [`decode_model`]; all errors
/// name `path`.
pub fn read_model_file<T: DeserializeOwned>(
    path: impl AsRef<Path>,
) -> Result<(String, T), ModelFileError> {
    let path = path.as_ref();
    let bytes = crate::bounded::read(path)
        .map_err(|io| ModelFileError::at(path, ModelFileErrorKind::Io { action: "read", io }))?;
    decode_model(&bytes).map_err(|e| e.in_file(path))
}

#[cfg(feature = "models")]
/// Writes any chronomap model (its [`AnyModel::kind`] is the file's kind).
///
/// # Errors
/// As [`write_model_file`].
pub fn write_any_model(path: impl AsRef<Path>, model: &AnyModel) -> Result<(), ModelFileError> {
    write_model_file(path, model.kind(), model)
}

#[cfg(feature = "models")]
/// Reads a model written by [`write_any_model`], checking that it is the kind the header says
/// and that its invariants hold, so that a file crafted by hand cannot make later code panic.
///
/// # Errors
/// As [`read_model_file`], or [`ModelFileErrorKind::Inconsistent`].
pub fn read_any_model(path: impl AsRef<Path>) -> Result<AnyModel, ModelFileError> {
    read_checked(path.as_ref())
}

#[cfg(feature = "models")]
/// Decodes a model encoded by [`encode_model`] with [`AnyModel::kind`] as kind, with the checks
/// of [`read_any_model`].
///
/// # Errors
/// As [`decode_model`], or [`ModelFileErrorKind::Inconsistent`].
pub fn decode_any_model(bytes: &[u8]) -> Result<AnyModel, ModelFileError> {
    decode_checked(bytes)
}

#[cfg(feature = "topo")]
/// The kind of edge-model files ([`write_edge_models`]).
pub const EDGE_MODELS_KIND: &str = "topo-edge-models";

#[cfg(feature = "topo")]
/// Writes the models of a topological map's edges (map included) as a model file of kind
/// [`EDGE_MODELS_KIND`], atomically, after the checks of [`read_edge_models`]: a file that
/// would be refused when read is not written.
///
/// # Errors
/// As [`write_model_file`], or [`ModelFileErrorKind::Inconsistent`] naming `path` (nothing
/// is written then).
pub fn write_edge_models(
    path: impl AsRef<Path>,
    models: &chronomap_topo::edges::EdgeModels,
) -> Result<(), ModelFileError> {
    let path = path.as_ref();
    models
        .check()
        .map_err(|reason| ModelFileError::at(path, ModelFileErrorKind::Inconsistent { reason }))?;
    write_model_file(path, EDGE_MODELS_KIND, models)
}

#[cfg(feature = "topo")]
/// Reads a file written by [`write_edge_models`], checking its kind and the models'
/// invariants.
///
/// # Errors
/// As [`read_model_file`], or [`ModelFileErrorKind::Inconsistent`] (another kind of model, or
/// broken invariants).
pub fn read_edge_models(
    path: impl AsRef<Path>,
) -> Result<chronomap_topo::edges::EdgeModels, ModelFileError> {
    let path = path.as_ref();
    let bytes = crate::bounded::read(path)
        .map_err(|io| ModelFileError::at(path, ModelFileErrorKind::Io { action: "read", io }))?;
    decode_edge_models(&bytes).map_err(|e| e.in_file(path))
}

#[cfg(feature = "topo")]
/// Decodes the bytes of an edge-model file, with the checks of [`read_edge_models`].
///
/// # Errors
/// As [`read_edge_models`].
pub fn decode_edge_models(
    bytes: &[u8],
) -> Result<chronomap_topo::edges::EdgeModels, ModelFileError> {
    let (kind, _) = check_container(bytes).map_err(ModelFileError::new)?;
    if kind != EDGE_MODELS_KIND {
        return Err(ModelFileError::new(ModelFileErrorKind::Inconsistent {
            reason: format!("this is a {kind:?} model, not the edge models of a topological map"),
        }));
    }
    // Files written before the spread of the durations adapted online read as not adapted yet,
    // and those written before the models kept the spread read without it.
    use chronomap_topo::edges::{EdgeModels, EdgeModelsWithoutAdaptation, EdgeModelsWithoutSpread};
    let (_, mut models): (String, EdgeModels) =
        decode_model_or_older::<_, EdgeModelsWithoutAdaptation>(bytes).or_else(|current| {
            decode_model_or_older::<EdgeModels, EdgeModelsWithoutSpread>(bytes).map_err(|_| current)
        })?;
    models.reindex();
    models
        .check()
        .map_err(|reason| ModelFileError::new(ModelFileErrorKind::Inconsistent { reason }))?;
    Ok(models)
}

/// A payload that names its own kind and can check its invariants: what [`read_checked`] and
/// [`decode_checked`] compare with the header and verify, so that a file crafted by hand cannot
/// make later code panic.
#[cfg(any(feature = "models", feature = "grid"))]
pub(crate) trait CheckedPayload: DeserializeOwned {
    /// What follows the kind in messages (`" model"`, or nothing).
    const NOUN: &'static str;

    /// The kind of this payload.
    fn payload_kind(&self) -> &str;

    /// Whether its invariants hold.
    fn invariants_hold(&self) -> bool;
}

#[cfg(feature = "models")]
impl CheckedPayload for AnyModel {
    const NOUN: &'static str = " model";

    fn payload_kind(&self) -> &str {
        self.kind()
    }

    fn invariants_hold(&self) -> bool {
        self.is_consistent()
    }
}

/// [`read_model_file`], then the checks of [`CheckedPayload`]; errors name `path`.
#[cfg(any(feature = "models", feature = "grid"))]
pub(crate) fn read_checked<T: CheckedPayload>(path: &Path) -> Result<T, ModelFileError> {
    let (kind, payload): (String, T) = read_model_file(path)?;
    check_payload(&kind, &payload).map_err(|e| e.in_file(path))?;
    Ok(payload)
}

/// [`decode_model`], then the checks of [`CheckedPayload`].
#[cfg(any(feature = "models", feature = "grid"))]
pub(crate) fn decode_checked<T: CheckedPayload>(bytes: &[u8]) -> Result<T, ModelFileError> {
    let (kind, payload): (String, T) = decode_model(bytes)?;
    check_payload(&kind, &payload)?;
    Ok(payload)
}

#[cfg(any(feature = "models", feature = "grid"))]
fn check_payload<T: CheckedPayload>(kind: &str, payload: &T) -> Result<(), ModelFileError> {
    let noun = T::NOUN;
    if kind != payload.payload_kind() {
        return Err(ModelFileError::new(ModelFileErrorKind::Inconsistent {
            reason: format!(
                "the header says {kind:?} but the payload is a {:?}{noun}",
                payload.payload_kind()
            ),
        }));
    }
    if !payload.invariants_hold() {
        return Err(ModelFileError::new(ModelFileErrorKind::Inconsistent {
            reason: format!("the {kind}{noun} breaks its invariants"),
        }));
    }
    Ok(())
}

fn checksum(header: &[u8], payload: &[u8]) -> u32 {
    let mut hasher = crc32fast::Hasher::new();
    hasher.update(header);
    hasher.update(payload);
    hasher.finalize()
}

/// Checks everything but the payload's content; returns the kind and the payload.
fn check_container(bytes: &[u8]) -> Result<(String, &[u8]), ModelFileErrorKind> {
    use ModelFileErrorKind as K;
    if bytes.is_empty() {
        return Err(K::Empty);
    }
    let magic = format!("{MAGIC} ");
    let prefix_len = bytes.len().min(magic.len());
    if bytes[..prefix_len] != magic.as_bytes()[..prefix_len] {
        return Err(K::NotAModelFile {
            start: quote(&bytes[..bytes.len().min(MAX_QUOTED_CHARS)]),
        });
    }
    let window = &bytes[..bytes.len().min(MAX_HEADER_LEN)];
    let Some(newline) = window.iter().position(|&b| b == b'\n') else {
        if bytes.len() < MAX_HEADER_LEN {
            return Err(K::TruncatedHeader { len: bytes.len() });
        }
        // Still tell a newer version apart from garbage after the magic word.
        return Err(
            version_error(&bytes[magic.len()..]).unwrap_or(K::MalformedHeader {
                header: quote(window),
                reason: "no line end within the longest possible header",
            }),
        );
    };
    let header_bytes = &bytes[..newline];
    let payload = &bytes[newline + 1..];
    if let Some(error) = version_error(&header_bytes[magic.len().min(header_bytes.len())..]) {
        return Err(error);
    }
    let malformed = |reason| K::MalformedHeader {
        header: quote(header_bytes),
        reason,
    };
    let header = std::str::from_utf8(header_bytes).map_err(|_| malformed("not ASCII text"))?;
    let Some((covered, crc_text)) = header.rsplit_once(" crc32=") else {
        return Err(malformed("no crc32 field at the end"));
    };
    let mut words = covered.split(' ');
    let (Some(_magic), Some(_version), Some(kind), Some(encoding), Some(length), None) = (
        words.next(),
        words.next(),
        words.next(),
        words.next(),
        words.next(),
        words.next(),
    ) else {
        return Err(malformed(
            "expected 6 fields: chronomap-model 1 kind= encoding= bytes= crc32=",
        ));
    };
    let kind = kind
        .strip_prefix("kind=")
        .ok_or_else(|| malformed("third field is not kind=..."))?;
    let encoding = encoding
        .strip_prefix("encoding=")
        .ok_or_else(|| malformed("fourth field is not encoding=..."))?;
    let length = length
        .strip_prefix("bytes=")
        .ok_or_else(|| malformed("fifth field is not bytes=..."))?;
    if crc_text.len() != 8
        || !crc_text
            .bytes()
            .all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f'))
    {
        return Err(malformed("crc32 is not 8 lowercase hexadecimal digits"));
    }
    let stored = u32::from_str_radix(crc_text, 16).map_err(|_| malformed("crc32 is not hex"))?;
    if length.is_empty() || !length.bytes().all(|b| b.is_ascii_digit()) {
        return Err(malformed("bytes= is not a decimal number"));
    }
    let declared: u64 = length
        .parse()
        .map_err(|_| malformed("bytes= is too large"))?;
    let computed = checksum(covered.as_bytes(), payload);
    let actual = payload.len() as u64;
    // Length first: a truncated file is reported as truncated, not as merely corrupted.
    if actual < declared {
        return Err(K::Truncated { declared, actual });
    }
    if actual > declared {
        return Err(K::TrailingBytes { declared, actual });
    }
    if computed != stored {
        return Err(K::ChecksumMismatch { stored, computed });
    }
    if encoding != "postcard" {
        return Err(K::UnsupportedEncoding {
            found: encoding.to_owned(),
        });
    }
    if !is_valid_kind(kind) {
        return Err(K::InvalidKind {
            kind: quote(kind.as_bytes()),
        });
    }
    Ok((kind.to_owned(), payload))
}

/// The version error for the text after the magic word, if its first word is not a
/// supported version.
fn version_error(after_magic: &[u8]) -> Option<ModelFileErrorKind> {
    let end = after_magic
        .iter()
        .position(|&b| b == b' ' || b == b'\n')
        .unwrap_or(after_magic.len());
    let word = &after_magic[..end];
    let supported = std::str::from_utf8(word)
        .ok()
        .and_then(|w| w.parse::<u32>().ok())
        .is_some_and(|v| SUPPORTED_VERSIONS.contains(&v) && is_canonical_number(word));
    (!supported).then(|| ModelFileErrorKind::UnsupportedVersion {
        found: quote(&word[..word.len().min(MAX_QUOTED_CHARS)]),
    })
}

/// Whether a version number is written without sign or leading zeros.
fn is_canonical_number(word: &[u8]) -> bool {
    word.first().is_some_and(|&b| b != b'0' && b != b'+')
}

fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), ModelFileError> {
    crate::atomic::write_atomically(path, bytes).map_err(|f| {
        ModelFileError::at(
            path,
            ModelFileErrorKind::Io {
                action: f.action,
                io: f.io,
            },
        )
    })
}

/// Header or payload excerpt for an error message (lossy UTF-8, shortened if long).
fn quote(bytes: &[u8]) -> String {
    crate::text::shorten(&String::from_utf8_lossy(bytes), MAX_HEADER_LEN)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_are_restricted_to_a_safe_alphabet() {
        assert!(is_valid_kind("fremen"));
        assert!(is_valid_kind("fremen:4"));
        assert!(is_valid_kind("any/v2+x_y-z.q"));
        assert!(!is_valid_kind(""));
        assert!(!is_valid_kind("a b"));
        assert!(!is_valid_kind("a=b"));
        assert!(!is_valid_kind("a\nb"));
        assert!(!is_valid_kind(&"x".repeat(MAX_KIND_LEN + 1)));
    }

    #[test]
    fn header_fits_in_the_search_window() {
        let kind = "k".repeat(MAX_KIND_LEN);
        let header = format!(
            "{MAGIC} {FORMAT_VERSION} kind={kind} encoding=postcard bytes={} crc32=ffffffff\n",
            u64::MAX
        );
        assert!(header.len() <= MAX_HEADER_LEN, "{}", header.len());
    }
}
