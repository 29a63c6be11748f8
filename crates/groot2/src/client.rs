//! A client of Groot2 publishers: what a monitor needs to watch a running tree.
//!
//! It speaks to BehaviorTree.CPP 4's `Groot2Publisher` (and Nav2's, and chronomap's own
//! [`crate::publisher`]) over a ZeroMQ REQ socket at the publisher's port: the tree as XML
//! (`FULLTREE`), every node's status (`STATUS`), the blackboards (`BLACKBOARD`, MessagePack),
//! recording on and off (`TOGGLE_RECORDING`) and the recorded transitions
//! (`GET_TRANSITIONS`). Every request has a timeout, every reply is bounded (each part by
//! ZeroMQ's `ZMQ_MAXMSGSIZE`, which drops the connection of a peer sending more, and the
//! parts together here) and checked (the header must echo the request's type and id); a
//! publisher that does not answer, answers garbage or says `error` gives a [`ClientError`]
//! that names it, the request and what was wrong. After any error the socket is closed and
//! the next request opens a new one, so a publisher that went away and came back is found
//! again (a REQ socket that missed a reply cannot send again).
//!
//! Requests are encoded and replies decoded by [`crate::protocol`]; this module adds the
//! socket, the checks a monitor needs on top (status and transition codes, uids given
//! twice) and the tree that the `FULLTREE` XML describes ([`parse_tree`]).

use std::time::Duration;

pub use crate::protocol::MsgValue;
use crate::protocol::{self, ProtocolError, Reply, RequestHeader, RequestType};
pub use chronomap_bt::Status;

/// Default time a publisher has to answer one request.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(2);
/// Default largest reply (all parts together; a tree of 10,000 nodes is about 2 MB of XML).
pub const DEFAULT_MAX_REPLY_BYTES: usize = 16 << 20;
/// Most parts of a reply (a header and a payload, or `error` and a message).
pub const MAX_REPLY_PARTS: usize = 2;

/// How a [`Client`] talks to a publisher.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ClientOptions {
    /// Time the publisher has to answer one request.
    pub timeout: Duration,
    /// Largest reply in bytes, all parts together.
    pub max_reply_bytes: usize,
}

impl Default for ClientOptions {
    fn default() -> Self {
        ClientOptions {
            timeout: DEFAULT_TIMEOUT,
            max_reply_bytes: DEFAULT_MAX_REPLY_BYTES,
        }
    }
}

/// What went wrong talking to a publisher.
#[derive(Debug, thiserror::Error)]
pub enum ClientError {
    /// The address is not `HOST:PORT`.
    #[error("{address:?} is not the HOST:PORT of a Groot2 publisher: {reason}")]
    Address {
        /// As given.
        address: String,
        /// What is wrong with it.
        reason: String,
    },
    /// No reply in time.
    #[error(
        "the publisher at {address} did not answer {request} within {secs} s (is it running \
         and reachable? a reply over {max_bytes} bytes is refused and looks the same)"
    )]
    Timeout {
        /// The publisher.
        address: String,
        /// The request (`FULLTREE`, `STATUS`, ...).
        request: &'static str,
        /// The timeout.
        secs: f64,
        /// The reply limit.
        max_bytes: usize,
    },
    /// The publisher answered `error`.
    #[error("the publisher at {address} refused {request}: {message}")]
    Refused {
        /// The publisher.
        address: String,
        /// The request.
        request: &'static str,
        /// Its message (at most 200 characters of it).
        message: String,
    },
    /// The reply is not what the protocol says.
    #[error("the publisher at {address} sent a malformed {request} reply: {reason}")]
    Malformed {
        /// The publisher.
        address: String,
        /// The request.
        request: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// ZeroMQ failed.
    #[error("ZeroMQ failed talking to {address} ({request}): {source}")]
    Transport {
        /// The publisher.
        address: String,
        /// The request.
        request: &'static str,
        /// ZeroMQ's error.
        source: zmq::Error,
    },
}

/// The name of a request in messages: BehaviorTree.CPP's `RequestType`, upper case.
fn request_name(request: RequestType) -> &'static str {
    match request {
        RequestType::FullTree => "FULLTREE",
        RequestType::Status => "STATUS",
        RequestType::Blackboard => "BLACKBOARD",
        RequestType::ToggleRecording => "TOGGLE_RECORDING",
        RequestType::GetTransitions => "GET_TRANSITIONS",
        other => other.name(),
    }
}

/// A node's status in a `STATUS` reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StatusEntry {
    /// The node's `_uid`.
    pub uid: u16,
    /// Its status now.
    pub status: Status,
    /// For an idle node, the status it had before going back to idle (code 10 + status).
    pub last: Option<Status>,
}

/// A `STATUS` reply.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StatusReply {
    /// The tree's UUID.
    pub uuid: [u8; 16],
    /// Every node, in the publisher's order.
    pub entries: Vec<StatusEntry>,
}

