//! The description of behavior trees, independent of running them: documents of trees, nodes
//! with a category, an ID, an instance name, port attributes and children, and the node models
//! (port manifests) of BehaviorTree.CPP's `<TreeNodesModel>`.
//!
//! This is what `chronomap-io` reads from and writes to BehaviorTree.CPP 4 XML, and what
//! analyses of trees (stochastic behavior trees of [Stüde 2024] §5.2.2, person search of §5.4) walk.
//! Attribute values are kept as written (`"3"`, `"{goal}"`, `"{=}"`); they are interpreted
//! when a [`Tree`](super::Tree) is instantiated and ticked.

use std::collections::HashMap;
use std::fmt;

use serde::{Deserialize, Serialize};

/// The five kinds of nodes of BehaviorTree.CPP (its `NodeType`, without `Undefined`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum NodeCategory {
    /// A leaf that acts; may return running.
    Action,
    /// A leaf that checks; returns success or failure only ([Stüde 2024] §5.2.1).
    Condition,
    /// A node with one or more children and a rule to tick them (sequence, fallback, parallel).
    Control,
    /// A node with exactly one child whose result it modifies.
    Decorator,
    /// A reference to another tree of the document, with its own blackboard scope.
    SubTree,
}

impl NodeCategory {
    /// The XML tag of the explicit form and of `<TreeNodesModel>` entries (`Action`, …).
    pub fn tag(self) -> &'static str {
        match self {
            NodeCategory::Action => "Action",
            NodeCategory::Condition => "Condition",
            NodeCategory::Control => "Control",
            NodeCategory::Decorator => "Decorator",
            NodeCategory::SubTree => "SubTree",
        }
    }

    /// The category of an explicit-form tag; `None` for other tags.
    pub fn from_tag(tag: &str) -> Option<NodeCategory> {
        match tag {
            "Action" => Some(NodeCategory::Action),
            "Condition" => Some(NodeCategory::Condition),
            "Control" => Some(NodeCategory::Control),
            "Decorator" => Some(NodeCategory::Decorator),
            "SubTree" => Some(NodeCategory::SubTree),
            _ => None,
        }
    }

    /// Actions and conditions.
    pub fn is_leaf(self) -> bool {
        matches!(self, NodeCategory::Action | NodeCategory::Condition)
    }

    /// How many children a node of this category has, as text (`"no children"`).
    pub fn children_rule(self) -> &'static str {
        match self {
            NodeCategory::Action | NodeCategory::Condition | NodeCategory::SubTree => "no children",
            NodeCategory::Control => "at least 1 child",
            NodeCategory::Decorator => "exactly 1 child",
        }
    }

    /// Whether `count` children fit the category.
    pub fn allows_children(self, count: usize) -> bool {
        match self {
            NodeCategory::Action | NodeCategory::Condition | NodeCategory::SubTree => count == 0,
            NodeCategory::Control => count >= 1,
            NodeCategory::Decorator => count == 1,
        }
    }
}

display_by_name!(NodeCategory, tag);

/// Which way a port passes values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum PortDirection {
    /// Read by the node.
    Input,
    /// Written by the node (its attribute must be a `{key}` reference).
    Output,
    /// Both.
    InOut,
}

impl PortDirection {
    /// The element name in `<TreeNodesModel>` (`input_port`, `output_port`, `inout_port`).
    pub fn tag(self) -> &'static str {
        match self {
            PortDirection::Input => "input_port",
            PortDirection::Output => "output_port",
            PortDirection::InOut => "inout_port",
        }
    }

    /// The direction of a `<TreeNodesModel>` element name.
    pub fn from_tag(tag: &str) -> Option<PortDirection> {
        match tag {
            "input_port" => Some(PortDirection::Input),
            "output_port" => Some(PortDirection::Output),
            "inout_port" => Some(PortDirection::InOut),
            _ => None,
        }
    }
}

/// The value type of a port as far as literal values can be checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PortType {
    /// `bool`: `true`/`false`/`1`/`0` (also `True`, `TRUE`, …).
    Bool,
    /// A signed integer (`int`, `long`, `int64_t`, …).
    Int,
    /// An unsigned integer (`unsigned int`, `uint32_t`, `size_t`, …).
    UInt,
    /// A floating-point number (`double`, `float`).
    Double,
    /// A string (`std::string`).
    String,
    /// Anything else, or no type given: not checked.
    Any,
}

