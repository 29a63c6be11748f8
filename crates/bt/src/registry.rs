//! Leaf implementations registered by ID (BehaviorTree.CPP's `BehaviorTreeFactory`), the
//! [`LeafNode`] trait, and what a leaf sees when it is ticked ([`LeafContext`]).
//!
//! A leaf is a trait object made fresh for every node instance by a factory closure, so it can
//! keep state across ticks (an action that returns running, then success). Its
//! [`LeafNode::tick`] sees in [`LeafContext::status`] whether it is starting (`Idle`, like
//! BehaviorTree.CPP's `StatefulActionNode::onStart`) or continuing (`Running`, `onRunning`);
//! [`LeafNode::halt`] is called when a running leaf is halted (`onHalted`). Stateless leaves
//! are plain closures ([`Registry::register_action_fn`], [`Registry::register_condition_fn`]).
//!
//! Custom control nodes and decorators (BehaviorTree.CPP's `registerNodeType` of a
//! `ControlNode` or `DecoratorNode` subclass) implement [`ControlNode`] and tick and halt their
//! children through a [`ControlContext`] ([`Registry::register_control`]). Nodes declared but
//! not implemented can be stubbed ([`Registry::register_stub`]). Enum values for scripts are
//! registered by name ([`Registry::register_enum`]).
//!
//! ```
//! use std::time::Duration;
//! use chronomap_bt::{
//!     BtDocument, ControlContext, ControlNode, NodeCategory, NodeDef, NodeModel, PortSpec,
//!     Registry, Status, TickError, Tree, TreeDef,
//! };
//!
//! /// Ticks its children from the last to the first, as a sequence (without memory).
//! struct BackwardSequence;
//!
//! impl ControlNode for BackwardSequence {
//!     fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError> {
//!         for k in (0..ctx.child_count()).rev() {
//!             match ctx.tick_child(k)? {
//!                 Status::Success | Status::Skipped => {}
//!                 Status::Running => return Ok(Status::Running),
//!                 other => {
//!                     ctx.reset_children();
//!                     return Ok(other);
//!                 }
//!             }
//!         }
//!         ctx.reset_children();
//!         Ok(Status::Success)
//!     }
//! }
//!
//! /// Inverts its child's result when `invert` is true.
//! struct MaybeInvert;
//!
//! impl ControlNode for MaybeInvert {
//!     fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError> {
//!         let invert: bool = ctx.input("invert")?;
//!         Ok(match ctx.tick_child(0)? {
//!             Status::Success if invert => Status::Failure,
//!             Status::Failure if invert => Status::Success,
//!             other => other,
//!         })
//!     }
//! }
//!
//! let mut registry = Registry::new();
//! registry.register_control(NodeModel::new(NodeCategory::Control, "BackwardSequence"), || {
//!     Box::new(BackwardSequence)
//! })?;
//! registry.register_control(
//!     NodeModel::new(NodeCategory::Decorator, "MaybeInvert")
//!         .port(PortSpec::input("invert").typed("bool")),
//!     || Box::new(MaybeInvert),
//! )?;
//! let root = NodeDef::control("BackwardSequence")
//!     .child(NodeDef::action("AlwaysFailure"))
//!     .child(
//!         NodeDef::decorator("MaybeInvert")
//!             .port("invert", "true")
//!             .child(NodeDef::action("AlwaysFailure")),
//!     );
//! let doc = BtDocument::single(TreeDef::new("Main", root));
//! let mut tree = Tree::new(&doc, &registry)?;
//! // The inverted failure succeeds, then the first child fails.
//! assert_eq!(tree.tick_once(Duration::ZERO)?, Status::Failure);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::{BTreeMap, HashMap, HashSet};
use std::sync::Arc;
use std::time::Duration;

use thiserror::Error;

use super::Status;
use super::blackboard::{Blackboard, FromValue, ScopeId, ScriptedWrite, Value};
use super::builtin::{
    BUILTIN_LEAVES, BuiltinKind, UNSUPPORTED_BUILTINS, builtin_model, is_builtin,
};
use super::error::{DefinitionErrorKind, PortError, TickError, TickErrorKind};
use super::model::{NodeCategory, NodeModel, PortSpec, blackboard_pointer};
use super::runtime::Tree;

pub use super::error::LeafError;

