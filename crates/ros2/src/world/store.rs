//! Saving and restoring the node's models: checkpoints (ordinary chronomap model and grid
//! files, made atomic by the checkpoint file `save_dir/checkpoint`), the write-ahead journal
//! between them ([`crate::journal`]), and the observation records. See [`World::save`] and
//! [`World::open`].

use std::collections::HashMap;
use std::fs::{File, OpenOptions};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use chronomap_core::TemporalModel;
use chronomap_grid::AnyGrid;
use chronomap_grid::{FremenGrid, GridGeometry};
use chronomap_io::grid_file::write_grid_state;
use chronomap_io::model_file::{read_model_file, write_model_file};
use chronomap_io::{read_any_model, read_grid_file, write_any_model};
use chronomap_models::learner::Learner;
use serde::{Deserialize, Serialize};

use super::{GridSource, World, describe};
use crate::config::{GridEntry, StateConfig};
use crate::journal::{Entry, Journal};
use crate::world::StoreError;

/// The checkpoint file (`save_dir/checkpoint`, a versioned, checksummed chronomap container of
/// kind [`CHECKPOINT_KIND`]): which journal position each saved file covers. It is replaced
/// atomically after every file of a checkpoint was written beside its final name, which makes
/// the checkpoint complete (see [`World::save`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub(super) struct Manifest {
    /// The journal position every record before which the checkpoint has seen.
    pub(super) head: u64,
    /// The saved files.
    pub(super) files: Vec<ManifestFile>,
    /// The observation records (`record_observations`) and their lengths at the checkpoint:
    /// what was appended after it is cut off at start, since replaying the journal appends it
    /// again. A record not listed had nothing before the checkpoint.
    pub(super) records: Vec<RecordLength>,
}

/// The length of an observation record at a checkpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(super) struct RecordLength {
    /// Path relative to `save_dir` (`states/door.txt`).
    pub(super) path: String,
    /// Bytes.
    pub(super) bytes: u64,
}

/// One file of a checkpoint.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(super) struct ManifestFile {
    /// Path relative to `save_dir` (`states/door.cmm`).
    pub(super) path: String,
    /// Journal records of its input from this position on are not in the file.
    pub(super) covers: u64,
}

/// Kind of the checkpoint file's container.
pub(super) const CHECKPOINT_KIND: &str = "ros2-checkpoint";

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
pub(super) struct Durable {
    pub(super) dir: PathBuf,
    pub(super) journal: Journal,
    /// Whether the last append or sync failed (logged once until one succeeds again).
    pub(super) failing: bool,
    pub(super) checkpoints: u64,
}

