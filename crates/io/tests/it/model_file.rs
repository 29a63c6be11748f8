//! Model files: round trips are bit-exact, and every kind of damage is detected, never a panic.

use std::path::PathBuf;

use chronomap_core::{FremenModel, TemporalModel};
use chronomap_io::model_file::{
    FORMAT_VERSION, ModelFileErrorKind, decode_model, encode_model, read_model_file,
    write_model_file,
};
use serde::{Deserialize, Serialize};

#[derive(Debug, PartialEq, Serialize, Deserialize)]
struct Small {
    name: String,
    sums: Vec<i128>,
    x: f64,
}

fn small() -> Small {
    Small {
        name: "door".into(),
        sums: vec![i128::MIN, -1, 0, 1, i128::MAX],
        x: -0.1,
    }
}

/// A FreMEn model trained on a few hundred observations of a door open 8:00-18:00 on
/// weekdays, with some noise.
fn trained_fremen() -> FremenModel {
    let times: Vec<f64> = (0..400)
        .map(|i| 1_451_865_600.0 + 1800.0 * i as f64)
        .collect();
    let values: Vec<f64> = times
        .iter()
        .enumerate()
        .map(|(i, &t)| {
            let hour = (t % 86_400.0) / 3600.0;
            let weekday = ((t / 86_400.0) as u64 + 4) % 7 < 5;
            let open = weekday && (8.0..18.0).contains(&hour);
            if i % 37 == 0 {
                f64::from(!open as u8)
            } else {
                f64::from(open as u8)
            }
        })
        .collect();
    let mut model = FremenModel::with_order(3);
    model.observe(&times, &values).unwrap();
    model
}