/// An action or condition implementation.
pub trait LeafNode: Send {
    /// Executes one tick and returns `Running`, `Success` or `Failure` (conditions: `Success`
    /// or `Failure`). [`LeafContext::status`] is `Idle` when an execution starts and `Running`
    /// when it continues.
    ///
    /// # Errors
    /// Anything that makes the tick impossible; the tree's tick fails with a [`TickError`]
    /// naming this node.
    ///
    /// [`TickError`]: super::TickError
    fn tick(&mut self, ctx: &mut LeafContext<'_>) -> Result<Status, LeafError>;

    /// Called when the node is halted while running (by a parent, a `Timeout` or
    /// [`Tree::halt`](super::Tree::halt)); its status becomes `Idle` afterwards. The default
    /// does nothing.
    fn halt(&mut self, ctx: &mut LeafContext<'_>) {
        let _ = ctx;
    }
}

/// What a leaf sees during a tick or a halt: its identity, its previous status, the time, and
/// its ports on the blackboard.
pub struct LeafContext<'a> {
    pub(crate) uid: u16,
    pub(crate) id: &'a str,
    pub(crate) name: &'a str,
    pub(crate) ports: &'a Ports,
    pub(crate) status: Status,
    pub(crate) now: Duration,
    pub(crate) blackboard: &'a mut Blackboard,
    pub(crate) scope: ScopeId,
}

impl LeafContext<'_> {
    /// The node's uid (1, 2, … in depth-first order).
    pub fn uid(&self) -> u16 {
        self.uid
    }

    /// The registration ID (`OpenDoor`).
    pub fn id(&self) -> &str {
        self.id
    }

    /// The instance name (the `name` attribute, or the ID).
    pub fn name(&self) -> &str {
        self.name
    }

    /// The status before this tick: `Idle` when starting, `Running` when continuing.
    pub fn status(&self) -> Status {
        self.status
    }

    /// The time of the tick (as given to [`Tree::tick_once`](super::Tree::tick_once)).
    pub fn now(&self) -> Duration {
        self.now
    }

    /// The port's attribute as written (after `{=}` expansion and defaults), if any.
    pub fn port_attribute(&self, port: &str) -> Option<&str> {
        port_attribute(self.ports, port)
    }

    /// Reads an input port as `T`: a literal is parsed, a `{key}` is read from the blackboard.
    ///
    /// # Errors
    /// [`PortError`] if the port has no value, refers to a missing entry, or does not convert.
    pub fn input<T: FromValue>(&self, port: &str) -> Result<T, PortError> {
        read_port(self.ports, port, self.blackboard, self.scope)
    }

    /// Like [`LeafContext::input`], but `None` when the port has no attribute and no default.
    ///
    /// # Errors
    /// As [`LeafContext::input`], except for a missing value.
    pub fn input_opt<T: FromValue>(&self, port: &str) -> Result<Option<T>, PortError> {
        match self.input(port) {
            Ok(v) => Ok(Some(v)),
            Err(PortError::Missing { .. }) => Ok(None),
            Err(e) => Err(e),
        }
    }

    /// Writes an output port: its attribute must be a `{key}` reference.
    ///
    /// # Errors
    /// [`PortError`] if the port has no attribute, is a literal, or the blackboard refuses
    /// the value (type change).
    pub fn set_output(&mut self, port: &str, value: impl Into<Value>) -> Result<(), PortError> {
        write_port(self.ports, port, value.into(), self.blackboard, self.scope)
    }

    /// The blackboard.
    pub fn blackboard(&self) -> &Blackboard {
        self.blackboard
    }

    /// The blackboard, writable.
    pub fn blackboard_mut(&mut self) -> &mut Blackboard {
        self.blackboard
    }

    /// The blackboard scope of this node (its subtree instance).
    pub fn scope(&self) -> ScopeId {
        self.scope
    }
}

pub(crate) fn port_attribute<'p>(ports: &'p Ports, port: &str) -> Option<&'p str> {
    ports.get(port)
}

/// A node's ports as it reads them: its own attributes (`{=}` expanded), then the defaults of
/// its model for the ports it does not give. The defaults are shared by every node of the
/// model, so that a model with many ports costs its size once, not once per node using it.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Ports {
    pub(crate) own: Vec<(String, String)>,
    pub(crate) defaults: Arc<Defaults>,
}

/// The ports of a model that have a default value, in the model's order, indexed by name.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub(crate) struct Defaults {
    list: Vec<(String, String)>,
    index: HashMap<String, usize>,
}

