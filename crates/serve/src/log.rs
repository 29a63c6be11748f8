//! The append-only observation log: what every write becomes before it is acknowledged.
//!
//! One log entry is one *commit group*: all the records the writer made durable in one
//! transaction, with a format version and a CRC-32 over its payload, so that a torn or
//! foreign entry is refused at recovery instead of silently changing a model.

use serde::{Deserialize, Serialize};

use crate::registry::ModelConfig;

/// Format of a commit group (first bytes of every log entry).
const MAGIC: &[u8; 8] = b"CMLOG\x001\n";

/// One change of the service's state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum LogRecord {
    /// A model is created.
    Create {
        /// Model id.
        id: String,
        /// Its configuration.
        config: ModelConfig,
    },
    /// Observations are added (values as given, in the model's range).
    Observe {
        /// Model id.
        id: String,
        /// Times (s).
        times: Vec<f64>,
        /// Values.
        values: Vec<f64>,
    },
    /// A model is removed.
    Remove {
        /// Model id.
        id: String,
    },
}

impl LogRecord {
    /// The id the record concerns.
    pub fn id(&self) -> &str {
        match self {
            LogRecord::Create { id, .. }
            | LogRecord::Observe { id, .. }
            | LogRecord::Remove { id } => id,
        }
    }

    /// Number of observations it adds.
    pub fn observations(&self) -> usize {
        match self {
            LogRecord::Observe { times, .. } => times.len(),
            _ => 0,
        }
    }
}

/// Why a log entry cannot be read.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum LogError {
    /// Not a commit group of this version.
    #[error("log entry {seq}: not a chronomap commit group of format 1")]
    Format {
        /// Log position.
        seq: u64,
    },
    /// The checksum does not match.
    #[error("log entry {seq}: checksum mismatch (stored {stored:08x}, computed {computed:08x})")]
    Checksum {
        /// Log position.
        seq: u64,
        /// Stored CRC-32.
        stored: u32,
        /// Computed CRC-32.
        computed: u32,
    },
    /// The payload does not decode.
    #[error("log entry {seq}: {reason}")]
    Decode {
        /// Log position.
        seq: u64,
        /// Why.
        reason: String,
    },
}

/// Encodes a commit group.
pub fn encode_group(records: &[LogRecord]) -> Vec<u8> {
    let payload = postcard::to_allocvec(records).expect("log records always serialise");
    let mut bytes = Vec::with_capacity(MAGIC.len() + 4 + payload.len());
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    bytes.extend_from_slice(&payload);
    bytes
}

/// Decodes a commit group stored at log position `seq`.
///
/// # Errors
/// Wrong format, checksum mismatch or undecodable payload.
pub fn decode_group(seq: u64, bytes: &[u8]) -> Result<Vec<LogRecord>, LogError> {
    let header = MAGIC.len() + 4;
    if bytes.len() < header || &bytes[..MAGIC.len()] != MAGIC {
        return Err(LogError::Format { seq });
    }
    let stored = u32::from_le_bytes(bytes[MAGIC.len()..header].try_into().expect("4 bytes"));
    let payload = &bytes[header..];
    let computed = crc32fast::hash(payload);
    if stored != computed {
        return Err(LogError::Checksum {
            seq,
            stored,
            computed,
        });
    }
    let (records, rest) =
        postcard::take_from_bytes::<Vec<LogRecord>>(payload).map_err(|e| LogError::Decode {
            seq,
            reason: e.to_string(),
        })?;
    if !rest.is_empty() {
        return Err(LogError::Decode {
            seq,
            reason: format!("{} bytes left over", rest.len()),
        });
    }
    Ok(records)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::registry::ModelConfig;

    fn group() -> Vec<LogRecord> {
        vec![
            LogRecord::Create {
                id: "door".into(),
                config: ModelConfig::parse(Some("fremen:3"), None).unwrap(),
            },
            LogRecord::Observe {
                id: "door".into(),
                times: vec![1.0, 2.5],
                values: vec![0.0, 1.0],
            },
            LogRecord::Remove { id: "door".into() },
        ]
    }

    #[test]
    fn groups_round_trip() {
        let bytes = encode_group(&group());
        assert_eq!(decode_group(7, &bytes).unwrap(), group());
    }

    #[test]
    fn damaged_groups_are_refused() {
        let bytes = encode_group(&group());
        let mut flipped = bytes.clone();
        *flipped.last_mut().unwrap() ^= 1;
        assert!(matches!(
            decode_group(3, &flipped),
            Err(LogError::Checksum { seq: 3, .. })
        ));
        assert_eq!(
            decode_group(4, &bytes[..10]),
            Err(LogError::Format { seq: 4 })
        );
        let mut other_version = bytes;
        other_version[6] = b'2';
        assert_eq!(
            decode_group(5, &other_version),
            Err(LogError::Format { seq: 5 })
        );
    }
}
