//! What a service needs before it can serve (`chronomap serve`): its private data folder, the
//! token that writes need (read from its file, or made and written there), the read-only maps it
//! serves, its store, and the signal that stops it. `chronomap serve --check` reads the same
//! files the same way, so that it finds what would stop the start.
//!
//! Errors name the file and the flag of `chronomap serve` that named it (`--topo door: …`).

use std::collections::HashMap;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use chronomap_app::open::FileKind;
use chronomap_io::navmap::{LoadSemantics, load_map};
use chronomap_topo::map::TopoMap;

use crate::maps::{Maps, ServedActivity, ServedTopo};
use crate::store::{RedbStore, Store, StoreError};

/// Shortest token accepted from a token file: 32 characters (128 bits as hex; the tokens
/// [`read_or_create_token`] makes are 64 hex characters, 256 bits).
pub const MIN_TOKEN_CHARS: usize = 32;

/// Most bytes of a token file (a token is at least [`MIN_TOKEN_CHARS`] characters; the
/// service makes 64).
pub const MAX_TOKEN_FILE_BYTES: u64 = 4096;

/// Why a service cannot start.
#[derive(Debug, thiserror::Error)]
pub enum StartupError {
    /// The data folder cannot be created.
    #[error("cannot create the data directory {}", .path.display())]
    DataDir {
        /// The folder.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The token file exists but cannot be read.
    #[error("cannot read the token file {}", .path.display())]
    TokenUnreadable {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// The token file is a folder, a device or a pipe.
    #[error(
        "{}: the token file is not a regular file (a directory, a device or a pipe)",
        .path.display()
    )]
    TokenNotAFile {
        /// The file.
        path: PathBuf,
    },
    /// Others than its owner may read the token file.
    #[error(
        "{}: the token file is readable by others (mode {mode:04o}); anyone who reads it can \
         change every model. Run `chmod 600 {}`",
        .path.display(),
        .path.display()
    )]
    TokenReadableByOthers {
        /// The file.
        path: PathBuf,
        /// Its permission bits.
        mode: u32,
    },
    /// The token file has more than [`MAX_TOKEN_FILE_BYTES`].
    #[error(
        "{}: the token file has more than {MAX_TOKEN_FILE_BYTES} bytes (is this the right file?)",
        .path.display()
    )]
    TokenTooLarge {
        /// The file.
        path: PathBuf,
    },
    /// The token is shorter than [`MIN_TOKEN_CHARS`] or not visible ASCII.
    #[error(
        "{}: a token must be at least {MIN_TOKEN_CHARS} visible ASCII characters without \
         spaces (this one has {chars}); delete the file to have a random one made",
        .path.display()
    )]
    TokenTooWeak {
        /// The file.
        path: PathBuf,
        /// Characters of the token found.
        chars: usize,
    },
    /// The system gave no random numbers.
    #[error("no random numbers for a token: {0}")]
    NoRandom(String),
    /// A new token file cannot be created.
    #[error("cannot create the token file {}", .path.display())]
    TokenCreate {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A new token file cannot be written.
    #[error("cannot write the token file {}", .path.display())]
    TokenWrite {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A map file cannot be read or does not fit its map.
    #[error("{flag} {name}")]
    Map {
        /// The flag of `chronomap serve` that names the file (`--topo`, `--topo-layout`,
        /// `--grid`, `--activity`, `--activity-map`).
        flag: &'static str,
        /// The name the map is served by.
        name: String,
        /// Why.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// The store cannot be opened.
    #[error(transparent)]
    Store(#[from] StoreError),
}

/// Creates the data folder `dir` (and its parents) if missing, readable by its owner only
/// (mode 0700 on unix).
///
/// # Errors
/// The folder cannot be created.
pub fn create_private_dir(dir: &Path) -> Result<(), StartupError> {
    let mut builder = std::fs::DirBuilder::new();
    builder.recursive(true);
    #[cfg(unix)]
    std::os::unix::fs::DirBuilderExt::mode(&mut builder, 0o700);
    builder.create(dir).map_err(|source| StartupError::DataDir {
        path: dir.to_path_buf(),
        source,
    })
}

/// The token in `path`, or a new random one (256 bits as 64 hex characters) written there,
/// readable by the owner only. An existing file is read by [`read_token`].
///
/// # Errors
/// As [`read_token`]; or the new file cannot be created or written.
pub fn read_or_create_token(path: &Path) -> Result<String, StartupError> {
    if let Some(token) = read_token(path)? {
        return Ok(token);
    }
    let mut bytes = [0u8; 32];
    getrandom::fill(&mut bytes).map_err(|e| StartupError::NoRandom(e.to_string()))?;
    let token: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let mut file = options
        .open(path)
        .map_err(|source| StartupError::TokenCreate {
            path: path.to_path_buf(),
            source,
        })?;
    writeln!(file, "{token}")
        .and_then(|()| file.sync_all())
        .map_err(|source| StartupError::TokenWrite {
            path: path.to_path_buf(),
            source,
        })?;
    Ok(token)
}

/// The token in the file `path`, `None` if there is no such file. The file must be a regular
/// file of at most [`MAX_TOKEN_FILE_BYTES`] (a device such as `/dev/zero` or a pipe is refused
/// before it is read), readable by its owner only (as ssh requires of private keys), and hold
/// at least [`MIN_TOKEN_CHARS`] visible ASCII characters (surrounding white space is not part
/// of the token).
///
/// # Errors
/// The file breaks one of these rules or cannot be read.
pub fn read_token(path: &Path) -> Result<Option<String>, StartupError> {
    let unreadable = |source| StartupError::TokenUnreadable {
        path: path.to_path_buf(),
        source,
    };
    let metadata = match std::fs::metadata(path) {
        Ok(metadata) => metadata,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(unreadable(e)),
    };
    if !metadata.is_file() {
        return Err(StartupError::TokenNotAFile {
            path: path.to_path_buf(),
        });
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = metadata.permissions().mode();
        if mode & 0o077 != 0 {
            return Err(StartupError::TokenReadableByOthers {
                path: path.to_path_buf(),
                mode: mode & 0o7777,
            });
        }
    }
    let text = match chronomap_io::read_regular_at_most(path, MAX_TOKEN_FILE_BYTES) {
        Ok(bytes) => String::from_utf8_lossy(&bytes).into_owned(),
        Err(e) if e.kind() == std::io::ErrorKind::InvalidData => {
            return Err(StartupError::TokenTooLarge {
                path: path.to_path_buf(),
            });
        }
        Err(e) => return Err(unreadable(e)),
    };
    let token = text.trim().to_owned();
    if token.chars().count() < MIN_TOKEN_CHARS || !token.bytes().all(|b| b.is_ascii_graphic()) {
        return Err(StartupError::TokenTooWeak {
            path: path.to_path_buf(),
            chars: token.chars().count(),
        });
    }
    Ok(Some(token))
}

/// The map files a service serves, by the names they are served by (`chronomap serve --topo
/// NAME=FILE` and its companions).
#[derive(Clone, Debug, Default)]
pub struct MapFiles {
    /// Edge models of topological maps (`--topo`).
    pub topological: Vec<(String, PathBuf)>,
    /// The node positions of a topological map, by its name (`--topo-layout`): a Nav2 route
    /// graph (`.geojson`, `.json`) or else a tmap2 map, either maybe compressed.
    pub layouts: HashMap<String, PathBuf>,
    /// Grid files (`--grid`).
    pub grids: Vec<(String, PathBuf)>,
    /// CoPA-Maps of people (`--activity`).
    pub activity: Vec<(String, PathBuf)>,
    /// The Nav2 map (YAML) of an activity map, by its name (`--activity-map`), whose walls mask
    /// its predictions.
    pub activity_maps: HashMap<String, PathBuf>,
}

/// Reads every map file of `files`, and lays out the topological maps.
///
/// # Errors
/// A file cannot be read, or a layout lacks a position of a node, naming the flag and name.
pub fn read_maps(files: &MapFiles) -> Result<Maps, StartupError> {
    fn map<E: std::error::Error + Send + Sync + 'static>(
        flag: &'static str,
        name: &str,
    ) -> impl FnOnce(E) -> StartupError {
        move |e| StartupError::Map {
            flag,
            name: name.to_owned(),
            source: Box::new(e),
        }
    }
    let mut maps = Maps::default();
    for (name, path) in &files.topological {
        let models =
            chronomap_io::model_file::read_edge_models(path).map_err(map("--topo", name))?;
        let served = match files.layouts.get(name) {
            Some(layout) => {
                let map_of = read_layout(layout).map_err(map("--topo-layout", name))?;
                ServedTopo::with_layout(models, &layout.display().to_string(), &map_of)
                    .map_err(map("--topo-layout", name))?
            }
            None => ServedTopo::new(models),
        };
        maps.topological.insert(name.clone(), served);
    }
    for (name, path) in &files.grids {
        let grid = chronomap_io::grid_file::read_grid_file(path).map_err(map("--grid", name))?;
        maps.grids.insert(name.clone(), grid);
    }
    for (name, path) in &files.activity {
        let model = chronomap_io::read_copa_map(path).map_err(map("--activity", name))?;
        let walls = files
            .activity_maps
            .get(name)
            .map(|yaml| load_map(yaml, LoadSemantics::Nav2))
            .transpose()
            .map_err(map("--activity-map", name))?;
        maps.activity
            .insert(name.clone(), ServedActivity::new(model, walls));
    }
    Ok(maps)
}

/// The nodes (with positions) of a Nav2 route graph (`.geojson`, `.json`) or else of a tmap2
/// map; either may be compressed (`.xz`, `.gz`).
///
/// # Errors
/// The file cannot be read as such a map.
pub fn read_layout(path: &Path) -> Result<TopoMap, chronomap_io::topo_files::TopoFileError> {
    match FileKind::by_name(path) {
        FileKind::RouteGeoJson => chronomap_io::topo_files::read_route_geojson(path),
        _ => chronomap_io::topo_files::read_tmap2(path),
    }
}

/// Where a service keeps its store.
#[derive(Clone, Debug)]
pub enum StoreLocation {
    /// `chronomap.redb` in a data folder (`--data`).
    Redb {
        /// The data folder.
        data: PathBuf,
    },
    /// A schema of a PostgreSQL database (`--postgres`, `--postgres-schema`).
    #[cfg(feature = "postgres")]
    Postgres {
        /// The connection string.
        config: String,
        /// The schema.
        schema: String,
    },
}

impl StoreLocation {
    /// The redb file of a data folder.
    pub fn redb_file(data: &Path) -> PathBuf {
        data.join("chronomap.redb")
    }
}

/// Opens the store a service writes: the redb file (created if missing), or the PostgreSQL
/// schema as its one owner, or with `fleet` as one of a fleet of services
/// ([`crate::fleet`]); a new PostgreSQL log is partitioned every `segment_groups` commit groups.
///
/// # Errors
/// The store cannot be opened (another process holds it, the database refuses).
pub fn open_store(
    at: &StoreLocation,
    fleet: bool,
    segment_groups: u64,
) -> Result<Arc<dyn Store>, StoreError> {
    let _ = (fleet, segment_groups);
    Ok(match at {
        StoreLocation::Redb { data } => Arc::new(RedbStore::open(StoreLocation::redb_file(data))?),
        #[cfg(feature = "postgres")]
        StoreLocation::Postgres { config, schema } => {
            use crate::store::{Access, OWNER_WAIT, PostgresStore};
            Arc::new(PostgresStore::connect_with(
                config,
                schema,
                if fleet { Access::Fleet } else { Access::Owner },
                OWNER_WAIT,
                segment_groups,
            )?)
        }
    })
}

/// Completes on Ctrl-C or (on unix) SIGTERM: the service's graceful shutdown.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let terminate = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut signal) => {
                signal.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let terminate = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {}
        () = terminate => {}
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder of this test's own.
    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "chronomap-serve-startup-{name}-{}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[cfg(unix)]
    fn write_private(path: &Path, bytes: &[u8]) {
        use std::os::unix::fs::PermissionsExt;
        std::fs::write(path, bytes).unwrap();
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(0o600)).unwrap();
    }

    #[test]
    #[cfg(unix)]
    fn a_token_file_is_read_within_its_limits() {
        use std::os::unix::fs::PermissionsExt;
        let dir = scratch("read");
        let file = dir.join("token");
        assert!(read_token(&file).unwrap().is_none());

        // Exactly 32 visible characters, with the line end and spaces around it.
        let token = "0123456789abcdef0123456789ABCDEF";
        write_private(&file, format!("  {token}\n").as_bytes());
        assert_eq!(read_token(&file).unwrap().as_deref(), Some(token));

        // One character fewer, or a space inside, is refused naming the count.
        write_private(&file, &token.as_bytes()[..31]);
        let e = read_token(&file).unwrap_err();
        assert!(
            matches!(e, StartupError::TokenTooWeak { chars: 31, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("at least 32 visible ASCII"), "{e}");
        write_private(&file, b"0123456789abcdef 0123456789abcdef");
        let e = read_token(&file).unwrap_err();
        assert!(
            matches!(e, StartupError::TokenTooWeak { chars: 33, .. }),
            "{e}"
        );

        // 4,096 bytes are read; 4,097 are not.
        let mut big = vec![b' '; MAX_TOKEN_FILE_BYTES as usize - token.len()];
        big.extend_from_slice(token.as_bytes());
        write_private(&file, &big);
        assert_eq!(read_token(&file).unwrap().as_deref(), Some(token));
        big.push(b'\n');
        write_private(&file, &big);
        let e = read_token(&file).unwrap_err();
        assert!(matches!(e, StartupError::TokenTooLarge { .. }), "{e}");
        assert!(
            e.to_string()
                .ends_with("has more than 4096 bytes (is this the right file?)")
        );

        // Readable by the group: refused with its mode.
        write_private(&file, token.as_bytes());
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o640)).unwrap();
        let e = read_token(&file).unwrap_err();
        assert!(matches!(
            e,
            StartupError::TokenReadableByOthers { mode: 0o640, .. }
        ));
        assert!(e.to_string().contains("(mode 0640)"), "{e}");

        // A folder and a device are refused before anything is read.
        let e = read_token(&dir).unwrap_err();
        assert!(matches!(e, StartupError::TokenNotAFile { .. }), "{e}");
        let e = read_token(Path::new("/dev/zero")).unwrap_err();
        assert!(matches!(e, StartupError::TokenNotAFile { .. }), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    #[cfg(unix)]
    fn a_missing_token_file_is_made_private_and_read_back() {
        use std::os::unix::fs::PermissionsExt;
        let dir = scratch("create");
        let data = dir.join("data");
        create_private_dir(&data).unwrap();
        let mode = std::fs::metadata(&data).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o700);
        let file = data.join("token");
        let token = read_or_create_token(&file).unwrap();
        assert_eq!(token.len(), 64);
        assert!(token.bytes().all(|b| b.is_ascii_hexdigit()));
        assert_eq!(
            std::fs::read_to_string(&file).unwrap(),
            format!("{token}\n")
        );
        let mode = std::fs::metadata(&file).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o600);
        // The second start reads the same token.
        assert_eq!(read_or_create_token(&file).unwrap(), token);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_missing_map_file_names_its_flag_and_name() {
        let files = MapFiles {
            grids: vec![("office".into(), PathBuf::from("no/such/office.cmg"))],
            ..MapFiles::default()
        };
        let e = read_maps(&files).unwrap_err();
        assert!(matches!(&e, StartupError::Map { flag: "--grid", name, .. } if name == "office"));
        assert_eq!(e.to_string(), "--grid office");
        assert!(std::error::Error::source(&e).is_some());
    }

    /// docs/limits.md names the token file's limit as it is here.
    #[test]
    fn the_token_file_limit_in_docs_limits_is_the_one_here() {
        let doc = include_str!("../../../docs/limits.md");
        let row = doc
            .lines()
            .find(|l| {
                l.starts_with("| `MAX_TOKEN_FILE_BYTES`")
                    && l.contains("`chronomap_serve::startup`")
            })
            .expect("docs/limits.md has a row for MAX_TOKEN_FILE_BYTES");
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        assert_eq!(cells[2].replace(',', ""), MAX_TOKEN_FILE_BYTES.to_string());
    }
}