impl PortType {
    /// The port type of a C++ type name as BehaviorTree.CPP writes it in `<TreeNodesModel>`.
    pub fn from_type_name(name: &str) -> PortType {
        match name.trim() {
            "bool" => PortType::Bool,
            "int" | "long" | "long long" | "short" | "int8_t" | "int16_t" | "int32_t"
            | "int64_t" | "signed char" => PortType::Int,
            "unsigned" | "unsigned int" | "unsigned long" | "unsigned long long"
            | "unsigned short" | "uint8_t" | "uint16_t" | "uint32_t" | "uint64_t" | "size_t"
            | "unsigned char" => PortType::UInt,
            "double" | "float" => PortType::Double,
            "std::string" | "string" => PortType::String,
            _ => PortType::Any,
        }
    }

    /// What a literal of this type looks like, for error messages.
    pub fn expected(self) -> &'static str {
        match self {
            PortType::Bool => "true, false, 1 or 0",
            PortType::Int => "an integer",
            PortType::UInt => "a non-negative integer",
            PortType::Double => "a number",
            PortType::String | PortType::Any => "any text",
        }
    }

    /// Checks a literal (not a `{key}` reference) against the type, with BehaviorTree.CPP's
    /// `convertFromString` rules.
    pub fn check_literal(self, text: &str) -> bool {
        match self {
            PortType::Bool => super::blackboard::parse_bool(text).is_some(),
            PortType::Int => text.parse::<i64>().is_ok(),
            PortType::UInt => text.parse::<u64>().is_ok(),
            PortType::Double => text.parse::<f64>().is_ok(),
            PortType::String | PortType::Any => true,
        }
    }
}

/// One port of a node model (`<input_port name="goal" type="Pose2D" default="…">doc</…>`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct PortSpec {
    /// The port (and attribute) name.
    pub name: String,
    /// Input, output or both.
    pub direction: PortDirection,
    /// The C++ type name as written in the model (`"int"`, `"std::string"`), if any.
    pub type_name: Option<String>,
    /// The value used when the attribute is absent (a literal or a `{key}`), if any.
    pub default: Option<String>,
    /// The documentation text, if any.
    pub description: Option<String>,
    /// Whether the attribute must be given (for the built-in nodes whose BehaviorTree.CPP
    /// implementation throws without it; models read from XML never require).
    pub required: bool,
}

impl PortSpec {
    fn new(name: &str, direction: PortDirection) -> PortSpec {
        PortSpec {
            name: name.to_owned(),
            direction,
            type_name: None,
            default: None,
            description: None,
            required: false,
        }
    }

    /// An input port without type, default or documentation.
    pub fn input(name: &str) -> PortSpec {
        PortSpec::new(name, PortDirection::Input)
    }

    /// An output port.
    pub fn output(name: &str) -> PortSpec {
        PortSpec::new(name, PortDirection::Output)
    }

    /// An input/output port.
    pub fn inout(name: &str) -> PortSpec {
        PortSpec::new(name, PortDirection::InOut)
    }

    /// With a C++ type name (`"int"`, `"double"`, `"bool"`, `"std::string"`, …).
    pub fn typed(mut self, type_name: &str) -> PortSpec {
        self.type_name = Some(type_name.to_owned());
        self
    }

    /// With a default value.
    pub fn with_default(mut self, default: &str) -> PortSpec {
        self.default = Some(default.to_owned());
        self
    }

    /// With documentation.
    pub fn described(mut self, description: &str) -> PortSpec {
        self.description = Some(description.to_owned());
        self
    }

    /// Marked as required.
    pub fn required(mut self) -> PortSpec {
        self.required = true;
        self
    }

    /// The checkable type of the port.
    pub fn port_type(&self) -> PortType {
        self.type_name
            .as_deref()
            .map_or(PortType::Any, PortType::from_type_name)
    }
}

/// The model of a node type: an entry of `<TreeNodesModel>` (category, ID, ports).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeModel {
    /// Action, condition, control, decorator or subtree.
    pub category: NodeCategory,
    /// The registration ID (the tag of the compact XML form).
    pub id: String,
    /// The ports, in declaration order.
    pub ports: Vec<PortSpec>,
    /// The `<description>` text, if any.
    pub description: Option<String>,
}

impl NodeModel {
    /// A model without ports.
    pub fn new(category: NodeCategory, id: &str) -> NodeModel {
        NodeModel {
            category,
            id: id.to_owned(),
            ports: Vec::new(),
            description: None,
        }
    }

