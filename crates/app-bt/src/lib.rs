//! # chronomap-app-bt
//!
//! The application layer for behavior trees ([Stüde 2024] chapter 5): what the command line
//! (and any other face) runs on BehaviorTree.CPP documents, beside `chronomap-app`, whose
//! [`report`](chronomap_app::report) tables and [`open`](chronomap_app::open) sniffing it uses.
//! The semantics stay in their domain crates (`chronomap-bt`: the BehaviorTree.CPP 4 runtime;
//! `chronomap-bt-stochastic`: the Markov chain of a tree; `chronomap-bt-monitor`: monitors and
//! the fault simulation; `chronomap-psbt`: person search); here they meet files and become jobs
//! with reports.
//!
//! ```
//! use chronomap_app_bt::bt::curve_times;
//!
//! // The times `bt analyse` evaluates a tree's outcome probabilities at: 0 to t_max in 4 steps.
//! assert_eq!(curve_times(8.0, 4), vec![0.0, 2.0, 4.0, 6.0, 8.0]);
//! ```
//!
//! | module | what the faces get |
//! |---|---|
//! | [`bt`] | a BehaviorTree.CPP document with node models, its registry under stubs, checks, scripted and live runs, the stochastic analysis and its default horizon (§5.2) |
//! | [`monitor`] | the monitoring simulation with injected faults, Tables 5.2 and 5.3 (§5.3) |
//! | [`psbt`] | the person search behavior tree: world set-up, synthesis and the comparison with the baselines (§5.4) |
#![deny(missing_docs)]

pub mod bt;
pub mod monitor;
pub mod psbt;