fn temp_dir(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("chronomap-io-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `bytes` with the first `from` in the header line replaced by `to` (payload untouched).
fn replace_in_header(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    let end = bytes.iter().position(|&b| b == b'\n').unwrap();
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    assert!(header.contains(from));
    let mut out = header.replacen(from, to, 1).into_bytes();
    out.extend_from_slice(&bytes[end..]);
    out
}

fn decode_small(bytes: &[u8]) -> Result<(String, Small), chronomap_io::ModelFileError> {
    decode_model(bytes)
}

#[test]
fn fremen_round_trip_predicts_bit_identically() {
    let model = trained_fremen();
    let dir = temp_dir("fremen");
    let path = dir.join("door.cmm");
    write_model_file(&path, "fremen", &model).unwrap();
    let (kind, loaded): (String, FremenModel) = read_model_file(&path).unwrap();
    assert_eq!(kind, "fremen");
    assert_eq!(loaded, model);
    assert_eq!(loaded.span(), model.span());
    for i in 0..2000 {
        let t = 1_451_865_600.0 + 977.0 * i as f64;
        assert_eq!(
            loaded.predict(t).to_bits(),
            model.predict(t).to_bits(),
            "t = {t}"
        );
    }
    assert_eq!(loaded.components(), model.components());
    // encoding is deterministic
    assert_eq!(
        encode_model("fremen", &loaded).unwrap(),
        std::fs::read(&path).unwrap()
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn i128_and_f64_fields_round_trip() {
    let bytes = encode_model("small", &small()).unwrap();
    let header_end = bytes.iter().position(|&b| b == b'\n').unwrap();
    let header = std::str::from_utf8(&bytes[..header_end]).unwrap();
    let payload_len = bytes.len() - header_end - 1;
    assert!(
        header.starts_with(&format!(
            "chronomap-model {FORMAT_VERSION} kind=small encoding=postcard bytes={payload_len} crc32="
        )),
        "{header}"
    );
    assert_eq!(decode_small(&bytes).unwrap(), ("small".into(), small()));
}

#[test]
fn every_single_byte_change_is_detected() {
    let bytes = encode_model("small", &small()).unwrap();
    for position in 0..bytes.len() {
        for mask in [0x01u8, 0x20, 0x80, 0xFF] {
            let mut damaged = bytes.clone();
            damaged[position] ^= mask;
            assert!(
                decode_small(&damaged).is_err(),
                "flip {mask:#04x} at byte {position} not detected"
            );
        }
    }
    // the same for a real model (payload of a few kilobytes), one mask
    let bytes = encode_model("fremen", &trained_fremen()).unwrap();
    for position in 0..bytes.len() {
        let mut damaged = bytes.clone();
        damaged[position] ^= 0x04;
        assert!(
            decode_model::<FremenModel>(&damaged).is_err(),
            "flip at byte {position} not detected"
        );
    }
}

#[test]
fn payload_and_checksum_damage_is_reported_as_such() {
    let bytes = encode_model("small", &small()).unwrap();
    let mut damaged = bytes.clone();
    *damaged.last_mut().unwrap() ^= 1;
    let err = decode_small(&damaged).unwrap_err();
    assert!(
        matches!(err.kind(), ModelFileErrorKind::ChecksumMismatch { .. }),
        "{err}"
    );
    assert!(
        err.to_string()
            .starts_with("checksum mismatch (header says ")
    );
    // changing the kind in the header is caught by the checksum too
    let err = decode_small(&replace_in_header(&bytes, "kind=small", "kind=smell")).unwrap_err();
    assert!(matches!(
        err.kind(),
        ModelFileErrorKind::ChecksumMismatch { .. }
    ));
}

#[test]
fn truncation_and_extra_bytes_are_detected() {
    let bytes = encode_model("small", &small()).unwrap();
    let header_end = bytes.iter().position(|&b| b == b'\n').unwrap();
    for len in 1..bytes.len() {
        let err = decode_small(&bytes[..len]).unwrap_err();
        if len <= header_end {
            assert!(
                matches!(err.kind(), ModelFileErrorKind::TruncatedHeader { .. }),
                "{len}: {err}"
            );
        } else {
            assert!(
                matches!(err.kind(), ModelFileErrorKind::Truncated { .. }),
                "{len}: {err}"
            );
        }
    }
    let err = decode_small(&bytes[..bytes.len() - 3]).unwrap_err();
    let declared = bytes.len() - header_end - 1;
    assert_eq!(
        err.to_string(),
        format!(
            "truncated: the header announces {declared} payload bytes but only {} follow",
            declared - 3
        )
    );
    let mut longer = bytes.clone();
    longer.extend_from_slice(b"xy");
    let err = decode_small(&longer).unwrap_err();
    assert!(matches!(
        err.kind(),
        ModelFileErrorKind::TrailingBytes { .. }
    ));
    assert_eq!(
        err.to_string(),
        format!(
            "2 unexpected bytes after the payload (the header announces {declared} payload bytes)"
        )
    );
}

#[test]
fn other_versions_are_rejected_naming_the_version() {
    let bytes = encode_model("small", &small()).unwrap();
    let err = decode_small(&replace_in_header(
        &bytes,
        "chronomap-model 1 ",
        "chronomap-model 2 ",
    ))
    .unwrap_err();
    assert!(matches!(err.kind(), ModelFileErrorKind::UnsupportedVersion { found } if found == "2"));
    assert_eq!(
        err.to_string(),
        r#"format version "2" is not supported (this build reads version 1)"#
    );
    // a future version with a header of another shape is still reported as a version problem
    let err = decode_small(b"chronomap-model 17 something else entirely\n...").unwrap_err();
    assert!(
        matches!(err.kind(), ModelFileErrorKind::UnsupportedVersion { found } if found == "17")
    );
    for version in ["01", "+1", "0", "1.0"] {
        let header = format!("chronomap-model {version} kind=small\n");
        let err = decode_small(header.as_bytes()).unwrap_err();
        assert!(
            matches!(err.kind(), ModelFileErrorKind::UnsupportedVersion { .. }),
            "{err}"
        );
    }
}

#[test]
fn garbage_and_empty_input_are_not_model_files() {
    let err = decode_small(b"").unwrap_err();
    assert!(matches!(err.kind(), ModelFileErrorKind::Empty));
    assert_eq!(
        err.to_string(),
        "empty (0 bytes): not a chronomap model file"
    );
    let err = decode_small(b"0 1\n60 0\n").unwrap_err();
    assert!(matches!(
        err.kind(),
        ModelFileErrorKind::NotAModelFile { .. }
    ));
    assert_eq!(
        err.to_string(),
        r#"not a chronomap model file (it starts with "0 1\n60 0\n", expected "chronomap-model ")"#
    );
    let garbage: Vec<u8> = (0..4096u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8)
        .collect();
    assert!(decode_small(&garbage).is_err());
    // the magic word followed by garbage without a line end
    let mut fake = b"chronomap-model 1 ".to_vec();
    fake.extend_from_slice(&[b'x'; 500]);
    let err = decode_small(&fake).unwrap_err();
    assert!(
        matches!(err.kind(), ModelFileErrorKind::MalformedHeader { .. }),
        "{err}"
    );
    let err = decode_small(b"chronomap-model 1 kind=small encoding=postcard bytes=0 crc32=xyz\n")
        .unwrap_err();
    assert!(
        matches!(err.kind(), ModelFileErrorKind::MalformedHeader { .. }),
        "{err}"
    );
}

#[test]
fn payload_of_another_type_does_not_decode() {
    let bytes = encode_model("small", &small()).unwrap();
    let err = decode_model::<FremenModel>(&bytes).unwrap_err();
    assert!(
        matches!(err.kind(), ModelFileErrorKind::Decode { kind, .. } if kind == "small"),
        "{err}"
    );
    // a payload with bytes left over is not accepted either
    let bytes = encode_model("pair", &(1u8, 2u8)).unwrap();
    let err = decode_model::<u8>(&bytes).unwrap_err();
    assert!(
        err.to_string()
            .contains("1 of 2 payload bytes are left over"),
        "{err}"
    );
}

#[test]
fn invalid_kinds_are_refused_when_encoding() {
    for kind in ["", "two words", "k=v", "line\nbreak"] {
        let err = encode_model(kind, &small()).unwrap_err();
        assert!(
            matches!(err.kind(), ModelFileErrorKind::InvalidKind { .. }),
            "{err}"
        );
    }
}

#[test]
fn file_errors_name_the_path_and_writes_leave_no_temporary_files() {
    let dir = temp_dir("files");
    let path = dir.join("m.cmm");
    write_model_file(&path, "small", &small()).unwrap();
    write_model_file(&path, "small", &Small { x: 2.0, ..small() }).unwrap();
    let (_, loaded): (String, Small) = read_model_file(&path).unwrap();
    assert_eq!(loaded.x, 2.0);
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, [std::ffi::OsString::from("m.cmm")]);

    let missing = dir.join("missing.cmm");
    let err = read_model_file::<Small>(&missing).unwrap_err();
    assert!(matches!(
        err.kind(),
        ModelFileErrorKind::Io { action: "read", .. }
    ));
    assert_eq!(err.path(), Some(missing.as_path()));
    assert!(
        err.to_string()
            .starts_with(&format!("{}: cannot read: ", missing.display()))
    );

    let in_missing_dir = dir.join("no/such/dir/m.cmm");
    let err = write_model_file(&in_missing_dir, "small", &small()).unwrap_err();
    assert!(matches!(err.kind(), ModelFileErrorKind::Io { .. }));
    assert_eq!(err.path(), Some(in_missing_dir.as_path()));

    std::fs::write(&path, b"chronomap-model 1 kind=small").unwrap();
    let err = read_model_file::<Small>(&path).unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "{}: truncated: the header line is incomplete (28 bytes)",
            path.display()
        )
    );
    std::fs::remove_dir_all(&dir).unwrap();
}