    /// With one more port.
    pub fn port(mut self, port: PortSpec) -> NodeModel {
        self.ports.push(port);
        self
    }

    /// The port called `name`, if declared.
    pub fn find_port(&self, name: &str) -> Option<&PortSpec> {
        self.ports.iter().find(|p| p.name == name)
    }
}

/// One node of a tree description.
///
/// The instance name defaults to the ID ([`NodeDef::instance_name`]), as in BehaviorTree.CPP.
/// `ports` keeps the port attributes in document order; for a `SubTree` they are the
/// remappings (`target="{goal}"` maps the subtree's key `target` to the parent's `goal`; a
/// literal sets the subtree's key to that text).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NodeDef {
    /// The kind of node.
    pub category: NodeCategory,
    /// The registration ID (`Sequence`, `OpenDoor`); for a `SubTree`, the ID of the tree used.
    pub id: String,
    /// The `name` attribute, if given.
    pub name: Option<String>,
    /// Port attributes (`name`, value as written), in document order.
    pub ports: Vec<(String, String)>,
    /// `_autoremap="true"` of a `SubTree`: keys not remapped explicitly are shared with the
    /// parent's blackboard under the same name.
    pub autoremap: bool,
    /// Pre- and post-condition scripts of BehaviorTree.CPP's scripting language (`_skipIf`,
    /// `_successIf`, `_failureIf`, `_while`, `_onSuccess`, `_onFailure`, `_onHalted`, `_post`):
    /// the attribute name and the script as written, in document order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub scripts: Vec<(String, String)>,
    /// The children, in tick order.
    pub children: Vec<NodeDef>,
}

impl NodeDef {
    /// A node without name, ports or children.
    pub fn new(category: NodeCategory, id: &str) -> NodeDef {
        NodeDef {
            category,
            id: id.to_owned(),
            name: None,
            ports: Vec::new(),
            autoremap: false,
            scripts: Vec::new(),
            children: Vec::new(),
        }
    }

    /// With a pre- or post-condition script (`_skipIf`, `_onSuccess`, …; see
    /// [`NodeDef::scripts`]).
    pub fn script(mut self, attribute: &str, code: &str) -> NodeDef {
        self.scripts.push((attribute.to_owned(), code.to_owned()));
        self
    }

    /// An action leaf.
    pub fn action(id: &str) -> NodeDef {
        NodeDef::new(NodeCategory::Action, id)
    }

    /// A condition leaf.
    pub fn condition(id: &str) -> NodeDef {
        NodeDef::new(NodeCategory::Condition, id)
    }

    /// A control node (add children with [`NodeDef::child`]).
    pub fn control(id: &str) -> NodeDef {
        NodeDef::new(NodeCategory::Control, id)
    }

    /// A decorator (add its child with [`NodeDef::child`]).
    pub fn decorator(id: &str) -> NodeDef {
        NodeDef::new(NodeCategory::Decorator, id)
    }

    /// A reference to the tree `tree_id`.
    pub fn subtree(tree_id: &str) -> NodeDef {
        NodeDef::new(NodeCategory::SubTree, tree_id)
    }

    /// With an instance name.
    pub fn named(mut self, name: &str) -> NodeDef {
        self.name = Some(name.to_owned());
        self
    }

    /// With one more port attribute.
    pub fn port(mut self, name: &str, value: &str) -> NodeDef {
        self.ports.push((name.to_owned(), value.to_owned()));
        self
    }

    /// With `_autoremap` set.
    pub fn autoremapped(mut self, on: bool) -> NodeDef {
        self.autoremap = on;
        self
    }

    /// With one more child.
    pub fn child(mut self, child: NodeDef) -> NodeDef {
        self.children.push(child);
        self
    }

    /// The `name` attribute, or the ID when there is none (BehaviorTree.CPP's default).
    pub fn instance_name(&self) -> &str {
        self.name.as_deref().unwrap_or(&self.id)
    }

