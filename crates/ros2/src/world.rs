//! What the node knows, without any middleware: the models of the configured states, grids
//! and edges, how messages become observations, how predictions become messages, and saving
//! and restoring. The node ([`crate::node`]) only moves messages and keeps time; everything
//! here is deterministic and tested without DDS.
//!
//! * **States** learn one observation per message, at the node's time of receipt, with the
//!   model of their spec ([`chronomap_models::ModelSpec::online_model`]): after the same observations it is
//!   bit for bit the model `chronomap fit` makes.
//! * **Maps** learn every `nav_msgs/OccupancyGrid` as a frame of a [`FremenGrid`] at its
//!   `header.stamp`, exactly as `chronomap grid build --frames` learns map files
//!   ([`FremenGrid::observe_occupancy`], [Krajník 2017] §VI).
//! * **People** ([`GridSource::People`]) cut time into bins; a bin in which at least one
//!   `PoseArray` arrived becomes one frame at the bin's middle, with every cell free except
//!   the cells someone was detected in (occupied). The grid's FreMEn cells then predict the
//!   probability that someone is in a cell during a bin, as [Krajník 2017] §VI models
//!   dynamic cells; it is published like a map.
//! * **Predicted maps** are the map `chronomap grid predict` computes, with cells as
//!   `nav2_map_server` publishes the map files it writes ([`MapValues`]).

use std::borrow::Cow;
use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::{ObservationError, TemporalModel};
use chronomap_grid::report::project_layers;
use chronomap_grid::{FremenGrid, GridConfig, GridError, GridGeometry};
use chronomap_io::grid_file::write_grid_state;
use chronomap_io::model_file::{read_model_file, write_model_file};
use chronomap_io::navmap::{
    LoadSemantics, MapMetadata, MapMode, OccupancyMap, SaveOptions, decode_map_image,
    decode_map_yaml, encode_map_image, encode_map_yaml,
};
use chronomap_io::{
    GridFile, ModelFileError, TopoFileError, read_any_model, read_edge_models, read_grid_file,
    write_any_model, write_route_geojson,
};
use chronomap_models::learner::{Learner, Refit, RefitError, RefitJob};
use chronomap_topo::edges::EdgeModels;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::config::{GridEntry, GridSource, MapValues, NodeConfig, StateConfig};
use crate::journal::{Entry, Journal, JournalError, JournalSettings};
use crate::msgs::{
    CostmapFilterInfo, Header, MapMetaData, OccupancyGrid, Point, Pose, PoseArray, Prediction,
    Quaternion, Time,
};

/// Free threshold of the maps `chronomap grid predict` writes (ROS 1 map_saver's, so that the
/// unknown grey stays unknown).
const FREE_THRESH: f64 = 0.196;
/// Occupied threshold of those maps (map_saver's).
const OCCUPIED_THRESH: f64 = 0.65;

/// Why a message was not learned (the node logs it and goes on).
#[derive(Debug, Error)]
pub enum LearnError {
    /// A state outside [0, 1] or not a number.
    #[error("value {0} is not in [0, 1]")]
    Value(f64),
    /// The observation contract (times in order, ...).
    #[error(transparent)]
    Observation(#[from] ObservationError),
    /// A map larger than `max_map_cells`.
    #[error("{width} x {height} cells is more than max_map_cells ({max})")]
    TooLarge {
        /// Cells per row.
        width: u32,
        /// Rows.
        height: u32,
        /// The limit.
        max: u64,
    },
    /// `data` does not hold `width · height` cells.
    #[error("width {width} x height {height} is {cells} cells but data holds {found} values")]
    DataLength {
        /// Cells per row.
        width: u32,
        /// Rows.
        height: u32,
        /// `width · height`.
        cells: u64,
        /// `data.len()`.
        found: usize,
    },
    /// A map whose size, resolution or origin differs from the grid's.
    #[error("the map is {found}, but this grid is {expected} (fixed by its first map)")]
    Geometry {
        /// The grid's geometry.
        expected: String,
        /// The message's.
        found: String,
    },
    /// A map with a rotated origin.
    #[error("the map's origin is rotated (orientation {0:?}); only unrotated maps are learned")]
    Rotated([f64; 4]),
    /// A message in another frame.
    #[error(
        "frame_id {found:?} is not the configured {expected:?} (poses and maps are not transformed)"
    )]
    Frame {
        /// The configured frame.
        expected: String,
        /// The message's.
        found: String,
    },
    /// A map or detection from before what was learned.
    #[error(
        "stamp {stamp} is not after the last learned {what} at {last} (already learned, or from the past)"
    )]
    Stale {
        /// The message's stamp, seconds.
        stamp: f64,
        /// The last learned time.
        last: f64,
        /// `frame` or `bin`.
        what: &'static str,
    },
    /// What the grid refused.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// A map the grids could not learn within `memory_limit`.
    #[error(
        "learning it could bring the grids to {:.1} MB, more than memory_limit ({:.1} MB); not learned",
        *needed as f64 / 1e6,
        *limit as f64 / 1e6
    )]
    Memory {
        /// What the grids could hold after it, at most (bytes).
        needed: u64,
        /// The limit (bytes).
        limit: u64,
    },
    /// A refit that cannot be installed (on replay).
    #[error(transparent)]
    Refit(RefitError),
}

