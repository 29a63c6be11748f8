//! Groot2's live monitoring protocol for chronomap's behavior trees.
//!
//! Groot2 (and other clients such as `btview`) watch a running tree over ZeroMQ: BehaviorTree.CPP
//! 4's `Groot2Publisher` answers requests on a REP socket at a port and publishes breakpoint
//! notifications on a PUB socket at the next port. This crate speaks the same protocol
//! (protocol 2, as in BehaviorTree.CPP 4.8.2) for a [`chronomap_bt::Tree`]:
//!
//! * [`protocol`] — the pure codec, no I/O: request and reply headers, decoding of every request
//!   with errors (wrong size, unknown type, too many or too large parts), the replies a server
//!   sends (the tree as XML, the status buffer, blackboards as MessagePack, recorded
//!   transitions, hooks as JSON), and the decoding of replies for clients.
//! * [`publisher`] — the server: a thread with the REP and PUB sockets, serving a snapshot of
//!   the tree that the tick loop updates after each tick, and the hooks' callbacks that
//!   replace a node's result or hold the ticks at a breakpoint (the rules in `hooks`).
#![deny(missing_docs)]

mod builtins;
pub mod client;
mod hooks;
pub mod protocol;
pub mod publisher;