    /// The value of the port attribute `name`, if given.
    pub fn port_value(&self, name: &str) -> Option<&str> {
        self.ports
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// Calls `visit` on this node and every descendant in depth-first pre-order, with the
    /// path of child indices from this node.
    pub fn walk<'a>(&'a self, visit: &mut dyn FnMut(&[usize], &'a NodeDef)) {
        // Without recursion, so that no depth of description overflows the stack: a stack of
        // the nodes whose children are being visited and the index of the next child.
        let mut path: Vec<usize> = Vec::new();
        let mut stack: Vec<(&'a NodeDef, usize)> = vec![(self, 0)];
        visit(&path, self);
        while let Some((node, next)) = stack.last_mut() {
            let Some(child) = node.children.get(*next) else {
                stack.pop();
                path.pop();
                continue;
            };
            path.push(*next);
            *next += 1;
            visit(&path, child);
            stack.push((child, 0));
        }
    }

    /// The descendant at a path of child indices (`[]` is this node).
    pub fn at(&self, path: &[usize]) -> Option<&NodeDef> {
        path.iter().try_fold(self, |node, &i| node.children.get(i))
    }
}

/// One `<BehaviorTree ID="…">`: an ID and its single root node.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TreeDef {
    /// The tree ID (what `SubTree ID` and `main_tree_to_execute` name).
    pub id: String,
    /// The root node.
    pub root: NodeDef,
}

impl TreeDef {
    /// A tree.
    pub fn new(id: &str, root: NodeDef) -> TreeDef {
        TreeDef {
            id: id.to_owned(),
            root,
        }
    }
}

/// A document of trees: the content of a BehaviorTree.CPP 4 XML file.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct BtDocument {
    /// `main_tree_to_execute`, if given.
    pub main_tree: Option<String>,
    /// The trees, in document order.
    pub trees: Vec<TreeDef>,
    /// The node models (`<TreeNodesModel>`), in document order.
    pub node_models: Vec<NodeModel>,
}

impl BtDocument {
    /// A document of one tree, which is the main tree.
    pub fn single(tree: TreeDef) -> BtDocument {
        BtDocument {
            main_tree: Some(tree.id.clone()),
            trees: vec![tree],
            node_models: Vec::new(),
        }
    }

    /// The tree with ID `id`.
    pub fn tree(&self, id: &str) -> Option<&TreeDef> {
        self.trees.iter().find(|t| t.id == id)
    }

    /// The node model with ID `id`.
    pub fn node_model(&self, id: &str) -> Option<&NodeModel> {
        self.node_models.iter().find(|m| m.id == id)
    }

    /// The trees by ID (the first of an ID, as with [`BtDocument::tree`]), for looking many up
    /// in constant time each.
    pub fn trees_by_id(&self) -> HashMap<&str, &TreeDef> {
        let mut map = HashMap::with_capacity(self.trees.len());
        for tree in &self.trees {
            map.entry(tree.id.as_str()).or_insert(tree);
        }
        map
    }

    /// The node models by ID (the first of an ID, as with [`BtDocument::node_model`]), for
    /// looking many up in constant time each.
    pub fn node_models_by_id(&self) -> HashMap<&str, &NodeModel> {
        let mut map = HashMap::with_capacity(self.node_models.len());
        for model in &self.node_models {
            map.entry(model.id.as_str()).or_insert(model);
        }
        map
    }
}

/// Where a node is in a document: the tree ID and the child indices from its root
/// (`[]` is the root, `[1, 0]` the first child of the root's second child).
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct NodeLocation {
    /// The tree ID.
    pub tree: String,
    /// Child indices from the root.
    pub path: Vec<usize>,
}

impl fmt::Display for NodeLocation {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "tree {:?}", self.tree)?;
        if self.path.is_empty() {
            write!(f, ", root node")
        } else {
            let path: Vec<String> = self.path.iter().map(usize::to_string).collect();
            write!(f, ", node at child path {}", path.join("/"))
        }
    }
}

/// The key of a blackboard reference `{key}` (surrounding spaces allowed, as in
/// BehaviorTree.CPP's `TreeNode::isBlackboardPointer`); `None` for a literal.
///
/// ```
/// use chronomap_bt::blackboard_pointer;
/// assert_eq!(blackboard_pointer("{goal}"), Some("goal"));
/// assert_eq!(blackboard_pointer(" {goal} "), Some("goal"));
/// assert_eq!(blackboard_pointer("goal"), None);
/// assert_eq!(blackboard_pointer("{}"), None);
/// ```
pub fn blackboard_pointer(text: &str) -> Option<&str> {
    let trimmed = text.trim_matches(' ');
    if trimmed.len() >= 3 && trimmed.starts_with('{') && trimmed.ends_with('}') {
        Some(&trimmed[1..trimmed.len() - 1])
    } else {
        None
    }
}
