//! Errors of tree descriptions ([`DefinitionError`]) and of ticking ([`TickError`]).

use std::fmt;

use thiserror::Error;

use super::blackboard::BlackboardError;
use super::model::{NodeCategory, NodeLocation};

/// What is wrong with a tree description (the part of a [`DefinitionError`] after the
/// location). Messages name the node ID and the attribute concerned.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[non_exhaustive]
pub enum DefinitionErrorKind {
    /// The document has no tree.
    #[error("the document has no <BehaviorTree>")]
    NoTrees,
    /// Several trees and no `main_tree_to_execute`.
    #[error(
        "the document has several trees ({}) and no main_tree_to_execute",
        .trees.join(", ")
    )]
    NoMainTree {
        /// The tree IDs.
        trees: Vec<String>,
    },
    /// A `SubTree` or `main_tree_to_execute` names a tree that does not exist.
    #[error("there is no <BehaviorTree ID=\"{id}\">")]
    UnknownTree {
        /// The ID asked for.
        id: String,
    },
    /// Two trees have the same ID.
    #[error("two trees have the ID \"{id}\"")]
    DuplicateTree {
        /// The ID.
        id: String,
    },
    /// A tree uses itself through subtrees.
    #[error("subtrees are recursive: {}", .chain.join(" -> "))]
    RecursiveSubTree {
        /// The tree IDs from the first to the repeated one.
        chain: Vec<String>,
    },
    /// An ID that is not built in, not registered and not declared in `<TreeNodesModel>`.
    #[error(
        "unknown node ID \"{id}\" (not a built-in node, not registered, and not declared in \
         <TreeNodesModel>; write <Action ID=\"{id}\"/> or <Condition ID=\"{id}\"/> or declare \
         it)"
    )]
    UnknownNode {
        /// The ID.
        id: String,
    },
    /// A BehaviorTree.CPP built-in node that chronomap does not implement.
    #[error("\"{id}\" is a BehaviorTree.CPP node that chronomap does not implement")]
    UnsupportedNode {
        /// The ID.
        id: String,
    },
    /// The explicit form names the wrong category (`<Action ID="Sequence">`).
    #[error("\"{id}\" is a {actual} node, not a {written}")]
    WrongCategory {
        /// The ID.
        id: String,
        /// The category written.
        written: NodeCategory,
        /// The category of the ID.
        actual: NodeCategory,
    },
    /// Wrong number of children for the category.
    #[error("{category} \"{id}\" needs {}, found {found}", .category.children_rule())]
    ChildCount {
        /// The ID.
        id: String,
        /// Its category.
        category: NodeCategory,
        /// The number of children found.
        found: usize,
    },
    /// A tree whose ID is the name of a node type, which BehaviorTree.CPP refuses when it loads
    /// the document ("must not use the name of a registered Node").
    #[error("a tree cannot have the ID \"{id}\", the name of a node type")]
    TreeIdIsANode {
        /// The ID.
        id: String,
    },
    /// A `ReactiveSequence` with more than one `AsyncSequence` child, which BehaviorTree.CPP
    /// refuses when it loads the tree.
    #[error("\"{id}\": a ReactiveSequence cannot have more than one async child (AsyncSequence)")]
    AsyncChildren {
        /// The ID (`ReactiveSequence`).
        id: String,
    },
    /// A required attribute is missing.
    #[error("\"{id}\" needs the attribute \"{port}\"")]
    MissingPort {
        /// The ID.
        id: String,
        /// The attribute.
        port: String,
    },
    /// An attribute that is not a port of the node.
    #[error(
        "\"{id}\" has no port \"{port}\" ({})",
        if .known.is_empty() { "it has no ports".to_owned() } else { format!("its ports: {}", .known.join(", ")) }
    )]
    UnknownPort {
        /// The ID.
        id: String,
        /// The attribute.
        port: String,
        /// The declared ports.
        known: Vec<String>,
    },
    /// A literal attribute value of the wrong type.
    #[error("attribute {port}=\"{value}\" of \"{id}\" is invalid (expected {expected})")]
    BadValue {
        /// The ID.
        id: String,
        /// The attribute.
        port: String,
        /// The value as written.
        value: String,
        /// What the port needs.
        expected: String,
    },
    /// An output port given a literal instead of a `{key}`.
    #[error(
        "output port {port}=\"{value}\" of \"{id}\" must be a blackboard reference such as \
         \"{{{port}}}\""
    )]
    OutputNotReference {
        /// The ID.
        id: String,
        /// The attribute.
        port: String,
        /// The value as written.
        value: String,
    },
    /// A `Parallel` threshold larger than its number of children (BehaviorTree.CPP throws
    /// "Number of children is less than threshold").
    #[error("Parallel {port}=\"{threshold}\" needs {required} children but it has {children}")]
    ParallelThreshold {
        /// `success_count` or `failure_count`.
        port: String,
        /// The threshold as written.
        threshold: i64,
        /// The number of children it requires.
        required: usize,
        /// The number of children.
        children: usize,
    },
    /// An empty ID.
    #[error("a node ID is empty")]
    EmptyId,
    /// More nodes than 16-bit uids can number.
    #[error("the tree has more than 65535 nodes (uids are 16-bit, as in Groot2 logs)")]
    TooManyNodes,
    /// The tree (with its subtrees expanded) nests deeper than [`MAX_DEPTH`] levels.
    ///
    /// [`MAX_DEPTH`]: super::runtime::MAX_DEPTH
    #[error("tree nesting deeper than {max} levels")]
    TooDeep {
        /// The limit.
        max: usize,
    },
    /// A script (a `Script`'s `code`, a `Precondition`'s `if`, a pre- or post-condition
    /// attribute such as `_skipIf`) that does not parse, or an unknown `_` attribute.
    #[error("attribute {attribute} of \"{id}\": {message}")]
    BadScript {
        /// The ID.
        id: String,
        /// The attribute (`code`, `if`, `_skipIf`, …).
        attribute: String,
        /// The script as written (quoted) and what is wrong with it.
        message: String,
    },
    /// A node whose number of children its ID does not allow (`IfThenElse`: 2 or 3).
    #[error("\"{id}\" needs {expected}, found {found}")]
    WrongChildren {
        /// The ID.
        id: String,
        /// What is needed (`"2 or 3 children"`).
        expected: String,
        /// The number of children found.
        found: usize,
    },
    /// A leaf that is known (declared) but has no implementation in the registry.
    #[error("no implementation is registered for {category} \"{id}\"")]
    NotImplemented {
        /// The ID.
        id: String,
        /// Its category.
        category: NodeCategory,
    },
}

