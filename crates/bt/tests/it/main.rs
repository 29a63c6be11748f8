//! Integration tests of chronomap-bt, in one test binary: the conformance cases derived from
//! BehaviorTree.CPP's gtests, the bounds (depth, width, bad ports and scripts) and custom
//! controls, decorators and stubs registered through the public API.

mod conformance;
mod custom_nodes;
mod robustness;
