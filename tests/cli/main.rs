//! The tests of the `chronomap` binary and of the whole stack on real data, one module per
//! command or dataset, in one test binary (one link instead of one per file).
#![allow(dead_code)] // each module uses a different subset of the shared helpers

mod common;
#[cfg(feature = "serve")]
mod service;

mod activity;
mod activity_disturbance;
mod activity_extract;
mod activity_model;
mod activity_truth;
mod architecture;
mod aruba;
mod basics;
mod bench_activity;
mod bench_grid_memory;
#[cfg(feature = "ros2")]
mod bench_ros2;
#[cfg(feature = "serve")]
mod bench_serve;
mod bt;
mod bt_btcpp_trees;
mod bt_differential;
mod bt_groot2;
mod casts;
mod closed_pipes;
mod events;
mod explore;
#[cfg(feature = "serve")]
mod export_parquet;
mod greg_door;
mod grid;
mod hostile;
mod hypertime;
mod ingest;
mod lidar;
mod limits;
mod monitor;
mod outputs;
mod psbt;
#[cfg(feature = "serve")]
mod read_only;
mod readme;
#[cfg(feature = "ros2")]
mod ros2_conventions;
#[cfg(feature = "ros2")]
mod ros2_crash;
#[cfg(feature = "ros2")]
mod ros2_models;
#[cfg(feature = "ros2")]
mod ros2_node;
#[cfg(feature = "serve")]
mod serve;
#[cfg(feature = "serve")]
mod serve_crash;
#[cfg(feature = "serve")]
mod serve_damage;
#[cfg(feature = "serve")]
mod serve_fleet;
#[cfg(feature = "serve")]
mod serve_network;
#[cfg(feature = "serve")]
mod serve_refit;
#[cfg(feature = "serve")]
mod serve_security;
mod sklearn_calibration;
mod sklearn_gmm;
mod storm_case;
mod storm_deadline;
mod storm_witham;
mod tom_door;
mod topo;
mod topo_deadline;
