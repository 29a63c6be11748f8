//! The subcommands: each turns flags into readers and models, calls the core, prints.

mod activity;
mod activity_disturbance;
mod activity_extract;
mod activity_model;
mod activity_truth;
mod bench;
mod bench_activity;
mod bench_bt;
#[cfg(feature = "serve")]
mod bench_fleet;
mod bench_grid_memory;
mod bench_ingest;
mod bench_plan;
mod bench_psbt;
#[cfg(feature = "ros2")]
mod bench_ros2;
#[cfg(feature = "serve")]
mod bench_serve;
mod bt;
mod compress;
mod demo;
mod demo_grids;
mod demo_topo;
mod eval;
mod events;
mod explore;
#[cfg(feature = "serve")]
mod export;
mod features;
mod grid;
mod ingest;
mod laser_log;
mod lidar;
mod maps;
mod model;
mod monitor;
mod psbt;
#[cfg(feature = "ros2")]
mod ros2;
#[cfg(feature = "serve")]
mod serve;
mod topo;

use anyhow::{Context, Result};
use chronomap_core::TimeSeries;
use chronomap_io::{read_any_model, read_pairs, read_test_set};
use chronomap_models::AnyModel;

use crate::cli::{
    ActivityCommand, BenchCommand, BtCommand, Command, EventsCommand, GridCommand, LidarCommand,
    MapsCommand, MonitorCommand, SeriesSource, TopoCommand,
};

/// Runs one subcommand.
pub fn run(command: Command) -> Result<()> {
    match command {
        Command::Demo(args) => demo::run(&args),
        Command::Eval(args) => eval::run(&args),
        Command::Fit(args) => model::fit(&args),
        Command::Predict(args) => model::predict(&args),
        Command::Inspect(args) => model::inspect(&args),
        Command::Anomalies(args) => model::anomalies(&args),
        Command::Compress(args) => compress::run(&args),
        Command::Ingest(args) => ingest::run(&args),
        Command::Grid(GridCommand::Build(args)) => grid::build(&args),
        Command::Grid(GridCommand::Predict(args)) => grid::predict(&args),
        Command::Grid(GridCommand::Stats(args)) => grid::stats(&args),
        Command::Grid(GridCommand::Plot(args)) => grid::plot(&args),
        Command::Bench(BenchCommand::Grid(args)) => bench::grid(&args),
        Command::Bench(BenchCommand::GridMemory(args)) => bench_grid_memory::grid_memory(&args),
        Command::Bench(BenchCommand::Plan(args)) => bench_plan::plan(&args),
        #[cfg(feature = "serve")]
        Command::Bench(BenchCommand::Serve(args)) => bench_serve::serve(&args),
        #[cfg(feature = "serve")]
        Command::Bench(BenchCommand::Fleet(args)) => bench_fleet::fleet(&args),
        Command::Bench(BenchCommand::Activity(args)) => bench_activity::activity(&args),
        Command::Bench(BenchCommand::Bt(args)) => bench_bt::bt(&args),
        Command::Bench(BenchCommand::Psbt(args)) => bench_psbt::psbt(&args),
        Command::Bench(BenchCommand::Ingest(args)) => bench_ingest::ingest(&args),
        Command::Bench(BenchCommand::Registration(args)) => lidar::bench_registration(&args),
        #[cfg(feature = "ros2")]
        Command::Bench(BenchCommand::Ros2(args)) => bench_ros2::ros2(&args),
        Command::Explore(args) => explore::run(&args),
        Command::Topo(TopoCommand::Fit(args)) => topo::fit(&args),
        Command::Topo(TopoCommand::Eval(args)) => topo::eval(&args),
        Command::Topo(TopoCommand::Split(args)) => topo::split(&args),
        Command::Topo(TopoCommand::Observe(args)) => topo::observe(&args),
        Command::Topo(TopoCommand::Predict(args)) => topo::predict(&args),
        Command::Plan(args) => topo::plan(&args),
        Command::Events(EventsCommand::Eval(args)) => events::eval(&args),
        Command::Activity(ActivityCommand::Eval(args)) => activity::eval(&args),
        Command::Activity(ActivityCommand::Truth(args)) => activity_truth::truth(&args),
        Command::Activity(ActivityCommand::Fit(args)) => activity_model::fit(&args),
        Command::Activity(ActivityCommand::Predict(args)) => activity_model::predict(&args),
        Command::Activity(ActivityCommand::Extract(args)) => activity_extract::run(&args),
        Command::Activity(ActivityCommand::Disturbance(args)) => activity_disturbance::run(&args),
        Command::Psbt(args) => psbt::run(&args),
        Command::Lidar(LidarCommand::Descriptors(args)) => lidar::descriptors(&args),
        Command::Lidar(LidarCommand::Eval(args)) => lidar::eval(&args),
        Command::Lidar(LidarCommand::Train(args)) => lidar::train(&args),
        Command::Lidar(LidarCommand::Detect(args)) => lidar::detect(&args),
        Command::Lidar(LidarCommand::Register(args)) => lidar::register_clouds(&args),
        Command::Maps(MapsCommand::Build(args)) => maps::build(&args),
        Command::Hypertime(args) => events::hypertime(&args),
        Command::Features(args) => features::run(&args),
        #[cfg(feature = "serve")]
        Command::Serve(args) => serve::serve(&args),
        #[cfg(feature = "serve")]
        Command::Client(args) => serve::client(&args),
        #[cfg(feature = "serve")]
        Command::Export(crate::cli::ExportCommand::Parquet(args)) => export::parquet(&args),
        #[cfg(feature = "ros2")]
        Command::Ros2(args) => ros2::run(&args),
        Command::Bt(BtCommand::Check(args)) => bt::check(&args),
        Command::Bt(BtCommand::Run(args)) => bt::run(&args),
        Command::Bt(BtCommand::Analyse(args)) => bt::analyse(&args),
        Command::Monitor(MonitorCommand::Sim(args)) => monitor::sim(&args),
    }
}

/// Reads a series from one `t value` file or two line-aligned files.
fn read_series(source: &SeriesSource) -> Result<TimeSeries> {
    Ok(match source {
        SeriesSource::Pairs(path) => read_pairs(path)?,
        SeriesSource::Split(times, values) => read_test_set(times, values)?,
    })
}

/// Display name of a series source.
fn source_name(source: &SeriesSource) -> String {
    match source {
        SeriesSource::Pairs(path) => path.display().to_string(),
        SeriesSource::Split(times, values) => format!("{},{}", times.display(), values.display()),
    }
}

/// Reads a model file, checking version, checksum and invariants.
fn load_model(path: &std::path::Path) -> Result<AnyModel> {
    read_any_model(path).context("cannot load the model")
}
