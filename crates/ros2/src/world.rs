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
//! * **Intervals** of continuous states (`Float32`, `Float64`) whose spec has a second
//!   moment (it learns online, or is `auto`): a second learner of the same spec is fed the
//!   squared values, at the same times, and refitted with the model (`auto`); the central
//!   interval is the Beta law's matched to the two moments
//!   ([`chronomap_core::spread::beta_interval`], [Johnson 1995] ch. 25), as the service
//!   answers them.
//! * **Predicted maps** are the map `chronomap grid predict` computes, with cells as
//!   `nav2_map_server` publishes the map files it writes ([`MapValues`]).

use std::borrow::Cow;
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use chronomap_core::spread::beta_interval;
use chronomap_core::{ObservationError, Parallelism, TemporalModel};
use chronomap_grid::report::project_layers;
use chronomap_grid::{FremenGrid, GridConfig, GridError, GridGeometry};
use chronomap_io::navmap::{
    LoadSemantics, MapMetadata, MapMode, SaveOptions, decode_map_image, decode_map_yaml,
    encode_map_image, encode_map_yaml,
};
use chronomap_io::{
    ModelFileError, RouteEdgeMetadata, TopoFileError, read_edge_models, write_route_geojson,
};
use chronomap_models::learner::{Learner, Refit, RefitError, RefitJob};
use chronomap_spatial::OccupancyMap;
use chronomap_topo::edges::{EVALUATION_COVERAGE, EdgeModels};
use thiserror::Error;

