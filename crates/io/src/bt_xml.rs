//! BehaviorTree.CPP 4 XML: reading tree files into [`BtDocument`]s and writing them back in
//! the canonical form Groot2 and BehaviorTree.CPP load.
//!
//! ```
//! use chronomap_bt::{NodeCategory, Registry};
//! use chronomap_io::bt_xml::{encode_bt_xml, parse_bt_xml};
//!
//! let text = r#"
//! <root BTCPP_format="4" main_tree_to_execute="Main">
//!   <BehaviorTree ID="Main">
//!     <Fallback>
//!       <Condition ID="IsDoorOpen"/>
//!       <RetryUntilSuccessful num_attempts="3">
//!         <Action ID="OpenDoor" speed="{door_speed}"/>
//!       </RetryUntilSuccessful>
//!     </Fallback>
//!   </BehaviorTree>
//! </root>"#;
//! let loaded = parse_bt_xml("door.xml", text, &Registry::new())?;
//! let root = &loaded.document.trees[0].root;
//! assert_eq!(root.id, "Fallback");
//! assert_eq!(root.children[1].children[0].category, NodeCategory::Action);
//!
//! // Saved in the canonical (compact) form, with a <TreeNodesModel> for OpenDoor and
//! // IsDoorOpen; loading that gives the same document.
//! let saved = encode_bt_xml(&loaded.document)?;
//! assert!(saved.contains(r#"<OpenDoor speed="{door_speed}"/>"#));
//! assert_eq!(parse_bt_xml("saved.xml", &saved, &Registry::new())?.document, loaded.document);
//!
//! // Errors name the file, line, column and attribute.
//! let bad = text.replace(r#"num_attempts="3""#, r#"num_attempts="three""#);
//! let err = parse_bt_xml("door.xml", &bad, &Registry::new()).unwrap_err();
//! assert_eq!(err.to_string(), "door.xml:6:29: attribute num_attempts=\"three\" of \
//!     \"RetryUntilSuccessful\" is invalid (expected an integer)");
//! assert_eq!(err.attribute(), Some("num_attempts"));
//! # Ok::<(), chronomap_io::bt_xml::BtXmlError>(())
//! ```
//!
//! # What is read
//! * `<root BTCPP_format="4" main_tree_to_execute="…">`: another format version is an error;
//!   a missing `BTCPP_format` is accepted with a warning, as BehaviorTree.CPP 4 does.
//! * `<BehaviorTree ID="…">` (several allowed), each with exactly one root node.
//! * Nodes in the explicit form (`<Action ID="OpenDoor"/>`, `<Condition ID>`, `<Control ID>`,
//!   `<Decorator ID>`) and the compact form (`<Sequence>`, `<OpenDoor/>`); `name`; ports as
//!   attributes; `<SubTree ID="…" port="{key}" _autoremap="true"/>`.
//! * `<TreeNodesModel>`: the category, ports (`input_port`, `output_port`, `inout_port` with
//!   `name`, `type`, `default` and text) and `<description>` of every node type; entries and
//!   elements that are not understood are skipped with a warning. A compact-form node must be
//!   built in, registered, or declared here (as Groot2 declares every custom node). An
//!   explicit-form leaf that is none of these gets a model inferred from its attributes, so
//!   that saved files (which are compact) load again.
//! * Attributes starting with `_` that BehaviorTree.CPP writes as metadata (`_uid`,
//!   `_fullpath`) are ignored; scripting attributes (`_skipIf`, `_successIf`, `_failureIf`,
//!   `_while`, `_onSuccess`, `_onFailure`, `_post`, `_onHalted`) and `<include>` are errors
//!   (not supported).
//!
//! After reading, the document is checked with [`chronomap_bt::validate`] (unknown IDs,
//! children per category, required and unknown ports, literal values, subtrees). Every error
//! is a [`BtXmlError`] with the line and column of the element or attribute concerned.
//!
//! # What is written
//! [`encode_bt_xml`] writes `<?xml …?>`, `<root BTCPP_format="4">`, each tree with nodes in
//! the compact form (the explicit form only for IDs that are not XML names), two-space
//! indentation, and the document's node models in `<TreeNodesModel>`. [`encode_tree_xml`]
//! writes a runtime tree the way BehaviorTree.CPP's `WriteTreeToXML(tree, true, true)` does
//! for Groot2 logs: one `<BehaviorTree>` per subtree instance with `_fullpath`, `_uid` on every
//! node, the ports as the nodes read them, and the models of the node types used.

