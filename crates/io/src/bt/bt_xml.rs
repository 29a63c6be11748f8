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
//! * `<include path="…"/>` as BehaviorTree.CPP 4 follows it: the path is relative to the
//!   directory of the file that contains the `<include>` (or absolute); the included file's
//!   trees and node models join the document, its own includes are followed, and its
//!   `main_tree_to_execute` is ignored (the first file's counts). A file reached twice
//!   (two files include a third) is read once; an include cycle (`a.xml -> b.xml -> a.xml`)
//!   is an error that lists the chain. `ros_pkg="…"` needs a ROS installation to resolve and
//!   is refused (give the path instead). Text read without a file ([`parse_bt_xml`]) has no
//!   directory to resolve includes from: an `<include>` there is an error.
//! * Nodes in the explicit form (`<Action ID="OpenDoor"/>`, `<Condition ID>`, `<Control ID>`,
//!   `<Decorator ID>`) and the compact form (`<Sequence>`, `<OpenDoor/>`); `name`; ports as
//!   attributes; `<SubTree ID="…" port="{key}" _autoremap="true"/>`.
//! * `<TreeNodesModel>`: the category, ports (`input_port`, `output_port`, `inout_port` with
//!   `name`, `type`, `default` and text) and `<description>` of every node type; entries and
//!   elements that are not understood are skipped with a warning. A compact-form node must be
//!   built in, registered, or declared here (as Groot2 declares every custom node) or in
//!   [`BtReadOptions::node_models`] (models from separate files, such as Nav2's
//!   `nav2_tree_nodes.xml`, read with [`read_node_models`]). An explicit-form leaf that is
//!   none of these gets a model inferred from its attributes, so that saved files (which are
//!   compact) load again. Declared custom controls and decorators are checked like built-in
//!   ones: a decorator has exactly one child, a control at least one, and only their ports.
//! * Scripting attributes (`_skipIf`, `_successIf`, `_failureIf`, `_while`, `_onSuccess`,
//!   `_onFailure`, `_post`, `_onHalted`) are kept in [`NodeDef::scripts`], in document order.
//!   Other attributes starting with `_` that BehaviorTree.CPP writes as metadata (`_uid`,
//!   `_fullpath`) are ignored.
//!
//! After reading, the document is checked with [`chronomap_bt::validate`] (unknown IDs,
//! children per category, required and unknown ports, literal values, subtrees). Every error
//! is a [`BtXmlError`] with the file, line and column of the element or attribute concerned
//! (the included file's, when the problem is there).
//!
//! # Limits
//! Reading takes time and memory in proportion to the size of the files, and
//! [`BtReadOptions`] bounds that size: at most [`MAX_BYTES`] bytes in all files together,
//! [`MAX_FILES`] included files, [`MAX_NODES`] XML nodes per file, [`MAX_ATTRIBUTES`] attributes
//! per element, nodes nested at most [`MAX_DEPTH`] levels deep; each limit is an error that
//! says which. A document type
//! declaration (`<!DOCTYPE …>`, and with it entity definitions that could expand without
//! bound) and XML namespaces (`<bt:Sequence>`, `xmlns="…"`) have no place in
//! BehaviorTree.CPP files and are refused.
//!
//! # What is written
//! [`encode_bt_xml`] writes `<?xml …?>`, `<root BTCPP_format="4">`, each tree with nodes in
//! the compact form (the explicit form only for IDs that are not XML names), scripting
//! attributes after the ports, two-space indentation, and the document's node models in
//! `<TreeNodesModel>` (those of its files, the models inferred for explicit-form leaves and
//! the models from [`BtReadOptions::node_models`] that the trees use, so that Groot2 shows the
//! ports of every custom node). [`encode_tree_xml`] writes a runtime tree the way
//! BehaviorTree.CPP's `WriteTreeToXML(tree, true, true)` does for Groot2 logs: one
//! `<BehaviorTree>` per subtree instance with `_fullpath`, `_uid` on every node, the ports as
//! the nodes read them, and the models of the node types used.

use std::cell::OnceCell;
use std::collections::{BTreeSet, HashMap, HashSet};
use std::fmt::{self, Write as _};
use std::io::{self, Read as _};
use std::path::{Path, PathBuf};
use std::rc::Rc;

use chronomap_bt::{
    BtDocument, DefinitionErrorKind, NodeCategory, NodeDef, NodeLocation, NodeModel, PortDirection,
    PortSpec, Registry, Tree, TreeDef, is_builtin, validate,
};
use roxmltree::{Document, Node, ParsingOptions};
use thiserror::Error;

/// Pre- and post-condition attributes of BehaviorTree.CPP's scripting language, kept in
/// [`NodeDef::scripts`].
pub const SCRIPT_ATTRIBUTES: [&str; 8] = [
    "_skipIf",
    "_successIf",
    "_failureIf",
    "_while",
    "_onSuccess",
    "_onFailure",
    "_post",
    "_onHalted",
];

/// The deepest nesting of nodes read by default (a tree root is at level 1).
pub const MAX_DEPTH: usize = 1000;
/// The most files an `<include>` chain may add by default.
pub const MAX_FILES: usize = 256;
/// The most bytes of all files of one document together by default (64 MiB).
pub const MAX_BYTES: u64 = 64 << 20;
/// The most XML nodes (elements, text, comments) of one file by default.
pub const MAX_NODES: u32 = 4_000_000;
/// The most attributes of one element by default (the XML parser checks them for duplicates
/// pairwise, so this bounds its time on one element).
pub const MAX_ATTRIBUTES: usize = 10_000;
/// The most pairs of attributes on one element, summed over the elements of all files of a
/// document (the XML parser compares the attributes of an element pairwise, so this bounds its
/// time on the whole document: one element of 10,000 attributes has 49,995,000 pairs, a
/// thousand elements of 50 attributes 1,225,000).
pub const MAX_ATTRIBUTE_PAIRS: u64 = 50_000_000;
/// The most namespace declarations (`xmlns`, `xmlns:p`) of one file (the XML parser copies
/// the declarations in scope to each element that declares one, and searches them for each
/// prefix, so this bounds its time). BehaviorTree.CPP files have none.
pub const MAX_NAMESPACES: usize = 64;