/// Why models could not be restored or saved.
#[derive(Debug, Error)]
pub enum StoreError {
    /// A saved model or grid file that cannot be read.
    #[error(transparent)]
    File(#[from] ModelFileError),
    /// A saved file made for another configuration.
    #[error("{file}: {reason}; move the file away to start this model afresh")]
    Mismatch {
        /// The file.
        file: String,
        /// What differs.
        reason: String,
    },
    /// A file or folder that cannot be written.
    #[error("{path}: cannot {action}: {source}")]
    Io {
        /// The path.
        path: String,
        /// What was being done.
        action: &'static str,
        /// Why.
        source: std::io::Error,
    },
    /// The edge models or the route graph.
    #[error(transparent)]
    Topo(#[from] TopoFileError),
    /// A route graph that cannot be made from the edge models.
    #[error("{0}")]
    Route(String),
    /// The write-ahead log cannot be read or written.
    #[error(transparent)]
    Journal(#[from] JournalError),
}

/// A state and what it learned.
struct StateSlot {
    model: Learner,
    learned: u64,
    record: Option<BufWriter<File>>,
}

/// A grid and what it learned.
struct GridSlot {
    grid: Option<FremenGrid>,
    /// People: the bin being filled.
    open: Option<OpenBin>,
    frames: u64,
}

/// A people bin that is still open.
struct OpenBin {
    index: i64,
    occupied: Vec<bool>,
    messages: u64,
    /// The journal position of its first message: a checkpoint covers the grid only up to it,
    /// so that replaying the journal from there fills the bin again.
    first: Option<u64>,
}

/// The checkpoint file (`save_dir/checkpoint`, a versioned, checksummed chronomap container of
/// kind [`CHECKPOINT_KIND`]): which journal position each saved file covers. It is replaced
/// atomically after every file of a checkpoint was written beside its final name, which makes
/// the checkpoint complete (see [`World::save`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
struct Manifest {
    /// The journal position every record before which the checkpoint has seen.
    head: u64,
    /// The saved files.
    files: Vec<ManifestFile>,
    /// The observation records (`record_observations`) and their lengths at the checkpoint:
    /// what was appended after it is cut off at start, since replaying the journal appends it
    /// again. A record not listed had nothing before the checkpoint.
    records: Vec<RecordLength>,
}

/// The length of an observation record at a checkpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct RecordLength {
    /// Path relative to `save_dir` (`states/door.txt`).
    path: String,
    /// Bytes.
    bytes: u64,
}

/// One file of a checkpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct ManifestFile {
    /// Path relative to `save_dir` (`states/door.cmm`).
    path: String,
    /// Journal records of its input from this position on are not in the file.
    covers: u64,
}

/// Kind of the checkpoint file's container.
const CHECKPOINT_KIND: &str = "ros2-checkpoint";

/// What the node restored at start: per input, from the checkpoint and from the journal.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Restored {
    /// Journal records replayed.
    pub replayed: u64,
    /// Journal records of inputs that are no longer configured (skipped).
    pub unknown: u64,
    /// Journal records the models refused on replay (skipped; logged).
    pub refused: u64,
    /// Bytes cut off the journal's end (a torn write).
    pub torn_bytes: u64,
    /// Per state, in configuration order: observations from the checkpoint's file and from
    /// the journal.
    pub states: Vec<(u64, u64)>,
    /// Per grid: frames from the checkpoint's file and from the journal.
    pub grids: Vec<(u64, u64)>,
    /// The journal position learning goes on at.
    pub position: u64,
}

/// What a checkpoint ([`World::save`]) wrote.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Saved {
    /// Its number since the node started (1, 2, ...).
    pub checkpoint: u64,
    /// The journal position it covers.
    pub position: u64,
    /// Model and grid files written.
    pub files: usize,
    /// Their bytes.
    pub bytes: u64,
    /// How long it took.
    pub millis: u64,
    /// Journal segments deleted (covered by it).
    pub segments_deleted: usize,
}

impl std::fmt::Display for Saved {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "checkpoint {} at journal position {}: {} files, {:.1} MB in {} ms; {} journal \
             segments deleted",
            self.checkpoint,
            self.position,
            self.files,
            self.bytes as f64 / 1e6,
            self.millis,
            self.segments_deleted
        )
    }
}

/// Where learning is made durable.
struct Durable {
    dir: PathBuf,
    journal: Journal,
    /// Whether the last append or sync failed (logged once until one succeeds again).
    failing: bool,
    checkpoints: u64,
}

/// Counts of one input since the node started.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Learned {
    /// Observations (states) or frames (maps, people bins) learned.
    pub observations: u64,
    /// Total after restoring (states: the model's count; grids: frames).
    pub total: u64,
}

/// The predicted map of a grid and its mask.
#[derive(Clone, Debug, PartialEq)]
pub struct GridPrediction {
    /// The predicted map.
    pub map: OccupancyGrid,
    /// The costmap-filter mask (scale semantics), if the grid has a filter.
    pub mask: Option<OccupancyGrid>,
}

/// Cell value tables `value + 1 → published value` for values −1..=100.
struct ValueTables {
    trinary: [i8; 102],
    scale: [i8; 102],
}

impl ValueTables {
    /// What `nav2_map_server` publishes for each cell value of a map that `chronomap grid
    /// predict` writes in `mode`: found by writing all 102 values as one map and loading it,
    /// with the functions that write and load the files.
    fn new() -> Self {
        let table = |mode: MapMode| -> [i8; 102] {
            let mut map = OccupancyMap::new(102, 1, 0.05, [0.0, 0.0, 0.0]);
            map.data = (-1..=100).collect();
            let options = SaveOptions {
                mode,
                free_thresh: FREE_THRESH,
                occupied_thresh: OCCUPIED_THRESH,
                ..SaveOptions::default()
            };
            let image = encode_map_image(&map, &options).expect("valid thresholds");
            let name = format!("table.{}", mode.image_extension());
            let yaml = encode_map_yaml(&name, &map, &options).expect("valid thresholds");
            let metadata: MapMetadata =
                decode_map_yaml("table.yaml", yaml.as_bytes()).expect("a map file we wrote");
            let loaded = decode_map_image(&name, &image, &metadata, LoadSemantics::Nav2)
                .expect("an image we wrote");
            loaded.data.try_into().expect("102 cells")
        };
        ValueTables {
            trinary: table(MapMode::Trinary),
            scale: table(MapMode::Scale),
        }
    }

    fn convert(&self, values: MapValues, data: &mut [i8]) {
        let table = match values {
            MapValues::Probability => return,
            MapValues::Trinary => &self.trinary,
            MapValues::Scale => &self.scale,
        };
        for v in data {
            *v = table[(*v as i16 + 1) as usize];
        }
    }
}

/// Everything the node learns and predicts (see the [module docs](self)).
pub struct World {
    config: NodeConfig,
    states: Vec<StateSlot>,
    grids: Vec<GridSlot>,
    edges: Option<EdgeModels>,
    tables: ValueTables,
    durable: Option<Durable>,
    restored: Restored,
}

impl World {
    /// Empty models for `config`, or the models saved in its `save_dir` with the journal
    /// replayed on top (synced as `sync_period` and `sync_messages` say), and the edge models.
    ///
    /// # Errors
    /// As [`World::open`].
    pub fn new(config: NodeConfig) -> Result<World, StoreError> {
        let settings = JournalSettings {
            sync_period: std::time::Duration::from_secs_f64(config.sync_period),
            sync_records: usize::try_from(config.sync_messages).unwrap_or(usize::MAX),
            // A map of the largest size accepted, with its headers.
            max_payload: usize::try_from(crate::config::MAX_MAX_MAP_CELLS + (1 << 20))
                .unwrap_or(usize::MAX),
        };
        World::open(config, settings)
    }