/// Why a tree description is invalid: where (tree and node, when known), the attribute
/// concerned (when there is one) and what is wrong.
///
/// Displays as `tree "Main", node at child path 0/1: "Repeat" needs the attribute
/// "num_cycles"`; file readers replace the location with `file:line:column`.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[error("{}{}", Located(self.0.location.as_ref()), self.0.kind)]
pub struct DefinitionError(Box<DefinitionRepr>);

#[derive(Clone, Debug, PartialEq, Eq)]
struct DefinitionRepr {
    location: Option<NodeLocation>,
    attribute: Option<String>,
    kind: DefinitionErrorKind,
}

struct Located<'a>(Option<&'a NodeLocation>);

impl fmt::Display for Located<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(location) => write!(f, "{location}: "),
            None => Ok(()),
        }
    }
}

impl DefinitionError {
    /// An error about the whole document.
    pub fn document(kind: DefinitionErrorKind) -> DefinitionError {
        DefinitionError(Box::new(DefinitionRepr {
            location: None,
            attribute: None,
            kind,
        }))
    }

    /// An error about the node at `location`.
    pub fn at(location: NodeLocation, kind: DefinitionErrorKind) -> DefinitionError {
        DefinitionError(Box::new(DefinitionRepr {
            location: Some(location),
            attribute: None,
            kind,
        }))
    }

    /// The same error, about the node at `location` (for checks that are given a stand-in
    /// location so that none is made per node checked).
    pub(crate) fn relocated(mut self, location: NodeLocation) -> DefinitionError {
        if self.0.location.is_some() {
            self.0.location = Some(location);
        }
        self
    }

    /// The same error, about the attribute `attribute`.
    pub fn with_attribute(mut self, attribute: &str) -> DefinitionError {
        self.0.attribute = Some(attribute.to_owned());
        self
    }

    /// The node concerned, if the error is about one node.
    pub fn location(&self) -> Option<&NodeLocation> {
        self.0.location.as_ref()
    }

    /// The attribute concerned, if any (`num_attempts`, `ID`, `main_tree_to_execute`).
    pub fn attribute(&self) -> Option<&str> {
        self.0.attribute.as_deref()
    }

    /// What is wrong.
    pub fn kind(&self) -> &DefinitionErrorKind {
        &self.0.kind
    }
}

/// Why a port could not be read or written during a tick.
#[derive(Clone, Debug, Error, PartialEq)]
#[non_exhaustive]
pub enum PortError {
    /// No attribute and no default value for the port.
    #[error("port \"{port}\" has no value (no attribute and no default)")]
    Missing {
        /// The port.
        port: String,
    },
    /// The port refers to a blackboard entry that does not exist.
    #[error("port \"{port}\" refers to the blackboard entry \"{key}\", which does not exist")]
    MissingEntry {
        /// The port.
        port: String,
        /// The key.
        key: String,
    },
    /// The value cannot be converted to the type asked for.
    #[error("port \"{port}\": {value:?} is not {expected}")]
    BadValue {
        /// The port.
        port: String,
        /// The value (literal or blackboard value, as text).
        value: String,
        /// What was asked for.
        expected: &'static str,
    },
    /// An output port whose attribute is a literal.
    #[error("output port \"{port}\" is {value:?}, not a blackboard reference such as {{key}}")]
    NotAReference {
        /// The port.
        port: String,
        /// The attribute value.
        value: String,
    },
    /// The blackboard refused the value.
    #[error("port \"{port}\": {error}")]
    Blackboard {
        /// The port.
        port: String,
        /// The blackboard's reason.
        error: BlackboardError,
    },
}