use std::collections::{BTreeSet, HashMap};
use std::fmt::{self, Write as _};
use std::io;
use std::path::Path;

use chronomap_bt::{
    BtDocument, DefinitionError, DefinitionErrorKind, NodeCategory, NodeDef, NodeModel,
    PortDirection, PortSpec, Registry, Tree, TreeDef, is_builtin, validate,
};
use roxmltree::{Document, Node, ParsingOptions};
use thiserror::Error;

/// Pre- and post-condition attributes of BehaviorTree.CPP's scripting language.
const SCRIPT_ATTRIBUTES: [&str; 8] = [
    "_skipIf",
    "_successIf",
    "_failureIf",
    "_while",
    "_onSuccess",
    "_onFailure",
    "_post",
    "_onHalted",
];

/// A document read from XML, and what was accepted with a warning.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BtXml {
    /// The trees and node models.
    pub document: BtDocument,
    /// Things that were read leniently (each `file:line:column: text`).
    pub warnings: Vec<String>,
    /// The 1-based line and column of every node's element, by tree ID and child path (as
    /// [`NodeLocation`](chronomap_bt::NodeLocation) locates nodes), so that an analysis
    /// of the document can name the line of a node.
    pub node_positions: HashMap<(String, Vec<usize>), (u32, u32)>,
}

impl BtXml {
    /// The line and column of the node at `location`, if it was read from this file.
    pub fn position(&self, location: &chronomap_bt::NodeLocation) -> Option<(u32, u32)> {
        self.node_positions
            .get(&(location.tree.clone(), location.path.clone()))
            .copied()
    }
}

/// What is wrong with a BehaviorTree.CPP XML file (the part of a [`BtXmlError`] after
/// `file:line:column:`).
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum BtXmlErrorKind {
    /// The file could not be read or written.
    #[error("cannot {action}: {io}")]
    Io {
        /// What was being done.
        action: &'static str,
        /// The underlying error.
        io: io::Error,
    },
    /// Not well-formed XML.
    #[error("not well-formed XML: {message}")]
    Xml {
        /// The parser's message.
        message: String,
    },
    /// The root element is not `<root>`.
    #[error("the root element is <{found}>, not <root> (not a BehaviorTree.CPP file)")]
    NotBtXml {
        /// The element found.
        found: String,
    },
    /// `BTCPP_format` is not 4.
    #[error(
        "attribute BTCPP_format=\"{found}\": only BehaviorTree.CPP format 4 is supported \
         (BehaviorTree.CPP ships convert_v3_to_v4.py for version 3 files)"
    )]
    Format {
        /// The value found.
        found: String,
    },
    /// `<include>` is not supported.
    #[error("<include> is not supported: put all trees in one file")]
    Include,
    /// An element that has no meaning where it is.
    #[error("unexpected element <{element}> in <{parent}>")]
    UnknownElement {
        /// The element.
        element: String,
        /// Its parent.
        parent: String,
    },
    /// A required attribute is missing.
    #[error("<{element}> needs the attribute \"{attribute}\"")]
    MissingAttribute {
        /// The element.
        element: String,
        /// The attribute.
        attribute: &'static str,
    },
    /// A `<BehaviorTree>` without exactly one root node.
    #[error("<BehaviorTree ID=\"{id}\"> must contain exactly one node, found {found}")]
    TreeRoot {
        /// The tree ID.
        id: String,
        /// The number of elements found.
        found: usize,
    },
    /// Two trees with one ID.
    #[error("attribute ID=\"{id}\": another <BehaviorTree> has this ID already")]
    DuplicateTree {
        /// The ID.
        id: String,
    },
    /// An attribute with a value it cannot have.
    #[error("attribute {attribute}=\"{value}\" of <{element}> is invalid ({expected})")]
    BadAttribute {
        /// The element.
        element: String,
        /// The attribute.
        attribute: String,
        /// Its value.
        value: String,
        /// What it needs.
        expected: &'static str,
    },
    /// A scripting attribute.
    #[error(
        "attribute {attribute} of <{element}>: BehaviorTree.CPP scripting (pre- and \
         post-conditions) is not supported"
    )]
    Scripting {
        /// The element.
        element: String,
        /// The attribute.
        attribute: String,
    },
    /// A problem of the tree description (unknown ID, children, ports, subtrees).
    #[error("{0}")]
    Definition(DefinitionErrorKind),
    /// A document that cannot be written as XML.
    #[error("cannot write the tree as XML: {reason}")]
    Unwritable {
        /// Why.
        reason: String,
    },
}