    /// Empty models for `config`, or, with `save_dir`, the last checkpoint's models and grids
    /// with the journal's records after it replayed (a checkpoint interrupted by a crash is
    /// completed or discarded first; see [`World::save`]), and the edge models; the journal is
    /// then appended to with `settings`. What was restored is logged and kept
    /// ([`World::restored`]).
    ///
    /// # Errors
    /// A saved file that cannot be read or was made for another configuration, a damaged
    /// checkpoint file or journal, unreadable edge models, or a record file that cannot be
    /// opened.
    pub fn open(config: NodeConfig, settings: JournalSettings) -> Result<World, StoreError> {
        let manifest = match &config.save_dir {
            Some(dir) => Some(recover_checkpoint(dir)?),
            None => None,
        };
        let covers: HashMap<&str, &ManifestFile> = manifest
            .iter()
            .flat_map(|m| &m.files)
            .map(|f| (f.path.as_str(), f))
            .collect();
        let mut states = Vec::new();
        for s in &config.states {
            let model = match config.save_dir.as_ref().map(|d| state_file(d, s)) {
                Some(file) if file.exists() => restore_state(&file, s)?,
                Some(file) => {
                    refuse_other_kind(&file, s)?;
                    s.empty_learner()
                }
                None => s.empty_learner(),
            };
            let record = match (&config.save_dir, config.record_observations) {
                (Some(dir), true) => {
                    let file = record_file(dir, s);
                    let saved = manifest
                        .iter()
                        .flat_map(|m| &m.records)
                        .find(|r| r.path == relative(&file, dir))
                        .map_or(0, |r| r.bytes);
                    Some(open_record(&file, saved)?)
                }
                _ => None,
            };
            states.push(StateSlot {
                model,
                learned: 0,
                record,
            });
        }
        let mut grids = Vec::new();
        for g in &config.grids {
            let grid = match config.save_dir.as_ref().map(|d| grid_file(d, g)) {
                Some(file) if file.exists() => Some(restore_grid(&file, g)?),
                _ => match &g.source {
                    GridSource::Map => None,
                    GridSource::People {
                        width,
                        height,
                        resolution,
                        origin,
                        ..
                    } => Some(
                        FremenGrid::new(
                            GridGeometry::planar(*width, *height, *resolution, *origin)
                                .map_err(|e| mismatch(&config.file, &g.name, e))?,
                            grid_config(g),
                        )
                        .map_err(|e| mismatch(&config.file, &g.name, e))?,
                    ),
                },
            };
            grids.push(GridSlot {
                grid,
                open: None,
                frames: 0,
            });
        }
        let edges = match &config.edges {
            Some(e) => Some(read_edge_models(&e.models)?),
            None => None,
        };
        let mut restored = Restored {
            states: states.iter().map(|s| (s.model.span().count, 0)).collect(),
            grids: grids
                .iter()
                .map(|g| (g.grid.as_ref().map_or(0, FremenGrid::frames), 0))
                .collect(),
            ..Restored::default()
        };
        let mut world = World {
            config,
            states,
            grids,
            edges,
            tables: ValueTables::new(),
            durable: None,
            restored: Restored::default(),
        };
        if let (Some(dir), Some(manifest)) = (world.config.save_dir.clone(), &manifest) {
            let cover = |path: PathBuf| {
                covers
                    .get(relative(&path, &dir).as_str())
                    .map_or(0, |f| f.covers)
            };
            let state_covers: Vec<u64> = world
                .config
                .states
                .iter()
                .map(|s| cover(state_file(&dir, s)))
                .collect();
            let grid_covers: Vec<u64> = world
                .config
                .grids
                .iter()
                .map(|g| cover(grid_file(&dir, g)))
                .collect();
            let (journal, read) = Journal::open(
                &dir.join(JOURNAL_DIR),
                manifest.head,
                settings,
                |seq, entry| -> Result<(), StoreError> {
                    world.replay(seq, &entry, &state_covers, &grid_covers, &mut restored);
                    Ok(())
                },
            )?;
            // Live learning counts what arrives from now on; replayed records are restored.
            for s in &mut world.states {
                s.learned = 0;
            }
            for g in &mut world.grids {
                g.frames = 0;
            }
            restored.torn_bytes = read.torn_bytes;
            restored.position = journal.next_position();
            world.durable = Some(Durable {
                dir,
                journal,
                failing: false,
                checkpoints: 0,
            });
            world.flush_records();
        }
        world.restored = restored;
        world.log_restored();
        Ok(world)
    }

    /// What was restored at start.
    pub fn restored(&self) -> &Restored {
        &self.restored
    }

    /// Applies journal record `seq` at start, unless the checkpoint's file of its input covers
    /// it; nothing is journaled again.
    fn replay(
        &mut self,
        seq: u64,
        entry: &Entry<'_>,
        state_covers: &[u64],
        grid_covers: &[u64],
        restored: &mut Restored,
    ) {
        let name = entry.name();
        // The state or grid the record belongs to, and the journal position its file covers.
        let state = || self.config.states.iter().position(|s| s.name == name);
        let target = match entry {
            Entry::State { .. } | Entry::Refit { .. } => state().map(|i| (i, state_covers[i])),
            Entry::Map { .. } => self.grid_index(name, true).map(|i| (i, grid_covers[i])),
            Entry::People { .. } | Entry::BinClosed { .. } => {
                self.grid_index(name, false).map(|i| (i, grid_covers[i]))
            }
        };
        let Some((index, covers)) = target else {
            restored.unknown += 1;
            return;
        };
        if seq < covers {
            return;
        }
        let grid = !matches!(entry, Entry::State { .. } | Entry::Refit { .. });
        let frames = if grid { self.grids[index].frames } else { 0 };
        let result = match entry {
            Entry::State { time, value, .. } => self
                .learn_state(index, *time, *value)
                .inspect(|()| restored.states[index].1 += 1),
            Entry::Refit { refit, .. } => self.states[index]
                .model
                .install(Refit::clone(refit))
                .map_err(LearnError::Refit),
            Entry::Map { message, .. } => self.learn_map(index, message),
            Entry::People { message, .. } => self.learn_people(index, message, Some(seq)),
            Entry::BinClosed { .. } => self.close_bin(index),
        };
        if grid {
            // Maps learn a frame each; people messages and closed bins when a bin closes.
            restored.grids[index].1 += self.grids[index].frames - frames;
        }
        match result {
            Ok(()) => restored.replayed += 1,
            Err(e) => {
                restored.refused += 1;
                log::warn!("journal position {seq} ({name}): not learned again: {e}");
            }
        }
    }

    /// The index of the map (`maps`) or people grid called `name`.
    fn grid_index(&self, name: &str, map: bool) -> Option<usize> {
        self.config
            .grids
            .iter()
            .position(|g| g.name == name && (g.source == GridSource::Map) == map)
    }