/// How to read a document: node models from other files, and the limits of reading.
#[derive(Clone, Debug)]
pub struct BtReadOptions {
    /// Models of custom nodes declared outside the document (`chronomap bt check --nodes`,
    /// [`read_node_models`]). They resolve IDs that are neither built in, registered nor
    /// declared in the document's own `<TreeNodesModel>`s (which take precedence); the ones
    /// the trees use are added to [`BtDocument::node_models`].
    pub node_models: Vec<NodeModel>,
    /// The deepest nesting of nodes ([`MAX_DEPTH`]). Reading recurses once per level, so much
    /// larger values need a larger stack.
    pub max_depth: usize,
    /// The most included files ([`MAX_FILES`]).
    pub max_files: usize,
    /// The most bytes of all files together ([`MAX_BYTES`]).
    pub max_bytes: u64,
    /// The most XML nodes of one file ([`MAX_NODES`]).
    pub max_nodes: u32,
    /// The most attributes of one element ([`MAX_ATTRIBUTES`]).
    pub max_attributes: usize,
}

impl Default for BtReadOptions {
    fn default() -> BtReadOptions {
        BtReadOptions {
            node_models: Vec::new(),
            max_depth: MAX_DEPTH,
            max_files: MAX_FILES,
            max_bytes: MAX_BYTES,
            max_nodes: MAX_NODES,
            max_attributes: MAX_ATTRIBUTES,
        }
    }
}

impl BtReadOptions {
    /// The default limits with node models from other files.
    pub fn with_node_models(models: Vec<NodeModel>) -> BtReadOptions {
        BtReadOptions {
            node_models: models,
            ..BtReadOptions::default()
        }
    }
}

/// A document read from XML, and what was accepted with a warning.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BtXml {
    /// The trees and node models.
    pub document: BtDocument,
    /// Things that were read leniently (each `file:line:column: text`).
    pub warnings: Vec<String>,
    /// The files read: the file itself, then each included file in the order it was read
    /// (as `path` joined to the including file's directory).
    pub files: Vec<String>,
    /// Per tree ID: the index into `files`, and the line and column of every node's element in
    /// depth-first pre-order.
    places: HashMap<String, (usize, Vec<Pos>)>,
}

impl BtXml {
    /// The line and column of the node at `location`, if it was read from these files.
    pub fn position(&self, location: &NodeLocation) -> Option<(u32, u32)> {
        self.locate(location)
            .map(|(_, line, column)| (line, column))
    }

    /// The file, line and column of the node at `location` (trees may come from included
    /// files).
    pub fn locate(&self, location: &NodeLocation) -> Option<(&str, u32, u32)> {
        let (file, positions) = self.places.get(&location.tree)?;
        let tree = self.document.tree(&location.tree)?;
        let (line, column) = *positions.get(preorder_index(&tree.root, &location.path)?)?;
        Some((self.files.get(*file)?.as_str(), line, column))
    }

    /// The file the tree `id` was read from.
    pub fn file_of(&self, tree: &str) -> Option<&str> {
        let (file, _) = self.places.get(tree)?;
        self.files.get(*file).map(String::as_str)
    }
}

/// The depth-first pre-order index of the node at `path` below `root`.
fn preorder_index(root: &NodeDef, path: &[usize]) -> Option<usize> {
    let mut index = 0;
    let mut node = root;
    for &i in path {
        let child = node.children.get(i)?;
        index += 1 + node.children[..i].iter().map(subtree_size).sum::<usize>();
        node = child;
    }
    Some(index)
}

/// The number of nodes of a subtree (without recursion).
fn subtree_size(node: &NodeDef) -> usize {
    let mut count = 0;
    let mut stack = vec![node];
    while let Some(n) = stack.pop() {
        count += 1;
        stack.extend(n.children.iter());
    }
    count
}

