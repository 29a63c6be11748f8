//! Property tests of the node's configuration reader (proptest, seeded so that a failure
//! reproduces): arbitrary bytes, and mutations of the bundled configurations (bit flips,
//! overwritten, inserted and deleted bytes, cuts, and values replaced by hostile ones), are
//! read as a configuration or refused with an error naming the file, never a panic.
//!
//! Mutated text names any path (`/`, `/proc/self`, `..`): the properties check the text only
//! ([`NodeConfig::parse_text`]), so that no probe file is made wherever a mutation points;
//! the files and folders are checked by [`NodeConfig::parse`] on the seeds, in a scratch
//! folder.
//!
//! The number of cases is small enough for CI (seconds); set `PROPTEST_CASES` for a deeper
//! run, e.g. `PROPTEST_CASES=100000 cargo test -p chronomap-ros2 --test config_properties`.

use std::path::{Path, PathBuf};

use chronomap_ros2::config::NodeConfig;
use chronomap_testutil::{edit, proptest_config, repo_path};
use proptest::prelude::*;

/// Every section and kind of value the reader knows (saved models, the edge models and the
/// route graph are in the scratch folder: the reader checks that they can be read and
/// written); the unit tests read it too.
const FULL: &str = include_str!("full.yaml");

/// The bundled configurations and [`FULL`], to mutate.
fn seeds() -> Vec<Vec<u8>> {
    [
        "examples/ros2/chronomap.yaml",
        "tests/hostile/ros2_save_dir_file.yaml",
        "tests/hostile/ros2_long_topic.yaml",
    ]
    .iter()
    .map(|p| std::fs::read(repo_path(p)).unwrap())
    .chain(std::iter::once(FULL.as_bytes().to_vec()))
    .collect()
}

/// Values that have broken readers: huge, negative, not numbers, nested, empty, odd text.
const HOSTILE: &[&str] = &[
    "-1",
    "0",
    "1e400",
    "-1e400",
    ".nan",
    ".inf",
    "18446744073709551616",
    "9223372036854775807",
    "~",
    "\"\"",
    "[]",
    "{}",
    "[[[[[[[[[[1]]]]]]]]]]",
    "{a: {b: {c: {d: 1}}}}",
    "!!binary aGVsbG8=",
    "&a [*a]",
    "*undefined",
    "/proc/self",
    "/",
    "..",
    "\"\\u0000\"",
    "fremen:99999999",
    "hist:0",
    "std_msgs/msg/",
    "true",
    "'",
    "\"",
    "|",
    ">-",
];

/// A mutation of `bytes`: flipped bits, overwritten, inserted or deleted bytes, a cut
/// ([`edit`]), or the value after a `: ` replaced by a hostile one.
fn mutate(mut bytes: Vec<u8>, edits: &[(usize, u8, u8)]) -> Vec<u8> {
    for &(at, kind, value) in edits {
        if bytes.is_empty() || kind % 6 != 5 {
            edit(&mut bytes, at, kind % 6, value);
            continue;
        }
        // The next `: ` at or after `at`, its value up to the end of the line.
        let at = at % bytes.len();
        let Some(colon) = bytes[at..].windows(2).position(|w| w == b": ") else {
            continue;
        };
        let start = at + colon + 2;
        let end = bytes[start..]
            .iter()
            .position(|&b| b == b'\n')
            .map_or(bytes.len(), |n| start + n);
        let hostile = HOSTILE[usize::from(value) % HOSTILE.len()].as_bytes();
        bytes.splice(start..end, hostile.iter().copied());
    }
    bytes
}

/// A folder of its own for the configurations read (their relative paths resolve there).
fn scratch() -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "chronomap-ros2-config-properties-{}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Reads `bytes` as the configuration `dir/node.yaml`, its text only (nothing on the file
/// system is looked at or created): a configuration or an error naming a file (this one, or
/// one it names), never a panic.
fn read(dir: &Path, bytes: &[u8]) {
    let path = dir.join("node.yaml");
    if let Err(e) = NodeConfig::parse_text(&path, bytes, None) {
        assert!(!e.file.is_empty() && !e.message.is_empty(), "{e}");
    }
}

proptest! {
    #![proptest_config(proptest_config(256, 20_261_205))]

    #[test]
    fn arbitrary_bytes_never_panic_the_config_reader(
        bytes in proptest::collection::vec(any::<u8>(), 0..512),
    ) {
        read(&scratch(), &bytes);
    }

    #[test]
    fn mutated_configs_never_panic_the_config_reader(
        seed in 0usize..16,
        edits in proptest::collection::vec((any::<usize>(), any::<u8>(), any::<u8>()), 1..8),
    ) {
        let seeds = seeds();
        let bytes = mutate(seeds[seed % seeds.len()].clone(), &edits);
        read(&scratch(), &bytes);
    }
}

/// The seeds themselves read as their authors meant: the bundled example and the full
/// configuration are accepted, the hostile save_dir is refused by line and parameter.
#[test]
fn the_seeds_read_as_expected() {
    let dir = scratch();
    let seeds = seeds();
    let path = dir.join("node.yaml");
    assert!(NodeConfig::parse(&path, &seeds[0], None).is_ok());
    // The edge models are read when the node starts; here only opened.
    std::fs::write(dir.join("witham.cmt"), "edge models").unwrap();
    let e = NodeConfig::parse(&path, &seeds[3], None).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}:47: edges.geojson: its folder {}: No such file or directory (os error 2)",
            path.display(),
            dir.join("out").display()
        )
    );
    std::fs::create_dir_all(dir.join("out")).unwrap();
    let full = NodeConfig::parse(&path, &seeds[3], None).unwrap();
    assert_eq!(full.states.len(), 2);
    assert_eq!(full.save_dir, Some(dir.join("state")));
    let edges = full.edges.unwrap();
    assert_eq!(edges.models, dir.join("witham.cmt"));
    assert_eq!(edges.geojson, dir.join("out/route.geojson"));
    std::fs::write(dir.join("bom.txt"), "x").unwrap();
    let e = NodeConfig::parse(&path, &seeds[1], None).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}:4: save_dir: {} is a file, not a folder",
            path.display(),
            dir.join("bom.txt").display()
        )
    );
}