    /// Logs what was restored, one line per input and one for the journal.
    fn log_restored(&self) {
        let Some(dir) = &self.config.save_dir else {
            return;
        };
        let r = &self.restored;
        for (index, s) in self.config.states.iter().enumerate() {
            let span = self.states[index].model.span();
            let (saved, replayed) = r.states[index];
            log::info!(
                "restored states.{}: {} with {} observations ({saved} saved, {replayed} from the \
                 journal){}",
                s.name,
                s.model,
                span.count,
                span.last_time()
                    .map_or(String::new(), |t| format!(", the last at {t}"))
            );
        }
        for (index, g) in self.config.grids.iter().enumerate() {
            let grid = self.grids[index].grid.as_ref();
            let (saved, replayed) = r.grids[index];
            let last = grid
                .and_then(|g| g.frame_span().last_time())
                .map_or(String::new(), |t| format!(", the last at {t}"));
            let open = self.grids[index].open.as_ref().map_or(String::new(), |b| {
                format!(", an open bin of {} messages", b.messages)
            });
            log::info!(
                "restored {}.{}: {} frames ({saved} saved, {replayed} from the journal){last}{open}",
                g.section(),
                g.name,
                saved + replayed
            );
        }
        log::info!(
            "journal {}: {} records replayed{}{}{}; learning goes on at position {}",
            dir.join(JOURNAL_DIR).display(),
            r.replayed,
            if r.unknown > 0 {
                format!(", {} of inputs no longer configured skipped", r.unknown)
            } else {
                String::new()
            },
            if r.refused > 0 {
                format!(", {} refused (logged)", r.refused)
            } else {
                String::new()
            },
            if r.torn_bytes > 0 {
                format!(", {} torn bytes cut off its end", r.torn_bytes)
            } else {
                String::new()
            },
            r.position
        );
    }

    /// The configuration.
    pub fn config(&self) -> &NodeConfig {
        &self.config
    }

    /// Learns `value` of state `index` observed at `time` (the node's time of receipt) and
    /// appends it to the journal.
    ///
    /// # Errors
    /// A value outside [0, 1] or a time before the state's last observation; nothing is
    /// learned then.
    pub fn observe_state(&mut self, index: usize, time: f64, value: f64) -> Result<(), LearnError> {
        self.learn_state(index, time, value)?;
        let name = &self.config.states[index].name;
        let entry = Entry::State {
            name: Cow::Borrowed(name),
            time,
            value,
        };
        journal(&mut self.durable, &entry);
        Ok(())
    }

    /// Learns a state observation (live or replayed).
    fn learn_state(&mut self, index: usize, time: f64, value: f64) -> Result<(), LearnError> {
        if !(0.0..=1.0).contains(&value) {
            return Err(LearnError::Value(value));
        }
        let slot = &mut self.states[index];
        slot.model.observe(&[time], &[value])?;
        slot.learned += 1;
        if let Some(record) = &mut slot.record {
            // `{}` writes the shortest text that reads back as the same f64.
            if let Err(e) = writeln!(record, "{time} {value}") {
                log::error!(
                    "states.{}: cannot append to the observation record: {e}; recording stops",
                    self.config.states[index].name
                );
                slot.record = None;
            }
        }
        Ok(())
    }

    /// Learns the map `msg` of grid `index` (a [`GridSource::Map`]) as a frame at its stamp.
    ///
    /// # Errors
    /// A map above `max_map_cells`, with data of the wrong length, in another frame, rotated,
    /// of another geometry than the first, not after the last learned frame, or with cell
    /// values outside −1..=100; nothing is learned then.
    ///
    /// # Panics
    /// If grid `index` is not a map grid.
    pub fn observe_map(&mut self, index: usize, msg: &OccupancyGrid) -> Result<(), LearnError> {
        self.learn_map(index, msg)?;
        let entry = Entry::Map {
            name: Cow::Borrowed(&self.config.grids[index].name),
            message: Cow::Borrowed(msg),
        };
        journal(&mut self.durable, &entry);
        Ok(())
    }

    /// Learns a map (live or replayed).
    fn learn_map(&mut self, index: usize, msg: &OccupancyGrid) -> Result<(), LearnError> {
        let entry = &self.config.grids[index];
        assert!(
            entry.source == GridSource::Map,
            "grid {index} is not a map grid"
        );
        let info = &msg.info;
        let cells = u64::from(info.width) * u64::from(info.height);
        if cells > self.config.max_map_cells {
            return Err(LearnError::TooLarge {
                width: info.width,
                height: info.height,
                max: self.config.max_map_cells,
            });
        }
        if cells != msg.data.len() as u64 {
            return Err(LearnError::DataLength {
                width: info.width,
                height: info.height,
                cells,
                found: msg.data.len(),
            });
        }
        check_frame(entry, &msg.header)?;
        let o = &info.origin.orientation;
        if (o.x, o.y, o.z, o.w) != (0.0, 0.0, 0.0, 1.0) {
            return Err(LearnError::Rotated([o.x, o.y, o.z, o.w]));
        }
        let geometry = GridGeometry::planar(
            info.width,
            info.height,
            f64::from(info.resolution),
            [info.origin.position.x, info.origin.position.y],
        )?;
        let stamp = msg.header.stamp.seconds();
        // What the other grids hold now; this one is bound before it learns the map.
        let others: u64 = self
            .grids
            .iter()
            .enumerate()
            .filter(|&(i, _)| i != index)
            .filter_map(|(_, g)| g.grid.as_ref())
            .map(|g| g.heap_bytes() as u64)
            .sum();
        let limit = self.config.memory_limit;
        let check = |grid: &FremenGrid| -> Result<(), LearnError> {
            let needed = others.saturating_add(grid.heap_bound_after_occupancy(&msg.data));
            match limit {
                Some(limit) if needed > limit => Err(LearnError::Memory { needed, limit }),
                _ => Ok(()),
            }
        };
        let slot = &mut self.grids[index];
        let grid = match &mut slot.grid {
            Some(grid) => {
                if *grid.geometry() != geometry {
                    return Err(LearnError::Geometry {
                        expected: describe(grid.geometry()),
                        found: describe(&geometry),
                    });
                }
                if let Some(last) = grid.frame_span().last_time()
                    && stamp <= last
                {
                    return Err(LearnError::Stale {
                        stamp,
                        last,
                        what: "frame",
                    });
                }
                check(grid)?;
                grid
            }
            None => {
                let fresh = FremenGrid::new(geometry, grid_config(entry))?;
                check(&fresh)?;
                slot.grid.insert(fresh)
            }
        };
        grid.observe_occupancy(stamp, &msg.data)?;
        slot.frames += 1;
        Ok(())
    }

    /// Adds the detections `msg` to grid `index` (a [`GridSource::People`]); closes the open
    /// bin first if `msg` belongs to a later one. Poses outside the grid are ignored.
    ///
    /// # Errors
    /// A message in another frame or from a bin that is already learned or closed.
    ///
    /// # Panics
    /// If grid `index` is not a people grid.
    pub fn observe_people(&mut self, index: usize, msg: &PoseArray) -> Result<(), LearnError> {
        let position = self.durable.as_ref().map(|d| d.journal.next_position());
        self.learn_people(index, msg, position)?;
        let entry = Entry::People {
            name: Cow::Borrowed(&self.config.grids[index].name),
            message: Cow::Borrowed(msg),
        };
        journal(&mut self.durable, &entry);
        Ok(())
    }