/// Node models read from a file of its own ([`read_node_models`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BtNodeModels {
    /// The models, in document order.
    pub models: Vec<NodeModel>,
    /// Things that were skipped or read leniently (each `file:line:column: text`).
    pub warnings: Vec<String>,
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
    /// A document type declaration.
    #[error(
        "a document type declaration (<!DOCTYPE ...>) is not accepted: BehaviorTree.CPP files \
         have none, and its entities could expand without bound"
    )]
    Dtd,
    /// An element or attribute in an XML namespace.
    #[error(
        "{what} is in the XML namespace \"{namespace}\": BehaviorTree.CPP files use plain \
         tags and attributes without namespaces"
    )]
    Namespace {
        /// `<Sequence>`, `attribute msec`.
        what: String,
        /// The namespace URI.
        namespace: String,
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
    /// An `<include>` in text that was not read from a file.
    #[error(
        "<include path=\"{path}\">: text read without a file has no directory to resolve \
         the path from (read the file instead)"
    )]
    IncludeWithoutFile {
        /// The path written.
        path: String,
    },
    /// `<include ros_pkg="…">`.
    #[error(
        "<include ros_pkg=\"{package}\">: ROS packages are not resolved here; give the \
         file's path instead (relative to this file, or absolute)"
    )]
    IncludeRosPkg {
        /// The package named.
        package: String,
    },
    /// An included file that cannot be read.
    #[error("<include path=\"{path}\">: cannot read {resolved}: {io}")]
    IncludeUnreadable {
        /// The path written.
        path: String,
        /// The path resolved against the including file's directory.
        resolved: String,
        /// The underlying error.
        io: io::Error,
    },
    /// An include cycle.
    #[error("<include path=\"{path}\"> makes an include cycle: {}", chain.join(" -> "))]
    IncludeCycle {
        /// The path written.
        path: String,
        /// The files of the cycle, from the first to the file that is included again.
        chain: Vec<String>,
    },
    /// Too many files.
    #[error("<include>: more than {limit} included files (a limit of this reader)")]
    TooManyFiles {
        /// The limit.
        limit: usize,
    },
    /// Too many bytes.
    #[error("the document's files are larger than {limit} bytes together (a limit of this reader)")]
    TooManyBytes {
        /// The limit.
        limit: u64,
    },
    /// Too many XML nodes in one file.
    #[error("more than {limit} XML nodes in one file (a limit of this reader)")]
    TooManyNodes {
        /// The limit.
        limit: u32,
    },
    /// An element with too many attributes.
    #[error("an element with more than {limit} attributes (a limit of this reader)")]
    TooManyAttributes {
        /// The limit.
        limit: usize,
    },
    /// Too many pairs of attributes on the elements of the document ([`MAX_ATTRIBUTE_PAIRS`]).
    #[error(
        "more than {limit} pairs of attributes on one element, summed over the elements of the \
         document's files (a limit of this reader: the XML parser compares them pairwise)"
    )]
    TooManyAttributePairs {
        /// The limit.
        limit: u64,
    },
    /// Too many namespace declarations in one file ([`MAX_NAMESPACES`]).
    #[error(
        "more than {limit} namespace declarations (xmlns) in one file (a limit of this reader)"
    )]
    TooManyNamespaces {
        /// The limit.
        limit: usize,
    },
    /// Nodes nested too deep.
    #[error("nodes nested deeper than {limit} levels (a limit of this reader)")]
    TooDeep {
        /// The limit.
        limit: usize,
    },
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
    #[error("attribute ID=\"{id}\": another <BehaviorTree> has this ID already ({first})")]
    DuplicateTree {
        /// The ID.
        id: String,
        /// Where the first one is (`file:line:column`).
        first: String,
    },
    /// A tree ID used as a node tag (`<CheckStatus/>` for `<SubTree ID="CheckStatus"/>`).
    #[error(
        "<{id}> names a <BehaviorTree> of the document, not a node type: write \
         <SubTree ID=\"{id}\"/>"
    )]
    TreeAsNode {
        /// The tree ID.
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

    fn in_file(mut self, file: &str) -> BtXmlError {
        self.file = Some(file.to_owned());
        self
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

/// Reads a BehaviorTree.CPP 4 XML file and the files it includes; IDs are resolved with
/// `registry` (built-in nodes and registered leaves) and the files' `<TreeNodesModel>`s.
///
/// # Errors
/// A [`BtXmlError`] naming the file, line, column and attribute (see [`parse_bt_xml`]).
pub fn read_bt_xml(path: impl AsRef<Path>, registry: &Registry) -> Result<BtXml, BtXmlError> {
    read_bt_xml_with(path, registry, &BtReadOptions::default())
}

/// [`read_bt_xml`] with node models from other files and other limits.
///
/// # Errors
/// As [`parse_bt_xml`], and for `<include>`s that cannot be followed (see the module
/// documentation) and files beyond the limits of `options`.
pub fn read_bt_xml_with(
    path: impl AsRef<Path>,
    registry: &Registry,
    options: &BtReadOptions,
) -> Result<BtXml, BtXmlError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let text = read_limited(path, options.max_bytes).map_err(|e| match e {
        Limited::Io(io) => BtXmlError::new(None, BtXmlErrorKind::Io { action: "read", io }),
        Limited::TooLarge => BtXmlError::new(
            None,
            BtXmlErrorKind::TooManyBytes {
                limit: options.max_bytes,
            },
        ),
    });
    let text = text.map_err(|e| e.in_file(&name))?;
    let key = std::fs::canonicalize(path).ok();
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    read_text(&name, &text, Some(dir), key, registry, options)
}

/// Reads BehaviorTree.CPP 4 XML text; `name` is used in messages. The text has no directory,
/// so an `<include>` is an error (use [`read_bt_xml`], or [`parse_bt_xml_in`]).
///
/// # Errors
/// A [`BtXmlError`] for XML that is not well-formed, a root element other than `<root>`, a
/// format other than 4, `<include>`, a DTD, namespaces, unexpected elements, missing `ID`s,
/// trees without exactly one root node, duplicate tree IDs, nodes nested too deep, and every
/// [`DefinitionErrorKind`] of [`validate`].
pub fn parse_bt_xml(name: &str, text: &str, registry: &Registry) -> Result<BtXml, BtXmlError> {
    read_text(name, text, None, None, registry, &BtReadOptions::default())
}

/// Reads BehaviorTree.CPP 4 XML text as if it were a file in the directory `dir` (which
/// `<include path>`s are relative to), with `options`.
///
/// # Errors
/// As [`read_bt_xml_with`].
pub fn parse_bt_xml_in(
    name: &str,
    text: &str,
    dir: &Path,
    registry: &Registry,
    options: &BtReadOptions,
) -> Result<BtXml, BtXmlError> {
    if text.len() as u64 > options.max_bytes {
        return Err(BtXmlError::new(
            None,
            BtXmlErrorKind::TooManyBytes {
                limit: options.max_bytes,
            },
        )
        .in_file(name));
    }
    read_text(name, text, Some(dir.to_path_buf()), None, registry, options)
}

/// Reads the `<TreeNodesModel>` of a file that declares node types (Nav2's
/// `nav2_tree_nodes.xml`, a Groot2 palette): a `<root>` whose `<TreeNodesModel>` entries are
/// kept; `<BehaviorTree>`s in it are skipped with a warning.
///
/// # Errors
/// A [`BtXmlError`] for files that cannot be read, are larger than [`MAX_BYTES`], are not
/// well-formed, have a DTD or another root element, or contain `<include>`.
pub fn read_node_models(path: impl AsRef<Path>) -> Result<BtNodeModels, BtXmlError> {
    let path = path.as_ref();
    let name = path.display().to_string();
    let text = read_limited(path, MAX_BYTES).map_err(|e| {
        let kind = match e {
            Limited::Io(io) => BtXmlErrorKind::Io { action: "read", io },
            Limited::TooLarge => BtXmlErrorKind::TooManyBytes { limit: MAX_BYTES },
        };
        BtXmlError::new(None, kind).in_file(&name)
    })?;
    parse_node_models(&name, &text)
}

/// [`read_node_models`] of text; `name` is used in messages.
///
/// # Errors
/// As [`read_node_models`].
pub fn parse_node_models(name: &str, text: &str) -> Result<BtNodeModels, BtXmlError> {
    let options = BtReadOptions::default();
    let doc = parse_document(name, text, &options, &mut 0)?;
    let source = Source::new(name.to_owned(), None, doc);
    let sources = [&source];
    let registry = Registry::new();
    let mut reader = Reader::new(&registry, &options, &sources);
    let root = source.doc.root_element();
    reader.check_root(0, root)?;
    for child in root.children().filter(Node::is_element) {
        reader.check_namespace(0, child)?;
        match child.tag_name().name() {
            "TreeNodesModel" => reader.read_models(0, child),
            "include" => {
                return Err(reader.error(
                    0,
                    child.range().start,
                    BtXmlErrorKind::UnknownElement {
                        element: "include".to_owned(),
                        parent: "root of a node-model file".to_owned(),
                    },
                ));
            }
            other => {
                let text = format!(
                    "skipped <{other}> (a node-model file is read for its <TreeNodesModel>)"
                );
                reader.warn(0, child.range().start, text);
            }
        }
    }
    Ok(BtNodeModels {
        models: reader.models,
        warnings: reader.warnings,
    })
}

enum Limited {
    Io(io::Error),
    TooLarge,
}

/// The file's text if it has at most `limit` bytes (reads at most `limit + 1`).
fn read_limited(path: &Path, limit: u64) -> Result<String, Limited> {
    // A directory, a device such as /dev/zero or a pipe is refused before reading.
    let file = crate::bounded::open_regular(path).map_err(Limited::Io)?;
    let mut bytes = Vec::new();
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(Limited::Io)?;
    if bytes.len() as u64 > limit {
        return Err(Limited::TooLarge);
    }
    String::from_utf8(bytes).map_err(|_| {
        Limited::Io(io::Error::new(
            io::ErrorKind::InvalidData,
            "the file is not UTF-8 text",
        ))
    })
}

type Pos = (u32, u32);

/// One file of a document, parsed.
struct Source<'t> {
    name: String,
    /// The directory includes are relative to (`None` for text without a file).
    dir: Option<PathBuf>,
    /// The files from the first to this one (canonical path, name), for cycles.
    chain: Rc<Vec<(Option<PathBuf>, String)>>,
    doc: Document<'t>,
    /// Byte offsets of line starts, made when first needed.
    lines: OnceCell<Vec<usize>>,
}