/// A recorded transition.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Transition {
    /// Microseconds since the publisher started recording.
    pub usec: u64,
    /// The node's `_uid`.
    pub uid: u16,
    /// The status it went to.
    pub status: Status,
}

/// A node of a tree read from `FULLTREE`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TreeNode {
    /// Its `_uid`.
    pub uid: u16,
    /// Its type: the XML element's name.
    pub type_id: String,
    /// Its `name`; for a `SubTree` node the last step of its `_fullpath` without `::uid`;
    /// the type for other nodes without one.
    pub name: String,
    /// `Action`, `Condition`, `Control`, `Decorator` or `SubTree`, as the tree's
    /// `TreeNodesModel` says (`SubTree` always).
    pub kind: Option<String>,
    /// Its parent; a subtree's root has its `SubTree` node as parent.
    pub parent: Option<u16>,
    /// Its children in order (a `SubTree` node's child is the subtree's root).
    pub children: Vec<u16>,
    /// The `_fullpath` of the `BehaviorTree` it is in (`""` for the main tree).
    pub tree: String,
    /// Its other attributes, in order.
    pub ports: Vec<(String, String)>,
}

/// A `BehaviorTree` element of a `FULLTREE` reply.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Subtree {
    /// Its `ID`.
    pub id: String,
    /// Its `_fullpath` (`""` for the main tree).
    pub path: String,
    /// Its root node.
    pub root: Option<u16>,
}

/// A tree read from `FULLTREE`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tree {
    /// The main tree's `ID`.
    pub main: String,
    /// The main tree's root.
    pub root: u16,
    /// The main tree, then the subtrees, in document order.
    pub trees: Vec<Subtree>,
    /// Every node, `BehaviorTree` by `BehaviorTree` in document order (the order of the
    /// status buffer of BehaviorTree.CPP).
    pub nodes: Vec<TreeNode>,
}

/// A `FULLTREE` reply.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TreeReply {
    /// The tree's UUID.
    pub uuid: [u8; 16],
    /// The XML as sent.
    pub xml: String,
    /// The tree it describes.
    pub tree: Tree,
}

/// A Groot2 client of one publisher.
pub struct Client {
    address: String,
    endpoint: String,
    options: ClientOptions,
    context: zmq::Context,
    socket: Option<zmq::Socket>,
    next_id: u32,
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client")
            .field("address", &self.address)
            .field("options", &self.options)
            .field("connected", &self.socket.is_some())
            .finish()
    }
}

