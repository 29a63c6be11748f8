//! The append-only observation log: what every write becomes before it is acknowledged.
//!
//! One log entry is one *commit group*: all the records the writer made durable in one
//! transaction, with a format version and a CRC-32 over its payload, so that a torn or
//! foreign entry is refused at recovery instead of silently changing a model.
//!
//! Format 2 (written since) also carries the entry's log position inside the checksum, so that
//! an entry found in the raw bytes of a damaged store file knows where it belongs
//! ([`scan_raw`]); format 1 entries (without it) are still read.

use chronomap_models::learner::Refit;
use serde::{Deserialize, Serialize};

use crate::registry::{ConfigV1, ModelConfig};

/// Format 1 of a commit group: magic, CRC-32 of the payload, payload.
const MAGIC_1: &[u8; 8] = b"CMLOG\x001\n";
/// Format 2: magic, CRC-32 of position and payload, position (u64 little-endian), payload.
const MAGIC: &[u8; 8] = b"CMLOG\x002\n";

/// One change of the service's state.
///
/// Stored as the record kinds `Create`, `Observe`, `Remove`, `Refit`, `CreateOnCalendar` and
/// `RefitWithSpread`, in that order, which only ever grows (the index of a kind is part of the
/// log format): a [`LogRecord::Create`] without a calendar of days off is written as services
/// before calendars wrote it (`Create`, the configuration as a [`ConfigV1`]), one with a
/// calendar as `CreateOnCalendar`; a [`LogRecord::Refit`] without a fit of the second moment
/// as `Refit`, one with it as `RefitWithSpread`. Older logs read as they did.
#[derive(Clone, Debug)]
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
    /// A model fitted on a whole series (`auto`, `fremen:auto`, ...) predicts with this fit of
    /// its kept observations from here on. The fit itself is logged, not only the point where
    /// it was made: the service fits on another thread while observations go on arriving,
    /// and the fit says which of them it covers (`through`), so that replay installs exactly
    /// what the live service installed, without fitting again.
    Refit {
        /// Model id.
        id: String,
        /// The fit ([`chronomap_models::Learner::install`]).
        refit: Box<Refit>,
        /// The fit of the model of the second moment of a model of continuous values
        /// ([`crate::registry::Entry::spread`]) on the same observations, squared; `None`
        /// for every other model (and if that fit failed).
        spread: Option<Box<Refit>>,
    },
}

/// How a [`LogRecord`] is stored; variants are only ever appended.
#[derive(Serialize, Deserialize)]
#[serde(rename = "LogRecord")]
enum Wire<Id, Times, Config, Fit> {
    /// A model without a calendar is created (the only `Create` before calendars).
    Create {
        /// Model id.
        id: Id,
        /// Its configuration, without a calendar.
        config: ConfigV1,
    },
    /// As [`LogRecord::Observe`].
    Observe {
        /// Model id.
        id: Id,
        /// Times (s).
        times: Times,
        /// Values.
        values: Times,
    },
    /// As [`LogRecord::Remove`].
    Remove {
        /// Model id.
        id: Id,
    },
    /// As [`LogRecord::Refit`].
    Refit {
        /// Model id.
        id: Id,
        /// The fit.
        refit: Fit,
    },
    /// A model with a calendar of days off is created.
    CreateOnCalendar {
        /// Model id.
        id: Id,
        /// Its whole configuration.
        config: Config,
    },
    /// As [`LogRecord::Refit`] with a fit of the second moment.
    RefitWithSpread {
        /// Model id.
        id: Id,
        /// The fit.
        refit: Fit,
        /// The fit of the second moment.
        spread: Fit,
    },
}

impl Serialize for LogRecord {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        // Borrowed, so that writing observations copies nothing.
        let wire: Wire<&str, &[f64], &ModelConfig, &Refit> = match self {
            LogRecord::Create { id, config } if config.days_off.is_empty() => Wire::Create {
                id,
                config: ConfigV1 {
                    spec: config.spec.clone(),
                    range: config.range,
                },
            },
            LogRecord::Create { id, config } => Wire::CreateOnCalendar { id, config },
            LogRecord::Observe { id, times, values } => Wire::Observe { id, times, values },
            LogRecord::Remove { id } => Wire::Remove { id },
            LogRecord::Refit {
                id,
                refit,
                spread: None,
            } => Wire::Refit { id, refit },
            LogRecord::Refit {
                id,
                refit,
                spread: Some(spread),
            } => Wire::RefitWithSpread { id, refit, spread },
        };
        wire.serialize(serializer)
    }
}

impl<'de> Deserialize<'de> for LogRecord {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        type Owned = Wire<String, Vec<f64>, ModelConfig, Box<Refit>>;
        Ok(match Owned::deserialize(deserializer)? {
            Wire::Create { id, config } => LogRecord::Create {
                id,
                config: config.into(),
            },
            Wire::CreateOnCalendar { id, config } => LogRecord::Create { id, config },
            Wire::Observe { id, times, values } => LogRecord::Observe { id, times, values },
            Wire::Remove { id } => LogRecord::Remove { id },
            Wire::Refit { id, refit } => LogRecord::Refit {
                id,
                refit,
                spread: None,
            },
            Wire::RefitWithSpread { id, refit, spread } => LogRecord::Refit {
                id,
                refit,
                spread: Some(spread),
            },
        })
    }
}