impl<'t> Source<'t> {
    fn new(name: String, dir: Option<PathBuf>, doc: Document<'t>) -> Source<'t> {
        Source {
            chain: Rc::new(vec![(None, name.clone())]),
            name,
            dir,
            doc,
            lines: OnceCell::new(),
        }
    }

    /// The 1-based line and column (in characters) of a byte offset.
    fn pos(&self, offset: usize) -> Pos {
        let text = self.doc.input_text();
        let lines = self.lines.get_or_init(|| {
            std::iter::once(0)
                .chain(text.match_indices('\n').map(|(i, _)| i + 1))
                .collect()
        });
        let offset = offset.min(text.len());
        let line = lines.partition_point(|&start| start <= offset) - 1;
        let column = text[lines[line]..offset].chars().count() + 1;
        (
            u32::try_from(line + 1).unwrap_or(u32::MAX),
            u32::try_from(column).unwrap_or(u32::MAX),
        )
    }
}

/// The 1-based line and column (in characters) of a byte offset, for a single error before
/// the document is parsed (a parsed file's positions come from [`Source::pos`]'s line index).
fn line_column(text: &str, offset: usize) -> Pos {
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().unwrap_or("").chars().count() + 1;
    (
        u32::try_from(line).unwrap_or(u32::MAX),
        u32::try_from(column).unwrap_or(u32::MAX),
    )
}

/// Parses one file's text; `pairs` counts the pairs of attributes of the document's elements
/// parsed so far.
fn parse_document<'t>(
    name: &str,
    text: &'t str,
    options: &BtReadOptions,
    pairs: &mut u64,
) -> Result<Document<'t>, BtXmlError> {
    if let Some((offset, kind)) = crowded_element(text, options.max_attributes, pairs) {
        return Err(BtXmlError::new(Some(line_column(text, offset)), kind).in_file(name));
    }
    let parsing = ParsingOptions {
        allow_dtd: false,
        nodes_limit: options.max_nodes,
        ..ParsingOptions::default()
    };
    Document::parse_with_options(text, parsing).map_err(|e| {
        let p = e.pos();
        let kind = match e {
            roxmltree::Error::DtdDetected => BtXmlErrorKind::Dtd,
            roxmltree::Error::NodesLimitReached => BtXmlErrorKind::TooManyNodes {
                limit: options.max_nodes,
            },
            _ => {
                let message = e.to_string();
                let message = message
                    .strip_suffix(&format!(" at {}:{}", p.row, p.col))
                    .unwrap_or(&message)
                    .to_owned();
                BtXmlErrorKind::Xml { message }
            }
        };
        let position = match kind {
            BtXmlErrorKind::Dtd => text
                .find("<!DOCTYPE")
                .map(|offset| line_column(text, offset)),
            BtXmlErrorKind::TooManyNodes { .. } => None,
            _ => Some((p.row, p.col)),
        };
        BtXmlError::new(position, kind).in_file(name)
    })
}

/// What the XML parser would spend more than linear time on, found in one pass over the text
/// before it is parsed: the offset of the first start tag with more than `limit` attributes
/// (counted as `=` outside quotes), of the tag that takes the attribute pairs of the document
/// (`pairs`, counted up) beyond [`MAX_ATTRIBUTE_PAIRS`], or of the namespace declaration beyond
/// [`MAX_NAMESPACES`] in this text. Comments, CDATA, processing instructions and declarations
/// are skipped. Not-well-formed text is left to the parser.
fn crowded_element(text: &str, limit: usize, pairs: &mut u64) -> Option<(usize, BtXmlErrorKind)> {
    let bytes = text.as_bytes();
    let skip_to = |from: usize, end: &str| {
        text[from..]
            .find(end)
            .map_or(bytes.len(), |i| from + i + end.len())
    };
    let mut namespaces = 0;
    let mut i = 0;
    while let Some(found) = text[i..].find('<') {
        let start = i + found;
        let rest = &text[start..];
        if rest.starts_with("<!--") {
            i = skip_to(start + 4, "-->");
        } else if rest.starts_with("<![CDATA[") {
            i = skip_to(start + 9, "]]>");
        } else if rest.starts_with("<?") {
            i = skip_to(start + 2, "?>");
        } else if rest.starts_with("<!") || rest.starts_with("</") {
            i = skip_to(start + 2, ">");
        } else {
            let mut count: usize = 0;
            let mut quote = None;
            let mut j = start + 1;
            while j < bytes.len() {
                let c = bytes[j];
                match quote {
                    Some(q) if c == q => quote = None,
                    Some(_) => {}
                    None if c == b'"' || c == b'\'' => quote = Some(c),
                    None if c == b'=' => count += 1,
                    None if c == b'>' || c == b'<' => break,
                    None if c.is_ascii_whitespace()
                        && is_namespace_declaration(&bytes[j + 1..]) =>
                    {
                        namespaces += 1;
                        if namespaces > MAX_NAMESPACES {
                            return Some((
                                j + 1,
                                BtXmlErrorKind::TooManyNamespaces {
                                    limit: MAX_NAMESPACES,
                                },
                            ));
                        }
                    }
                    None => {}
                }
                j += 1;
            }
            if count > limit {
                return Some((start, BtXmlErrorKind::TooManyAttributes { limit }));
            }
            let c = count as u64;
            *pairs = pairs.saturating_add(c * c.saturating_sub(1) / 2);
            if *pairs > MAX_ATTRIBUTE_PAIRS {
                return Some((
                    start,
                    BtXmlErrorKind::TooManyAttributePairs {
                        limit: MAX_ATTRIBUTE_PAIRS,
                    },
                ));
            }
            i = j;
        }
        if i >= bytes.len() {
            break;
        }
    }
    None
}