/// Why a BehaviorTree.CPP XML file could not be read or written: the file, the 1-based line
/// and column, the attribute concerned (when there is one) and the problem.
///
/// Displays as `door.xml:14:9: "Repeat" needs the attribute "num_cycles"`; when the problem's
/// text does not name the attribute it is added: `door.xml:2:40: attribute
/// main_tree_to_execute: there is no <BehaviorTree ID="Mian">`.
#[derive(Debug, Error)]
pub struct BtXmlError {
    file: Option<String>,
    position: Option<(u32, u32)>,
    attribute: Option<String>,
    kind: Box<BtXmlErrorKind>,
}

impl fmt::Display for BtXmlError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (&self.file, self.position) {
            (Some(file), Some((line, column))) => write!(f, "{file}:{line}:{column}: ")?,
            (Some(file), None) => write!(f, "{file}: ")?,
            (None, Some((line, column))) => write!(f, "line {line}, column {column}: ")?,
            (None, None) => {}
        }
        let message = self.kind.to_string();
        match &self.attribute {
            Some(a) if !message.contains(a.as_str()) => write!(f, "attribute {a}: {message}"),
            _ => f.write_str(&message),
        }
    }
}

impl BtXmlError {
    fn new(position: Option<(u32, u32)>, kind: BtXmlErrorKind) -> BtXmlError {
        BtXmlError {
            file: None,
            position,
            attribute: None,
            kind: Box::new(kind),
        }
    }

    fn with_attribute(mut self, attribute: &str) -> BtXmlError {
        self.attribute = Some(attribute.to_owned());
        self
    }

    /// The file concerned, if any.
    pub fn file(&self) -> Option<&str> {
        self.file.as_deref()
    }

    /// The 1-based line, if known.
    pub fn line(&self) -> Option<u32> {
        self.position.map(|p| p.0)
    }

    /// The 1-based column, if known.
    pub fn column(&self) -> Option<u32> {
        self.position.map(|p| p.1)
    }

    /// The attribute concerned, if any (`num_attempts`, `ID`, `BTCPP_format`).
    pub fn attribute(&self) -> Option<&str> {
        self.attribute.as_deref()
    }

    /// What is wrong.
    pub fn kind(&self) -> &BtXmlErrorKind {
        &self.kind
    }
}

// ---------------------------------------------------------------------------------------------
// Reading

/// Reads a BehaviorTree.CPP 4 XML file; IDs are resolved with `registry` (built-in nodes and
/// registered leaves) and the file's `<TreeNodesModel>`.
///
/// # Errors
/// A [`BtXmlError`] naming the file, line, column and attribute (see [`parse_bt_xml`]).
pub fn read_bt_xml(path: impl AsRef<Path>, registry: &Registry) -> Result<BtXml, BtXmlError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let text = crate::bounded::read_to_string(path).map_err(|io| {
        let mut e = BtXmlError::new(None, BtXmlErrorKind::Io { action: "read", io });
        e.file = Some(name.clone());
        e
    })?;
    parse_bt_xml(&name, &text, registry)
}

/// Reads BehaviorTree.CPP 4 XML text; `name` is used in messages.
///
/// # Errors
/// A [`BtXmlError`] for XML that is not well-formed, a root element other than `<root>`, a
/// format other than 4, `<include>`, unexpected elements, missing `ID`s, trees without exactly
/// one root node, duplicate tree IDs, scripting attributes, and every
/// [`DefinitionErrorKind`] of [`validate`].
pub fn parse_bt_xml(name: &str, text: &str, registry: &Registry) -> Result<BtXml, BtXmlError> {
    parse(text, registry)
        .map_err(|mut e| {
            e.file = Some(name.to_owned());
            e
        })
        .map(|(document, warnings, node_positions)| BtXml {
            document,
            node_positions,
            warnings: warnings
                .into_iter()
                .map(|((line, column), text)| format!("{name}:{line}:{column}: {text}"))
                .collect(),
        })
}

