//! # chronomap-topo
//!
//! Navigation on topological maps whose edges know time (Fentanes et al., "Now or later?",
//! ICRA 2015): [`map`] — named nodes and directed edges; [`edges`] — one success and one
//! duration model per edge, learned from traversal attempts, with prediction intervals of
//! durations ([`duration_intervals`]); [`ltl`] — co-safe LTL tasks over
//! node names and their automata ([`automaton`]); [`mdp`] — the Navigation MDP at a time `t`,
//! its product with a task automaton, and the solver of `Pmax` and expected time; [`plan`] —
//! all of it together: the policy for a task started now, and "now or later?"; [`deadline`] —
//! the policy most likely to fulfil a task within a deadline ("arrive by T with 95 %
//! probability"), by backward induction over the product with the time left; [`report`] —
//! what front ends report of them: fit summaries (Table II), merged test maps, per-edge
//! scores, routes and the now-or-later table (Table III); [`layout`] — computed drawings of
//! maps without node positions (stress majorization, Gansner et al. 2004).
#![deny(missing_docs)]

pub mod automaton;
pub mod deadline;
pub mod duration_intervals;
pub mod edges;
pub mod layout;
pub mod ltl;
pub mod map;
pub mod mdp;
pub mod plan;
pub mod report;

pub use map::TopoMap;