/// Whether an attribute starting at `rest` declares a namespace (`xmlns=`, `xmlns:p=`).
fn is_namespace_declaration(rest: &[u8]) -> bool {
    rest.strip_prefix(b"xmlns").is_some_and(|after| {
        matches!(after.first(), Some(b':' | b'=') | None)
            || after.first().is_some_and(u8::is_ascii_whitespace)
    })
}

fn read_text(
    name: &str,
    text: &str,
    dir: Option<PathBuf>,
    key: Option<PathBuf>,
    registry: &Registry,
    options: &BtReadOptions,
) -> Result<BtXml, BtXmlError> {
    let mut pairs = 0;
    let doc = parse_document(name, text, options, &mut pairs)?;
    let mut source = Source::new(name.to_owned(), dir, doc);
    source.chain = Rc::new(vec![(key.clone(), name.to_owned())]);
    let mut loader = Loader {
        registry,
        options,
        bytes: text.len() as u64,
        pairs,
        files: 0,
        loaded: key.into_iter().collect(),
    };
    let mut pending = Vec::new();
    loader.queue_includes(&source, 0, &mut pending)?;
    load(&mut loader, &mut pending, vec![&source])
}

/// An `<include>` to follow.
struct Pending {
    /// The path as written.
    written: String,
    /// Joined to the including file's directory.
    resolved: PathBuf,
    /// The including file (index into the sources) and the offset of the `path` attribute.
    from: (usize, usize),
}

struct Loader<'r> {
    registry: &'r Registry,
    options: &'r BtReadOptions,
    /// Bytes read so far.
    bytes: u64,
    /// Pairs of attributes on one element read so far ([`MAX_ATTRIBUTE_PAIRS`]).
    pairs: u64,
    /// `<include>`s followed so far.
    files: usize,
    /// Canonical paths of the files read.
    loaded: HashSet<PathBuf>,
}

impl Loader<'_> {
    /// Puts the `<include>`s of `source` (the `index`th) on the stack, the first on top.
    fn queue_includes(
        &mut self,
        source: &Source<'_>,
        index: usize,
        pending: &mut Vec<Pending>,
    ) -> Result<(), BtXmlError> {
        let root = source.doc.root_element();
        if root.tag_name().name() != "root" {
            return Ok(()); // refused when the file is read
        }
        let mut found = Vec::new();
        for include in root
            .children()
            .filter(|n| n.is_element() && n.tag_name().name() == "include")
        {
            let at = include.range().start;
            let error = |kind, attribute: Option<&str>| {
                let offset = attribute
                    .and_then(|a| include.attributes().find(|x| x.name() == a))
                    .map_or(at, |a| a.range().start);
                let e = BtXmlError::new(Some(source.pos(offset)), kind).in_file(&source.name);
                match attribute {
                    Some(a) => e.with_attribute(a),
                    None => e,
                }
            };
            if let Some(package) = include.attribute("ros_pkg") {
                return Err(error(
                    BtXmlErrorKind::IncludeRosPkg {
                        package: package.to_owned(),
                    },
                    Some("ros_pkg"),
                ));
            }
            let Some(path) = include.attribute("path") else {
                return Err(error(
                    BtXmlErrorKind::MissingAttribute {
                        element: "include".to_owned(),
                        attribute: "path",
                    },
                    Some("path"),
                ));
            };
            let Some(dir) = &source.dir else {
                return Err(error(
                    BtXmlErrorKind::IncludeWithoutFile {
                        path: path.to_owned(),
                    },
                    Some("path"),
                ));
            };
            self.files += 1;
            if self.files > self.options.max_files {
                return Err(error(
                    BtXmlErrorKind::TooManyFiles {
                        limit: self.options.max_files,
                    },
                    None,
                ));
            }
            let path_at = include
                .attributes()
                .find(|a| a.name() == "path")
                .map_or(at, |a| a.range().start);
            found.push(Pending {
                written: path.to_owned(),
                resolved: dir.join(path),
                from: (index, path_at),
            });
        }
        pending.extend(found.into_iter().rev());
        Ok(())
    }
}