/// An error returned by a leaf: a message of its own, or a port problem.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum LeafError {
    /// The leaf's own message.
    #[error("{0}")]
    Failed(String),
    /// A port could not be read or written.
    #[error(transparent)]
    Port(#[from] PortError),
}

impl LeafError {
    /// An error with a message.
    pub fn new(message: impl Into<String>) -> LeafError {
        LeafError::Failed(message.into())
    }
}

/// What went wrong in a tick (the part of a [`TickError`] after the node).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum TickErrorKind {
    /// A port of a built-in node could not be read.
    #[error(transparent)]
    Port(#[from] PortError),
    /// A leaf returned an error.
    #[error(transparent)]
    Leaf(#[from] LeafError),
    /// A leaf returned `Idle`, which BehaviorTree.CPP forbids ("A children should not return
    /// IDLE").
    #[error("the leaf returned IDLE")]
    ReturnedIdle,
    /// A node's tick ended with idle, which `TreeNode::setStatus` refuses ("you are not
    /// allowed to set manually the status to IDLE"): a `WhileDoElse` whose condition was
    /// skipped, a `Precondition` whose `else` is `IDLE`.
    #[error(
        "the node's tick ended with IDLE, which BehaviorTree.CPP refuses (\"you are not \
         allowed to set manually the status to IDLE\")"
    )]
    SetIdle,
    /// A node that BehaviorTree.CPP refuses while ticking: a port it cannot read, a wrong
    /// number of children, a skipped condition of `IfThenElse`; the message is
    /// BehaviorTree.CPP's.
    #[error("{0}")]
    Refused(String),
    /// A condition returned `Running` (conditions cannot, [Stüde 2024] §5.2.1).
    #[error("a condition returned RUNNING (conditions return SUCCESS or FAILURE)")]
    ConditionRunning,
    /// A `Parallel` threshold larger than its number of children.
    #[error("{port} = {threshold} needs {required} children but the node has {children}")]
    ParallelThreshold {
        /// `success_count` or `failure_count`.
        port: &'static str,
        /// The threshold.
        threshold: i64,
        /// The number of children it requires.
        required: usize,
        /// The number of children.
        children: usize,
    },
    /// A script failed while it ran (unknown variable, type mismatch, …).
    #[error("script {attribute}=\"{code}\": {error}")]
    Script {
        /// The attribute holding the script (`code`, `_skipIf`, …).
        attribute: String,
        /// The script.
        code: String,
        /// What went wrong.
        error: super::scripting::ScriptError,
    },
    /// A custom control or decorator failed (its own message).
    #[error("{0}")]
    Node(String),
    /// The tick time is earlier than the previous one.
    #[error("time went backwards: tick at {now:?} after a tick at {previous:?}")]
    ClockWentBackwards {
        /// The previous tick time.
        previous: std::time::Duration,
        /// The time given.
        now: std::time::Duration,
    },
}

/// Why a tick failed: the node (uid, instance name and ID), when the error belongs to one, and
/// what went wrong. After an error the tree should be halted ([`Tree::halt`]) before it is
/// ticked again.
///
/// [`Tree::halt`]: super::Tree::halt
#[derive(Debug, Error)]
#[error("{}{}", NodePrefix(self.0.node.as_ref()), self.0.kind)]
pub struct TickError(Box<TickRepr>);

#[derive(Debug)]
struct TickRepr {
    node: Option<(u16, String, String)>,
    kind: TickErrorKind,
}

impl TickError {
    /// An error of the node `(uid, instance name, ID)`, or of no node.
    pub fn new(node: Option<(u16, String, String)>, kind: TickErrorKind) -> TickError {
        TickError(Box::new(TickRepr { node, kind }))
    }

    /// The uid of the node the error belongs to, if any.
    pub fn uid(&self) -> Option<u16> {
        self.0.node.as_ref().map(|n| n.0)
    }

    /// `(uid, instance name, ID)` of the node the error belongs to, if any.
    pub fn node(&self) -> Option<(u16, &str, &str)> {
        self.0
            .node
            .as_ref()
            .map(|(uid, name, id)| (*uid, name.as_str(), id.as_str()))
    }

    /// What went wrong.
    pub fn kind(&self) -> &TickErrorKind {
        &self.0.kind
    }
}

struct NodePrefix<'a>(Option<&'a (u16, String, String)>);

impl fmt::Display for NodePrefix<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some((uid, name, id)) if name == id => write!(f, "node {uid} ({id}): "),
            Some((uid, name, id)) => write!(f, "node {uid} ({name:?}, {id}): "),
            None => Ok(()),
        }
    }
}