use crate::config::{GridEntry, GridSource, MapValues, NodeConfig};
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
    #[error("{path}: cannot {action}: {io}")]
    Io {
        /// The path.
        path: String,
        /// What was being done.
        action: &'static str,
        /// Why (part of the message, not a further error in the chain).
        io: std::io::Error,
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
    /// States with an interval ([`StateConfig::has_interval`]): the same spec fed the squared
    /// values, the second moment ([`chronomap_core::spread`]). `None` for the others, and for
    /// a model restored from files of a node before intervals (it never learned the squares).
    spread: Option<Learner>,
    learned: u64,
    /// Observations on days off since the node started (not learned).
    days_off: u64,
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

/// Counts of one input since the node started.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Learned {
    /// Observations (states) or frames (maps, people bins) learned.
    pub observations: u64,
    /// Total after restoring (states: the model's count; grids: frames).
    pub total: u64,
    /// States: observations made on a day off (`days_off_file`), not learned; grids: 0.
    pub days_off: u64,
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
            let fresh_spread = || s.has_interval().then(|| s.empty_learner());
            let (model, spread) = match config.save_dir.as_ref().map(|d| (d, state_file(d, s))) {
                Some((dir, file)) if file.exists() => {
                    let model = restore_state(&file, s)?;
                    let spread = restore_spread(dir, s, &model, &covers)?;
                    (model, spread)
                }
                Some((_, file)) => {
                    refuse_other_kind(&file, s)?;
                    (s.empty_learner(), fresh_spread())
                }
                None => (s.empty_learner(), fresh_spread()),
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
                spread,
                learned: 0,
                days_off: 0,
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
            Entry::State { .. } | Entry::Refit { .. } | Entry::RefitWithSpread { .. } => {
                state().map(|i| (i, state_covers[i]))
            }
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
        let grid = !matches!(
            entry,
            Entry::State { .. } | Entry::Refit { .. } | Entry::RefitWithSpread { .. }
        );
        let frames = if grid { self.grids[index].frames } else { 0 };
        let result = match entry {
            Entry::State { time, value, .. } => self
                .learn_state(index, *time, *value)
                .inspect(|()| restored.states[index].1 += 1),
            Entry::Refit { refit, .. } => self
                .install_fits(index, refit, None)
                .map_err(LearnError::Refit),
            Entry::RefitWithSpread { refit, spread, .. } => self
                .install_fits(index, refit, Some(spread))
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
    /// appends it to the journal; with a calendar (`days_off_file`), an observation on a day
    /// off is neither learned nor journaled nor recorded, only counted ([`Learned::days_off`]),
    /// and `Ok(false)` says so. (Journal records are replayed as they were learned, whatever
    /// the calendar is now, so that a restart gives the model that was saved.)
    ///
    /// # Errors
    /// A value outside [0, 1] or a time before the state's last observation; nothing is
    /// learned then.
    pub fn observe_state(
        &mut self,
        index: usize,
        time: f64,
        value: f64,
    ) -> Result<bool, LearnError> {
        if self.config.days_off.contains(time) {
            check_state_value(value)?;
            self.states[index].days_off += 1;
            return Ok(false);
        }
        self.learn_state(index, time, value)?;
        let name = &self.config.states[index].name;
        let entry = Entry::State {
            name: Cow::Borrowed(name),
            time,
            value,
        };
        journal(&mut self.durable, &entry);
        Ok(true)
    }

    /// Learns a state observation (live or replayed).
    fn learn_state(&mut self, index: usize, time: f64, value: f64) -> Result<(), LearnError> {
        check_state_value(value)?;
        let slot = &mut self.states[index];
        slot.model.observe(&[time], &[value])?;
        if let Some(spread) = &mut slot.spread
            && let Err(e) = spread.observe(&[time], &[value * value])
        {
            // It learned every observation the model did, so it takes this one too; should it
            // not, the state goes on without an interval rather than with a wrong one.
            log::error!(
                "states.{}: the model of the squared values refused {time} {value}: {e}; no \
                 interval from now on",
                self.config.states[index].name
            );
            slot.spread = None;
        }
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
        // With `memory_limit`: what the other grids hold now, and this one bound before it
        // learns the map (a pass over its cells, skipped without a limit).
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
            let Some(limit) = limit else {
                return Ok(());
            };
            let needed = others.saturating_add(grid.heap_bound_after_occupancy(&msg.data));
            if needed > limit {
                return Err(LearnError::Memory { needed, limit });
            }
            Ok(())
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
                days_off: s.days_off,
            })
            .collect();
        let grids = self
            .grids
            .iter()
            .map(|g| Learned {
                observations: g.frames,
                total: g.grid.as_ref().map_or(0, FremenGrid::frames),
                days_off: 0,
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

    /// The kept squared observations of state `index` for the refit of its second moment,
    /// made with [`World::refit_job`]: `Some` for `auto` states with an interval.
    pub fn spread_refit_job(&self, index: usize) -> Option<RefitJob> {
        self.states[index].spread.as_ref()?.refit_job()
    }

    /// Puts a refit of state `index` in place, with the fit of its squared values (`spread`,
    /// from [`World::spread_refit_job`]) if there is one, and journals both (the fitted models
    /// themselves, so that a restart installs them at the same place without fitting again).
    /// Without `spread` (its fit failed) the second moment keeps its last fit.
    ///
    /// # Errors
    /// As [`Learner::install`], or a fit of the second moment for a state without one;
    /// nothing changes then.
    pub fn install_refit(
        &mut self,
        index: usize,
        refit: Refit,
        spread: Option<Refit>,
    ) -> Result<(), RefitError> {
        self.install_fits(index, &refit, spread.as_ref())?;
        let name = Cow::Borrowed(self.config.states[index].name.as_str());
        let entry = match spread {
            None => Entry::Refit {
                name,
                refit: Box::new(refit),
            },
            Some(spread) => Entry::RefitWithSpread {
                name,
                refit: Box::new(refit),
                spread: Box::new(spread),
            },
        };
        journal(&mut self.durable, &entry);
        Ok(())
    }

    /// Installs the fits of a refit (live or replayed): both or neither.
    fn install_fits(
        &mut self,
        index: usize,
        refit: &Refit,
        spread: Option<&Refit>,
    ) -> Result<(), RefitError> {
        let slot = &mut self.states[index];
        // The second moment's fit goes into a copy first (cheap: kept observations are
        // shared), so that a refused fit of either changes nothing.
        let spread = match (spread, &slot.spread) {
            (None, _) => None,
            (Some(fit), Some(learner)) => {
                let mut learner = learner.clone();
                learner.install(fit.clone())?;
                Some(learner)
            }
            (Some(_), None) => {
                return Err(RefitError::NotThisLearner {
                    reason: format!(
                        "a fit of the second moment, and states.{} has no model of it",
                        self.config.states[index].name
                    ),
                });
            }
        };
        slot.model.install(refit.clone())?;
        if spread.is_some() {
            slot.spread = spread;
        }
        Ok(())
    }

    /// The learner of the squared values of state `index` (the second moment), for states
    /// with an interval ([`StateConfig::has_interval`](crate::config::StateConfig::has_interval)).
    pub fn state_spread(&self, index: usize) -> Option<&Learner> {
        self.states[index].spread.as_ref()
    }

    /// Whether state `index` gives intervals now ([`World::state_interval`] is `Some` at every
    /// time).
    pub fn state_has_interval(&self, index: usize) -> bool {
        let slot = &self.states[index];
        slot.model.model().is_some() && slot.spread.as_ref().is_some_and(|s| s.model().is_some())
    }

    /// The central interval of coverage `states.NAME.coverage` of state `index` at `time`
    /// (a day off predicted at its stand-in, as [`World::predict_state`]): the Beta law's of
    /// the model's mean and the second moment's prediction
    /// ([`chronomap_core::spread::beta_interval`], [Johnson 1995] ch. 25). `None` for states
    /// without one: Bool states, specs without a second moment (`fremen:auto`, ...), `auto`
    /// before the fit of its squares, models restored from files of a node before intervals.
    pub fn state_interval(&self, index: usize, time: f64) -> Option<(f64, f64)> {
        // (Whether there is one does not depend on the time: `state_has_interval`.)
        let slot = &self.states[index];
        let second = slot.spread.as_ref()?.model()?;
        let mean = slot.model.model()?;
        let time = self.config.days_off.stand_in(time);
        Some(beta_interval(
            mean.predict(time),
            second.predict(time),
            self.config.states[index].coverage,
        ))
    }

    /// The grid of entry `index`, once it has one.
    pub fn grid(&self, index: usize) -> Option<&FremenGrid> {
        self.grids[index].grid.as_ref()
    }

    /// Probability and entropy (bits) of state `index` at `time`; with a calendar
    /// (`days_off_file`), a time on a day off is predicted at its stand-in
    /// ([`DaysOff::stand_in`](chronomap_core::calendar::DaysOff::stand_in): the same time of
    /// day on the most recent Sunday that is not a day off).
    pub fn predict_state(&self, index: usize, time: f64) -> (f64, f64) {
        let model = &self.states[index].model;
        let time = self.config.days_off.stand_in(time);
        (model.predict(time), model.entropy(time))
    }

    /// The prediction of state `index` for `time`, made at `made` (the node's time), as
    /// `chronomap_msgs/msg/Prediction`: stamped with `time` (on a day off too), with p and its
    /// entropy ([`World::predict_state`]), the model's spec and its observation count, and
    /// the interval ([`World::state_interval`]) with its coverage — or `lower` = `upper` =
    /// NaN and `coverage` 0 when the state has none.
    pub fn state_prediction(&self, index: usize, time: f64, made: Time) -> Prediction {
        let model = &self.states[index].model;
        let (probability, entropy) = self.predict_state(index, time);
        let (lower, upper, coverage) = match self.state_interval(index, time) {
            Some((lower, upper)) => (lower, upper, self.config.states[index].coverage),
            None => (f64::NAN, f64::NAN, 0.0),
        };
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
            lower,
            upper,
            coverage,
        }
    }

    /// The predicted map of grid `index` at `time` (and its mask), stamped `stamp`; `None`
    /// before the grid's first map.
    pub fn predict_grid(&self, index: usize, time: f64, stamp: Time) -> Option<GridPrediction> {
        let entry = &self.config.grids[index];
        let grid = self.grids[index].grid.as_ref()?;
        let g = *grid.geometry();
        // The grid predicts with its own order, which the configuration checked is the
        // entry's (a restored grid of another order is refused); its changing cells are
        // fitted on the global rayon pool, as the node's other parallel work.
        let values = project_layers(
            &g,
            &grid.predict_map(time, Parallelism::Rayon(0)),
            0..g.depth,
        );
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

    /// Rewrites the route graph with the edges' success probabilities, expected durations and
    /// their 90 % intervals ([`EVALUATION_COVERAGE`]) at `time` (atomically), as `chronomap
    /// topo predict --geojson` writes it; `false` without edges.
    ///
    /// # Errors
    /// A graph that cannot be written.
    pub fn write_route_graph(&self, time: f64) -> Result<bool, StoreError> {
        let (Some(models), Some(config)) = (&self.edges, &self.config.edges) else {
            return Ok(false);
        };
        let (success, duration) = models.at(time);
        let metadata: Vec<RouteEdgeMetadata> = success
            .into_iter()
            .zip(duration)
            .enumerate()
            .map(|(edge, (p, secs))| {
                RouteEdgeMetadata::new(p, secs).with_time_interval(
                    models.duration_interval(edge, time, EVALUATION_COVERAGE),
                    EVALUATION_COVERAGE,
                )
            })
            .collect();
        write_route_geojson(&config.geojson, models.map(), &metadata)?;
        Ok(true)
    }
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

/// A state's observed value must lie in [0, 1] (on a day off too, though it is not learned).
fn check_state_value(value: f64) -> Result<(), LearnError> {
    if (0.0..=1.0).contains(&value) {
        Ok(())
    } else {
        Err(LearnError::Value(value))
    }
}

mod store;

use store::{
    Durable, JOURNAL_DIR, ManifestFile, journal, mismatch, open_record, recover_checkpoint,
    refuse_other_kind, relative, restore_grid, restore_spread, restore_state,
};
pub use store::{Saved, grid_file, record_file, spread_file, state_file};

#[cfg(test)]
mod tests;