    /// Adds detections (live or replayed); `position` is the message's journal position.
    fn learn_people(
        &mut self,
        index: usize,
        msg: &PoseArray,
        position: Option<u64>,
    ) -> Result<(), LearnError> {
        let entry = &self.config.grids[index];
        let GridSource::People { bin_secs, .. } = entry.source else {
            panic!("grid {index} is not a people grid");
        };
        check_frame(entry, &msg.header)?;
        let stamp = msg.header.stamp.seconds();
        if !(stamp.is_finite() && stamp >= 0.0) {
            return Err(ObservationError::NegativeTime {
                index: 0,
                time: stamp,
            }
            .into());
        }
        let bin = (stamp / bin_secs).floor() as i64;
        if let Some(open) = &self.grids[index].open
            && bin > open.index
        {
            self.close_bin(index)?;
        }
        let slot = &mut self.grids[index];
        let grid = slot
            .grid
            .as_ref()
            .expect("people grids exist from the start");
        let geometry = *grid.geometry();
        let middle = bin_middle(bin, bin_secs);
        match &slot.open {
            Some(open) if bin < open.index => {
                return Err(LearnError::Stale {
                    stamp,
                    last: bin_middle(open.index, bin_secs),
                    what: "bin",
                });
            }
            None => {
                if let Some(last) = grid.frame_span().last_time()
                    && middle <= last
                {
                    return Err(LearnError::Stale {
                        stamp,
                        last,
                        what: "bin",
                    });
                }
                slot.open = Some(OpenBin {
                    index: bin,
                    occupied: vec![false; geometry.cells()],
                    messages: 0,
                    first: position,
                });
            }
            Some(_) => {}
        }
        let open = slot.open.as_mut().expect("opened above");
        open.messages += 1;
        for pose in &msg.poses {
            if let Some(cell) = cell_of(&geometry, &pose.position) {
                open.occupied[cell] = true;
            }
        }
        Ok(())
    }

    /// Closes people bins that ended at least one bin before `now` (late messages of a bin
    /// are still taken during the next one).
    ///
    /// # Errors
    /// As [`FremenGrid::observe_occupancy`].
    pub fn close_stale_bins(&mut self, now: f64) -> Result<(), LearnError> {
        for index in 0..self.grids.len() {
            if let GridSource::People { bin_secs, .. } = self.config.grids[index].source
                && let Some(open) = &self.grids[index].open
                && now >= (open.index + 2) as f64 * bin_secs
            {
                self.close_bin_journaled(index)?;
            }
        }
        Ok(())
    }

    /// Learns the open bin of people grid `index` (if any) and journals that it did.
    fn close_bin_journaled(&mut self, index: usize) -> Result<(), LearnError> {
        if self.grids[index].open.is_none() {
            return Ok(());
        }
        // Journaled whatever the outcome: replaying it does the same.
        let closed = self.close_bin(index);
        let entry = Entry::BinClosed {
            name: Cow::Borrowed(&self.config.grids[index].name),
        };
        journal(&mut self.durable, &entry);
        closed
    }

    /// Learns the open bin of people grid `index` as a frame.
    fn close_bin(&mut self, index: usize) -> Result<(), LearnError> {
        let GridSource::People { bin_secs, .. } = self.config.grids[index].source else {
            return Ok(());
        };
        let slot = &mut self.grids[index];
        let Some(open) = slot.open.take() else {
            return Ok(());
        };
        let frame: Vec<i8> = open
            .occupied
            .iter()
            .map(|&o| if o { 100 } else { 0 })
            .collect();
        let grid = slot
            .grid
            .as_mut()
            .expect("people grids exist from the start");
        grid.observe_occupancy(bin_middle(open.index, bin_secs), &frame)?;
        slot.frames += 1;
        Ok(())
    }

    /// What state `index` and grid entries learned: `(states, grids)` in configuration order.
    pub fn learned(&self) -> (Vec<Learned>, Vec<Learned>) {
        let states = self
            .states
            .iter()
            .map(|s| Learned {
                observations: s.learned,
                total: s.model.span().count,
            })
            .collect();
        let grids = self
            .grids
            .iter()
            .map(|g| Learned {
                observations: g.frames,
                total: g.grid.as_ref().map_or(0, FremenGrid::frames),
            })
            .collect();
        (states, grids)
    }

    /// The learner of state `index`: its model, or (specs fitted on a whole series) its kept
    /// observations and last fit.
    pub fn state_model(&self, index: usize) -> &Learner {
        &self.states[index].model
    }

    /// Whether state `index` learns a model fitted on a whole series whose refit policy
    /// (`refit_observations`, `refit_period`) calls for a refit now.
    pub fn refit_due(&self, index: usize) -> bool {
        self.states[index]
            .model
            .is_due(&self.config.states[index].refit)
    }

    /// The kept observations of state `index` for a refit ([`RefitJob::run`], on any thread),
    /// `None` for models that learn online.
    pub fn refit_job(&self, index: usize) -> Option<RefitJob> {
        self.states[index].model.refit_job()
    }

    /// Puts a refit of state `index` in place and journals it (the fitted model itself, so
    /// that a restart installs it at the same place without fitting again).
    ///
    /// # Errors
    /// As [`Learner::install`]; nothing changes then.
    pub fn install_refit(&mut self, index: usize, refit: Refit) -> Result<(), RefitError> {
        self.states[index].model.install(refit.clone())?;
        let entry = Entry::Refit {
            name: Cow::Borrowed(&self.config.states[index].name),
            refit: Box::new(refit),
        };
        journal(&mut self.durable, &entry);
        Ok(())
    }

    /// The grid of entry `index`, once it has one.
    pub fn grid(&self, index: usize) -> Option<&FremenGrid> {
        self.grids[index].grid.as_ref()
    }

    /// Probability and entropy (bits) of state `index` at `time`.
    pub fn predict_state(&self, index: usize, time: f64) -> (f64, f64) {
        let model = &self.states[index].model;
        (model.predict(time), model.entropy(time))
    }

    /// The prediction of state `index` for `time`, made at `made` (the node's time), as
    /// `chronomap_msgs/msg/Prediction`: stamped with `time`, with p, its entropy, the model's
    /// spec and its observation count.
    pub fn state_prediction(&self, index: usize, time: f64, made: Time) -> Prediction {
        let model = &self.states[index].model;
        let (probability, entropy) = self.predict_state(index, time);
        Prediction {
            header: Header {
                stamp: Time::from_seconds(time),
                frame_id: String::new(),
            },
            name: self.config.states[index].name.clone(),
            model: self.config.states[index].model.to_string(),
            probability,
            entropy,
            made,
            observations: model.span().count,
        }
    }

