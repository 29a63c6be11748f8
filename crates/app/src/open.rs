//! What kind of file a path holds, by its first bytes where they tell (the magic word of
//! chronomap's model-file container, [`chronomap_io::model_file`]) and by its name where only
//! the name tells (text formats: GeoJSON, tmap2 YAML, BehaviorTree.CPP XML; `.xz` and `.gz`
//! looked through). The faces ask here before they choose a reader; the reader then checks
//! everything (version, checksum, content) and names what is wrong.

use std::io::Read;
use std::path::Path;

use chronomap_io::model_file::{MAGIC, is_valid_kind};
use chronomap_io::{COPA_MAP_KIND, EDGE_MODELS_KIND};
use thiserror::Error;

/// Most bytes read to tell a file's kind: the longest header of the model-file container.
const SNIFF_BYTES: usize = 160;

/// What a file holds, as far as its start or its name tells.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FileKind {
    /// chronomap's versioned, checksummed container: a model, a grid, a CoPA-Map, edge models.
    /// `kind` is the kind the header names (`fremen`, `grid-state`, `copa-map`, …), or the one
    /// the name implies (`.cmt`: edge models, `.cmcopa`: a CoPA-Map); `None` where neither
    /// says (`.cmm`, `.cmg`, a damaged header).
    ModelFile {
        /// The kind, where known.
        kind: Option<String>,
    },
    /// A Nav2 route graph: GeoJSON (`.geojson`, `.json`).
    RouteGeoJson,
    /// A STRANDS topological map (`.tmap2`, `.yaml`, `.yml`).
    Tmap2,
    /// A BehaviorTree.CPP XML document (`.xml`).
    BtXml,
    /// Anything else.
    Other,
}

/// A file whose start cannot be read.
#[derive(Debug, Error)]
#[error("{path}: cannot {action}")]
pub struct SniffError {
    /// The file.
    pub path: String,
    /// `open` or `read`.
    pub action: &'static str,
    /// Why.
    #[source]
    pub source: std::io::Error,
}

impl FileKind {
    /// The kind by the file's start: the model-file container by its magic word (and the kind
    /// its header names), anything else by its name ([`FileKind::by_name`]).
    ///
    /// # Errors
    /// The file cannot be opened or read.
    pub fn of(path: &Path) -> Result<FileKind, SniffError> {
        let fail = |action, source| SniffError {
            path: path.display().to_string(),
            action,
            source,
        };
        let file = std::fs::File::open(path).map_err(|e| fail("open", e))?;
        let mut start = Vec::with_capacity(SNIFF_BYTES);
        file.take(SNIFF_BYTES as u64)
            .read_to_end(&mut start)
            .map_err(|e| fail("read", e))?;
        Ok(FileKind::of_bytes(&start).unwrap_or_else(|| FileKind::by_name(path)))
    }

    /// The model-file container if `start` (the first bytes of a file) begins with its magic
    /// word, with the kind its header names; `None` otherwise.
    pub fn of_bytes(start: &[u8]) -> Option<FileKind> {
        let rest = start.strip_prefix(MAGIC.as_bytes())?.strip_prefix(b" ")?;
        // `VERSION kind=KIND encoding=…`
        let kind = rest
            .split(|&b| b == b' ' || b == b'\n')
            .nth(1)
            .and_then(|field| field.strip_prefix(b"kind="))
            .and_then(|kind| std::str::from_utf8(kind).ok())
            .filter(|kind| is_valid_kind(kind))
            .map(str::to_owned);
        Some(FileKind::ModelFile { kind })
    }