impl Client {
    /// A client of the publisher at `address` (`HOST:PORT`, its request port); connects at
    /// the first request.
    ///
    /// # Errors
    /// The address is not `HOST:PORT` with a port from 1 to 65535.
    pub fn new(address: &str, options: ClientOptions) -> Result<Client, ClientError> {
        let bad = |reason: &str| ClientError::Address {
            address: address.to_owned(),
            reason: reason.to_owned(),
        };
        let (host, port) = address.rsplit_once(':').ok_or_else(|| bad("no :PORT"))?;
        if host.is_empty() {
            return Err(bad("no host"));
        }
        match port.parse::<u16>() {
            Ok(p) if p > 0 => {}
            _ => return Err(bad("the port is not a number from 1 to 65535")),
        }
        let seed = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos())
            ^ std::process::id().rotate_left(16);
        Ok(Client {
            address: address.to_owned(),
            endpoint: format!("tcp://{address}"),
            options,
            context: zmq::Context::new(),
            socket: None,
            next_id: seed,
        })
    }

    /// The publisher's `HOST:PORT`.
    pub fn address(&self) -> &str {
        &self.address
    }

    /// A [`ClientError::Malformed`] for this publisher (for checks made by callers, such as
    /// statuses that do not match the tree).
    pub fn malformed(&self, request: &'static str, reason: String) -> ClientError {
        ClientError::Malformed {
            address: self.address.clone(),
            request,
            reason,
        }
    }

    /// Closes the connection; the next request opens a new one.
    pub fn disconnect(&mut self) {
        self.socket = None;
    }

    fn socket(&mut self, request: RequestType) -> Result<&zmq::Socket, ClientError> {
        if self.socket.is_none() {
            let transport = |source| ClientError::Transport {
                address: self.address.clone(),
                request: request_name(request),
                source,
            };
            let socket = self.context.socket(zmq::REQ).map_err(transport)?;
            let millis = i32::try_from(self.options.timeout.as_millis()).unwrap_or(i32::MAX);
            let max = i64::try_from(self.options.max_reply_bytes).unwrap_or(i64::MAX);
            socket.set_linger(0).map_err(transport)?;
            socket.set_rcvtimeo(millis).map_err(transport)?;
            socket.set_sndtimeo(millis).map_err(transport)?;
            socket.set_maxmsgsize(max).map_err(transport)?;
            socket.set_reconnect_ivl(100).map_err(transport)?;
            socket.set_reconnect_ivl_max(1000).map_err(transport)?;
            socket.connect(&self.endpoint).map_err(transport)?;
            self.socket = Some(socket);
        }
        Ok(self.socket.as_ref().expect("socket just made"))
    }

    /// Sends a request and returns the reply's tree UUID and payload (empty if it has none).
    fn call(
        &mut self,
        request: RequestType,
        body: Option<&[u8]>,
    ) -> Result<([u8; 16], Vec<u8>), ClientError> {
        let outcome = self.exchange(request, body);
        if outcome.is_err() {
            // A REQ socket that missed its reply (or got garbage) cannot send again.
            self.socket = None;
        }
        outcome
    }

    fn exchange(
        &mut self,
        request: RequestType,
        body: Option<&[u8]>,
    ) -> Result<([u8; 16], Vec<u8>), ClientError> {
        self.next_id = self
            .next_id
            .wrapping_mul(1_664_525)
            .wrapping_add(1_013_904_223);
        let header = RequestHeader::new(request, self.next_id);
        let parts = protocol::encode_request(request, self.next_id, body);
        let (address, options) = (self.address.clone(), self.options);
        let name = request_name(request);
        let transport = |source| ClientError::Transport {
            address: address.clone(),
            request: name,
            source,
        };
        let timeout = || ClientError::Timeout {
            address: address.clone(),
            request: name,
            secs: options.timeout.as_secs_f64(),
            max_bytes: options.max_reply_bytes,
        };
        let socket = self.socket(request)?;
        match socket.send_multipart(parts, 0) {
            Ok(()) => {}
            Err(zmq::Error::EAGAIN) => return Err(timeout()),
            Err(e) => return Err(transport(e)),
        }
        let mut parts: Vec<Vec<u8>> = Vec::with_capacity(2);
        let mut total = 0usize;
        loop {
            let part = match socket.recv_bytes(0) {
                Ok(part) => part,
                Err(zmq::Error::EAGAIN) => return Err(timeout()),
                Err(e) => return Err(transport(e)),
            };
            total += part.len();
            parts.push(part);
            if !socket.get_rcvmore().map_err(transport)? {
                break;
            }
            if parts.len() >= MAX_REPLY_PARTS || total > options.max_reply_bytes {
                return Err(self.malformed(
                    name,
                    format!(
                        "more than {MAX_REPLY_PARTS} parts or {} bytes",
                        options.max_reply_bytes
                    ),
                ));
            }
        }
        if total > options.max_reply_bytes {
            return Err(self.malformed(
                name,
                format!("{total} bytes, more than {}", options.max_reply_bytes),
            ));
        }
        match protocol::decode_reply(&parts, &header) {
            Ok(Reply::Answer { header, mut body }) => {
                if body.len() > 1 {
                    return Err(self.malformed(name, format!("{} parts", body.len() + 1)));
                }
                Ok((header.tree_uuid, body.pop().unwrap_or_default()))
            }
            Ok(Reply::Error(message)) => Err(ClientError::Refused {
                address: self.address.clone(),
                request: name,
                message: message.chars().take(200).collect(),
            }),
            Err(e) => Err(self.malformed(name, e.to_string())),
        }
    }

    fn protocol_error(&self, request: RequestType, e: &ProtocolError) -> ClientError {
        self.malformed(request_name(request), e.to_string())
    }

    /// The tree (`FULLTREE`).
    ///
    /// # Errors
    /// No reply in time, an error reply, or XML that is not a BehaviorTree.CPP 4 tree with
    /// `_uid`s (the message names the line).
    pub fn full_tree(&mut self) -> Result<TreeReply, ClientError> {
        let (uuid, payload) = self.call(RequestType::FullTree, None)?;
        let xml = String::from_utf8(payload)
            .map_err(|e| self.malformed("FULLTREE", format!("the XML is not UTF-8: {e}")))?;
        let tree = parse_tree(&xml).map_err(|reason| self.malformed("FULLTREE", reason))?;
        Ok(TreeReply { uuid, xml, tree })
    }

    /// Every node's status (`STATUS`).
    ///
    /// # Errors
    /// No reply in time, an error reply, or a buffer that is not 3 bytes per node, with
    /// an unknown status code or a uid given twice.
    pub fn status(&mut self) -> Result<StatusReply, ClientError> {
        let (uuid, payload) = self.call(RequestType::Status, None)?;
        let states = protocol::decode_status(&payload)
            .map_err(|e| self.protocol_error(RequestType::Status, &e))?;
        let entries = status_entries(&states).map_err(|reason| self.malformed("STATUS", reason))?;
        Ok(StatusReply { uuid, entries })
    }

    /// The blackboards of the (sub)trees named (`BLACKBOARD`): a map from each name the
    /// publisher knows to its entries.
    ///
    /// # Errors
    /// No reply in time, an error reply, or MessagePack that does not decode.
    pub fn blackboard(&mut self, names: &[String]) -> Result<MsgValue, ClientError> {
        let list = names.join(";");
        let (_, payload) = self.call(RequestType::Blackboard, Some(list.as_bytes()))?;
        protocol::decode_msgpack(&payload)
            .map_err(|e| self.protocol_error(RequestType::Blackboard, &e))
    }

    /// Turns recording on; returns the publisher's time then (microseconds since the unix
    /// epoch). Transitions recorded before are dropped by the publisher.
    ///
    /// # Errors
    /// No reply in time, an error reply, or no time in it.
    pub fn start_recording(&mut self) -> Result<u64, ClientError> {
        let (_, payload) = self.call(RequestType::ToggleRecording, Some(b"start"))?;
        protocol::decode_recording_start(&payload)
            .map_err(|e| self.protocol_error(RequestType::ToggleRecording, &e))
    }

    /// Turns recording off.
    ///
    /// # Errors
    /// No reply in time or an error reply.
    pub fn stop_recording(&mut self) -> Result<(), ClientError> {
        self.call(RequestType::ToggleRecording, Some(b"stop"))
            .map(|_| ())
    }

    /// The transitions recorded since the last such request (BehaviorTree.CPP keeps the
    /// last 1000).
    ///
    /// # Errors
    /// No reply in time, an error reply, or a buffer that is not 9 bytes per transition with
    /// known status codes.
    pub fn transitions(&mut self) -> Result<Vec<Transition>, ClientError> {
        let (_, payload) = self.call(RequestType::GetTransitions, None)?;
        let recorded = protocol::decode_transitions(&payload)
            .map_err(|e| self.protocol_error(RequestType::GetTransitions, &e))?;
        transitions_of(&recorded).map_err(|reason| self.malformed("GET_TRANSITIONS", reason))
    }
}