impl Defaults {
    /// The defaults of `model`'s ports (the first port of a name counts).
    pub(crate) fn of(model: &NodeModel) -> Defaults {
        let mut defaults = Defaults::default();
        for spec in &model.ports {
            if let Some(default) = &spec.default
                && !defaults.index.contains_key(&spec.name)
            {
                defaults
                    .index
                    .insert(spec.name.clone(), defaults.list.len());
                defaults.list.push((spec.name.clone(), default.clone()));
            }
        }
        defaults
    }
}

impl Ports {
    /// The value of `port`: the node's own attribute, or the model's default.
    pub(crate) fn get(&self, port: &str) -> Option<&str> {
        match self.own.iter().find(|(n, _)| n == port) {
            Some((_, v)) => Some(v.as_str()),
            None => self
                .defaults
                .index
                .get(port)
                .map(|&i| self.defaults.list[i].1.as_str()),
        }
    }

    /// The node's own attributes, then the defaults of the ports it does not give.
    pub(crate) fn merged(&self) -> Vec<(String, String)> {
        let own: HashSet<&str> = self.own.iter().map(|(n, _)| n.as_str()).collect();
        let mut ports = self.own.clone();
        ports.extend(
            self.defaults
                .list
                .iter()
                .filter(|(n, _)| !own.contains(n.as_str()))
                .cloned(),
        );
        ports
    }
}

/// BehaviorTree.CPP's `TreeNode::getInput`: a `{key}` reads the blackboard (strings there are
/// parsed), a literal is parsed with `convertFromString`.
pub(crate) fn read_port<T: FromValue>(
    ports: &Ports,
    port: &str,
    blackboard: &Blackboard,
    scope: ScopeId,
) -> Result<T, PortError> {
    let raw = port_attribute(ports, port).ok_or_else(|| PortError::Missing {
        port: port.to_owned(),
    })?;
    let value = match blackboard_pointer(raw) {
        Some(key) => blackboard
            .get_in(scope, key)
            .ok_or_else(|| PortError::MissingEntry {
                port: port.to_owned(),
                key: key.to_owned(),
            })?
            .clone(),
        None => Value::Str(raw.to_owned()),
    };
    T::from_value(&value).ok_or_else(|| PortError::BadValue {
        port: port.to_owned(),
        value: value.to_string(),
        expected: T::EXPECTED,
    })
}

pub(crate) fn write_port(
    ports: &Ports,
    port: &str,
    value: Value,
    blackboard: &mut Blackboard,
    scope: ScopeId,
) -> Result<(), PortError> {
    let raw = port_attribute(ports, port).ok_or_else(|| PortError::Missing {
        port: port.to_owned(),
    })?;
    let key = blackboard_pointer(raw).ok_or_else(|| PortError::NotAReference {
        port: port.to_owned(),
        value: raw.to_owned(),
    })?;
    blackboard
        .set_in(scope, key, value)
        .map_err(|error| PortError::Blackboard {
            port: port.to_owned(),
            error,
        })
}

/// Why a registration was refused.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
#[non_exhaustive]
pub enum RegistryError {
    /// The ID is registered already (BehaviorTree.CPP: "ID [...] already registered").
    #[error("\"{id}\" is registered already")]
    AlreadyRegistered {
        /// The ID.
        id: String,
    },
    /// The ID is a built-in node.
    #[error("\"{id}\" is a built-in node")]
    Builtin {
        /// The ID.
        id: String,
    },
    /// The registration function does not take this category (leaves with `register*`,
    /// controls and decorators with `register_control`; `SubTree`s are never registered).
    #[error("\"{id}\" is a {category}, which this registration function does not take")]
    NotALeaf {
        /// The ID.
        id: String,
        /// The category given.
        category: NodeCategory,
    },
    /// An empty ID.
    #[error("an empty ID cannot be registered")]
    EmptyId,
    /// A condition stub cannot return running.
    #[error("\"{id}\" is a condition; a stub of a condition cannot return RUNNING")]
    RunningCondition {
        /// The ID.
        id: String,
    },
}

type Factory = Arc<dyn Fn() -> Box<dyn LeafNode> + Send + Sync>;
type ControlFactory = Arc<dyn Fn() -> Box<dyn ControlNode> + Send + Sync>;

#[derive(Clone)]
enum Implementation {
    Leaf(Factory),
    Control(ControlFactory),
    Builtin(BuiltinKind),
}

struct Entry {
    model: NodeModel,
    check_ports: bool,
    implementation: Implementation,
}