type Pos = (u32, u32);

/// Where an element and its attributes are.
#[derive(Default)]
struct ElementPos {
    element: Pos,
    attributes: Vec<(String, Pos)>,
}

impl ElementPos {
    fn of(node: Node<'_, '_>) -> ElementPos {
        let doc = node.document();
        ElementPos {
            element: pos(doc, node.range().start),
            attributes: node
                .attributes()
                .map(|a| (a.name().to_owned(), pos(doc, a.range().start)))
                .collect(),
        }
    }

    fn attribute(&self, name: &str) -> Option<Pos> {
        self.attributes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, p)| *p)
    }

    /// The attribute's position if it is present, else the element's.
    fn best(&self, attribute: Option<&str>) -> Pos {
        attribute
            .and_then(|a| self.attribute(a))
            .unwrap_or(self.element)
    }
}

fn pos(doc: &Document<'_>, offset: usize) -> Pos {
    let p = doc.text_pos_at(offset);
    (p.row, p.col)
}

struct Reader<'a> {
    registry: &'a Registry,
    models: Vec<NodeModel>,
    nodes: HashMap<(String, Vec<usize>), ElementPos>,
    warnings: Vec<(Pos, String)>,
}

type Parsed = (
    BtDocument,
    Vec<(Pos, String)>,
    HashMap<(String, Vec<usize>), Pos>,
);

fn parse(text: &str, registry: &Registry) -> Result<Parsed, BtXmlError> {
    let options = ParsingOptions {
        allow_dtd: false,
        ..ParsingOptions::default()
    };
    let xml = Document::parse_with_options(text, options).map_err(|e| {
        let p = e.pos();
        let message = e.to_string();
        let message = message
            .strip_suffix(&format!(" at {}:{}", p.row, p.col))
            .unwrap_or(&message)
            .to_owned();
        BtXmlError::new(Some((p.row, p.col)), BtXmlErrorKind::Xml { message })
    })?;
    let root = xml.root_element();
    let root_pos = ElementPos::of(root);
    if root.tag_name().name() != "root" {
        return Err(BtXmlError::new(
            Some(root_pos.element),
            BtXmlErrorKind::NotBtXml {
                found: root.tag_name().name().to_owned(),
            },
        ));
    }
    let mut reader = Reader {
        registry,
        models: Vec::new(),
        nodes: HashMap::new(),
        warnings: Vec::new(),
    };
    match root.attribute("BTCPP_format") {
        Some(v) if v.trim() == "4" => {}
        Some(v) => {
            return Err(BtXmlError::new(
                Some(root_pos.best(Some("BTCPP_format"))),
                BtXmlErrorKind::Format {
                    found: v.to_owned(),
                },
            )
            .with_attribute("BTCPP_format"));
        }
        None => reader.warnings.push((
            root_pos.element,
            "<root> has no BTCPP_format attribute; read as format 4 (as BehaviorTree.CPP 4 \
             does)"
                .to_owned(),
        )),
    }
    let main_tree = root.attribute("main_tree_to_execute").map(str::to_owned);

    // Node models first, so that compact-form nodes resolve wherever they are declared.
    let mut tree_elements = Vec::new();
    for child in root.children().filter(Node::is_element) {
        match child.tag_name().name() {
            "BehaviorTree" => tree_elements.push(child),
            "TreeNodesModel" => reader.read_models(child),
            "include" => {
                return Err(BtXmlError::new(
                    Some(ElementPos::of(child).element),
                    BtXmlErrorKind::Include,
                ));
            }
            other => {
                return Err(BtXmlError::new(
                    Some(ElementPos::of(child).element),
                    BtXmlErrorKind::UnknownElement {
                        element: other.to_owned(),
                        parent: "root".to_owned(),
                    },
                ));
            }
        }
    }
    reader.infer_models(&tree_elements);

    let mut trees = Vec::new();
    let mut tree_positions: HashMap<String, ElementPos> = HashMap::new();
    for element in tree_elements {
        let p = ElementPos::of(element);
        let id = element.attribute("ID").ok_or_else(|| {
            BtXmlError::new(
                Some(p.element),
                BtXmlErrorKind::MissingAttribute {
                    element: "BehaviorTree".to_owned(),
                    attribute: "ID",
                },
            )
            .with_attribute("ID")
        })?;
        if tree_positions.contains_key(id) {
            return Err(BtXmlError::new(
                Some(p.best(Some("ID"))),
                BtXmlErrorKind::DuplicateTree { id: id.to_owned() },
            )
            .with_attribute("ID"));
        }
        let roots: Vec<Node<'_, '_>> = element.children().filter(Node::is_element).collect();
        let [root_element] = roots.as_slice() else {
            return Err(BtXmlError::new(
                Some(p.element),
                BtXmlErrorKind::TreeRoot {
                    id: id.to_owned(),
                    found: roots.len(),
                },
            ));
        };
        let root_node = reader.read_node(*root_element, id, &mut Vec::new())?;
        trees.push(TreeDef::new(id, root_node));
        tree_positions.insert(id.to_owned(), p);
    }

    let document = BtDocument {
        main_tree,
        trees,
        node_models: reader.models,
    };
    validate(&document, registry).map_err(|e| {
        let position = match e.location() {
            Some(location) => reader
                .nodes
                .get(&(location.tree.clone(), location.path.clone()))
                .map(|p| p.best(e.attribute())),
            None => match e.attribute() {
                Some("main_tree_to_execute") => Some(root_pos.best(e.attribute())),
                _ => Some(root_pos.element),
            },
        };
        located(position, e)
    })?;
    let positions = reader
        .nodes
        .into_iter()
        .map(|(key, p)| (key, p.element))
        .collect();
    Ok((document, reader.warnings, positions))
}