// ---------------------------------------------------------------------------------------------
// Checks on decoded replies (pure)

/// The statuses of a `STATUS` reply, checked: codes 0–4 and 10–14 only (10 + the last status
/// of a node that went back to idle), no uid twice.
///
/// # Errors
/// An unknown code or a uid given twice, naming the node and entry.
pub fn status_entries(states: &[protocol::NodeState]) -> Result<Vec<StatusEntry>, String> {
    let mut seen = vec![false; 1 << 16];
    states
        .iter()
        .enumerate()
        .map(|(i, state)| {
            let uid = state.uid;
            if std::mem::replace(&mut seen[usize::from(uid)], true) {
                return Err(format!("node uid {uid} is given twice (entry {i})"));
            }
            let status = state.status().ok_or_else(|| {
                format!(
                    "node uid {uid} (entry {i}) has status code {}, not 0-4 or 10-14",
                    state.code
                )
            })?;
            let last = if state.code >= 10 {
                state.idle_after()
            } else {
                None
            };
            Ok(StatusEntry { uid, status, last })
        })
        .collect()
}

/// The transitions of a `GET_TRANSITIONS` reply, checked: status codes 0–4 only.
///
/// # Errors
/// An unknown code, naming the transition and node.
pub fn transitions_of(
    recorded: &[protocol::RecordedTransition],
) -> Result<Vec<Transition>, String> {
    recorded
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let status = Status::from_code(t.status).ok_or_else(|| {
                format!(
                    "transition {i} (node uid {}) has status code {}, not 0-4",
                    t.uid, t.status
                )
            })?;
            Ok(Transition {
                usec: t.time_us,
                uid: t.uid,
                status,
            })
        })
        .collect()
}

/// Most XML nodes (elements, attributes' owners, text) of a `FULLTREE` reply.
pub const MAX_XML_NODES: u32 = 2_000_000;

/// Attributes of a node element that are not ports.
const NOT_PORTS: [&str; 3] = ["name", "_uid", "_fullpath"];