/// A new instance of a registered node.
pub(crate) enum Instance {
    Leaf(Box<dyn LeafNode>),
    Control(Box<dyn ControlNode>),
    Builtin(BuiltinKind),
}

/// What a stub registered with [`Registry::register_stub`] returns, for leaves. Stubs of
/// controls behave as a `Sequence` and stubs of decorators pass their child's status through,
/// whatever the policy.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StubPolicy {
    /// Succeeds at every tick.
    Success,
    /// Fails at every tick.
    Failure,
    /// Returns running for `n` ticks, then succeeds (and starts over after that or after a
    /// halt); `Running(0)` is `Success`. Actions only.
    Running(u32),
}

/// A custom control node or decorator (BehaviorTree.CPP's `ControlNode` and `DecoratorNode`
/// subclasses): a fresh instance per node, made by the factory given to
/// [`Registry::register_control`], which ticks and halts its children through a
/// [`ControlContext`]. A decorator is a control node with exactly one child (index 0).
///
/// As in BehaviorTree.CPP, the node is set running before [`ControlNode::tick`] is called
/// and its status becomes what `tick` returns; a node that completes should reset its children
/// ([`ControlContext::reset_children`]) so that they start afresh next time. Pre- and
/// post-condition attributes (`_skipIf`, `_onSuccess`, …) are handled by the runtime around
/// `tick`, as for every node.
pub trait ControlNode: Send {
    /// One tick: returns `Running`, `Success`, `Failure` or `Skipped` (not `Idle`).
    ///
    /// # Errors
    /// A child's [`TickError`] (pass it on with `?`), or the node's own
    /// ([`ControlContext::error`]).
    fn tick(&mut self, ctx: &mut ControlContext<'_>) -> Result<Status, TickError>;

    /// Called when the node is halted (BehaviorTree.CPP's `halt()`). The default resets every
    /// child ([`ControlContext::reset_children`]: running children are halted), as
    /// `ControlNode::halt` does; the runtime resets the children again afterwards in case an
    /// implementation forgets.
    fn halt(&mut self, ctx: &mut ControlContext<'_>) {
        ctx.reset_children();
    }
}

/// What a [`ControlNode`] sees: its identity, previous status, the time, its ports, and its
/// children, which it can tick and halt.
pub struct ControlContext<'a> {
    pub(crate) tree: &'a mut Tree,
    pub(crate) index: usize,
    pub(crate) previous: Status,
}

impl ControlContext<'_> {
    /// The node's uid.
    pub fn uid(&self) -> u16 {
        self.tree.nodes()[self.index].uid()
    }

    /// The instance name.
    pub fn name(&self) -> &str {
        self.tree.nodes()[self.index].name()
    }

    /// The status before this tick (`Idle` when starting, `Running` when continuing); during
    /// [`ControlNode::halt`], the status being halted.
    pub fn status(&self) -> Status {
        self.previous
    }

    /// The time of the tick.
    pub fn now(&self) -> Duration {
        self.tree.now()
    }

    /// The number of children.
    pub fn child_count(&self) -> usize {
        self.tree.nodes()[self.index].children().len()
    }

    /// The status of child `k` (`Idle` for a `k` out of range).
    pub fn child_status(&self, k: usize) -> Status {
        self.child(k)
            .map_or(Status::Idle, |c| self.tree.nodes()[c].status())
    }

    fn child(&self, k: usize) -> Option<usize> {
        self.tree.nodes()[self.index].children().get(k).copied()
    }

    /// Ticks child `k` (its pre- and post-conditions included) and returns its status.
    ///
    /// # Errors
    /// The child's [`TickError`]; an error of this node if there is no child `k`.
    pub fn tick_child(&mut self, k: usize) -> Result<Status, TickError> {
        let child = self.child(k).ok_or_else(|| {
            self.error(format!(
                "has no child {k} (it has {} children)",
                self.child_count()
            ))
        })?;
        self.tree.execute_tick(child)
    }

    /// Resets child `k`: halts it if it is running, then sets it idle (BehaviorTree.CPP's
    /// `haltChild`). Nothing happens for a `k` out of range.
    pub fn halt_child(&mut self, k: usize) {
        if let Some(child) = self.child(k)
            && let Err(error) = self.tree.halt_child(child)
        {
            self.tree.halt_error.get_or_insert(error);
        }
    }

    /// Resets every child (BehaviorTree.CPP's `resetChildren`). An `_onHalted` script that
    /// fails ends the tick with its error when this node's tick returns.
    pub fn reset_children(&mut self) {
        if let Err(error) = self.tree.reset_children(self.index) {
            self.tree.halt_error.get_or_insert(error);
        }
    }

    /// Reads an input port as `T` (a literal is parsed, a `{key}` read from the blackboard).
    ///
    /// # Errors
    /// A [`TickError`] of this node naming the port.
    pub fn input<T: FromValue>(&self, port: &str) -> Result<T, TickError> {
        self.tree.port(self.index, port)
    }

    /// Writes an output port (its attribute must be a `{key}`).
    ///
    /// # Errors
    /// A [`TickError`] of this node naming the port.
    pub fn set_output(&mut self, port: &str, value: impl Into<Value>) -> Result<(), TickError> {
        self.tree.set_port(self.index, port, value.into())
    }

    /// The blackboard.
    pub fn blackboard(&self) -> &Blackboard {
        self.tree.blackboard()
    }

    /// The blackboard, writable.
    pub fn blackboard_mut(&mut self) -> &mut Blackboard {
        self.tree.blackboard_mut()
    }

    /// The blackboard scope of this node.
    pub fn scope(&self) -> ScopeId {
        self.tree.nodes()[self.index].scope()
    }

    /// An error of this node with a message, to return from [`ControlNode::tick`].
    pub fn error(&self, message: impl Into<String>) -> TickError {
        self.tree
            .node_error(self.index, TickErrorKind::Node(message.into()))
    }
}