fn located(position: Option<Pos>, e: DefinitionError) -> BtXmlError {
    let mut error = BtXmlError::new(position, BtXmlErrorKind::Definition(e.kind().clone()));
    error.attribute = e.attribute().map(str::to_owned);
    error
}

impl Reader<'_> {
    /// `<TreeNodesModel>`: keeps what it understands, warns about the rest.
    fn read_models(&mut self, element: Node<'_, '_>) {
        for entry in element.children().filter(Node::is_element) {
            let p = ElementPos::of(entry);
            let tag = entry.tag_name().name();
            let Some(category) = NodeCategory::from_tag(tag) else {
                self.warnings.push((
                    p.element,
                    format!("<TreeNodesModel>: skipped the unknown entry <{tag}>"),
                ));
                continue;
            };
            let Some(id) = entry.attribute("ID") else {
                self.warnings.push((
                    p.element,
                    format!("<TreeNodesModel>: skipped <{tag}> without an ID"),
                ));
                continue;
            };
            if self.models.iter().any(|m| m.id == id) {
                self.warnings.push((
                    p.element,
                    format!("<TreeNodesModel>: skipped a second model of \"{id}\""),
                ));
                continue;
            }
            let mut model = NodeModel::new(category, id);
            for item in entry.children().filter(Node::is_element) {
                let item_tag = item.tag_name().name();
                if item_tag == "description" {
                    model.description = text_of(item);
                    continue;
                }
                let Some(direction) = PortDirection::from_tag(item_tag) else {
                    self.warnings.push((
                        ElementPos::of(item).element,
                        format!("<TreeNodesModel>: skipped <{item_tag}> in the model of \"{id}\""),
                    ));
                    continue;
                };
                let Some(port) = item.attribute("name") else {
                    self.warnings.push((
                        ElementPos::of(item).element,
                        format!("<TreeNodesModel>: skipped a port without a name in \"{id}\""),
                    ));
                    continue;
                };
                model.ports.push(PortSpec {
                    name: port.to_owned(),
                    direction,
                    type_name: item.attribute("type").map(str::to_owned),
                    default: item.attribute("default").map(str::to_owned),
                    description: text_of(item),
                    required: false,
                });
            }
            self.models.push(model);
        }
    }

    /// Models for explicit-form leaves that are neither built in, registered nor declared,
    /// with the attributes used as ports.
    fn infer_models(&mut self, trees: &[Node<'_, '_>]) {
        let mut inferred: Vec<NodeModel> = Vec::new();
        for tree in trees {
            for node in tree.descendants().filter(Node::is_element) {
                let category = match node.tag_name().name() {
                    "Action" => NodeCategory::Action,
                    "Condition" => NodeCategory::Condition,
                    _ => continue,
                };
                let Some(id) = node.attribute("ID") else {
                    continue;
                };
                if is_builtin(id)
                    || self.registry.contains(id)
                    || self.models.iter().any(|m| m.id == id)
                {
                    continue;
                }
                let index = match inferred.iter().position(|m| m.id == id) {
                    Some(i) => i,
                    None => {
                        inferred.push(NodeModel::new(category, id));
                        inferred.len() - 1
                    }
                };
                for attribute in node.attributes() {
                    let name = attribute.name();
                    if is_port_attribute(name) && inferred[index].find_port(name).is_none() {
                        inferred[index].ports.push(PortSpec::inout(name));
                    }
                }
            }
        }
        self.models.extend(inferred);
    }

    fn read_node(
        &mut self,
        element: Node<'_, '_>,
        tree: &str,
        path: &mut Vec<usize>,
    ) -> Result<NodeDef, BtXmlError> {
        let p = ElementPos::of(element);
        let tag = element.tag_name().name();
        let (category, id, explicit) = match NodeCategory::from_tag(tag) {
            Some(category) => {
                let id = element.attribute("ID").ok_or_else(|| {
                    BtXmlError::new(
                        Some(p.element),
                        BtXmlErrorKind::MissingAttribute {
                            element: tag.to_owned(),
                            attribute: "ID",
                        },
                    )
                    .with_attribute("ID")
                })?;
                (category, id, true)
            }
            None => match self.registry.lookup(tag, &self.models) {
                Ok(manifest) => (manifest.category, tag, false),
                Err(kind) => {
                    return Err(BtXmlError::new(
                        Some(p.element),
                        BtXmlErrorKind::Definition(kind),
                    ));
                }
            },
        };
        let mut node = NodeDef::new(category, id);
        for attribute in element.attributes() {
            let name = attribute.name();
            let value = attribute.value();
            let bad =
                |kind| Err(BtXmlError::new(Some(p.best(Some(name))), kind).with_attribute(name));
            match name {
                "ID" if explicit => {}
                "name" => node.name = Some(value.to_owned()),
                "_autoremap" => {
                    if category != NodeCategory::SubTree {
                        return bad(BtXmlErrorKind::BadAttribute {
                            element: tag.to_owned(),
                            attribute: name.to_owned(),
                            value: value.to_owned(),
                            expected: "_autoremap belongs to <SubTree> only",
                        });
                    }
                    node.autoremap = match value {
                        "1" | "true" | "True" | "TRUE" => true,
                        "0" | "false" | "False" | "FALSE" => false,
                        _ => {
                            return bad(BtXmlErrorKind::BadAttribute {
                                element: tag.to_owned(),
                                attribute: name.to_owned(),
                                value: value.to_owned(),
                                expected: "expected true or false",
                            });
                        }
                    };
                }
                n if SCRIPT_ATTRIBUTES.contains(&n) => {
                    return bad(BtXmlErrorKind::Scripting {
                        element: tag.to_owned(),
                        attribute: name.to_owned(),
                    });
                }
                n if !is_port_attribute(n) => {} // metadata such as _uid, _fullpath
                _ => node.ports.push((name.to_owned(), value.to_owned())),
            }
        }
        for (index, child) in element.children().filter(Node::is_element).enumerate() {
            path.push(index);
            let child_node = self.read_node(child, tree, path)?;
            path.pop();
            node.children.push(child_node);
        }
        self.nodes.insert((tree.to_owned(), path.clone()), p);
        Ok(node)
    }
}