/// Reads the pending includes one by one, each file's text and parse living in a frame of
/// this recursion (at most `max_files` deep), then reads the document from all of them.
fn load<'s>(
    loader: &mut Loader<'_>,
    pending: &mut Vec<Pending>,
    sources: Vec<&'s Source<'s>>,
) -> Result<BtXml, BtXmlError> {
    let Some(next) = pending.pop() else {
        return read_sources(loader.registry, loader.options, &sources);
    };
    let from = sources[next.from.0];
    let at = |kind| {
        BtXmlError::new(Some(from.pos(next.from.1)), kind)
            .in_file(&from.name)
            .with_attribute("path")
    };
    let resolved = tidy(&next.resolved).display().to_string();
    let unreadable = |io| BtXmlErrorKind::IncludeUnreadable {
        path: next.written.clone(),
        resolved: resolved.clone(),
        io,
    };
    let key = std::fs::canonicalize(&next.resolved).map_err(|io| at(unreadable(io)))?;
    if let Some(start) = from
        .chain
        .iter()
        .position(|(k, _)| k.as_ref() == Some(&key))
    {
        let mut chain: Vec<String> = from.chain[start..].iter().map(|(_, n)| n.clone()).collect();
        chain.push(resolved.clone());
        return Err(at(BtXmlErrorKind::IncludeCycle {
            path: next.written.clone(),
            chain,
        }));
    }
    if !loader.loaded.insert(key.clone()) {
        // Read already through another include: its trees are in the document.
        return load(loader, pending, sources);
    }
    let remaining = loader.options.max_bytes.saturating_sub(loader.bytes);
    let text = read_limited(&next.resolved, remaining).map_err(|e| match e {
        Limited::Io(io) => at(unreadable(io)),
        Limited::TooLarge => at(BtXmlErrorKind::TooManyBytes {
            limit: loader.options.max_bytes,
        }),
    })?;
    loader.bytes += text.len() as u64;
    let doc = parse_document(&resolved, &text, loader.options, &mut loader.pairs)?;
    let mut chain = from.chain.as_ref().clone();
    chain.push((Some(key), resolved.clone()));
    let source = Source {
        name: resolved,
        dir: Some(
            next.resolved
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default(),
        ),
        chain: Rc::new(chain),
        doc,
        lines: OnceCell::new(),
    };
    let index = sources.len();
    loader.queue_includes(&source, index, pending)?;
    let mut sources: Vec<&Source<'_>> = sources;
    sources.push(&source);
    load(loader, pending, sources)
}

/// The path without `.` components and with `dir/..` pairs removed, for messages (the file is
/// opened by the path as joined, so symbolic links resolve as the system does).
fn tidy(path: &Path) -> PathBuf {
    use std::path::Component;
    let mut out: Vec<Component<'_>> = Vec::new();
    for component in path.components() {
        match component {
            Component::CurDir => {}
            Component::ParentDir if matches!(out.last(), Some(Component::Normal(_))) => {
                out.pop();
            }
            c => out.push(c),
        }
    }
    if out.is_empty() {
        return PathBuf::from(".");
    }
    out.iter().collect()
}

/// Where an element comes from: the source index and the element.
type Placed<'a> = (usize, Node<'a, 'a>);

struct Reader<'a, 'r> {
    registry: &'r Registry,
    options: &'r BtReadOptions,
    sources: &'a [&'a Source<'a>],
    models: Vec<NodeModel>,
    /// Index into `models` by ID.
    model_index: HashMap<String, usize>,
    /// `options.node_models` by ID.
    external: HashMap<&'r str, &'r NodeModel>,
    /// Tree elements by ID.
    tree_ids: HashMap<&'a str, Placed<'a>>,
    warnings: Vec<String>,
}

impl<'a, 'r> Reader<'a, 'r> {
    fn new(
        registry: &'r Registry,
        options: &'r BtReadOptions,
        sources: &'a [&'a Source<'a>],
    ) -> Reader<'a, 'r> {
        let mut external = HashMap::new();
        for model in &options.node_models {
            external.entry(model.id.as_str()).or_insert(model);
        }
        Reader {
            registry,
            options,
            sources,
            models: Vec::new(),
            model_index: HashMap::new(),
            external,
            tree_ids: HashMap::new(),
            warnings: Vec::new(),
        }
    }

    fn error(&self, source: usize, offset: usize, kind: BtXmlErrorKind) -> BtXmlError {
        let s = self.sources[source];
        BtXmlError::new(Some(s.pos(offset)), kind).in_file(&s.name)
    }

    /// An error at `attribute` of `element` (at the element if it has no such attribute).
    fn error_at(
        &self,
        (source, element): Placed<'a>,
        attribute: Option<&str>,
        kind: BtXmlErrorKind,
    ) -> BtXmlError {
        let offset = attribute
            .and_then(|a| element.attributes().find(|x| x.name() == a))
            .map_or(element.range().start, |a| a.range().start);
        let e = self.error(source, offset, kind);
        match attribute {
            Some(a) => e.with_attribute(a),
            None => e,
        }
    }

    fn warn(&mut self, source: usize, offset: usize, text: String) {
        let s = self.sources[source];
        let (line, column) = s.pos(offset);
        self.warnings
            .push(format!("{}:{line}:{column}: {text}", s.name));
    }

    /// Refuses elements and attributes in namespaces.
    fn check_namespace(&self, source: usize, element: Node<'a, 'a>) -> Result<(), BtXmlError> {
        if let Some(namespace) = element.tag_name().namespace() {
            return Err(self.error(
                source,
                element.range().start,
                BtXmlErrorKind::Namespace {
                    what: format!("<{}>", element.tag_name().name()),
                    namespace: namespace.to_owned(),
                },
            ));
        }
        for attribute in element.attributes() {
            if let Some(namespace) = attribute.namespace() {
                return Err(self
                    .error(
                        source,
                        attribute.range().start,
                        BtXmlErrorKind::Namespace {
                            what: format!("attribute {}", attribute.name()),
                            namespace: namespace.to_owned(),
                        },
                    )
                    .with_attribute(attribute.name()));
            }
        }
        Ok(())
    }

    /// `<root>` and its `BTCPP_format`.
    fn check_root(&mut self, source: usize, root: Node<'a, 'a>) -> Result<(), BtXmlError> {
        if root.tag_name().name() != "root" {
            return Err(self.error(
                source,
                root.range().start,
                BtXmlErrorKind::NotBtXml {
                    found: root.tag_name().name().to_owned(),
                },
            ));
        }
        self.check_namespace(source, root)?;
        match root.attribute("BTCPP_format") {
            Some(v) if v.trim() == "4" => Ok(()),
            Some(v) => Err(self.error_at(
                (source, root),
                Some("BTCPP_format"),
                BtXmlErrorKind::Format {
                    found: v.to_owned(),
                },
            )),
            None => {
                self.warn(
                    source,
                    root.range().start,
                    "<root> has no BTCPP_format attribute; read as format 4 (as \
                     BehaviorTree.CPP 4 does)"
                        .to_owned(),
                );
                Ok(())
            }
        }
    }