/// Where the category and ports of an ID come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ManifestSource {
    /// A node chronomap implements (controls, decorators, `SubTree`, built-in leaves).
    Builtin,
    /// A leaf registered in the [`Registry`].
    Registered,
    /// A `<TreeNodesModel>` entry of the document (known, but not necessarily implemented).
    Declared,
}

/// What validation knows about an ID: its category, and its ports if they are to be checked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Manifest {
    /// The category.
    pub category: NodeCategory,
    /// The ports; `None` when any attribute is accepted as a port (subtree remappings, leaves
    /// registered without a port list).
    pub ports: Option<Vec<PortSpec>>,
    /// Where this comes from.
    pub source: ManifestSource,
}

/// Node implementations by ID. [`Registry::new`] holds the built-in leaves `AlwaysSuccess`,
/// `AlwaysFailure`, `SetBlackboard` and `Sleep`; the built-in controls, decorators, scripting
/// nodes and `SubTree` are part of the runtime and are always known. Users add leaves, custom
/// controls and decorators, stubs, and enum values for scripts.
pub struct Registry {
    leaves: BTreeMap<String, Entry>,
    enums: BTreeMap<String, i64>,
}

impl Default for Registry {
    fn default() -> Registry {
        Registry::new()
    }
}

impl std::fmt::Debug for Registry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Registry")
            .field("nodes", &self.leaves.keys().collect::<Vec<_>>())
            .field("enums", &self.enums)
            .finish()
    }
}

impl Registry {
    /// A registry of the built-in leaves.
    pub fn new() -> Registry {
        let mut registry = Registry {
            leaves: BTreeMap::new(),
            enums: BTreeMap::new(),
        };
        for id in BUILTIN_LEAVES {
            let model = builtin_model(id).expect("built-in leaves have models");
            let factory: Factory = match id {
                "AlwaysSuccess" => Arc::new(|| Box::new(Constant(Status::Success))),
                "AlwaysFailure" => Arc::new(|| Box::new(Constant(Status::Failure))),
                "SetBlackboard" => Arc::new(|| Box::new(SetBlackboard)),
                "Sleep" => Arc::new(|| Box::new(Sleep { until: None })),
                _ => unreachable!("every built-in leaf has a factory"),
            };
            registry.leaves.insert(
                id.to_owned(),
                Entry {
                    model,
                    check_ports: true,
                    implementation: Implementation::Leaf(factory),
                },
            );
        }
        registry
    }

    fn insert(
        &mut self,
        model: NodeModel,
        check_ports: bool,
        factory: Factory,
    ) -> Result<(), RegistryError> {
        self.insert_implementation(model, check_ports, Implementation::Leaf(factory))
    }