    /// The kind by the file's name alone (a compressed `.xz` or `.gz` file by the name before
    /// that): `.cmm`, `.cmg`, `.cmt`, `.cmcopa` are model files, `.geojson` and `.json` route
    /// graphs, `.tmap2`, `.yaml` and `.yml` tmap2 maps, `.xml` behavior trees.
    pub fn by_name(path: &Path) -> FileKind {
        let extension = |p: &Path| {
            p.extension()
                .and_then(|e| e.to_str())
                .map(str::to_ascii_lowercase)
        };
        let name = match extension(path).as_deref() {
            Some("xz" | "gz") => path.file_stem().and_then(|s| extension(Path::new(s))),
            other => other.map(str::to_owned),
        };
        let model = |kind: Option<&str>| FileKind::ModelFile {
            kind: kind.map(str::to_owned),
        };
        match name.as_deref() {
            Some("cmm" | "cmg") => model(None),
            Some("cmt") => model(Some(EDGE_MODELS_KIND)),
            Some("cmcopa") => model(Some(COPA_MAP_KIND)),
            Some("geojson" | "json") => FileKind::RouteGeoJson,
            Some("tmap2" | "yaml" | "yml") => FileKind::Tmap2,
            Some("xml") => FileKind::BtXml,
            _ => FileKind::Other,
        }
    }

    /// Whether this is chronomap's model-file container.
    pub fn is_model_file(&self) -> bool {
        matches!(self, FileKind::ModelFile { .. })
    }

    /// The kind a model file holds, where known.
    pub fn model_kind(&self) -> Option<&str> {
        match self {
            FileKind::ModelFile { kind } => kind.as_deref(),
            _ => None,
        }
    }

    /// Whether this is a CoPA-Map file (by its header, or by its name `.cmcopa`).
    pub fn is_copa_map(&self) -> bool {
        self.model_kind() == Some(COPA_MAP_KIND)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model(kind: Option<&str>) -> FileKind {
        FileKind::ModelFile {
            kind: kind.map(str::to_owned),
        }
    }

    #[test]
    fn the_header_names_the_kind() {
        let header = b"chronomap-model 1 kind=grid-lossy encoding=postcard bytes=12 crc32=0";
        assert_eq!(FileKind::of_bytes(header), Some(model(Some("grid-lossy"))));
        // Cut inside the header: the magic word still tells.
        assert_eq!(
            FileKind::of_bytes(b"chronomap-model 1 ki"),
            Some(model(None))
        );
        assert_eq!(
            FileKind::of_bytes(b"chronomap-model 1 kind=a b"),
            Some(model(Some("a")))
        );
        assert_eq!(
            FileKind::of_bytes(b"chronomap-model 1 kind= x"),
            Some(model(None))
        );
        assert_eq!(FileKind::of_bytes(b"chronomap-modelx"), None);
        assert_eq!(FileKind::of_bytes(b"t,person,x,y\n"), None);
        assert_eq!(FileKind::of_bytes(b""), None);
    }

    #[test]
    fn names_tell_text_formats_through_compression() {
        let of = |name: &str| FileKind::by_name(Path::new(name));
        assert_eq!(of("witham.geojson.xz"), FileKind::RouteGeoJson);
        assert_eq!(of("ROUTE.JSON"), FileKind::RouteGeoJson);
        assert_eq!(of("witham.tmap2.gz"), FileKind::Tmap2);
        assert_eq!(of("tree.xml"), FileKind::BtXml);
        assert_eq!(of("atc.cmcopa"), model(Some("copa-map")));
        assert!(of("atc.cmcopa").is_copa_map());
        assert_eq!(of("w.cmt"), model(Some("topo-edge-models")));
        assert_eq!(of("door.cmm"), model(None));
        assert_eq!(of("tracks.csv"), FileKind::Other);
        assert_eq!(of("archive.xz"), FileKind::Other);
    }

    #[test]
    fn content_wins_over_the_name() {
        let dir = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-open-{}", std::process::id())),
        );
        let disguised = chronomap_testutil::write(
            &dir,
            "tracks.csv",
            "chronomap-model 1 kind=copa-map encoding=postcard bytes=0 crc32=00000000\n",
        );
        assert!(FileKind::of(&disguised).unwrap().is_copa_map());
        let text = chronomap_testutil::write(&dir, "map.json", "{}");
        assert_eq!(FileKind::of(&text).unwrap(), FileKind::RouteGeoJson);
        let missing = dir.join("missing.cmcopa");
        let error = FileKind::of(&missing).unwrap_err();
        assert_eq!(
            error.to_string(),
            format!("{}: cannot open", missing.display())
        );
        assert_eq!(error.source.kind(), std::io::ErrorKind::NotFound);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
