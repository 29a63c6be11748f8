//! Leaf implementations registered by ID (BehaviorTree.CPP's `BehaviorTreeFactory`), the
//! [`LeafNode`] trait, and what a leaf sees when it is ticked ([`LeafContext`]).
//!
//! A leaf is a trait object made fresh for every node instance by a factory closure, so it can
//! keep state across ticks (an action that returns running, then success). Its
//! [`LeafNode::tick`] sees in [`LeafContext::status`] whether it is starting (`Idle`, like
//! BehaviorTree.CPP's `StatefulActionNode::onStart`) or continuing (`Running`, `onRunning`);
//! [`LeafNode::halt`] is called when a running leaf is halted (`onHalted`). Stateless leaves
//! are plain closures ([`Registry::register_action_fn`], [`Registry::register_condition_fn`]).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use thiserror::Error;

use super::Status;
use super::blackboard::{Blackboard, FromValue, ScopeId, Value};
use super::builtin::{
    BUILTIN_LEAVES, BuiltinKind, UNSUPPORTED_BUILTINS, builtin_model, is_builtin,
};
use super::error::{DefinitionErrorKind, PortError};
use super::model::{NodeCategory, NodeModel, PortSpec, blackboard_pointer};

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
    pub(crate) ports: &'a [(String, String)],
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

pub(crate) fn port_attribute<'p>(ports: &'p [(String, String)], port: &str) -> Option<&'p str> {
    ports
        .iter()
        .find(|(n, _)| n == port)
        .map(|(_, v)| v.as_str())
}

/// BehaviorTree.CPP's `TreeNode::getInput`: a `{key}` reads the blackboard (strings there are
/// parsed), a literal is parsed with `convertFromString`.
pub(crate) fn read_port<T: FromValue>(
    ports: &[(String, String)],
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
    ports: &[(String, String)],
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
    /// Only actions and conditions can be registered.
    #[error("\"{id}\" is a {category}; only actions and conditions can be registered")]
    NotALeaf {
        /// The ID.
        id: String,
        /// The category given.
        category: NodeCategory,
    },
    /// An empty ID.
    #[error("an empty ID cannot be registered")]
    EmptyId,
}

type Factory = Arc<dyn Fn() -> Box<dyn LeafNode> + Send + Sync>;

struct Entry {
    model: NodeModel,
    check_ports: bool,
    factory: Factory,
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

/// Leaf implementations by ID. [`Registry::new`] holds the built-in leaves `AlwaysSuccess`,
/// `AlwaysFailure`, `SetBlackboard` and `Sleep`; controls, decorators and `SubTree` are part of
/// the runtime and are always known.
pub struct Registry {
    leaves: BTreeMap<String, Entry>,
}

impl Default for Registry {
    fn default() -> Registry {
        Registry::new()
    }
}

impl std::fmt::Debug for Registry {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Registry")
            .field("leaves", &self.leaves.keys().collect::<Vec<_>>())
            .finish()
    }
}

impl Registry {
    /// A registry of the built-in leaves.
    pub fn new() -> Registry {
        let mut registry = Registry {
            leaves: BTreeMap::new(),
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
                    factory,
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
        if model.id.is_empty() {
            return Err(RegistryError::EmptyId);
        }
        if !model.category.is_leaf() {
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
                factory,
            },
        );
        Ok(())
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

    /// Whether a leaf `id` is registered (built-in leaves included).
    pub fn contains(&self, id: &str) -> bool {
        self.leaves.contains_key(id)
    }

    /// The model of the registered leaf `id`.
    pub fn model(&self, id: &str) -> Option<&NodeModel> {
        self.leaves.get(id).map(|e| &e.model)
    }

    /// The IDs of the registered leaves (built-in leaves included), sorted.
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

    /// A new instance of the leaf `id`, if registered.
    pub(crate) fn instantiate(&self, id: &str) -> Option<Box<dyn LeafNode>> {
        self.leaves.get(id).map(|e| (e.factory)())
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
        let value = match blackboard_pointer(&raw) {
            Some(source) => ctx
                .blackboard
                .get_in(ctx.scope, source)
                .cloned()
                .ok_or_else(|| PortError::MissingEntry {
                    port: "value".to_owned(),
                    key: source.to_owned(),
                })?,
            None => Value::Str(raw),
        };
        ctx.blackboard
            .set_in(ctx.scope, &key, value)
            .map_err(|error| PortError::Blackboard {
                port: "output_key".to_owned(),
                error,
            })?;
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