    fn insert_implementation(
        &mut self,
        model: NodeModel,
        check_ports: bool,
        implementation: Implementation,
    ) -> Result<(), RegistryError> {
        if model.id.is_empty() {
            return Err(RegistryError::EmptyId);
        }
        let fits = match &implementation {
            Implementation::Leaf(_) => model.category.is_leaf(),
            Implementation::Control(_) | Implementation::Builtin(_) => matches!(
                model.category,
                NodeCategory::Control | NodeCategory::Decorator
            ),
        };
        if !fits {
            return Err(RegistryError::NotALeaf {
                id: model.id,
                category: model.category,
            });
        }
        if is_builtin(&model.id) {
            return Err(RegistryError::Builtin { id: model.id });
        }
        if self.leaves.contains_key(&model.id) {
            return Err(RegistryError::AlreadyRegistered { id: model.id });
        }
        self.leaves.insert(
            model.id.clone(),
            Entry {
                model,
                check_ports,
                implementation,
            },
        );
        Ok(())
    }

    /// Registers a custom control node (category [`NodeCategory::Control`]) or decorator
    /// ([`NodeCategory::Decorator`]) with its model; `factory` makes one instance per node.
    /// Attributes that are not among the model's ports are rejected when a tree is validated.
    /// See [`ControlNode`] and the example in the [module documentation](self).
    ///
    /// # Errors
    /// [`RegistryError`] for a duplicate, built-in or empty ID, or another category.
    pub fn register_control<F>(&mut self, model: NodeModel, factory: F) -> Result<(), RegistryError>
    where
        F: Fn() -> Box<dyn ControlNode> + Send + Sync + 'static,
    {
        self.insert_implementation(model, true, Implementation::Control(Arc::new(factory)))
    }

    /// Registers a stand-in for a node that is declared but not implemented (the ports of
    /// `model` are accepted and not used): an action or condition returns what `policy` says
    /// ([`StubPolicy`]); a control node behaves as a `Sequence` (its children are ticked in
    /// order, with memory of the running one) and a decorator passes its child's status
    /// through, whatever `policy` is.
    ///
    /// # Errors
    /// [`RegistryError`] for a duplicate, built-in or empty ID, a `SubTree` model, or a
    /// condition with [`StubPolicy::Running`] (conditions cannot return running).
    pub fn register_stub(
        &mut self,
        model: NodeModel,
        policy: StubPolicy,
    ) -> Result<(), RegistryError> {
        match model.category {
            NodeCategory::Control => self.insert_implementation(
                model,
                true,
                Implementation::Builtin(BuiltinKind::Sequence),
            ),
            NodeCategory::Decorator => self.insert_implementation(
                model,
                true,
                Implementation::Builtin(BuiltinKind::PassThrough),
            ),
            NodeCategory::Condition if matches!(policy, StubPolicy::Running(n) if n > 0) => {
                Err(RegistryError::RunningCondition { id: model.id })
            }
            NodeCategory::SubTree => Err(RegistryError::NotALeaf {
                id: model.id,
                category: model.category,
            }),
            _ => self.insert(
                model,
                true,
                Arc::new(move || {
                    Box::new(Stub {
                        policy,
                        remaining: 0,
                    })
                }),
            ),
        }
    }

    /// Registers an enum value for scripts (BehaviorTree.CPP's `registerScriptingEnum`): the
    /// name reads as the integer in every script, before blackboard keys, and compares equal
    /// to it in `Switch` cases. Registering a name again replaces its value.
    pub fn register_enum(&mut self, name: &str, value: i64) {
        self.enums.insert(name.to_owned(), value);
    }

    /// The registered enum values, by name.
    pub fn enums(&self) -> &BTreeMap<String, i64> {
        &self.enums
    }

    /// Registers a leaf with a model (category action or condition, ID, ports). Attributes
    /// that are not among the model's ports are rejected when a tree is validated, and port
    /// defaults apply. `factory` makes one instance per node.
    ///
    /// # Errors
    /// [`RegistryError`] for a duplicate, built-in or empty ID or a non-leaf category.
    pub fn register<F>(&mut self, model: NodeModel, factory: F) -> Result<(), RegistryError>
    where
        F: Fn() -> Box<dyn LeafNode> + Send + Sync + 'static,
    {
        self.insert(model, true, Arc::new(factory))
    }

    /// Registers a leaf without a port list: any attribute is accepted as a port.
    ///
    /// # Errors
    /// As [`Registry::register`].
    pub fn register_unchecked<F>(
        &mut self,
        category: NodeCategory,
        id: &str,
        factory: F,
    ) -> Result<(), RegistryError>
    where
        F: Fn() -> Box<dyn LeafNode> + Send + Sync + 'static,
    {
        self.insert(NodeModel::new(category, id), false, Arc::new(factory))
    }

