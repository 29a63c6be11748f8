//! Model files with a valid checksum but impossible numbers (NaN, infinities, values out of
//! range) written into their payload: every reader refuses them as inconsistent, or what it
//! accepts still predicts finite numbers in range. The files are made with the crate's own
//! writer, so only the checks after decoding stand between them and the predictions.

use chronomap_core::TemporalModel;
use chronomap_io::model_file::{ModelFileErrorKind, decode_any_model, encode_model};
use chronomap_models::{AnyModel, FitOptions, ModelSpec};
use serde::Serialize;
use serde::ser::SerializeTuple;

/// A payload written as it is: postcard writes each `u8` of a tuple as one byte, so the file
/// holds these bytes after a header with their length and a valid checksum.
struct Raw<'a>(&'a [u8]);

impl Serialize for Raw<'_> {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut tuple = serializer.serialize_tuple(self.0.len())?;
        for byte in self.0 {
            tuple.serialize_element(byte)?;
        }
        tuple.end()
    }
}

/// The payload of the model file `bytes` (after the header line).
fn payload(bytes: &[u8]) -> &[u8] {
    let newline = bytes.iter().position(|&b| b == b'\n').unwrap();
    &bytes[newline + 1..]
}

/// The model file of `kind` whose payload is `payload` with the 8 bytes at `offset` replaced
/// by `value` (little-endian, as postcard stores an `f64`), with a valid checksum.
pub fn with_f64_at(kind: &str, payload: &[u8], offset: usize, value: f64) -> Vec<u8> {
    let mut damaged = payload.to_vec();
    damaged[offset..offset + 8].copy_from_slice(&value.to_le_bytes());
    encode_model(kind, &Raw(&damaged)).unwrap()
}

/// The values written over every offset of a payload.
pub const HOSTILE: [f64; 4] = [f64::NAN, f64::NEG_INFINITY, -1.0, 1e308];

/// A door open 8:00-18:00 on weekdays, every half hour for three weeks, with some noise.
fn door() -> (Vec<f64>, Vec<f64>) {
    let times: Vec<f64> = (0..1008)
        .map(|i| 1_451_865_600.0 + 1800.0 * i as f64)
        .collect();
    let values = times
        .iter()
        .enumerate()
        .map(|(i, &t)| {
            let hour = (t % 86_400.0) / 3600.0;
            let weekday = ((t / 86_400.0) as u64 + 4) % 7 < 5;
            let open = weekday && (8.0..18.0).contains(&hour);
            f64::from(u8::from(open != (i % 37 == 0)))
        })
        .collect();
    (times, values)
}

/// Whether `model` predicts probabilities in [0, 1] and finite entropies at a few times.
fn predicts_in_range(model: &AnyModel) -> bool {
    [0.0, 1_451_865_600.0, 1_452_000_000.5, 1_460_000_000.0]
        .iter()
        .all(|&t| {
            let p = model.predict(t);
            (0.0..=1.0).contains(&p) && model.entropy(t).is_finite()
        })
}

#[test]
fn models_with_impossible_numbers_are_refused_after_the_checksum() {
    let (times, values) = door();
    let mut failures = Vec::new();
    for spec in [
        "mean",
        "hist:24",
        "fremen:3",
        "persistence:2",
        "stm",
        "pergam:2",
        "hyt-km",
        "auto",
    ] {
        let fitted = spec
            .parse::<ModelSpec>()
            .unwrap()
            .fit(&times, &values, &FitOptions::default())
            .unwrap();
        let bytes = encode_model(fitted.model.kind(), &fitted.model).unwrap();
        let body = payload(&bytes);
        // Every offset of small payloads; of large ones (hypertime keeps its observations)
        // the start and the fitted part at the end.
        let offsets =
            (0..=body.len() - 8).filter(|&i| body.len() < 4096 || i < 512 || i + 2048 > body.len());
        for offset in offsets {
            for value in HOSTILE {
                let file = with_f64_at(fitted.model.kind(), body, offset, value);
                match decode_any_model(&file) {
                    Ok(model) if !predicts_in_range(&model) => {
                        failures.push(format!("{spec}: {value} at byte {offset}"));
                    }
                    Ok(_) => {}
                    Err(e) => assert!(
                        matches!(
                            e.kind(),
                            ModelFileErrorKind::Decode { .. }
                                | ModelFileErrorKind::Inconsistent { .. }
                        ),
                        "{spec}: {e}"
                    ),
                }
            }
        }
    }
    assert!(failures.is_empty(), "accepted: {failures:#?}");
}

/// The defect as reported: a short-term (Markov) model whose dwell time is NaN, in a file with
/// a valid checksum, made `predict` print `NaN`; now reading it says what is wrong.
#[test]
fn a_nan_parameter_behind_a_valid_checksum_is_refused_when_read() {
    let (times, values) = door();
    let fitted = "stm"
        .parse::<ModelSpec>()
        .unwrap()
        .fit(&times, &values, &FitOptions::default())
        .unwrap();
    let bytes = encode_model("stm", &fitted.model).unwrap();
    // The variant (1 byte), count (varint, 2 bytes), first, last, last value, then D_0.
    let damaged = with_f64_at("stm", payload(&bytes), 27, f64::NAN);
    let dir = chronomap_testutil::scratch!("nan_model");
    let path = dir.join("door.cmm");
    std::fs::write(&path, &damaged).unwrap();
    let err = chronomap_io::model_file::read_any_model(&path).unwrap_err();
    assert!(
        matches!(err.kind(), ModelFileErrorKind::Inconsistent { .. }),
        "{err}"
    );
    assert_eq!(
        err.to_string(),
        format!(
            "{}: the model in the file is inconsistent: the stm model breaks its invariants",
            path.display()
        )
    );
}

/// A stacked model (`auto`) inside a stacked model is refused while decoding, at the second
/// level: a file nesting them 100,000 deep gets a decoding error, not a stack overflow
/// (without the refusal, this test overflows its thread's stack).
#[test]
fn stacked_models_nested_in_a_file_are_refused_without_recursion() {
    let (times, values) = door();
    let fitted = ModelSpec::Auto
        .fit(&times, &values, &FitOptions::default())
        .unwrap();
    assert_eq!(fitted.model.kind(), "stack");
    let bytes = encode_model("stack", &fitted.model).unwrap();
    let stack = payload(&bytes);
    let variant = stack[0];
    for depth in [100_000usize, 1] {
        // Each level: the variant, one member (the level below), then one weight of 1.0.
        let mut nested = Vec::new();
        for _ in 0..depth {
            nested.extend([variant, 1]);
        }
        nested.extend_from_slice(stack);
        for _ in 0..depth {
            nested.push(1);
            nested.extend(1.0f64.to_le_bytes());
        }
        let file = encode_model("stack", &Raw(&nested)).unwrap();
        // (postcard reports the refusal without its message.)
        let err = decode_any_model(&file).unwrap_err();
        assert!(
            matches!(err.kind(), ModelFileErrorKind::Decode { .. }),
            "depth {depth}: {err}"
        );
    }
    // The stack itself reads back and predicts as fitted.
    let model = decode_any_model(&bytes).unwrap();
    let t = times[times.len() - 1] + 3600.0;
    assert_eq!(
        model.predict(t).to_bits(),
        fitted.model.predict(t).to_bits()
    );
}