    /// The predicted map of grid `index` at `time` (and its mask), stamped `stamp`; `None`
    /// before the grid's first map.
    pub fn predict_grid(&self, index: usize, time: f64, stamp: Time) -> Option<GridPrediction> {
        let entry = &self.config.grids[index];
        let grid = self.grids[index].grid.as_ref()?;
        let g = *grid.geometry();
        // The grid predicts with its own order, which the configuration checked is the
        // entry's (a restored grid of another order is refused).
        let values = project_layers(&g, &grid.predict_map(time), 0..g.depth);
        let probabilities = OccupancyMap::from_probabilities(
            g.width,
            g.height,
            g.resolution as f32,
            [g.origin[0], g.origin[1], 0.0],
            &values,
        )
        .data;
        let message = |data: Vec<i8>| OccupancyGrid {
            header: Header {
                stamp,
                frame_id: entry.frame_id.clone(),
            },
            info: MapMetaData {
                map_load_time: stamp,
                resolution: g.resolution as f32,
                width: g.width,
                height: g.height,
                origin: Pose {
                    position: Point {
                        x: g.origin[0],
                        y: g.origin[1],
                        z: 0.0,
                    },
                    orientation: Quaternion::default(),
                },
            },
            data,
        };
        let mask = entry.filter.as_ref().map(|_| {
            let mut data = probabilities.clone();
            self.tables.convert(MapValues::Scale, &mut data);
            message(data)
        });
        let mut data = probabilities;
        self.tables.convert(entry.values, &mut data);
        Some(GridPrediction {
            map: message(data),
            mask,
        })
    }

    /// The filter info of grid `index`, if it has a filter.
    pub fn filter_info(&self, index: usize, stamp: Time) -> Option<CostmapFilterInfo> {
        let entry = &self.config.grids[index];
        entry.filter.as_ref().map(|f| CostmapFilterInfo {
            header: Header {
                stamp,
                frame_id: entry.frame_id.clone(),
            },
            filter_type: f.filter_type,
            filter_mask_topic: f.mask_topic.clone(),
            base: f.base,
            multiplier: f.multiplier,
        })
    }

    /// Rewrites the route graph with the edges' success probabilities and expected durations
    /// at `time` (atomically), as `chronomap topo predict --geojson` writes it; `false` without
    /// edges.
    ///
    /// # Errors
    /// A graph that cannot be written.
    pub fn write_route_graph(&self, time: f64) -> Result<bool, StoreError> {
        let (Some(models), Some(config)) = (&self.edges, &self.config.edges) else {
            return Ok(false);
        };
        let (success, duration) = models.at(time);
        let metadata: Vec<(f64, f64)> = success.into_iter().zip(duration).collect();
        write_route_geojson(&config.geojson, models.map(), &metadata)?;
        Ok(true)
    }

    /// Writes and syncs the journal if the oldest unsynced record waited the sync period or
    /// enough records wait (the node calls it every round), with the observation records.
    /// Failures are logged (once until it works again); learning goes on in memory and the
    /// next checkpoint saves it.
    pub fn sync_journal(&mut self, now: Instant) {
        let Some(durable) = &mut self.durable else {
            return;
        };
        match durable.journal.sync_if_due(now) {
            Ok(false) => {}
            Ok(true) => {
                if durable.failing {
                    log::info!("journal: writing works again");
                    durable.failing = false;
                }
                log::trace!(
                    "journal: synced up to position {}",
                    durable.journal.next_position()
                );
                self.flush_records();
            }
            Err(e) => {
                if !std::mem::replace(&mut durable.failing, true) {
                    log::error!(
                        "journal: {e}; what is learned from now on is kept in memory and saved \
                         by the next checkpoint"
                    );
                }
            }
        }
    }

    /// Flushes the observation records (`record_observations`), logging failures.
    fn flush_records(&mut self) {
        for (s, slot) in self.config.states.iter().zip(&mut self.states) {
            if let Some(record) = &mut slot.record
                && let Err(e) = record.flush()
            {
                log::error!(
                    "states.{}: cannot write the observation record: {e}; recording stops",
                    s.name
                );
                slot.record = None;
            }
        }
    }

    /// A checkpoint: saves every model and grid into `save_dir` and forgets the journal
    /// records they cover; nothing without `save_dir`. With `finish` (at shutdown), open
    /// people bins are learned first.
    ///
    /// The files are ordinary chronomap model and grid files (`chronomap predict`, `grid
    /// predict` read them). A checkpoint is atomic: the journal is synced and a new segment
    /// started at position `H`; every file is written (synced) beside its final name as
    /// `NAME.next-H`; the checkpoint file (`save_dir/checkpoint`: `H` and, per file, the
    /// journal position its content covers) is replaced atomically — from here on the
    /// checkpoint counts; then the files are renamed to their names and the covered journal
    /// segments deleted. A crash before the checkpoint file was replaced leaves the previous
    /// checkpoint and the whole journal (the `.next-H` files are deleted at start); a crash
    /// after it is completed at start by the renames.
    ///
    /// Returns what it wrote (`None` without `save_dir`).
    ///
    /// # Errors
    /// A folder or file that cannot be written; the previous checkpoint and the journal then
    /// still hold everything.
    pub fn save(&mut self, finish: bool) -> Result<Option<Saved>, StoreError> {
        if finish {
            for index in 0..self.grids.len() {
                if let Err(e) = self.close_bin_journaled(index) {
                    log::error!("{}: the last bin: {e}", self.config.grids[index].name);
                }
            }
        }
        let Some(durable) = &mut self.durable else {
            return Ok(None);
        };
        let started = Instant::now();
        let dir = durable.dir.clone();
        durable.journal.rotate()?;
        if std::mem::replace(&mut durable.failing, false) {
            log::info!("journal: writing works again");
        }
        let head = durable.journal.next_position();
        let mut manifest = Manifest {
            head,
            ..Manifest::default()
        };
        let mut written: Vec<(PathBuf, PathBuf)> = Vec::new();
        let mut bytes = 0u64;
        let result = (|| -> Result<(), StoreError> {
            for (s, slot) in self.config.states.iter().zip(&mut self.states) {
                let file = state_file(&dir, s);
                let next = next_name(&file, head);
                make_parent(&file)?;
                match &slot.model {
                    Learner::Online(model) => write_any_model(&next, model)?,
                    learner => write_model_file(&next, LEARNER_KIND, learner)?,
                }
                let record = record_file(&dir, s);
                let io = |source| StoreError::Io {
                    path: record.display().to_string(),
                    action: "write",
                    source,
                };
                let record_bytes = match &mut slot.record {
                    Some(writer) => {
                        writer.flush().map_err(io)?;
                        writer.get_ref().sync_data().map_err(io)?;
                        Some(writer.get_ref().metadata().map_err(io)?.len())
                    }
                    // Not recording now: a record of earlier runs keeps its length.
                    None => std::fs::metadata(&record).ok().map(|m| m.len()),
                };
                if let Some(bytes) = record_bytes {
                    manifest.records.push(RecordLength {
                        path: relative(&record, &dir),
                        bytes,
                    });
                }
                bytes += file_len(&next);
                manifest.files.push(ManifestFile {
                    path: relative(&file, &dir),
                    covers: head,
                });
                written.push((next, file));
            }
            for (g, slot) in self.config.grids.iter().zip(&self.grids) {
                let Some(grid) = &slot.grid else {
                    continue;
                };
                let file = grid_file(&dir, g);
                let next = next_name(&file, head);
                make_parent(&file)?;
                write_grid_state(&next, grid)?;
                bytes += file_len(&next);
                // An open people bin is not in the file: replaying from its first message
                // fills it again.
                let covers = slot.open.as_ref().and_then(|b| b.first).unwrap_or(head);
                manifest.files.push(ManifestFile {
                    path: relative(&file, &dir),
                    covers,
                });
                written.push((next, file));
            }
            write_model_file(dir.join(CHECKPOINT_FILE), CHECKPOINT_KIND, &manifest)?;
            Ok(())
        })();
        if let Err(e) = result {
            for (next, _) in &written {
                let _ = std::fs::remove_file(next);
            }
            return Err(e);
        }
        complete_checkpoint(&dir, &manifest)?;
        let keep = manifest
            .files
            .iter()
            .map(|f| f.covers)
            .min()
            .unwrap_or(head);
        let forgotten = durable.journal.forget_before(keep)?;
        durable.checkpoints += 1;
        let saved = Saved {
            checkpoint: durable.checkpoints,
            position: head,
            files: written.len(),
            bytes,
            millis: started.elapsed().as_millis() as u64,
            segments_deleted: forgotten,
        };
        log::info!("{saved}");
        Ok(Some(saved))
    }
}