impl PartialEq for LogRecord {
    fn eq(&self, other: &Self) -> bool {
        use LogRecord::*;
        match (self, other) {
            (Create { id, config }, Create { id: i, config: c }) => id == i && config == c,
            (
                Observe { id, times, values },
                Observe {
                    id: i,
                    times: t,
                    values: v,
                },
            ) => id == i && times == t && values == v,
            (Remove { id }, Remove { id: i }) => id == i,
            // Models have no `PartialEq`: fits are equal when they serialise alike.
            (
                Refit { id, refit, spread },
                Refit {
                    id: i,
                    refit: r,
                    spread: s,
                },
            ) => {
                let bytes = |fit| postcard::to_allocvec(fit).ok();
                id == i
                    && bytes(refit) == bytes(r)
                    && spread.as_ref().map(bytes) == s.as_ref().map(bytes)
            }
            _ => false,
        }
    }
}

impl LogRecord {
    /// The id the record concerns.
    pub fn id(&self) -> &str {
        match self {
            LogRecord::Create { id, .. }
            | LogRecord::Observe { id, .. }
            | LogRecord::Remove { id }
            | LogRecord::Refit { id, .. } => id,
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
    /// Not a commit group of a known format.
    #[error("log entry {seq}: not a chronomap commit group of format 1 or 2")]
    Format {
        /// Log position.
        seq: u64,
    },
    /// An intact entry that says it belongs at another position.
    #[error("log entry {seq}: holds the entry of position {stored}")]
    Misplaced {
        /// Log position.
        seq: u64,
        /// The position inside the entry.
        stored: u64,
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

/// Encodes a commit group for log position `seq` (format 2).
pub fn encode_group(seq: u64, records: &[LogRecord]) -> Vec<u8> {
    let payload = postcard::to_allocvec(records).expect("log records always serialise");
    let mut bytes = Vec::with_capacity(MAGIC.len() + 12 + payload.len());
    bytes.extend_from_slice(MAGIC);
    let mut crc = crc32fast::Hasher::new();
    crc.update(&seq.to_le_bytes());
    crc.update(&payload);
    bytes.extend_from_slice(&crc.finalize().to_le_bytes());
    bytes.extend_from_slice(&seq.to_le_bytes());
    bytes.extend_from_slice(&payload);
    bytes
}

/// Decodes a commit group stored at log position `seq`.
///
/// # Errors
/// Unknown format, checksum mismatch, an entry of another position, undecodable payload.
pub fn decode_group(seq: u64, bytes: &[u8]) -> Result<Vec<LogRecord>, LogError> {
    let (stored_crc, computed, payload) = checked_parts(seq, bytes)?;
    if stored_crc != computed {
        return Err(LogError::Checksum {
            seq,
            stored: stored_crc,
            computed,
        });
    }
    if bytes[..MAGIC.len()] == *MAGIC {
        let stored = u64::from_le_bytes(bytes[12..20].try_into().expect("8 bytes"));
        if stored != seq {
            return Err(LogError::Misplaced { seq, stored });
        }
    }
    decode_payload(seq, payload)
}

/// Stored and computed CRC-32 and the payload of an entry of a known format.
fn checked_parts(seq: u64, bytes: &[u8]) -> Result<(u32, u32, &[u8]), LogError> {
    let magic = bytes.get(..MAGIC.len()).ok_or(LogError::Format { seq })?;
    let crc_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    if magic == MAGIC_1 && bytes.len() >= 12 {
        let payload = &bytes[12..];
        Ok((crc_at(8), crc32fast::hash(payload), payload))
    } else if magic == MAGIC && bytes.len() >= 20 {
        Ok((crc_at(8), crc32fast::hash(&bytes[12..]), &bytes[20..]))
    } else {
        Err(LogError::Format { seq })
    }
}

fn decode_payload(seq: u64, payload: &[u8]) -> Result<Vec<LogRecord>, LogError> {
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

/// The model ids a damaged entry still names, read despite its checksum (a flipped byte in a
/// time leaves the ids readable); empty when its payload does not decode. A damaged entry may
/// have changed other models too.
pub fn ids_of_damaged(bytes: &[u8]) -> Vec<String> {
    let Ok((_, _, payload)) = checked_parts(0, bytes) else {
        return Vec::new();
    };
    let Ok((records, _)) = postcard::take_from_bytes::<Vec<LogRecord>>(payload) else {
        return Vec::new();
    };
    let mut ids: Vec<String> = records.iter().map(|r| r.id().to_owned()).collect();
    ids.sort();
    ids.dedup();
    ids
}

/// Every intact format-2 commit group in raw bytes (a store file redb can no longer open):
/// `(position, entry bytes)`, in the order found; copies may repeat (copy-on-write stores keep
/// old pages), and a position may have two different intact entries (one of a transaction that
/// never committed), which the caller must resolve.
pub fn scan_raw(bytes: &[u8]) -> Vec<(u64, Vec<u8>)> {
    let mut found = Vec::new();
    let mut at = 0;
    while let Some(offset) = find(&bytes[at..], MAGIC) {
        let start = at + offset;
        at = start + 1;
        let Some(header) = bytes.get(start..start + 20) else {
            break;
        };
        let stored_crc = u32::from_le_bytes(header[8..12].try_into().expect("4 bytes"));
        let seq = u64::from_le_bytes(header[12..20].try_into().expect("8 bytes"));
        let rest = &bytes[start + 20..];
        let Ok((_, left)) = postcard::take_from_bytes::<Vec<LogRecord>>(rest) else {
            continue;
        };
        let end = bytes.len() - left.len();
        if crc32fast::hash(&bytes[start + 12..end]) == stored_crc {
            found.push((seq, bytes[start..end].to_vec()));
            at = end;
        }
    }
    found
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
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
        let bytes = encode_group(7, &group());
        assert_eq!(decode_group(7, &bytes).unwrap(), group());
        // Format 1 (no position) is still read.
        let payload = postcard::to_allocvec(&group()).unwrap();
        let mut old = MAGIC_1.to_vec();
        old.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
        old.extend_from_slice(&payload);
        assert_eq!(decode_group(3, &old).unwrap(), group());
    }

    #[test]
    fn a_creation_with_a_calendar_is_a_record_kind_of_its_own() {
        let days_off = chronomap_core::calendar::DaysOff::new([16_885, 16_888]);
        let config = ModelConfig::parse(Some("auto"), Some([0.0, 5.0]))
            .unwrap()
            .with_days_off(days_off);
        let records = vec![LogRecord::Create {
            id: "door".into(),
            config,
        }];
        let payload = postcard::to_allocvec(&records).unwrap();
        // One record, of the fifth kind (appended after `Refit`).
        assert_eq!(payload[..2], [1, 4]);
        assert_eq!(
            decode_group(2, &encode_group(2, &records)).unwrap(),
            records
        );
        // Without a calendar, the first kind as before.
        assert_eq!(postcard::to_allocvec(&group()).unwrap()[..2], [3, 0]);
    }

    #[test]
    fn a_refit_with_its_second_moment_is_a_record_kind_of_its_own() {
        use chronomap_core::TemporalModel as _;
        let fit = |values: &[f64]| {
            let mut learner = "fremen:auto"
                .parse::<chronomap_models::ModelSpec>()
                .unwrap()
                .learner(100)
                .unwrap();
            let times: Vec<f64> = (0..values.len()).map(|i| 3600.0 * i as f64).collect();
            learner.observe(&times, values).unwrap();
            Box::new(
                learner
                    .refit_job()
                    .unwrap()
                    .run(&chronomap_models::FitOptions::default())
                    .unwrap(),
            )
        };
        let values: Vec<f64> = (0..48).map(|h| f64::from(h % 24) / 24.0).collect();
        let squares: Vec<f64> = values.iter().map(|v| v * v).collect();
        let without = vec![LogRecord::Refit {
            id: "temp".into(),
            refit: fit(&values),
            spread: None,
        }];
        let with = vec![LogRecord::Refit {
            id: "temp".into(),
            refit: fit(&values),
            spread: Some(fit(&squares)),
        }];
        // Without a second moment the fourth kind, as before; with one the sixth.
        assert_eq!(postcard::to_allocvec(&without).unwrap()[..2], [1, 3]);
        assert_eq!(postcard::to_allocvec(&with).unwrap()[..2], [1, 5]);
        for records in [without, with] {
            assert_eq!(
                decode_group(4, &encode_group(4, &records)).unwrap(),
                records
            );
        }
    }

    #[test]
    fn raw_bytes_give_back_every_intact_group_with_its_position() {
        let mut file = b"redb header and pages ...".to_vec();
        file.extend(encode_group(1, &group()));
        file.extend([0u8; 100]);
        let mut damaged = encode_group(2, &group());
        // A flipped bit in the time 2.5: the checksum fails, the ids still read.
        let time = damaged
            .windows(8)
            .position(|w| w == 2.5f64.to_le_bytes())
            .unwrap();
        damaged[time] ^= 0x10;
        assert_eq!(ids_of_damaged(&damaged), vec!["door".to_string()]);
        file.extend(&damaged);
        file.extend(encode_group(3, &group()[..1]));
        let found = scan_raw(&file);
        let positions: Vec<u64> = found.iter().map(|(seq, _)| *seq).collect();
        assert_eq!(positions, vec![1, 3]);
        assert_eq!(decode_group(3, &found[1].1).unwrap(), group()[..1]);
    }

    #[test]
    fn damaged_groups_are_refused() {
        let bytes = encode_group(3, &group());
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
        assert_eq!(
            decode_group(4, &bytes),
            Err(LogError::Misplaced { seq: 4, stored: 3 })
        );
        let mut other_version = bytes;
        other_version[6] = b'3';
        assert_eq!(
            decode_group(5, &other_version),
            Err(LogError::Format { seq: 5 })
        );
    }
}
