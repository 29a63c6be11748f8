//! Jobs on topological maps whose edges know time ([Fentanes 2015]): the edge models of a
//! directory of edge files (§IV, the file at fault named), and their evaluation on the later
//! attempts of another directory against the static per-edge rates (§V-A), by both protocols
//! and edge by edge.
//!
//! Files in, result structs out: the faces print the tables and map their own argument names.

use std::path::{Path, PathBuf};

use chronomap_core::BuildError;
use chronomap_core::progress::Progress;
use chronomap_io::{DataError, read_edge_directory};
use chronomap_topo::edges::{Attempt, EdgeEvaluation, EdgeModelConfig, EdgeModels};
use chronomap_topo::map::TopoMap;
use chronomap_topo::report::{EdgeScore, MergeError, Protocol, merge_maps, per_edge_scores};

/// Why a job on edge files failed.
#[derive(Debug, thiserror::Error)]
pub enum TopoJobError {
    /// A directory of edge files cannot be read.
    #[error(transparent)]
    Read(#[from] DataError),
    /// The attempts of one edge cannot be fitted.
    #[error(
        "{}{}: {error}",
        file.display(),
        attempt.map(|n| format!(": attempt {n}")).unwrap_or_default()
    )]
    Fit {
        /// The edge file (`DIR/EDGE.data`), or `DIR/the map.data` when the map and the
        /// attempts disagree.
        file: PathBuf,
        /// The attempt at fault, counted from 1.
        attempt: Option<usize>,
        /// Why.
        error: BuildError,
    },
    /// The test directory holds no attempt.
    #[error("{}: no test attempts", dir.display())]
    NoTestAttempts {
        /// The test directory.
        dir: PathBuf,
    },
    /// The training and test maps do not fit together.
    #[error(transparent)]
    Merge(#[from] MergeError),
    /// The models cannot score the test attempts.
    #[error(transparent)]
    Evaluate(#[from] BuildError),
}

/// Fits the success and duration models of every edge ([Fentanes 2015] §IV) from `attempts`
/// (one list per edge of `map`), naming the edge file in `dir` whose attempts are at fault.
///
/// # Errors
/// [`TopoJobError::Fit`] with the file and attempt.
pub fn fit_edge_models(
    map: TopoMap,
    attempts: &[Vec<Attempt>],
    config: EdgeModelConfig,
    dir: &Path,
) -> Result<EdgeModels, TopoJobError> {
    EdgeModels::fit(map, attempts, config).map_err(|(edge, error)| TopoJobError::Fit {
        file: dir.join(format!("{edge}.data")),
        attempt: error.observation_index().map(|i| i + 1),
        error,
    })
}

/// Edge models fitted on one directory and scored on the later attempts of another
/// ([Fentanes 2015] §V-A).
#[derive(Clone, Debug)]
pub struct Evaluation {
    /// The models, fitted on the training attempts over the union of both maps.
    pub models: EdgeModels,
    /// Training attempts in all.
    pub train_attempts: usize,
    /// The scores when each test attempt is predicted from everything before it.
    pub online: EdgeEvaluation,
    /// The scores of the models as fitted.
    pub frozen: EdgeEvaluation,
    /// Every edge with test attempts scored alone, when asked for.
    pub per_edge: Vec<EdgeScore>,
}

impl Evaluation {
    /// The scores of `protocol`.
    pub fn by(&self, protocol: Protocol) -> &EdgeEvaluation {
        match protocol {
            Protocol::Online => &self.online,
            Protocol::Frozen => &self.frozen,
        }
    }
}

/// Reads the edge files of `train` and `test`, fits the models of the union of their maps on
/// the training attempts with `config`, and scores them on the test attempts by both protocols;
/// with `per_edge`, also every edge alone by that protocol (reported to `progress` as the stage
/// `edges`).
///
/// # Errors
/// [`TopoJobError`]: a directory that cannot be read, a test directory without attempts, maps
/// that disagree on an edge, attempts that cannot be fitted or scored.
pub fn evaluate(
    train: &Path,
    test: &Path,
    config: EdgeModelConfig,
    per_edge: Option<Protocol>,
    progress: &dyn Progress,
) -> Result<Evaluation, TopoJobError> {
    let train_stats = read_edge_directory(train)?;
    let test_stats = read_edge_directory(test)?;
    if test_stats.total_attempts() == 0 {
        return Err(TopoJobError::NoTestAttempts {
            dir: test.to_path_buf(),
        });
    }
    let train_attempts = train_stats.total_attempts();
    let (map, train_lists, test_lists) = merge_maps(
        train_stats.map,
        train_stats.attempts,
        &test_stats.map,
        &test_stats.attempts,
    )?;
    let models = fit_edge_models(map, &train_lists, config, train)?;
    let online = Protocol::Online.evaluate(&models, &test_lists)?;
    let frozen = Protocol::Frozen.evaluate(&models, &test_lists)?;
    let per_edge = match per_edge {
        Some(protocol) => per_edge_scores(&models, &train_lists, &test_lists, protocol, progress)?,
        None => Vec::new(),
    };
    Ok(Evaluation {
        models,
        train_attempts,
        online,
        frozen,
        per_edge,
    })
}

#[cfg(test)]
mod tests {
    use chronomap_core::progress::NoProgress;

    use super::*;

    #[test]
    fn a_test_directory_without_attempts_is_named() {
        let tmp = chronomap_testutil::fresh_dir(
            std::env::temp_dir().join(format!("chronomap-app-topo-{}", std::process::id())),
        );
        let (train, test) = (tmp.join("train"), tmp.join("test"));
        std::fs::create_dir_all(&train).unwrap();
        std::fs::create_dir_all(&test).unwrap();
        // `time duration success`: one success, one failure.
        chronomap_testutil::write(&train, "A_B.data", "0 10 1\n60 20 0\n");
        let error =
            evaluate(&train, &test, EdgeModelConfig::default(), None, &NoProgress).unwrap_err();
        assert_eq!(
            error.to_string(),
            format!("{}: no test attempts", test.display())
        );
        // With one later attempt: scored, and scored alone as the edge's only one.
        chronomap_testutil::write(&test, "A_B.data", "120 10 1\n");
        let done = evaluate(
            &train,
            &test,
            EdgeModelConfig::default(),
            Some(Protocol::Frozen),
            &NoProgress,
        )
        .unwrap();
        assert_eq!(done.train_attempts, 2);
        assert_eq!((done.frozen.attempts, done.frozen.successes), (1, 1));
        assert_eq!(done.per_edge.len(), 1);
        assert_eq!(done.per_edge[0].train_attempts, 2);
        assert_eq!(done.by(Protocol::Frozen), &done.frozen);
        let _ = std::fs::remove_dir_all(&tmp);
    }
}