/// The tree a `FULLTREE` reply describes: the `BehaviorTree` elements of BehaviorTree.CPP's
/// `WriteTreeToXML` (with `_uid` on every node and `_fullpath` on trees and `SubTree` nodes),
/// each `SubTree` node linked to the `BehaviorTree` of the same `_fullpath`, kinds from the
/// `TreeNodesModel`.
///
/// # Errors
/// XML that does not parse, no `BehaviorTree`, a node without a valid `_uid`, a uid given
/// twice, a subtree used twice (each naming the line).
pub fn parse_tree(xml: &str) -> Result<Tree, String> {
    let options = roxmltree::ParsingOptions {
        allow_dtd: false,
        nodes_limit: MAX_XML_NODES,
        ..roxmltree::ParsingOptions::default()
    };
    let document = roxmltree::Document::parse_with_options(xml, options)
        .map_err(|e| format!("the tree's XML does not parse: {e}"))?;
    let line = |node: roxmltree::Node| document.text_pos_at(node.range().start).row;
    let root = document.root_element();
    let mut kinds: std::collections::HashMap<&str, &str> = std::collections::HashMap::new();
    for model in root.children().filter(|n| n.has_tag_name("TreeNodesModel")) {
        for entry in model.children().filter(roxmltree::Node::is_element) {
            if let Some(id) = entry.attribute("ID") {
                kinds.insert(id, entry.tag_name().name());
            }
        }
    }
    let mut trees = Vec::new();
    let mut nodes: Vec<TreeNode> = Vec::new();
    let mut index_of: std::collections::HashMap<u16, usize> = std::collections::HashMap::new();
    // SubTree nodes by the path of the tree they stand for.
    let mut subtree_nodes: Vec<(u16, String, u32)> = Vec::new();
    for tree in root.children().filter(|n| n.has_tag_name("BehaviorTree")) {
        let id = tree
            .attribute("ID")
            .ok_or_else(|| format!("line {}: a BehaviorTree without ID", line(tree)))?;
        let path = tree.attribute("_fullpath").unwrap_or("").to_owned();
        let mut root_uid = None;
        // Depth-first, in document order, with an explicit stack (no recursion on depth).
        let mut stack: Vec<(roxmltree::Node, Option<u16>)> = tree
            .children()
            .filter(roxmltree::Node::is_element)
            .map(|n| (n, None))
            .collect();
        stack.reverse();
        while let Some((element, parent)) = stack.pop() {
            let uid_text = element.attribute("_uid").ok_or_else(|| {
                format!(
                    "line {}: node <{}> has no _uid",
                    line(element),
                    element.tag_name().name()
                )
            })?;
            let uid: u16 = uid_text.parse().map_err(|_| {
                format!(
                    "line {}: node <{}> has _uid {uid_text:?}, not a number from 0 to 65535",
                    line(element),
                    element.tag_name().name()
                )
            })?;
            if index_of.insert(uid, nodes.len()).is_some() {
                return Err(format!(
                    "line {}: node uid {uid} is given twice",
                    line(element)
                ));
            }
            let type_id = element.tag_name().name().to_owned();
            let kind = if type_id == "SubTree" {
                Some("SubTree".to_owned())
            } else {
                kinds.get(type_id.as_str()).map(|k| (*k).to_owned())
            };
            if type_id == "SubTree" {
                let target = element
                    .attribute("_fullpath")
                    .ok_or_else(|| {
                        format!("line {}: a SubTree node without _fullpath", line(element))
                    })?
                    .to_owned();
                subtree_nodes.push((uid, target, line(element)));
            }
            match parent {
                Some(p) => nodes[index_of[&p]].children.push(uid),
                None => {
                    if root_uid.replace(uid).is_some() {
                        return Err(format!(
                            "line {}: BehaviorTree {id:?} has more than one root node",
                            line(element)
                        ));
                    }
                }
            }
            // A SubTree node has no `name`: BehaviorTree.CPP keeps it as the last step of
            // `_fullpath` (`dock`, `patrol/dock`), or the ID and `::uid` when it had none.
            let name = match element.attribute("name") {
                Some(name) => name.to_owned(),
                None if type_id == "SubTree" => {
                    let path = element.attribute("_fullpath").unwrap_or("");
                    let last = path.rsplit('/').next().unwrap_or(path);
                    let last = last.split("::").next().unwrap_or(last);
                    if last.is_empty() {
                        type_id.clone()
                    } else {
                        last.to_owned()
                    }
                }
                None => type_id.clone(),
            };
            nodes.push(TreeNode {
                uid,
                name,
                type_id,
                kind,
                parent,
                children: Vec::new(),
                tree: path.clone(),
                ports: element
                    .attributes()
                    .filter(|a| !NOT_PORTS.contains(&a.name()))
                    .map(|a| (a.name().to_owned(), a.value().to_owned()))
                    .collect(),
            });
            let children: Vec<_> = element
                .children()
                .filter(roxmltree::Node::is_element)
                .collect();
            stack.extend(children.into_iter().rev().map(|c| (c, Some(uid))));
        }
        trees.push(Subtree {
            id: id.to_owned(),
            path,
            root: root_uid,
        });
    }
    if trees.is_empty() {
        return Err("the tree's XML has no BehaviorTree".into());
    }
    for (uid, target, at) in subtree_nodes {
        let Some(tree) = trees.iter().find(|t| t.path == target) else {
            continue; // a subtree the publisher did not send: shown as a leaf
        };
        let Some(child) = tree.root else { continue };
        let child_node = &mut nodes[index_of[&child]];
        if child_node.parent.is_some() || child == uid {
            return Err(format!(
                "line {at}: the subtree {target:?} is used by more than one SubTree node"
            ));
        }
        child_node.parent = Some(uid);
        nodes[index_of[&uid]].children.push(child);
    }
    let main = trees
        .iter()
        .find(|t| t.path.is_empty())
        .unwrap_or(&trees[0]);
    let root = main
        .root
        .ok_or_else(|| format!("the main tree {:?} has no node", main.id))?;
    // Every node reached from the root once: no SubTree node leads back to a tree above it.
    let mut seen = vec![false; nodes.len()];
    let mut stack = vec![root];
    while let Some(uid) = stack.pop() {
        let i = index_of[&uid];
        if std::mem::replace(&mut seen[i], true) {
            return Err(format!(
                "node uid {uid} is reached twice: the subtrees form a cycle"
            ));
        }
        stack.extend(nodes[i].children.iter().copied());
    }
    Ok(Tree {
        main: main.id.clone(),
        root,
        trees,
        nodes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use chronomap_testutil::{BtcppTree, bt_python, free_port_pair};
    use std::io::{Read, Write};

    #[test]
    fn statuses_keep_the_last_status_of_idle_nodes() {
        // uid 1 running, uid 2 idle after success (12), uid 3 idle after failure (13),
        // uid 300 skipped, uid 4 idle after running (11: halted), uid 5 idle.
        let buffer = [1, 0, 1, 2, 0, 12, 3, 0, 13, 44, 1, 4, 4, 0, 11, 5, 0, 0];
        let entries = status_entries(&protocol::decode_status(&buffer).unwrap()).unwrap();
        let expected = [
            (1, Status::Running, None),
            (2, Status::Idle, Some(Status::Success)),
            (3, Status::Idle, Some(Status::Failure)),
            (300, Status::Skipped, None),
            (4, Status::Idle, Some(Status::Running)),
            (5, Status::Idle, None),
        ];
        assert_eq!(entries.len(), expected.len());
        for (e, (uid, status, last)) in entries.iter().zip(expected) {
            assert_eq!((e.uid, e.status, e.last), (uid, status, last));
        }
        let check = |bytes: &[u8]| status_entries(&protocol::decode_status(bytes).unwrap());
        assert_eq!(
            check(&[7, 0, 9]).unwrap_err(),
            "node uid 7 (entry 0) has status code 9, not 0-4 or 10-14"
        );
        assert_eq!(
            check(&[7, 0, 1, 7, 0, 2]).unwrap_err(),
            "node uid 7 is given twice (entry 1)"
        );
    }

    #[test]
    fn transitions_have_48_bit_offsets_and_known_statuses() {
        // 0x0102030405 µs = 4,328,719,365 µs, node 0x0203 = 515, FAILURE.
        let buffer = [0x05, 0x04, 0x03, 0x02, 0x01, 0x00, 0x03, 0x02, 3];
        let t = transitions_of(&protocol::decode_transitions(&buffer).unwrap()).unwrap();
        let expected = Transition {
            usec: 4_328_719_365,
            uid: 515,
            status: Status::Failure,
        };
        assert_eq!(t, vec![expected]);
        let mut bad = buffer;
        bad[8] = 14;
        assert_eq!(
            transitions_of(&protocol::decode_transitions(&bad).unwrap()).unwrap_err(),
            "transition 0 (node uid 515) has status code 14, not 0-4"
        );
    }

    /// BehaviorTree.CPP 4.8.2's `WriteTreeToXML` of a tree with a subtree (abridged model).
    const XML: &str = r#"<root BTCPP_format="4">
    <BehaviorTree ID="Main" _fullpath="">
        <Sequence name="seq" _uid="1">
            <Script name="Script" _uid="2" code="x:=42"/>
            <Fallback name="Fallback" _uid="3">
                <Act name="a1" _uid="4"/>
            </Fallback>
            <SubTree ID="Sub" _fullpath="Sub::5" _uid="5" x="{x}"/>
        </Sequence>
    </BehaviorTree>
    <BehaviorTree ID="Sub" _fullpath="Sub::5">
        <Inverter name="Inverter" _uid="6">
            <Act name="Act" _uid="7"/>
        </Inverter>
    </BehaviorTree>
    <TreeNodesModel>
        <Action ID="Act"/>
        <Control ID="Fallback"/>
        <Decorator ID="Inverter"/>
        <Action ID="Script"><input_port name="code" type="std::string"/></Action>
        <Control ID="Sequence"/>
    </TreeNodesModel>
</root>"#;

    #[test]
    fn trees_link_subtrees_below_their_subtree_node() {
        let tree = parse_tree(XML).unwrap();
        assert_eq!(tree.main, "Main");
        assert_eq!(tree.root, 1);
        let uids: Vec<u16> = tree.nodes.iter().map(|n| n.uid).collect();
        assert_eq!(uids, [1, 2, 3, 4, 5, 6, 7]);
        let node = |uid: u16| tree.nodes.iter().find(|n| n.uid == uid).unwrap();
        assert_eq!(node(1).children, [2, 3, 5]);
        assert_eq!(node(5).children, [6]);
        assert_eq!(node(6).parent, Some(5));
        assert_eq!(node(6).tree, "Sub::5");
        assert_eq!(node(4).name, "a1");
        assert_eq!(node(4).kind.as_deref(), Some("Action"));
        assert_eq!(node(3).kind.as_deref(), Some("Control"));
        assert_eq!(node(5).kind.as_deref(), Some("SubTree"));
        assert_eq!(node(5).name, "Sub");
        assert_eq!(
            node(5).ports,
            [
                ("ID".to_owned(), "Sub".to_owned()),
                ("x".to_owned(), "{x}".to_owned())
            ]
        );
        assert_eq!(tree.trees[1].root, Some(6));

        let no_uid = XML.replace(r#"<Act name="a1" _uid="4"/>"#, r#"<Act name="a1"/>"#);
        assert_eq!(
            parse_tree(&no_uid).unwrap_err(),
            "line 6: node <Act> has no _uid"
        );
        let twice = XML.replace(r#"_uid="7""#, r#"_uid="2""#);
        assert_eq!(
            parse_tree(&twice).unwrap_err(),
            "line 13: node uid 2 is given twice"
        );
        let cycle = XML.replace(
            r#"<Act name="Act" _uid="7"/>"#,
            r#"<SubTree ID="Main" _fullpath="" _uid="7"/>"#,
        );
        assert_eq!(
            parse_tree(&cycle).unwrap_err(),
            "node uid 1 is reached twice: the subtrees form a cycle"
        );
        assert!(
            parse_tree("<root/>")
                .unwrap_err()
                .contains("no BehaviorTree")
        );
        assert!(
            parse_tree("<root><BehaviorTree")
                .unwrap_err()
                .contains("does not parse")
        );
    }

    // ---- against real publishers and broken ones ----------------------------------------

    fn quick() -> ClientOptions {
        ClientOptions {
            timeout: Duration::from_millis(700),
            max_reply_bytes: 1 << 20,
        }
    }

    #[test]
    fn a_real_behaviortree_cpp_publisher_is_read_whole() {
        let Some(python) = bt_python() else { return };
        let port = free_port_pair();
        let _tree = BtcppTree::start(&python, port, Some("patrol"));
        let mut client =
            Client::new(&format!("127.0.0.1:{port}"), ClientOptions::default()).unwrap();
        let reply = client.full_tree().unwrap();
        let tree = &reply.tree;
        // 43 nodes with uids 1..=43: 37 in Patrol (the SubTree node 5 among them), then the 6
        // of the Dock subtree, which BT.CPP numbers 6..=11 when it instantiates it.
        assert_eq!(tree.main, "Patrol");
        assert_eq!(tree.nodes.len(), 43);
        let mut uids: Vec<u16> = tree.nodes.iter().map(|n| n.uid).collect();
        uids.sort_unstable();
        assert_eq!(uids, (1..=43).collect::<Vec<u16>>());
        let node = |name: &str| tree.nodes.iter().find(|n| n.name == name).unwrap();
        assert_eq!(node("dock").uid, 5);
        assert_eq!(node("dock").children, [6]);
        assert_eq!(node("docking").parent, Some(5));
        assert_eq!(node("docking").tree, "dock");
        assert_eq!(node("go_kitchen").type_id, "MoveTo");
        assert_eq!(node("go_kitchen").kind.as_deref(), Some("Action"));
        assert_eq!(node("battery_ok").kind.as_deref(), Some("Condition"));
        assert_eq!(node("patrol_round").children.len(), 12);
        // Statuses: the same uids in the same order as the tree's nodes.
        let status = client.status().unwrap();
        assert_eq!(status.uuid, reply.uuid);
        let order: Vec<u16> = status.entries.iter().map(|e| e.uid).collect();
        assert_eq!(order, tree.nodes.iter().map(|n| n.uid).collect::<Vec<_>>());
        // The blackboards of both trees, by the names Groot2 uses.
        let names: Vec<String> = vec!["Patrol".into(), "dock".into()];
        let boards = client.blackboard(&names).unwrap();
        let MsgValue::Map(boards) = boards else {
            panic!("{boards:?}")
        };
        let patrol = &boards
            .iter()
            .find(|(k, _)| *k == MsgValue::Str("Patrol".into()))
            .unwrap()
            .1;
        let MsgValue::Map(entries) = patrol else {
            panic!()
        };
        assert!(entries.contains(&(MsgValue::Str("robot".into()), MsgValue::Str("tiago".into()))));
        // Recording: transitions arrive, each of a node of the tree, times increasing.
        let started = client.start_recording().unwrap();
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap();
        assert!((started as f64 / 1e6 - now.as_secs_f64()).abs() < 5.0);
        std::thread::sleep(Duration::from_millis(600));
        let transitions = client.transitions().unwrap();
        assert!(transitions.len() > 10, "{transitions:?}");
        assert!(transitions.windows(2).all(|w| w[0].usec <= w[1].usec));
        assert!(transitions.iter().all(|t| (1..=43).contains(&t.uid)));
        client.stop_recording().unwrap();
    }

    /// A REP server on `port` that answers each request with `reply(request parts)`.
    fn fake_publisher(
        port: u16,
        replies: usize,
        reply: impl Fn(&[Vec<u8>]) -> Option<Vec<Vec<u8>>> + Send + 'static,
    ) -> std::thread::JoinHandle<()> {
        let context = zmq::Context::new();
        let socket = context.socket(zmq::REP).unwrap();
        socket.set_linger(0).unwrap();
        socket.bind(&format!("tcp://127.0.0.1:{port}")).unwrap();
        std::thread::spawn(move || {
            for _ in 0..replies {
                let request = socket.recv_multipart(0).unwrap();
                match reply(&request) {
                    Some(parts) => socket.send_multipart(parts, 0).unwrap(),
                    None => {
                        // Silent past the client's timeout; a REP socket must still answer
                        // before it receives again (to a peer that is gone by then).
                        std::thread::sleep(Duration::from_millis(800));
                        socket.send(&b"late"[..], 0).unwrap();
                    }
                }
            }
            drop(socket);
            drop(context);
        })
    }

    fn echo_header(request: &[Vec<u8>]) -> Vec<u8> {
        let mut header = request[0].clone();
        header.extend([0xab; 16]);
        header
    }

    #[test]
    fn garbage_errors_and_silence_are_reported_and_the_client_recovers() {
        // 1: garbage; 2: a wrong status code; 3: an error; 4: nothing; 5: a good reply.
        let port = free_port_pair();
        let address = format!("127.0.0.1:{port}");
        let count = std::sync::Arc::new(std::sync::atomic::AtomicUsize::new(0));
        let seen = std::sync::Arc::clone(&count);
        let server = fake_publisher(port, 5, move |request| {
            match seen.fetch_add(1, std::sync::atomic::Ordering::SeqCst) {
                0 => Some(vec![b"\x00garbage".to_vec()]),
                1 => Some(vec![echo_header(request), vec![1, 0, 99]]),
                2 => Some(vec![b"error".to_vec(), b"Request not recognized".to_vec()]),
                3 => None,
                _ => Some(vec![echo_header(request), vec![1, 0, 2, 2, 0, 12]]),
            }
        });
        let mut client = Client::new(&address, quick()).unwrap();
        let e = client.status().unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "the publisher at {address} sent a malformed STATUS reply: a reply header has 8 \
                 bytes, expected 22"
            )
        );
        let e = client.status().unwrap_err().to_string();
        assert!(
            e.ends_with("node uid 1 (entry 0) has status code 99, not 0-4 or 10-14"),
            "{e}"
        );
        let e = client.status().unwrap_err().to_string();
        assert_eq!(
            e,
            format!("the publisher at {address} refused STATUS: Request not recognized")
        );
        let e = client.status().unwrap_err();
        assert!(
            matches!(
                e,
                ClientError::Timeout {
                    request: "STATUS",
                    ..
                }
            ),
            "{e}"
        );
        // A new socket after the silence: the publisher's next answer is read.
        let ok = client.status().unwrap();
        assert_eq!(ok.entries[1].last, Some(Status::Success));
        server.join().unwrap();
        assert_eq!(count.load(std::sync::atomic::Ordering::SeqCst), 5);
    }

    #[test]
    fn oversized_replies_and_non_zeromq_peers_time_out_within_bounds() {
        // A reply of 4 MiB to a client that takes 1 MiB: ZeroMQ drops the connection.
        let port = free_port_pair();
        let server = fake_publisher(port, 1, |request| {
            Some(vec![echo_header(request), vec![b'x'; 4 << 20]])
        });
        let mut client = Client::new(&format!("127.0.0.1:{port}"), quick()).unwrap();
        let started = std::time::Instant::now();
        let e = client.full_tree().unwrap_err();
        assert!(
            matches!(
                e,
                ClientError::Timeout {
                    request: "FULLTREE",
                    ..
                }
            ),
            "{e}"
        );
        assert!(started.elapsed() < Duration::from_secs(3));
        server.join().unwrap();

        // A TCP server that sends bytes that are not ZeroMQ at all.
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let junk = std::thread::spawn(move || {
            if let Ok((mut stream, _)) = listener.accept() {
                let _ = stream.write_all(&[0xff; 64 * 1024]);
                let mut sink = [0u8; 1024];
                let _ = stream.set_read_timeout(Some(Duration::from_secs(2)));
                let _ = stream.read(&mut sink);
            }
        });
        let mut client = Client::new(&format!("127.0.0.1:{port}"), quick()).unwrap();
        let e = client.status().unwrap_err();
        assert!(matches!(e, ClientError::Timeout { .. }), "{e}");
        junk.join().unwrap();

        // Nobody at all.
        let port = free_port_pair();
        let mut client = Client::new(&format!("127.0.0.1:{port}"), quick()).unwrap();
        let e = client.status().unwrap_err().to_string();
        assert!(e.contains("did not answer STATUS within 0.7 s"), "{e}");
        assert!(
            Client::new("localhost", quick())
                .unwrap_err()
                .to_string()
                .contains("no :PORT")
        );
    }
}
