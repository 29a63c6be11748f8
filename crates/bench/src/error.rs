//! Why a benchmark of [`fremen`](crate::fremen), [`grid`](crate::grid) or [`plan`](crate::plan)
//! could not run: one error type for the three, since a benchmark is an edge of the workspace
//! that only reports what went wrong.

use std::path::PathBuf;

use chronomap_core::{BuildError, ObservationError};
use chronomap_grid::GridError;
use chronomap_grid::build::PartitionError;
use chronomap_io::DataError;
use chronomap_synth::SynthError;
use chronomap_topo::map::TopoError;
use chronomap_topo::mdp::MdpError;
use chronomap_topo::plan::PlanError;
use thiserror::Error;

/// Why a FreMEn, grid or planning benchmark could not run.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum BenchError {
    /// A data file could not be read.
    #[error(transparent)]
    Data(#[from] DataError),
    /// The data are not a valid series for the model.
    #[error(transparent)]
    Observation(#[from] ObservationError),
    /// A model could not be built from the data.
    #[error(transparent)]
    Build(#[from] BuildError),
    /// An FFT FreMEn build did not reconstruct its input bit for bit.
    #[error("the FFT FreMEn build of order {order} ({method}) is not lossless")]
    NotLossless {
        /// The model order.
        order: usize,
        /// How the spectrum was computed.
        method: &'static str,
    },
    /// The training file holds no observation.
    #[error("{file}: no observation")]
    Empty {
        /// The file below `data/`.
        file: &'static str,
    },
    /// A component of a trained model has a period outside the model's candidate set.
    #[error("a component of period {period_secs} s is not among the candidate periods")]
    UnknownPeriod {
        /// The component's period.
        period_secs: f64,
    },
    /// The office cannot be generated with this configuration.
    #[error(transparent)]
    Office(#[from] SynthError),
    /// The grid cannot be built.
    #[error(transparent)]
    Grid(#[from] GridError),
    /// A part of the office cannot be streamed or built.
    #[error(transparent)]
    Partition(#[from] PartitionError),
    /// The edge files could not be read.
    #[error("cannot read the Witham edges in {}", dir.display())]
    Edges {
        /// The directory.
        dir: PathBuf,
        /// What went wrong (boxed: a data error is large).
        source: Box<DataError>,
    },
    /// The model of an edge could not be fitted.
    #[error("edge {edge}: {source}")]
    Fit {
        /// The edge.
        edge: String,
        /// What went wrong.
        source: BuildError,
    },
    /// A task could not be planned.
    #[error(transparent)]
    Plan(#[from] PlanError),
    /// A start node is not on the map.
    #[error(transparent)]
    Node(#[from] TopoError),
    /// A case could not be exported for Storm.
    #[error(transparent)]
    Export(#[from] MdpError),
    /// A file or directory for Storm could not be written.
    #[error("cannot write {}", path.display())]
    Write {
        /// The file or directory.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// The Python interpreter could not be started.
    #[error("cannot run {}", python.display())]
    StormStart {
        /// The interpreter.
        python: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// The timing script failed.
    #[error("{} storm_time.py failed ({status}):\n{stderr}", python.display())]
    StormFailed {
        /// The interpreter.
        python: PathBuf,
        /// How the process ended.
        status: String,
        /// What it wrote on stderr.
        stderr: String,
    },
    /// A bag could not be read.
    #[error(transparent)]
    Bag(#[from] chronomap_rosbag::BagError),
    /// A bag has no such topic, or one chronomap does not ingest.
    #[error("{bag}: {problem}")]
    Topic {
        /// The bag.
        bag: String,
        /// What is wrong with the topic.
        problem: String,
    },
    /// A file could not be read.
    #[error("cannot read {}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// The timing script's output is not JSON.
    #[error("storm_time.py output")]
    StormOutput(#[source] serde_json::Error),
    /// The baseline of the grid memory benchmark (the grid representation of format 1) does not
    /// hold what the grid it is compared with holds, or its file size cannot be computed.
    #[error("grid memory baseline: {0}")]
    GridBaseline(String),
    /// No private network namespace could be made for the DDS benchmark.
    #[error(
        "cannot make a private network namespace (`unshare -n` as root, `unshare -rn` \
         otherwise, and iproute2's `ip`): the DDS benchmark does not run on the real network"
    )]
    NoPrivateNetwork,
    /// The map benchmark's Python driver could not be started.
    #[error("cannot run {} bench_maps.py", python.display())]
    MapsStart {
        /// The interpreter.
        python: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// The map benchmark's Python driver failed.
    #[error("{} bench_maps.py failed ({status})", python.display())]
    MapsFailed {
        /// The interpreter.
        python: PathBuf,
        /// How the process ended.
        status: String,
    },
    /// The map benchmark's Python driver printed something that is not its report.
    #[error("bench_maps.py output: {0}")]
    MapsOutput(String),
}