    /// `<TreeNodesModel>`: keeps what it understands, warns about the rest.
    fn read_models(&mut self, source: usize, element: Node<'a, 'a>) {
        for entry in element.children().filter(Node::is_element) {
            let at = entry.range().start;
            let tag = entry.tag_name().name();
            let Some(category) = NodeCategory::from_tag(tag) else {
                self.warn(
                    source,
                    at,
                    format!("<TreeNodesModel>: skipped the unknown entry <{tag}>"),
                );
                continue;
            };
            let Some(id) = entry.attribute("ID") else {
                self.warn(
                    source,
                    at,
                    format!("<TreeNodesModel>: skipped <{tag}> without an ID"),
                );
                continue;
            };
            if self.model_index.contains_key(id) {
                self.warn(
                    source,
                    at,
                    format!("<TreeNodesModel>: skipped a second model of \"{id}\""),
                );
                continue;
            }
            let mut model = NodeModel::new(category, id);
            for item in entry.children().filter(Node::is_element) {
                let item_tag = item.tag_name().name();
                if item_tag == "description" {
                    model.description = text_of(item);
                    continue;
                }
                // Nav2 declares some ports as `bidirectional_port` (BehaviorTree.CPP's
                // BidirectionalPort, written `inout_port` by BehaviorTree.CPP itself).
                let direction = match item_tag {
                    "bidirectional_port" => Some(PortDirection::InOut),
                    tag => PortDirection::from_tag(tag),
                };
                let Some(direction) = direction else {
                    self.warn(
                        source,
                        item.range().start,
                        format!("<TreeNodesModel>: skipped <{item_tag}> in the model of \"{id}\""),
                    );
                    continue;
                };
                let Some(port) = item.attribute("name") else {
                    self.warn(
                        source,
                        item.range().start,
                        format!("<TreeNodesModel>: skipped a port without a name in \"{id}\""),
                    );
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
            self.add_model(model);
        }
    }

    fn add_model(&mut self, model: NodeModel) {
        self.model_index.insert(model.id.clone(), self.models.len());
        self.models.push(model);
    }

    /// Whether `id` is built in, registered or has a model already.
    fn known(&self, id: &str) -> bool {
        is_builtin(id) || self.registry.contains(id) || self.model_index.contains_key(id)
    }

    /// Adds the model from `options.node_models` of an ID the trees use, if that is where it
    /// is known from.
    fn use_external(&mut self, id: &str) {
        if !self.known(id)
            && let Some(model) = self.external.get(id)
        {
            let model = (*model).clone();
            self.add_model(model);
        }
    }

    /// Models for explicit-form leaves that are neither built in, registered nor declared,
    /// with the attributes used as ports.
    fn infer_models(&mut self, trees: &[Placed<'a>]) {
        let mut inferred: Vec<(NodeModel, HashSet<&'a str>)> = Vec::new();
        let mut index: HashMap<&'a str, usize> = HashMap::new();
        for &(_, tree) in trees {
            for node in tree.descendants().filter(Node::is_element) {
                let category = match node.tag_name().name() {
                    "Action" => NodeCategory::Action,
                    "Condition" => NodeCategory::Condition,
                    _ => continue,
                };
                let Some(id) = node.attribute("ID") else {
                    continue;
                };
                if self.known(id) || self.external.contains_key(id) {
                    continue;
                }
                let i = *index.entry(id).or_insert_with(|| {
                    inferred.push((NodeModel::new(category, id), HashSet::new()));
                    inferred.len() - 1
                });
                let (model, names) = &mut inferred[i];
                for attribute in node.attributes() {
                    let name = attribute.name();
                    if is_port_attribute(name) && names.insert(name) {
                        model.ports.push(PortSpec::inout(name));
                    }
                }
            }
        }
        for (model, _) in inferred {
            self.add_model(model);
        }
    }

    /// Reads a node and its descendants, appending them to `order` in depth-first pre-order.
    fn read_node(
        &mut self,
        source: usize,
        element: Node<'a, 'a>,
        depth: usize,
        order: &mut Vec<Placed<'a>>,
    ) -> Result<NodeDef, BtXmlError> {
        if depth > self.options.max_depth {
            return Err(self.error(
                source,
                element.range().start,
                BtXmlErrorKind::TooDeep {
                    limit: self.options.max_depth,
                },
            ));
        }
        self.check_namespace(source, element)?;
        order.push((source, element));
        let tag = element.tag_name().name();
        let (category, id, explicit) = match NodeCategory::from_tag(tag) {
            Some(category) => {
                let id = element.attribute("ID").ok_or_else(|| {
                    self.error_at(
                        (source, element),
                        None,
                        BtXmlErrorKind::MissingAttribute {
                            element: tag.to_owned(),
                            attribute: "ID",
                        },
                    )
                    .with_attribute("ID")
                })?;
                if category != NodeCategory::SubTree {
                    self.use_external(id);
                }
                (category, id, true)
            }
            None => {
                self.use_external(tag);
                match self.registry.lookup(tag, &[]) {
                    Ok(manifest) => (manifest.category, tag, false),
                    Err(kind) => match self.model_index.get(tag) {
                        Some(&i) => (self.models[i].category, tag, false),
                        None => {
                            let kind = match kind {
                                DefinitionErrorKind::UnknownNode { .. }
                                    if self.tree_ids.contains_key(tag) =>
                                {
                                    BtXmlErrorKind::TreeAsNode { id: tag.to_owned() }
                                }
                                kind => BtXmlErrorKind::Definition(kind),
                            };
                            return Err(self.error(source, element.range().start, kind));
                        }
                    },
                }
            }
        };
        let mut node = NodeDef::new(category, id);
        for attribute in element.attributes() {
            let name = attribute.name();
            let value = attribute.value();
            let bad = |expected| {
                Err(self.error_at(
                    (source, element),
                    Some(name),
                    BtXmlErrorKind::BadAttribute {
                        element: tag.to_owned(),
                        attribute: name.to_owned(),
                        value: value.to_owned(),
                        expected,
                    },
                ))
            };
            match name {
                "ID" if explicit => {}
                "name" => node.name = Some(value.to_owned()),
                "_autoremap" => {
                    if category != NodeCategory::SubTree {
                        return bad("_autoremap belongs to <SubTree> only");
                    }
                    node.autoremap = match value {
                        "1" | "true" | "True" | "TRUE" => true,
                        "0" | "false" | "False" | "FALSE" => false,
                        _ => return bad("expected true or false"),
                    };
                }
                n if SCRIPT_ATTRIBUTES.contains(&n) => {
                    node.scripts.push((name.to_owned(), value.to_owned()));
                }
                n if !is_port_attribute(n) => {} // metadata such as _uid, _fullpath
                _ => node.ports.push((name.to_owned(), value.to_owned())),
            }
        }
        for child in element.children().filter(Node::is_element) {
            let child_node = self.read_node(source, child, depth + 1, order)?;
            node.children.push(child_node);
        }
        Ok(node)
    }
}

/// Reads the document from its files (the first, then the included ones).
fn read_sources<'a>(
    registry: &Registry,
    options: &BtReadOptions,
    sources: &'a [&'a Source<'a>],
) -> Result<BtXml, BtXmlError> {
    let mut reader = Reader::new(registry, options, sources);
    let first_root = sources[0].doc.root_element();
    let main_tree = first_root
        .attribute("main_tree_to_execute")
        .map(str::to_owned);

    // Node models and tree IDs first, so that compact-form nodes resolve wherever they are
    // declared.
    let mut tree_elements: Vec<Placed<'a>> = Vec::new();
    for (index, source) in sources.iter().enumerate() {
        let root = source.doc.root_element();
        reader.check_root(index, root)?;
        for child in root.children().filter(Node::is_element) {
            reader.check_namespace(index, child)?;
            match child.tag_name().name() {
                "BehaviorTree" => {
                    let id = child.attribute("ID").ok_or_else(|| {
                        reader
                            .error_at(
                                (index, child),
                                None,
                                BtXmlErrorKind::MissingAttribute {
                                    element: "BehaviorTree".to_owned(),
                                    attribute: "ID",
                                },
                            )
                            .with_attribute("ID")
                    })?;
                    if let Some(&(first_source, first)) = reader.tree_ids.get(id) {
                        let s = sources[first_source];
                        let (line, column) = s.pos(first.range().start);
                        return Err(reader.error_at(
                            (index, child),
                            Some("ID"),
                            BtXmlErrorKind::DuplicateTree {
                                id: id.to_owned(),
                                first: format!("{}:{line}:{column}", s.name),
                            },
                        ));
                    }
                    reader.tree_ids.insert(id, (index, child));
                    tree_elements.push((index, child));
                }
                "TreeNodesModel" => reader.read_models(index, child),
                "include" => {} // followed by the loader
                other => {
                    return Err(reader.error(
                        index,
                        child.range().start,
                        BtXmlErrorKind::UnknownElement {
                            element: other.to_owned(),
                            parent: "root".to_owned(),
                        },
                    ));
                }
            }
        }
    }
    reader.infer_models(&tree_elements);

    let mut trees = Vec::with_capacity(tree_elements.len());
    let mut orders: Vec<Vec<Placed<'a>>> = Vec::with_capacity(tree_elements.len());
    for &(index, element) in &tree_elements {
        let id = element.attribute("ID").unwrap_or_default();
        let mut roots = element.children().filter(Node::is_element);
        let (Some(root_element), None) = (roots.next(), roots.next()) else {
            let found = element.children().filter(Node::is_element).count();
            return Err(reader.error(
                index,
                element.range().start,
                BtXmlErrorKind::TreeRoot {
                    id: id.to_owned(),
                    found,
                },
            ));
        };
        let mut order = Vec::new();
        let root_node = reader.read_node(index, root_element, 1, &mut order)?;
        trees.push(TreeDef::new(id, root_node));
        orders.push(order);
    }

    let document = BtDocument {
        main_tree,
        trees,
        node_models: std::mem::take(&mut reader.models),
    };
    let tree_index: HashMap<&str, usize> = document
        .trees
        .iter()
        .enumerate()
        .map(|(i, t)| (t.id.as_str(), i))
        .collect();
    validate(&document, registry).map_err(|e| {
        let placed = e.location().and_then(|location| {
            let &t = tree_index.get(location.tree.as_str())?;
            let i = preorder_index(&document.trees[t].root, &location.path)?;
            orders[t].get(i).copied()
        });
        let kind = BtXmlErrorKind::Definition(e.kind().clone());
        let error = match placed {
            Some(placed) => reader.error_at(placed, e.attribute(), kind),
            None => match e.attribute() {
                Some("main_tree_to_execute") => {
                    reader.error_at((0, first_root), Some("main_tree_to_execute"), kind)
                }
                _ => reader.error(0, first_root.range().start, kind),
            },
        };
        BtXmlError {
            attribute: e.attribute().map(str::to_owned),
            ..error
        }
    })?;

    // Line and column of every node: one forward pass per file (the nodes of a file come in
    // document order), so that this is linear in the size of the files.
    let mut cursors: Vec<(usize, Pos)> = vec![(0, (1, 1)); sources.len()];
    let mut places = HashMap::with_capacity(orders.len());
    for (t, (tree, order)) in document.trees.iter().zip(&orders).enumerate() {
        let file = tree_elements[t].0;
        let positions: Vec<Pos> = order
            .iter()
            .map(|&(source, element)| {
                advance(sources[source], &mut cursors[source], element.range().start)
            })
            .collect();
        places.insert(tree.id.clone(), (file, positions));
    }
    Ok(BtXml {
        document,
        warnings: reader.warnings,
        files: sources.iter().map(|s| s.name.clone()).collect(),
        places,
    })
}

/// Moves a `(offset, (line, column))` cursor forward to `offset` (or looks it up if it lies
/// behind) and returns its line and column.
fn advance(source: &Source<'_>, cursor: &mut (usize, Pos), offset: usize) -> Pos {
    if offset < cursor.0 {
        *cursor = (offset, source.pos(offset));
        return cursor.1;
    }
    let text = source.doc.input_text();
    let (mut line, mut column) = cursor.1;
    for c in text[cursor.0..offset].chars() {
        if c == '\n' {
            line += 1;
            column = 1;
        } else {
            column += 1;
        }
    }
    *cursor = (offset, (line, column));
    cursor.1
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
/// back as something else (`name`, `ID`, `_…`), script attributes other than
/// [`SCRIPT_ATTRIBUTES`], and an `_autoremap` on a node that is not a `SubTree`.
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
    for (attribute, code) in &node.scripts {
        if !SCRIPT_ATTRIBUTES.contains(&attribute.as_str()) {
            return Err(unwritable(format!(
                "\"{attribute}\" of \"{}\" is not a scripting attribute ({})",
                node.id,
                SCRIPT_ATTRIBUTES.join(", ")
            )));
        }
        write_attribute(out, attribute, code);
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
    for (port, value) in &node.ports() {
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