impl World {
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
    pub(super) fn flush_records(&mut self) {
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
                    io: source,
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
                if let Some(spread) = &slot.spread {
                    // The second moment, beside the model and covering what it covers.
                    let file = spread_file(&dir, s);
                    let next = next_name(&file, head);
                    match spread {
                        Learner::Online(model) => write_any_model(&next, model)?,
                        learner => write_model_file(&next, LEARNER_KIND, learner)?,
                    }
                    bytes += file_len(&next);
                    manifest.files.push(ManifestFile {
                        path: relative(&file, &dir),
                        covers: head,
                    });
                    written.push((next, file));
                }
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
pub(super) const CHECKPOINT_FILE: &str = "checkpoint";
/// The journal folder in `save_dir`.
pub(super) const JOURNAL_DIR: &str = "journal";

/// Appends `entry` to the journal, if there is one; a failure is logged once (learning goes
/// on in memory; the next checkpoint saves it).
pub(super) fn journal(durable: &mut Option<Durable>, entry: &Entry<'_>) {
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
pub(super) fn next_name(file: &Path, head: u64) -> PathBuf {
    let mut name = file.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".next-{head}"));
    file.with_file_name(name)
}

/// `file` relative to `dir`, with `/` (the checkpoint file's names).
pub(super) fn relative(file: &Path, dir: &Path) -> String {
    let relative = file.strip_prefix(dir).unwrap_or(file);
    relative
        .components()
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

pub(super) fn file_len(path: &Path) -> u64 {
    std::fs::metadata(path).map_or(0, |m| m.len())
}

/// Renames the files of the checkpoint `manifest` from their `.next-H` names (those still
/// there) and makes the renames durable.
pub(super) fn complete_checkpoint(dir: &Path, manifest: &Manifest) -> Result<(), StoreError> {
    let mut folders = Vec::new();
    for f in &manifest.files {
        let file = dir.join(&f.path);
        let next = next_name(&file, manifest.head);
        if next.exists() {
            std::fs::rename(&next, &file).map_err(|source| StoreError::Io {
                path: next.display().to_string(),
                action: "rename",
                io: source,
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
pub(super) fn recover_checkpoint(dir: &Path) -> Result<Manifest, StoreError> {
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
            io: source,
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
                    io: source,
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

/// `dir/states/NAME.squares.cmm` (or `.cml`, as [`state_file`]): the learner of the squared
/// values of a state with a prediction interval (the second moment,
/// [`chronomap_core::spread`]), saved beside its model by the same checkpoint. (State names
/// are ROS name tokens, without dots: no state's file is called so.)
pub fn spread_file(dir: &Path, state: &StateConfig) -> PathBuf {
    let extension = if state.learns_online() { "cmm" } else { "cml" };
    dir.join("states")
        .join(format!("{}.squares.{extension}", state.name))
}

/// `dir/states/NAME.txt`: the learned observations as `t value` lines.
pub fn record_file(dir: &Path, state: &StateConfig) -> PathBuf {
    dir.join("states").join(format!("{}.txt", state.name))
}

/// `dir/maps/NAME.cmg` or `dir/people/NAME.cmg`.
pub fn grid_file(dir: &Path, grid: &GridEntry) -> PathBuf {
    dir.join(grid.section()).join(format!("{}.cmg", grid.name))
}

pub(super) fn make_parent(file: &Path) -> Result<(), StoreError> {
    let parent = file.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(|source| StoreError::Io {
        path: parent.display().to_string(),
        action: "create the folder",
        io: source,
    })
}

/// Opens the observation record `file` for appending; what was appended after the last
/// checkpoint (`saved`: its length then) is cut off first, since replaying the journal appends
/// it again.
pub(super) fn open_record(file: &Path, saved: u64) -> Result<BufWriter<File>, StoreError> {
    make_parent(file)?;
    let io = |action| {
        move |source| StoreError::Io {
            path: file.display().to_string(),
            action,
            io: source,
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

pub(super) fn mismatch(file: &Path, name: &str, reason: impl std::fmt::Display) -> StoreError {
    StoreError::Mismatch {
        file: file.display().to_string(),
        reason: format!("{name}: {reason}"),
    }
}

/// Kind of the files of refitted learners (`states/NAME.cml`).
pub(super) const LEARNER_KIND: &str = "learner";

pub(super) fn restore_state(file: &Path, state: &StateConfig) -> Result<Learner, StoreError> {
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

/// The learner of the squared values of `state` whose model `model` was restored from its
/// file: the one the same checkpoint saved (`covers`: the checkpoint's files), or `None` for
/// states without an interval, and for a model saved by a node before intervals (it never
/// learned the squares: the state has no interval until its files are moved away; logged).
///
/// # Errors
/// A file that cannot be read, of another spec, or that learned another number of
/// observations than the model.
pub(super) fn restore_spread(
    dir: &Path,
    state: &StateConfig,
    model: &Learner,
    covers: &HashMap<&str, &ManifestFile>,
) -> Result<Option<Learner>, StoreError> {
    if !state.has_interval() {
        return Ok(None);
    }
    let model_file = state_file(dir, state);
    let file = spread_file(dir, state);
    let covered = |f: &Path| covers.get(relative(f, dir).as_str()).map(|m| m.covers);
    // Written by the checkpoint that wrote the model (a file the checkpoint does not name is
    // left over from an earlier configuration of the state).
    if !(file.exists() && covered(&file).is_some() && covered(&file) == covered(&model_file)) {
        log::warn!(
            "{}: saved without the model of its squared values (by a node before prediction \
             intervals): states.{} gives no interval; move its files away to start it afresh \
             with one",
            model_file.display(),
            state.name
        );
        return Ok(None);
    }
    let spread = restore_state(&file, state)?;
    let (learned, squared) = (model.span().count, spread.span().count);
    if learned != squared {
        return Err(StoreError::Mismatch {
            file: file.display().to_string(),
            reason: format!(
                "it learned {squared} squared values, but {} learned {learned} values",
                model_file.display()
            ),
        });
    }
    Ok(Some(spread))
}

/// An error if the file of the other kind of learner for `state` is there (a model learning
/// online saved as `.cmm`, refitted as `.cml`): the model changed and the old one would be
/// left behind silently.
pub(super) fn refuse_other_kind(file: &Path, state: &StateConfig) -> Result<(), StoreError> {
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

pub(super) fn restore_grid(file: &Path, entry: &GridEntry) -> Result<FremenGrid, StoreError> {
    let name = file.display().to_string();
    let grid = match read_grid_file(file)? {
        AnyGrid::State(grid) => *grid,
        other => {
            return Err(StoreError::Mismatch {
                file: name,
                reason: format!(
                    "it holds a {} grid, not a learning state",
                    chronomap_io::grid_kind(&other)
                ),
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