/// The checkpoint file in `save_dir`.
const CHECKPOINT_FILE: &str = "checkpoint";
/// The journal folder in `save_dir`.
const JOURNAL_DIR: &str = "journal";

/// Appends `entry` to the journal, if there is one; a failure is logged once (learning goes
/// on in memory; the next checkpoint saves it).
fn journal(durable: &mut Option<Durable>, entry: &Entry<'_>) {
    let Some(durable) = durable else {
        return;
    };
    if let Err(e) = durable.journal.append(entry, Instant::now())
        && !std::mem::replace(&mut durable.failing, true)
    {
        log::error!(
            "journal: {e}; what is learned from now on is kept in memory and saved by the next \
             checkpoint"
        );
    }
}

/// `NAME.next-H`: where a checkpoint at journal position `head` writes `file` first.
fn next_name(file: &Path, head: u64) -> PathBuf {
    let mut name = file.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".next-{head}"));
    file.with_file_name(name)
}

/// `file` relative to `dir`, with `/` (the checkpoint file's names).
fn relative(file: &Path, dir: &Path) -> String {
    let relative = file.strip_prefix(dir).unwrap_or(file);
    relative
        .components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

fn file_len(path: &Path) -> u64 {
    std::fs::metadata(path).map_or(0, |m| m.len())
}

/// Renames the files of the checkpoint `manifest` from their `.next-H` names (those still
/// there) and makes the renames durable.
fn complete_checkpoint(dir: &Path, manifest: &Manifest) -> Result<(), StoreError> {
    let mut folders = Vec::new();
    for f in &manifest.files {
        let file = dir.join(&f.path);
        let next = next_name(&file, manifest.head);
        if next.exists() {
            std::fs::rename(&next, &file).map_err(|source| StoreError::Io {
                path: next.display().to_string(),
                action: "rename",
                source,
            })?;
            if let Some(parent) = file.parent()
                && !folders.contains(&parent.to_path_buf())
            {
                folders.push(parent.to_path_buf());
            }
        }
    }
    for folder in folders {
        crate::journal::sync_dir(&folder)?;
    }
    Ok(())
}

/// At start: reads the checkpoint file of `dir` (writing a first one, covering the files
/// there, if there is none and no journal yet), completes an interrupted checkpoint and
/// deletes files of one that never counted.
fn recover_checkpoint(dir: &Path) -> Result<Manifest, StoreError> {
    let file = dir.join(CHECKPOINT_FILE);
    let manifest = if file.exists() {
        let (kind, manifest): (String, Manifest) = read_model_file(&file)?;
        if kind != CHECKPOINT_KIND {
            return Err(StoreError::Mismatch {
                file: file.display().to_string(),
                reason: format!("it holds a `{kind}`, not the node's checkpoint"),
            });
        }
        manifest
    } else {
        let journal = dir.join(JOURNAL_DIR);
        let has_segments = std::fs::read_dir(&journal).is_ok_and(|mut d| d.next().is_some());
        if has_segments {
            return Err(StoreError::Mismatch {
                file: file.display().to_string(),
                reason: format!(
                    "missing, but {} holds a journal: without the checkpoint file the journal \
                     cannot be replayed without learning some of it twice",
                    journal.display()
                ),
            });
        }
        // Saved by a node without a journal (or never): its files and records cover everything.
        std::fs::create_dir_all(dir).map_err(|source| StoreError::Io {
            path: dir.display().to_string(),
            action: "create the folder",
            source,
        })?;
        let mut manifest = Manifest::default();
        for item in std::fs::read_dir(dir.join("states"))
            .into_iter()
            .flatten()
            .flatten()
        {
            let path = item.path();
            if path.extension().is_some_and(|e| e == "txt")
                && let Ok(meta) = item.metadata()
                && meta.is_file()
            {
                manifest.records.push(RecordLength {
                    path: relative(&path, dir),
                    bytes: meta.len(),
                });
            }
        }
        write_model_file(&file, CHECKPOINT_KIND, &manifest)?;
        manifest
    };
    complete_checkpoint(dir, &manifest)?;
    for section in ["states", "maps", "people"] {
        let Ok(items) = std::fs::read_dir(dir.join(section)) else {
            continue;
        };
        for item in items.flatten() {
            let name = item.file_name();
            if name.to_string_lossy().contains(".next-") {
                let path = item.path();
                log::info!(
                    "{}: deleted, written by a checkpoint that did not complete",
                    path.display()
                );
                std::fs::remove_file(&path).map_err(|source| StoreError::Io {
                    path: path.display().to_string(),
                    action: "delete",
                    source,
                })?;
            }
        }
    }
    Ok(manifest)
}

/// `dir/states/NAME.cmm` (a model file as `chronomap fit` writes it), or `NAME.cml` for a model
/// fitted on a whole series (its kept observations and last fit, kind `learner`).
pub fn state_file(dir: &Path, state: &StateConfig) -> PathBuf {
    let extension = if state.learns_online() { "cmm" } else { "cml" };
    dir.join("states")
        .join(format!("{}.{extension}", state.name))
}

/// `dir/states/NAME.txt`: the learned observations as `t value` lines.
pub fn record_file(dir: &Path, state: &StateConfig) -> PathBuf {
    dir.join("states").join(format!("{}.txt", state.name))
}

/// `dir/maps/NAME.cmg` or `dir/people/NAME.cmg`.
pub fn grid_file(dir: &Path, grid: &GridEntry) -> PathBuf {
    dir.join(grid.section()).join(format!("{}.cmg", grid.name))
}

fn make_parent(file: &Path) -> Result<(), StoreError> {
    let parent = file.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|source| StoreError::Io {
        path: parent.display().to_string(),
        action: "create the folder",
        source,
    })
}

