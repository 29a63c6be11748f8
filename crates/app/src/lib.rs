//! # chronomap-app
//!
//! The application layer between chronomap's domains and its faces (the command line, the
//! service, the Python package and the ROS 2 node), in the spirit of kiss-icp's `pipeline`:
//! what more than one face needs and no single domain owns. The domains stay pure (no I/O,
//! clock or printing); the faces only translate arguments, messages and errors; everything that
//! combines files with algorithms into a job lives here, once.
//!
//! Data still flow one way, observations → models → predictions → decisions: this crate
//! depends on the domains and on `chronomap-io`, and nothing below it depends on it.
//!
//! ```
//! use std::path::Path;
//! use chronomap_app::open::FileKind;
//!
//! // A face asks what a file holds before it chooses a reader: by the container's header
//! // where there is one, by the name (through `.xz`/`.gz`) where there is not.
//! let header = b"chronomap-model 1 kind=copa-map encoding=postcard bytes=12 crc32=0badf00d\n";
//! let kind = FileKind::of_bytes(header).unwrap();
//! assert!(kind.is_copa_map());
//! assert_eq!(FileKind::by_name(Path::new("witham.tmap2.xz")), FileKind::Tmap2);
//! assert_eq!(FileKind::by_name(Path::new("door.xml")), FileKind::BtXml);
//! ```
//!
//! | module | what the faces get |
//! |---|---|
//! | [`open`] | what kind of file a path holds |
//! | [`report`] | plain-text tables and units for the reports the jobs render |
//! | [`activity`], [`disturbance`] | activity models opened by content, rate maps, sample extraction, the evaluation of [Stüde 2024] §4.3.2 and the service-disturbance experiment (eq. 4.22) |
//! | [`grid`] | the grid build job and its hold-out error table ([Krajník 2017] §VI), what a grid file holds, predicted maps (§VIII) |
//! | [`model`] | a model fitted and written, what a model file holds, anomalies ([Krajník 2017], [Krajník 2019]) |
//! | [`demo`] | the sections of `chronomap demo`: doors beside the original FreMEn code, FFT FreMEn, grids ([Krajník 2017]) |
//! | [`eval`], [`compress`] | the FreMEn benchmark experiment and the compression study ([Krajník 2017]) |
//! | [`events`], [`ingest`] | people as events and tracks, the pedestrian study ([Krajník 2019] §V-D) |
//! | [`datasets`], [`explore`] | the exploration datasets (Aruba, Brayford), the strategy × model table, Figs. 5 and 6 ([Santos 2017]) |
//! | [`topo`] | edge-model fits, evaluations, splits, predictions, timed plans and now-or-later tables, the Witham demo ([Fentanes 2015]) |
//! | [`features`] | which features will be visible ([Krajník 2017] §VII Table I, [Krajník 2019] §V-B) |
//!
//! The jobs of two families live in crates of their own beside this one, as linfa keeps one
//! crate per algorithm family: `chronomap-app-range` (laser logs, loop closure, registration,
//! the map manager: [Stüde 2024] chapter 3) and `chronomap-app-bt` (behavior trees,
//! monitoring, person search: chapter 5). They share this crate's [`report`] and [`open`].
#![deny(missing_docs)]

pub mod activity;
#[cfg(feature = "plot")]
pub mod calibration_plots;
pub mod compress;
pub mod datasets;
pub mod demo;
pub mod disturbance;
pub mod eval;
pub mod events;
pub mod explore;
pub mod features;
pub mod grid;
#[cfg(feature = "rosbag")]
pub mod ingest;
pub mod model;
pub mod open;
pub mod report;
pub mod topo;