/// Attributes that are ports: not `name` or `ID`, not starting with `_`.
fn is_port_attribute(name: &str) -> bool {
    name != "name" && name != "ID" && !name.starts_with('_')
}

fn text_of(element: Node<'_, '_>) -> Option<String> {
    let text: String = element
        .children()
        .filter(Node::is_text)
        .filter_map(|t| t.text())
        .collect();
    let text = text.trim();
    (!text.is_empty()).then(|| text.to_owned())
}

// ---------------------------------------------------------------------------------------------
// Writing

/// Writes a document as canonical BehaviorTree.CPP 4 XML (see the module documentation).
///
/// # Errors
/// [`BtXmlErrorKind::Unwritable`] for port names that are not XML names or that would be read
/// back as something else (`name`, `ID`, `_…`), and for an `_autoremap` on a node that is not
/// a `SubTree`.
pub fn encode_bt_xml(doc: &BtDocument) -> Result<String, BtXmlError> {
    let mut out =
        String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<root BTCPP_format=\"4\"");
    if let Some(main) = &doc.main_tree {
        write_attribute(&mut out, "main_tree_to_execute", main);
    }
    out.push_str(">\n");
    for tree in &doc.trees {
        out.push_str("  <BehaviorTree");
        write_attribute(&mut out, "ID", &tree.id);
        out.push_str(">\n");
        write_node(&mut out, &tree.root, 2)?;
        out.push_str("  </BehaviorTree>\n");
    }
    if !doc.node_models.is_empty() {
        write_models(&mut out, doc.node_models.iter(), 1)?;
    }
    out.push_str("</root>\n");
    Ok(out)
}