/// Opens the observation record `file` for appending; what was appended after the last
/// checkpoint (`saved`: its length then) is cut off first, since replaying the journal appends
/// it again.
fn open_record(file: &Path, saved: u64) -> Result<BufWriter<File>, StoreError> {
    make_parent(file)?;
    let io = |action| {
        move |source| StoreError::Io {
            path: file.display().to_string(),
            action,
            source,
        }
    };
    let handle = OpenOptions::new()
        .create(true)
        .append(true)
        .open(file)
        .map_err(io("open for appending"))?;
    let len = handle.metadata().map_err(io("inspect"))?.len();
    if len > saved {
        handle
            .set_len(saved)
            .map_err(io("cut back to the checkpoint"))?;
    } else if len < saved {
        log::warn!(
            "{}: {len} bytes, shorter than the {saved} of the last checkpoint: lines are missing",
            file.display()
        );
    }
    Ok(BufWriter::new(handle))
}

fn mismatch(file: &Path, name: &str, reason: impl std::fmt::Display) -> StoreError {
    StoreError::Mismatch {
        file: file.display().to_string(),
        reason: format!("{name}: {reason}"),
    }
}

/// Kind of the files of refitted learners (`states/NAME.cml`).
const LEARNER_KIND: &str = "learner";

fn restore_state(file: &Path, state: &StateConfig) -> Result<Learner, StoreError> {
    let mismatch = |reason: String| StoreError::Mismatch {
        file: file.display().to_string(),
        reason,
    };
    let learner = if state.learns_online() {
        Learner::Online(read_any_model(file)?)
    } else {
        let (kind, learner): (String, Learner) = read_model_file(file)?;
        if kind != LEARNER_KIND || !learner.is_consistent() {
            return Err(mismatch(format!(
                "not the kept observations and fit of a refitted model (kind `{kind}`{})",
                if learner.is_consistent() {
                    ""
                } else {
                    ", inconsistent"
                }
            )));
        }
        learner
    };
    if learner.spec() != state.model {
        return Err(mismatch(format!(
            "it holds a `{}` model, but states.{}.model is `{}`",
            learner.spec(),
            state.name,
            state.model
        )));
    }
    if learner.keep().is_some_and(|k| k != state.keep) {
        log::info!(
            "{}: kept {} observations at most, states.{}.keep is now {}: it applies from the \
             next observation",
            file.display(),
            learner.keep().unwrap_or(0),
            state.name,
            state.keep
        );
    }
    Ok(learner)
}

/// An error if the file of the other kind of learner for `state` is there (a model learning
/// online saved as `.cmm`, refitted as `.cml`): the model changed and the old one would be
/// left behind silently.
fn refuse_other_kind(file: &Path, state: &StateConfig) -> Result<(), StoreError> {
    let other = file.with_extension(if state.learns_online() { "cml" } else { "cmm" });
    if other.exists() {
        let spec = if state.learns_online() {
            read_model_file::<Learner>(&other).map(|(_, l)| l.spec().to_string())
        } else {
            read_any_model(&other).map(|m| m.spec().to_string())
        }
        .unwrap_or_else(|_| "another".into());
        return Err(StoreError::Mismatch {
            file: other.display().to_string(),
            reason: format!(
                "it holds a `{spec}` model, but states.{}.model is `{}`",
                state.name, state.model
            ),
        });
    }
    Ok(())
}

fn restore_grid(file: &Path, entry: &GridEntry) -> Result<FremenGrid, StoreError> {
    let name = file.display().to_string();
    let grid = match read_grid_file(file)? {
        GridFile::State(grid) => *grid,
        other => {
            return Err(StoreError::Mismatch {
                file: name,
                reason: format!("it holds a {} grid, not a learning state", other.kind()),
            });
        }
    };
    let section = entry.section();
    if grid.config().fremen != entry.fremen {
        return Err(StoreError::Mismatch {
            file: name,
            reason: format!(
                "its cells have periods {} and order {}, but {section}.{} says periods {} and order {}",
                grid.config().fremen.periods,
                grid.config().fremen.order,
                entry.name,
                entry.fremen.periods,
                entry.fremen.order
            ),
        });
    }
    if let GridSource::People {
        width,
        height,
        resolution,
        origin,
        ..
    } = &entry.source
    {
        let configured = GridGeometry::planar(*width, *height, *resolution, *origin)
            .map_err(|e| mismatch(file, &entry.name, e))?;
        if *grid.geometry() != configured {
            return Err(StoreError::Mismatch {
                file: name,
                reason: format!(
                    "it is {}, but {section}.{} is {}",
                    describe(grid.geometry()),
                    entry.name,
                    describe(&configured)
                ),
            });
        }
    }
    Ok(grid)
}

/// The grid configuration of `chronomap grid build` with `--order` and `--periods` as
/// configured: no history kept.
fn grid_config(entry: &GridEntry) -> GridConfig {
    GridConfig {
        fremen: entry.fremen.clone(),
        keep_history: false,
    }
}

fn check_frame(entry: &GridEntry, header: &Header) -> Result<(), LearnError> {
    if header.frame_id == entry.frame_id {
        Ok(())
    } else {
        Err(LearnError::Frame {
            expected: entry.frame_id.clone(),
            found: header.frame_id.clone(),
        })
    }
}

fn describe(g: &GridGeometry) -> String {
    format!(
        "{} x {} cells of {} m at ({}, {})",
        g.width, g.height, g.resolution, g.origin[0], g.origin[1]
    )
}

/// The middle of bin `index` of `bin_secs` seconds.
fn bin_middle(index: i64, bin_secs: f64) -> f64 {
    (index as f64 + 0.5) * bin_secs
}

/// The cell of a 2-D grid a position falls in.
fn cell_of(g: &GridGeometry, p: &Point) -> Option<usize> {
    let x = ((p.x - g.origin[0]) / g.resolution).floor();
    let y = ((p.y - g.origin[1]) / g.resolution).floor();
    let inside = x >= 0.0 && y >= 0.0 && x < f64::from(g.width) && y < f64::from(g.height);
    inside.then(|| y as usize * g.width as usize + x as usize)
}

#[cfg(test)]
mod tests;