    /// Registers a stateless action (any attributes accepted as ports).
    ///
    /// # Errors
    /// As [`Registry::register`].
    pub fn register_action_fn<F>(&mut self, id: &str, tick: F) -> Result<(), RegistryError>
    where
        F: Fn(&mut LeafContext<'_>) -> Result<Status, LeafError> + Send + Sync + 'static,
    {
        self.register_fn(NodeCategory::Action, id, tick)
    }

    /// Registers a stateless condition (any attributes accepted as ports).
    ///
    /// # Errors
    /// As [`Registry::register`].
    pub fn register_condition_fn<F>(&mut self, id: &str, tick: F) -> Result<(), RegistryError>
    where
        F: Fn(&mut LeafContext<'_>) -> Result<Status, LeafError> + Send + Sync + 'static,
    {
        self.register_fn(NodeCategory::Condition, id, tick)
    }

    fn register_fn<F>(
        &mut self,
        category: NodeCategory,
        id: &str,
        tick: F,
    ) -> Result<(), RegistryError>
    where
        F: Fn(&mut LeafContext<'_>) -> Result<Status, LeafError> + Send + Sync + 'static,
    {
        let tick: Arc<TickFn> = Arc::new(tick);
        self.register_unchecked(category, id, move || {
            Box::new(FnLeaf {
                tick: Arc::clone(&tick),
            })
        })
    }

    /// Whether a node `id` is registered (built-in leaves included).
    pub fn contains(&self, id: &str) -> bool {
        self.leaves.contains_key(id)
    }

    /// The model of the registered node `id`.
    pub fn model(&self, id: &str) -> Option<&NodeModel> {
        self.leaves.get(id).map(|e| &e.model)
    }

    /// The IDs of the registered nodes (built-in leaves included), sorted.
    pub fn ids(&self) -> impl Iterator<Item = &str> {
        self.leaves.keys().map(String::as_str)
    }

    /// What is known about `id`: a built-in control, decorator or `SubTree`; a registered leaf;
    /// or a model in `declared` (a document's `<TreeNodesModel>`), in that order.
    ///
    /// # Errors
    /// [`DefinitionErrorKind::EmptyId`], [`DefinitionErrorKind::UnsupportedNode`] for
    /// BehaviorTree.CPP built-ins chronomap does not implement, and
    /// [`DefinitionErrorKind::UnknownNode`] otherwise.
    pub fn lookup(
        &self,
        id: &str,
        declared: &[NodeModel],
    ) -> Result<Manifest, DefinitionErrorKind> {
        if id.is_empty() {
            return Err(DefinitionErrorKind::EmptyId);
        }
        if let Some(kind) = BuiltinKind::of(id) {
            let ports = match kind {
                BuiltinKind::SubTree => None,
                _ => Some(builtin_model(id).expect("built-ins have models").ports),
            };
            return Ok(Manifest {
                category: kind.category(),
                ports,
                source: ManifestSource::Builtin,
            });
        }
        if let Some(entry) = self.leaves.get(id) {
            return Ok(Manifest {
                category: entry.model.category,
                ports: entry.check_ports.then(|| entry.model.ports.clone()),
                source: if BUILTIN_LEAVES.contains(&id) {
                    ManifestSource::Builtin
                } else {
                    ManifestSource::Registered
                },
            });
        }
        if let Some(model) = declared.iter().find(|m| m.id == id) {
            return Ok(Manifest {
                category: model.category,
                ports: (model.category != NodeCategory::SubTree).then(|| model.ports.clone()),
                source: ManifestSource::Declared,
            });
        }
        if UNSUPPORTED_BUILTINS.contains(&id) {
            return Err(DefinitionErrorKind::UnsupportedNode { id: id.to_owned() });
        }
        Err(DefinitionErrorKind::UnknownNode { id: id.to_owned() })
    }

    /// A new instance of the node `id`, if registered.
    pub(crate) fn instantiate(&self, id: &str) -> Option<Instance> {
        self.leaves.get(id).map(|e| match &e.implementation {
            Implementation::Leaf(factory) => Instance::Leaf(factory()),
            Implementation::Control(factory) => Instance::Control(factory()),
            Implementation::Builtin(kind) => Instance::Builtin(*kind),
        })
    }
}

type TickFn = dyn Fn(&mut LeafContext<'_>) -> Result<Status, LeafError> + Send + Sync;

struct FnLeaf {
    tick: Arc<TickFn>,
}

impl LeafNode for FnLeaf {
    fn tick(&mut self, ctx: &mut LeafContext<'_>) -> Result<Status, LeafError> {
        (self.tick)(ctx)
    }
}

/// A leaf of [`Registry::register_stub`].
struct Stub {
    policy: StubPolicy,
    remaining: u32,
}

impl LeafNode for Stub {
    fn tick(&mut self, ctx: &mut LeafContext<'_>) -> Result<Status, LeafError> {
        Ok(match self.policy {
            StubPolicy::Success => Status::Success,
            StubPolicy::Failure => Status::Failure,
            StubPolicy::Running(n) => {
                if ctx.status() != Status::Running {
                    self.remaining = n;
                }
                if self.remaining == 0 {
                    Status::Success
                } else {
                    self.remaining -= 1;
                    Status::Running
                }
            }
        })
    }

    fn halt(&mut self, _: &mut LeafContext<'_>) {
        self.remaining = 0;
    }
}

/// `AlwaysSuccess`, `AlwaysFailure`.
struct Constant(Status);

impl LeafNode for Constant {
    fn tick(&mut self, _: &mut LeafContext<'_>) -> Result<Status, LeafError> {
        Ok(self.0)
    }
}

/// BehaviorTree.CPP's `SetBlackboard`: writes `value` (a literal, or a copy of the entry a
/// `{key}` names) to the entry named by `output_key` (a plain key such as `"result"` or
/// `"@result"`; a `{key}` there is read and its text used as the name), then succeeds.
struct SetBlackboard;

impl LeafNode for SetBlackboard {
    fn tick(&mut self, ctx: &mut LeafContext<'_>) -> Result<Status, LeafError> {
        let key: String = ctx.input("output_key")?;
        let raw = ctx
            .port_attribute("value")
            .ok_or_else(|| PortError::Missing {
                port: "value".to_owned(),
            })?
            .to_owned();
        let mut copies_scripted = false;
        let value = match blackboard_pointer(&raw) {
            Some(source) => {
                copies_scripted = ctx.blackboard.is_scripted_in(ctx.scope, source)
                    && ctx.blackboard.sequence_id_in(ctx.scope, &key).is_none();
                ctx.blackboard
                    .get_in(ctx.scope, source)
                    .cloned()
                    .ok_or_else(|| PortError::MissingEntry {
                        port: "value".to_owned(),
                        key: source.to_owned(),
                    })?
            }
            None => match ctx.blackboard.write_text_to_scripted_in(ctx.scope, &key) {
                ScriptedWrite::NotScripted => Value::Str(raw),
                ScriptedWrite::Emptied => return Ok(Status::Success),
                ScriptedWrite::Refused => {
                    return Err(LeafError::new(format!(
                        "Can't convert string [{raw}] to type [BT::Any] (the entry [{key}] \
                         was made by a script, and has no port type to convert to)"
                    )));
                }
            },
        };
        ctx.blackboard
            .set_in(ctx.scope, &key, value)
            .map_err(|error| PortError::Blackboard {
                port: "output_key".to_owned(),
                error,
            })?;
        if copies_scripted {
            ctx.blackboard.mark_any_typed_in(ctx.scope, &key);
        }
        Ok(Status::Success)
    }
}

/// BehaviorTree.CPP's `SleepNode`: succeeds at once for `msec` = 0, otherwise returns running
/// until a tick at or after start + `msec` (BehaviorTree.CPP's timer fires in between; here the
/// injected clock decides at the next tick).
struct Sleep {
    until: Option<Duration>,
}

impl LeafNode for Sleep {
    fn tick(&mut self, ctx: &mut LeafContext<'_>) -> Result<Status, LeafError> {
        let msec: u64 = ctx.input("msec")?;
        if ctx.status() == Status::Idle || self.until.is_none() {
            if msec == 0 {
                return Ok(Status::Success);
            }
            self.until = Some(ctx.now().saturating_add(Duration::from_millis(msec)));
            return Ok(Status::Running);
        }
        if self.until.is_some_and(|until| ctx.now() >= until) {
            self.until = None;
            Ok(Status::Success)
        } else {
            Ok(Status::Running)
        }
    }

    fn halt(&mut self, _: &mut LeafContext<'_>) {
        self.until = None;
    }
}