/// Writes a document to a file (atomically).
///
/// # Errors
/// As [`encode_bt_xml`], and [`BtXmlErrorKind::Io`] if the file cannot be written.
pub fn write_bt_xml(path: impl AsRef<Path>, doc: &BtDocument) -> Result<(), BtXmlError> {
    let path = path.as_ref();
    let text = encode_bt_xml(doc)?;
    crate::atomic::write_atomically(path, text.as_bytes()).map_err(|failure| {
        let mut e = BtXmlError::new(
            None,
            BtXmlErrorKind::Io {
                action: failure.action,
                io: failure.io,
            },
        );
        e.file = Some(path.display().to_string());
        e
    })
}

fn unwritable(reason: String) -> BtXmlError {
    BtXmlError::new(None, BtXmlErrorKind::Unwritable { reason })
}

fn write_node(out: &mut String, node: &NodeDef, depth: usize) -> Result<(), BtXmlError> {
    indent(out, depth);
    let compact = node.category != NodeCategory::SubTree && is_xml_name(&node.id);
    if compact {
        let _ = write!(out, "<{}", node.id);
    } else {
        let _ = write!(out, "<{}", node.category.tag());
        write_attribute(out, "ID", &node.id);
    }
    if let Some(name) = &node.name {
        write_attribute(out, "name", name);
    }
    for (port, value) in &node.ports {
        if !is_xml_name(port) || !is_port_attribute(port) {
            return Err(unwritable(format!(
                "the port name {port:?} of \"{}\" cannot be an XML attribute of a node",
                node.id
            )));
        }
        write_attribute(out, port, value);
    }
    if node.autoremap {
        if node.category != NodeCategory::SubTree {
            return Err(unwritable(format!(
                "\"{}\" is not a SubTree but has _autoremap set",
                node.id
            )));
        }
        write_attribute(out, "_autoremap", "true");
    }
    if node.children.is_empty() {
        out.push_str("/>\n");
        return Ok(());
    }
    out.push_str(">\n");
    for child in &node.children {
        write_node(out, child, depth + 1)?;
    }
    indent(out, depth);
    if compact {
        let _ = writeln!(out, "</{}>", node.id);
    } else {
        let _ = writeln!(out, "</{}>", node.category.tag());
    }
    Ok(())
}

fn write_models<'a>(
    out: &mut String,
    models: impl Iterator<Item = &'a NodeModel>,
    depth: usize,
) -> Result<(), BtXmlError> {
    indent(out, depth);
    out.push_str("<TreeNodesModel>\n");
    for model in models {
        indent(out, depth + 1);
        let _ = write!(out, "<{}", model.category.tag());
        write_attribute(out, "ID", &model.id);
        if model.ports.is_empty() && model.description.is_none() {
            out.push_str("/>\n");
            continue;
        }
        out.push_str(">\n");
        for port in &model.ports {
            indent(out, depth + 2);
            let _ = write!(out, "<{}", port.direction.tag());
            write_attribute(out, "name", &port.name);
            if let Some(t) = &port.type_name {
                write_attribute(out, "type", t);
            }
            if let Some(d) = &port.default {
                write_attribute(out, "default", d);
            }
            match &port.description {
                Some(text) => {
                    out.push('>');
                    escape_text(out, text);
                    let _ = writeln!(out, "</{}>", port.direction.tag());
                }
                None => out.push_str("/>\n"),
            }
        }
        if let Some(text) = &model.description {
            indent(out, depth + 2);
            out.push_str("<description>");
            escape_text(out, text);
            out.push_str("</description>\n");
        }
        indent(out, depth + 1);
        let _ = writeln!(out, "</{}>", model.category.tag());
    }
    indent(out, depth);
    out.push_str("</TreeNodesModel>\n");
    Ok(())
}

