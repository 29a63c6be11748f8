//! Conformance of the runtime with BehaviorTree.CPP 4: cases derived from its gtests
//! (`tests/gtest_*.cpp` of BehaviorTree.CPP, MIT-licensed; the trees and the expected results
//! are theirs, the code is ours). Each case is named after the gtest it comes from
//! (`file__case`) and says which one in a comment.
//!
//! The gtests' asynchronous test actions (which return running for some milliseconds) are
//! replaced by actions that return running on the first tick of an execution
//! (`AsyncSuccess`, `AsyncFailure`), and their conditions that change over time by
//! `ScriptCondition`s on blackboard entries the test sets, since conditions cannot return
//! running here ([Stüde 2024] §5.2.1).

// Case names are `gtest file__gtest case`, with the double underscore.
#![allow(non_snake_case)]

mod support;

mod controls;
mod decorators;
mod scripting;