/// Writes a runtime tree as BehaviorTree.CPP's `WriteTreeToXML(tree, add_metadata = true,
/// add_builtin_models = true)` does (the XML inside a Groot2 `.btlog`): one `<BehaviorTree
/// ID _fullpath>` per subtree instance, every node in the compact form with `name` (a
/// `SubTree` node with `ID` and `_fullpath` instead) and `_uid`, the ports as the node reads
/// them, and a `<TreeNodesModel>` of the node types used.
pub fn encode_tree_xml(tree: &Tree) -> String {
    let mut out = String::from("<root BTCPP_format=\"4\">\n");
    for instance in tree.subtrees() {
        out.push_str("  <BehaviorTree");
        write_attribute(&mut out, "ID", &instance.tree_id);
        write_attribute(&mut out, "_fullpath", &instance.path);
        out.push_str(">\n");
        write_runtime_node(&mut out, tree, usize::from(instance.root_uid) - 1, 2);
        out.push_str("  </BehaviorTree>\n");
    }
    let mut seen = BTreeSet::new();
    let models: Vec<&NodeModel> = tree
        .node_models()
        .filter(|m| seen.insert(m.id.clone()))
        .collect();
    if !models.is_empty() {
        // Models come from validated trees and registries; their names are written as values.
        let _ = write_models(&mut out, models.into_iter(), 1);
    }
    out.push_str("</root>\n");
    out
}

fn write_runtime_node(out: &mut String, tree: &Tree, index: usize, depth: usize) {
    let node = &tree.nodes()[index];
    indent(out, depth);
    let subtree = node.category() == NodeCategory::SubTree;
    let tag = if subtree || !is_xml_name(node.id()) {
        node.category().tag()
    } else {
        node.id()
    };
    let _ = write!(out, "<{tag}");
    if subtree || tag != node.id() {
        write_attribute(out, "ID", node.id());
    }
    if subtree {
        let path = tree
            .subtrees()
            .iter()
            .find(|s| s.subtree_uid == Some(node.uid()))
            .map_or("", |s| s.path.as_str());
        write_attribute(out, "_fullpath", path);
    } else {
        write_attribute(out, "name", node.name());
    }
    write_attribute(out, "_uid", &node.uid().to_string());
    for (port, value) in node.ports() {
        if is_xml_name(port) && is_port_attribute(port) {
            write_attribute(out, port, value);
        }
    }
    if subtree || node.children().is_empty() {
        out.push_str("/>\n");
        return;
    }
    out.push_str(">\n");
    for &child in node.children() {
        write_runtime_node(out, tree, child, depth + 1);
    }
    indent(out, depth);
    let _ = writeln!(out, "</{tag}>");
}

fn indent(out: &mut String, depth: usize) {
    for _ in 0..depth {
        out.push_str("  ");
    }
}

fn write_attribute(out: &mut String, name: &str, value: &str) {
    let _ = write!(out, " {name}=\"");
    for c in value.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            // Attribute-value normalisation would turn these into spaces.
            '\t' => out.push_str("&#9;"),
            '\n' => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            c => out.push(c),
        }
    }
    out.push('"');
}

fn escape_text(out: &mut String, text: &str) {
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            c => out.push(c),
        }
    }
}

/// A conservative XML name: a letter or `_`, then letters, digits, `_`, `-`, `.` (non-ASCII
/// letters allowed); no `:` (namespaces).
fn is_xml_name(name: &str) -> bool {
    let mut chars = name.chars();
    let Some(first) = chars.next() else {
        return false;
    };
    (first.is_alphabetic() || first == '_')
        && chars.all(|c| c.is_alphanumeric() || matches!(c, '_' | '-' | '.'))
        && !name.to_ascii_lowercase().starts_with("xml")
}
