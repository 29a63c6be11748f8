//! The messages of Groot2's live protocol (protocol 2, BehaviorTree.CPP 4.8.2's
//! `Groot2Publisher`), encoded and decoded without I/O.
//!
//! # Requests and replies
//! Every request is a ZeroMQ multipart message whose first part is a 6-byte [`RequestHeader`]:
//! the protocol (2), the request type as an ASCII letter ([`RequestType`]) and a 32-bit id
//! (little-endian) that the reply echoes. Some requests carry a second part (the blackboard
//! names, a hook as JSON, `start`/`stop`). A reply's first part is a 22-byte [`ReplyHeader`]:
//! the request header with the protocol set to 2, then the 16-byte UUID of the tree; the
//! answer follows in a second part. A request the server cannot answer gets the two parts
//! `error` and a message instead ([`Reply::Error`]).
//!
//! | request | second part | answer |
//! |---|---|---|
//! | `T` FULLTREE | | the tree as XML, as `WriteTreeToXML(tree, true, true)` writes it ([`encode_full_tree`]) |
//! | `S` STATUS | | 3 bytes a node: uid (`u16` LE) and status ([`StatusBuffer`]) |
//! | `B` BLACKBOARD | names separated by `;` | MessagePack map of name → blackboard ([`encode_blackboards`]) |
//! | `I` HOOK_INSERT | a [`Hook`] or an array of them as JSON | nothing |
//! | `R` HOOK_REMOVE | `{"uid":…,"position":…}` | nothing |
//! | `U` BREAKPOINT_UNLOCK | `{"uid","desired_status","position","remove_when_done"}` | nothing |
//! | `D` HOOKS_DUMP | | the pre-tick hooks as a JSON array |
//! | `A` REMOVE_ALL_HOOKS, `X` DISABLE_ALL_HOOKS | | nothing |
//! | `r` TOGGLE_RECORDING | `start` or `stop` | for `start`: the server's time in µs since the Unix epoch, as text |
//! | `t` GET_TRANSITIONS | | 9 bytes a transition recorded since the last request ([`encode_transitions`]) |
//!
//! `N` BREAKPOINT_REACHED is not a request: the server publishes it (header and the node's uid
//! as text) on its PUB socket when a breakpoint stops a node.
//!
//! # Bounds
//! Decoding never panics and allocates at most in proportion to its input: a request has at
//! most [`MAX_REQUEST_PARTS`] parts of at most [`MAX_REQUEST_PART_SIZE`] bytes; MessagePack is
//! read at most [`MAX_MSGPACK_DEPTH`] levels deep, and a length is checked against the bytes
//! left before anything is allocated for it.

use std::fmt;

use chronomap_bt::Status;
use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The protocol number of the header (`kProtocolID`).
pub const PROTOCOL_ID: u8 = 2;

/// Size of a [`RequestHeader`] on the wire.
pub const REQUEST_HEADER_SIZE: usize = 6;

/// Size of a [`ReplyHeader`] on the wire (the request header and the 16-byte tree UUID).
pub const REPLY_HEADER_SIZE: usize = REQUEST_HEADER_SIZE + 16;

/// The most parts a request may have (BehaviorTree.CPP's requests have one or two).
pub const MAX_REQUEST_PARTS: usize = 8;

/// The largest part of a request, in bytes. A request's second part is a list of blackboard
/// names or a hook as JSON: a few hundred bytes.
pub const MAX_REQUEST_PART_SIZE: usize = 1 << 20;

/// The deepest nesting of arrays and maps [`decode_msgpack`] reads.
pub const MAX_MSGPACK_DEPTH: usize = 64;

/// The most transitions a server keeps between two GET_TRANSITIONS requests (the oldest are
/// dropped), as BehaviorTree.CPP.
pub const MAX_RECORDED_TRANSITIONS: usize = 1000;

/// The 16-byte identifier of a tree that every reply carries.
pub type TreeUuid = [u8; 16];

/// The type of a request: an ASCII letter on the wire (BehaviorTree.CPP's `Monitor::RequestType`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RequestType {
    /// `T`: the tree as XML.
    FullTree,
    /// `S`: the status of every node.
    Status,
    /// `B`: the values of a set of blackboards.
    Blackboard,
    /// `I`: insert (or update) hooks.
    HookInsert,
    /// `R`: remove a hook.
    HookRemove,
    /// `N`: published by the server when a breakpoint is reached (not a request).
    BreakpointReached,
    /// `U`: unlock a breakpoint.
    BreakpointUnlock,
    /// `D`: the hooks as JSON.
    HooksDump,
    /// `A`: remove every hook (a client does this before it disconnects).
    RemoveAllHooks,
    /// `X`: disable every hook.
    DisableAllHooks,
    /// `r`: start or stop recording transitions.
    ToggleRecording,
    /// `t`: the transitions recorded since the last such request.
    GetTransitions,
}

impl RequestType {
    /// Every request type, in BehaviorTree.CPP's order.
    pub const ALL: [RequestType; 12] = [
        RequestType::FullTree,
        RequestType::Status,
        RequestType::Blackboard,
        RequestType::HookInsert,
        RequestType::HookRemove,
        RequestType::BreakpointReached,
        RequestType::BreakpointUnlock,
        RequestType::HooksDump,
        RequestType::RemoveAllHooks,
        RequestType::DisableAllHooks,
        RequestType::ToggleRecording,
        RequestType::GetTransitions,
    ];

    /// The byte on the wire.
    pub fn code(self) -> u8 {
        match self {
            RequestType::FullTree => b'T',
            RequestType::Status => b'S',
            RequestType::Blackboard => b'B',
            RequestType::HookInsert => b'I',
            RequestType::HookRemove => b'R',
            RequestType::BreakpointReached => b'N',
            RequestType::BreakpointUnlock => b'U',
            RequestType::HooksDump => b'D',
            RequestType::RemoveAllHooks => b'A',
            RequestType::DisableAllHooks => b'X',
            RequestType::ToggleRecording => b'r',
            RequestType::GetTransitions => b't',
        }
    }

    /// The type of a byte; `None` for bytes that name none.
    pub fn from_code(code: u8) -> Option<RequestType> {
        RequestType::ALL.into_iter().find(|t| t.code() == code)
    }

    /// BehaviorTree.CPP's name (`Monitor::ToString`): `full_tree`, `status`, …
    pub fn name(self) -> &'static str {
        match self {
            RequestType::FullTree => "full_tree",
            RequestType::Status => "status",
            RequestType::Blackboard => "blackboard",
            RequestType::HookInsert => "hook_insert",
            RequestType::HookRemove => "hook_remove",
            RequestType::BreakpointReached => "breakpoint_reached",
            RequestType::BreakpointUnlock => "breakpoint_unlock",
            RequestType::HooksDump => "hooks_dump",
            RequestType::RemoveAllHooks => "hooks_remove_all",
            RequestType::DisableAllHooks => "disable_hooks",
            RequestType::ToggleRecording => "toggle_recording",
            RequestType::GetTransitions => "get_transitions",
        }
    }

    /// Whether the request carries a second part (and BehaviorTree.CPP refuses it without).
    pub fn needs_body(self) -> bool {
        matches!(
            self,
            RequestType::Blackboard
                | RequestType::HookInsert
                | RequestType::HookRemove
                | RequestType::BreakpointUnlock
                | RequestType::ToggleRecording
        )
    }
}

impl fmt::Display for RequestType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} ({:?})", self.name(), char::from(self.code()))
    }
}

/// Why a message could not be decoded.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
#[non_exhaustive]
pub enum ProtocolError {
    /// A header (or fixed-size record) of the wrong size.
    #[error("{what} has {got} bytes, expected {expected}")]
    WrongSize {
        /// What was decoded.
        what: &'static str,
        /// The size it must have.
        expected: usize,
        /// The size it has.
        got: usize,
    },
    /// A protocol other than [`PROTOCOL_ID`].
    #[error("protocol {got}, expected {PROTOCOL_ID}")]
    WrongProtocol {
        /// The protocol byte received.
        got: u8,
    },
    /// A request-type byte that names no request the server answers.
    #[error("unknown request type 0x{code:02x}")]
    UnknownType {
        /// The byte received.
        code: u8,
    },
    /// A message with no parts.
    #[error("empty message")]
    Empty,
    /// More parts than a message may have.
    #[error("{got} parts, at most {max}")]
    TooManyParts {
        /// The number of parts.
        got: usize,
        /// The limit.
        max: usize,
    },
    /// A part larger than allowed.
    #[error("part {part} has {size} bytes, at most {max}")]
    Oversized {
        /// The part (0 = header).
        part: usize,
        /// Its size.
        size: usize,
        /// The limit.
        max: usize,
    },
    /// A request of a type that needs two parts came with another number.
    #[error("{kind} must be a 2-part message, got {got} parts")]
    PartCount {
        /// The request type.
        kind: RequestType,
        /// The number of parts.
        got: usize,
    },
    /// A reply whose header does not echo the request.
    #[error("the reply answers request {got_type:?} #{got_id}, not {want_type:?} #{want_id}")]
    Mismatch {
        /// The type asked.
        want_type: char,
        /// The id asked.
        want_id: u32,
        /// The type answered.
        got_type: char,
        /// The id answered.
        got_id: u32,
    },
    /// A body that does not parse (JSON, MessagePack, text, records).
    #[error("{what}: {reason}")]
    Malformed {
        /// What was decoded.
        what: &'static str,
        /// What is wrong, with the byte offset where useful.
        reason: String,
    },
}

impl ProtocolError {
    fn malformed(what: &'static str, reason: impl Into<String>) -> ProtocolError {
        ProtocolError::Malformed {
            what,
            reason: reason.into(),
        }
    }

    /// The text of the `error` reply a server sends for this error: BehaviorTree.CPP's words
    /// where it answers the same request with an error (`wrong request header`, `must be 2
    /// parts message`, `Request not recognized`), this error's own message otherwise.
    pub fn reply_text(&self) -> String {
        match self {
            ProtocolError::WrongSize { .. } | ProtocolError::Empty => {
                "wrong request header".to_owned()
            }
            ProtocolError::UnknownType { .. } => "Request not recognized".to_owned(),
            ProtocolError::PartCount { .. } => "must be 2 parts message".to_owned(),
            other => other.to_string(),
        }
    }
}

/// The first part of a request (`Monitor::RequestHeader`): protocol, type, id.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RequestHeader {
    /// The protocol byte ([`PROTOCOL_ID`]).
    pub protocol: u8,
    /// The request-type byte ([`RequestType::code`]); kept raw so that an unknown type can
    /// be echoed.
    pub type_code: u8,
    /// The request id, echoed by the reply.
    pub unique_id: u32,
}

impl RequestHeader {
    /// A header of protocol 2.
    pub fn new(kind: RequestType, unique_id: u32) -> RequestHeader {
        RequestHeader {
            protocol: PROTOCOL_ID,
            type_code: kind.code(),
            unique_id,
        }
    }

    /// The request type, if the byte names one.
    pub fn kind(&self) -> Option<RequestType> {
        RequestType::from_code(self.type_code)
    }

    /// The 6 bytes on the wire: protocol, type, id (little-endian).
    pub fn encode(&self) -> [u8; REQUEST_HEADER_SIZE] {
        let id = self.unique_id.to_le_bytes();
        [self.protocol, self.type_code, id[0], id[1], id[2], id[3]]
    }

    /// Reads a header. Only the size is checked (BehaviorTree.CPP's server checks nothing
    /// else); [`RequestHeader::check`] checks protocol and type.
    ///
    /// # Errors
    /// [`ProtocolError::WrongSize`] unless `bytes` has exactly 6 bytes.
    pub fn decode(bytes: &[u8]) -> Result<RequestHeader, ProtocolError> {
        let b: [u8; REQUEST_HEADER_SIZE] =
            bytes.try_into().map_err(|_| ProtocolError::WrongSize {
                what: "a request header",
                expected: REQUEST_HEADER_SIZE,
                got: bytes.len(),
            })?;
        Ok(RequestHeader {
            protocol: b[0],
            type_code: b[1],
            unique_id: u32::from_le_bytes([b[2], b[3], b[4], b[5]]),
        })
    }

    /// The request type, checking the protocol too.
    ///
    /// # Errors
    /// [`ProtocolError::WrongProtocol`], [`ProtocolError::UnknownType`].
    pub fn check(&self) -> Result<RequestType, ProtocolError> {
        if self.protocol != PROTOCOL_ID {
            return Err(ProtocolError::WrongProtocol { got: self.protocol });
        }
        self.kind().ok_or(ProtocolError::UnknownType {
            code: self.type_code,
        })
    }
}

/// The first part of a reply (`Monitor::ReplyHeader`): the request's header (protocol 2) and
/// the tree's UUID.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ReplyHeader {
    /// The request answered, with the protocol set to 2.
    pub request: RequestHeader,
    /// The tree's identifier.
    pub tree_uuid: TreeUuid,
}

impl ReplyHeader {
    /// The header of the reply to `request`.
    pub fn answering(request: &RequestHeader, tree_uuid: TreeUuid) -> ReplyHeader {
        ReplyHeader {
            request: RequestHeader {
                protocol: PROTOCOL_ID,
                ..*request
            },
            tree_uuid,
        }
    }

    /// The 22 bytes on the wire.
    pub fn encode(&self) -> [u8; REPLY_HEADER_SIZE] {
        let mut out = [0; REPLY_HEADER_SIZE];
        out[..REQUEST_HEADER_SIZE].copy_from_slice(&self.request.encode());
        out[REQUEST_HEADER_SIZE..].copy_from_slice(&self.tree_uuid);
        out
    }

    /// Reads a reply header.
    ///
    /// # Errors
    /// [`ProtocolError::WrongSize`] unless `bytes` has exactly 22 bytes;
    /// [`ProtocolError::WrongProtocol`] for a protocol other than 2.
    pub fn decode(bytes: &[u8]) -> Result<ReplyHeader, ProtocolError> {
        if bytes.len() != REPLY_HEADER_SIZE {
            return Err(ProtocolError::WrongSize {
                what: "a reply header",
                expected: REPLY_HEADER_SIZE,
                got: bytes.len(),
            });
        }
        let request = RequestHeader::decode(&bytes[..REQUEST_HEADER_SIZE])?;
        if request.protocol != PROTOCOL_ID {
            return Err(ProtocolError::WrongProtocol {
                got: request.protocol,
            });
        }
        let mut tree_uuid = [0; 16];
        tree_uuid.copy_from_slice(&bytes[REQUEST_HEADER_SIZE..]);
        Ok(ReplyHeader { request, tree_uuid })
    }
}

/// A request decoded strictly: protocol 2, a known type, the parts it needs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Request {
    /// The header.
    pub header: RequestHeader,
    /// Its type.
    pub kind: RequestType,
    /// The second part, if any.
    pub body: Option<Vec<u8>>,
}

/// Checks the number and sizes of a message's parts against [`MAX_REQUEST_PARTS`] and
/// [`MAX_REQUEST_PART_SIZE`].
///
/// # Errors
/// [`ProtocolError::Empty`], [`ProtocolError::TooManyParts`], [`ProtocolError::Oversized`].
pub fn check_parts<P: AsRef<[u8]>>(parts: &[P]) -> Result<(), ProtocolError> {
    if parts.is_empty() {
        return Err(ProtocolError::Empty);
    }
    if parts.len() > MAX_REQUEST_PARTS {
        return Err(ProtocolError::TooManyParts {
            got: parts.len(),
            max: MAX_REQUEST_PARTS,
        });
    }
    for (part, p) in parts.iter().enumerate() {
        let size = p.as_ref().len();
        if size > MAX_REQUEST_PART_SIZE {
            return Err(ProtocolError::Oversized {
                part,
                size,
                max: MAX_REQUEST_PART_SIZE,
            });
        }
    }
    Ok(())
}

/// Decodes a request strictly: bounded parts, a 6-byte header, protocol 2, a type a server
/// answers (not [`RequestType::BreakpointReached`]), and exactly two parts for the types that
/// carry a body ([`RequestType::needs_body`]).
///
/// # Errors
/// Any [`ProtocolError`] of the checks above.
pub fn decode_request<P: AsRef<[u8]>>(parts: &[P]) -> Result<Request, ProtocolError> {
    check_parts(parts)?;
    let header = RequestHeader::decode(parts[0].as_ref())?;
    let kind = header.check()?;
    if kind == RequestType::BreakpointReached {
        return Err(ProtocolError::UnknownType {
            code: header.type_code,
        });
    }
    if kind.needs_body() && parts.len() != 2 {
        return Err(ProtocolError::PartCount {
            kind,
            got: parts.len(),
        });
    }
    Ok(Request {
        header,
        kind,
        body: parts.get(1).map(|p| p.as_ref().to_vec()),
    })
}

/// The parts of a request of type `kind` with id `unique_id` and an optional second part.
pub fn encode_request(kind: RequestType, unique_id: u32, body: Option<&[u8]>) -> Vec<Vec<u8>> {
    let mut parts = vec![RequestHeader::new(kind, unique_id).encode().to_vec()];
    if let Some(body) = body {
        parts.push(body.to_vec());
    }
    parts
}

/// The parts of an error reply: `error` and the message (BehaviorTree.CPP's `sendErrorReply`).
pub fn encode_error_reply(message: &str) -> Vec<Vec<u8>> {
    vec![b"error".to_vec(), message.as_bytes().to_vec()]
}

/// A reply, decoded by a client.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    /// An answer: the header and the parts that follow it (usually one).
    Answer {
        /// The reply header.
        header: ReplyHeader,
        /// The parts after the header.
        body: Vec<Vec<u8>>,
    },
    /// The server refused the request: the message of its `error` reply.
    Error(String),
}

impl Reply {
    /// The first part after the header, or an empty slice.
    pub fn payload(&self) -> &[u8] {
        match self {
            Reply::Answer { body, .. } => body.first().map_or(&[][..], Vec::as_slice),
            Reply::Error(_) => &[],
        }
    }
}

/// Decodes the reply to `request`: an `error` reply, or a header that echoes the request's
/// type and id (protocol 2) and the parts after it.
///
/// # Errors
/// [`ProtocolError::Empty`], a header of the wrong size or protocol,
/// [`ProtocolError::Mismatch`] when the header answers another request,
/// [`ProtocolError::Malformed`] for an error reply whose message is not UTF-8 or that has not
/// exactly two parts.
pub fn decode_reply<P: AsRef<[u8]>>(
    parts: &[P],
    request: &RequestHeader,
) -> Result<Reply, ProtocolError> {
    let first = parts.first().ok_or(ProtocolError::Empty)?.as_ref();
    if first == b"error" {
        if parts.len() != 2 {
            return Err(ProtocolError::malformed(
                "an error reply",
                format!("{} parts, expected 2", parts.len()),
            ));
        }
        let text = std::str::from_utf8(parts[1].as_ref())
            .map_err(|e| ProtocolError::malformed("an error reply", e.to_string()))?;
        return Ok(Reply::Error(text.to_owned()));
    }
    let header = ReplyHeader::decode(first)?;
    if header.request.type_code != request.type_code
        || header.request.unique_id != request.unique_id
    {
        return Err(ProtocolError::Mismatch {
            want_type: char::from(request.type_code),
            want_id: request.unique_id,
            got_type: char::from(header.request.type_code),
            got_id: header.request.unique_id,
        });
    }
    Ok(Reply::Answer {
        header,
        body: parts[1..].iter().map(|p| p.as_ref().to_vec()).collect(),
    })
}

// ---------------------------------------------------------------------------------------------
// STATUS

/// The status code a STATUS reply gives a node that went back to idle after `last`:
/// 10 + `last` (11 running, 12 success, 13 failure, 14 skipped), as BehaviorTree.CPP's
/// `IDLE_FROM_*`.
pub fn idle_from(last: Status) -> u8 {
    10 + last.code()
}

/// One node of a STATUS reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct NodeState {
    /// The node's uid.
    pub uid: u16,
    /// The code: 0–4 a [`Status`], 10 + a status for a node that went back to idle after
    /// that status ([`idle_from`]).
    pub code: u8,
}

impl NodeState {
    /// The current status (idle for codes 10 and above); `None` for a code that is neither.
    pub fn status(&self) -> Option<Status> {
        match self.code {
            0..=4 => Status::from_code(self.code),
            10..=14 => Some(Status::Idle),
            _ => None,
        }
    }

    /// The status before the node went back to idle, for codes 10–14.
    pub fn idle_after(&self) -> Option<Status> {
        self.code.checked_sub(10).and_then(Status::from_code)
    }
}

/// The status buffer of a STATUS reply: every node, in the order of BehaviorTree.CPP's
/// `Groot2Publisher` (tree instance by tree instance, each in depth-first order), with the
/// code of its last transition. Fed with the transitions of each tick ([`StatusBuffer::apply`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StatusBuffer {
    /// uid and code of every node, in wire order.
    nodes: Vec<NodeState>,
    /// Index into `nodes` of each uid (uid − 1).
    index: Vec<usize>,
}

impl StatusBuffer {
    /// A buffer with every node idle, in the wire order of `tree` ([`wire_order`]).
    pub fn new(tree: &chronomap_bt::Tree) -> StatusBuffer {
        let order = wire_order(tree);
        let mut index = vec![0; order.len()];
        let nodes = order
            .iter()
            .enumerate()
            .map(|(k, &uid)| {
                index[usize::from(uid) - 1] = k;
                NodeState { uid, code: 0 }
            })
            .collect();
        StatusBuffer { nodes, index }
    }

    /// Records a status change (BehaviorTree.CPP's `Groot2Publisher::callback`): the new
    /// status, or 10 + the previous one for a change to idle. Unknown uids are ignored.
    pub fn apply(&mut self, uid: u16, from: Status, to: Status) {
        let Some(&k) = usize::from(uid)
            .checked_sub(1)
            .and_then(|i| self.index.get(i))
        else {
            return;
        };
        self.nodes[k].code = if to == Status::Idle {
            idle_from(from)
        } else {
            to.code()
        };
    }

    /// The nodes in wire order.
    pub fn nodes(&self) -> &[NodeState] {
        &self.nodes
    }

    /// The reply payload: 3 bytes a node.
    pub fn encode(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(3 * self.nodes.len());
        for n in &self.nodes {
            out.extend_from_slice(&n.uid.to_le_bytes());
            out.push(n.code);
        }
        out
    }
}

/// The uids of `tree` in the order of BehaviorTree.CPP's status buffer: for each tree instance
/// (main tree first, then subtrees in depth-first order of their `SubTree` nodes), its nodes
/// in depth-first order, a `SubTree` node with the instance that contains it.
pub fn wire_order(tree: &chronomap_bt::Tree) -> Vec<u16> {
    let nodes = tree.nodes();
    let mut out = Vec::with_capacity(nodes.len());
    for instance in tree.subtrees() {
        let mut stack = vec![usize::from(instance.root_uid) - 1];
        while let Some(i) = stack.pop() {
            let node = &nodes[i];
            out.push(node.uid());
            if node.category() != chronomap_bt::NodeCategory::SubTree {
                stack.extend(node.children().iter().rev());
            }
        }
    }
    out
}

/// Decodes a STATUS payload.
///
/// # Errors
/// [`ProtocolError::Malformed`] if its length is not a multiple of 3.
pub fn decode_status(payload: &[u8]) -> Result<Vec<NodeState>, ProtocolError> {
    if !payload.len().is_multiple_of(3) {
        return Err(ProtocolError::malformed(
            "a status reply",
            format!("{} bytes, not a multiple of 3", payload.len()),
        ));
    }
    Ok(payload
        .chunks_exact(3)
        .map(|c| NodeState {
            uid: u16::from_le_bytes([c[0], c[1]]),
            code: c[2],
        })
        .collect())
}

// ---------------------------------------------------------------------------------------------
// Transitions

/// A status change as GET_TRANSITIONS sends it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct RecordedTransition {
    /// Microseconds since recording started (48 bits on the wire).
    pub time_us: u64,
    /// The node's uid.
    pub uid: u16,
    /// The new status code (0–4).
    pub status: u8,
}

/// The GET_TRANSITIONS payload: 9 bytes a transition (the low 6 bytes of the time, the uid,
/// the status), as BehaviorTree.CPP's server writes them.
pub fn encode_transitions(transitions: &[RecordedTransition]) -> Vec<u8> {
    let mut out = Vec::with_capacity(9 * transitions.len());
    for t in transitions {
        out.extend_from_slice(&t.time_us.to_le_bytes()[..6]);
        out.extend_from_slice(&t.uid.to_le_bytes());
        out.push(t.status);
    }
    out
}

/// Decodes a GET_TRANSITIONS payload.
///
/// # Errors
/// [`ProtocolError::Malformed`] if its length is not a multiple of 9.
pub fn decode_transitions(payload: &[u8]) -> Result<Vec<RecordedTransition>, ProtocolError> {
    if !payload.len().is_multiple_of(9) {
        return Err(ProtocolError::malformed(
            "a transitions reply",
            format!("{} bytes, not a multiple of 9", payload.len()),
        ));
    }
    Ok(payload
        .chunks_exact(9)
        .map(|c| {
            let mut time = [0; 8];
            time[..6].copy_from_slice(&c[..6]);
            RecordedTransition {
                time_us: u64::from_le_bytes(time),
                uid: u16::from_le_bytes([c[6], c[7]]),
                status: c[8],
            }
        })
        .collect())
}

/// Decodes the reply to TOGGLE_RECORDING `start`: the server's time in microseconds since the
/// Unix epoch, as decimal text.
///
/// # Errors
/// [`ProtocolError::Malformed`] for anything but decimal digits.
pub fn decode_recording_start(payload: &[u8]) -> Result<u64, ProtocolError> {
    std::str::from_utf8(payload)
        .ok()
        .filter(|s| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| {
            ProtocolError::malformed(
                "a recording start time",
                format!(
                    "{:?} is not a number of microseconds",
                    String::from_utf8_lossy(payload)
                ),
            )
        })
}

// ---------------------------------------------------------------------------------------------
// Hooks

/// Where a hook acts: before a node's tick (the only position BehaviorTree.CPP 4.8.2 runs) or
/// after it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum HookPosition {
    /// Before the tick (`0`).
    Pre,
    /// After the tick (`1`).
    Post,
}

impl HookPosition {
    /// The JSON number.
    pub fn code(self) -> i64 {
        match self {
            HookPosition::Pre => 0,
            HookPosition::Post => 1,
        }
    }

    fn from_code(code: i64) -> Option<HookPosition> {
        match code {
            0 => Some(HookPosition::Pre),
            1 => Some(HookPosition::Post),
            _ => None,
        }
    }
}

/// What a hook does: stop the tree until a client unlocks it, or replace the node's tick by
/// a status.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum HookMode {
    /// An interactive breakpoint (`0`).
    Breakpoint,
    /// The node returns `desired_status` without being ticked (`1`).
    Replace,
}

impl HookMode {
    /// The JSON number.
    pub fn code(self) -> i64 {
        match self {
            HookMode::Breakpoint => 0,
            HookMode::Replace => 1,
        }
    }

    fn from_code(code: i64) -> Option<HookMode> {
        match code {
            0 => Some(HookMode::Breakpoint),
            1 => Some(HookMode::Replace),
            _ => None,
        }
    }
}

/// A hook (`Monitor::Hook`) as JSON carries it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Hook {
    /// Whether it acts.
    pub enabled: bool,
    /// The node.
    pub uid: u16,
    /// Breakpoint or replacement.
    pub mode: HookMode,
    /// Removed after it acted once.
    pub once: bool,
    /// The status the node returns (`SKIPPED`: ticked normally).
    pub desired_status: Status,
    /// Before or after the tick.
    pub position: HookPosition,
}

/// The JSON object of a hook, with its members in the order nlohmann::json prints them
/// (sorted by name).
#[derive(Serialize, Deserialize)]
struct HookJson {
    desired_status: String,
    enabled: bool,
    mode: i64,
    once: bool,
    position: i64,
    uid: i64,
}

impl Hook {
    /// The JSON text, as BehaviorTree.CPP's HOOKS_DUMP prints one:
    /// `{"desired_status":"SKIPPED","enabled":true,"mode":0,"once":false,"position":0,"uid":3}`.
    pub fn to_json(&self) -> String {
        let json = HookJson {
            desired_status: self.desired_status.as_str().to_owned(),
            enabled: self.enabled,
            mode: self.mode.code(),
            once: self.once,
            position: self.position.code(),
            uid: i64::from(self.uid),
        };
        serde_json::to_string(&json).unwrap_or_default()
    }

    fn from_value(v: &serde_json::Value) -> Result<Hook, ProtocolError> {
        let bad = |reason: String| ProtocolError::malformed("a hook", reason);
        let obj = v
            .as_object()
            .ok_or_else(|| bad(format!("{v} is not a JSON object")))?;
        let field = |name: &str| {
            obj.get(name)
                .ok_or_else(|| bad(format!("the member \"{name}\" is missing")))
        };
        let boolean = |name: &str| {
            field(name)?
                .as_bool()
                .ok_or_else(|| bad(format!("\"{name}\" is not true or false")))
        };
        let integer = |name: &str| {
            field(name)?
                .as_i64()
                .ok_or_else(|| bad(format!("\"{name}\" is not an integer")))
        };
        let uid = integer("uid")?;
        let uid = u16::try_from(uid).map_err(|_| bad(format!("uid {uid} is not a node uid")))?;
        let mode = integer("mode")?;
        let mode = HookMode::from_code(mode).ok_or_else(|| bad(format!("mode {mode} (0 or 1)")))?;
        let position = integer("position")?;
        let position = HookPosition::from_code(position)
            .ok_or_else(|| bad(format!("position {position} (0 or 1)")))?;
        let status = field("desired_status")?
            .as_str()
            .ok_or_else(|| bad("\"desired_status\" is not a string".to_owned()))?;
        let desired_status = parse_status_name(status)
            .ok_or_else(|| bad(format!("desired_status {status:?} is not a node status")))?;
        Ok(Hook {
            enabled: boolean("enabled")?,
            uid,
            mode,
            once: boolean("once")?,
            desired_status,
            position,
        })
    }
}

/// A status by BehaviorTree.CPP's upper-case name (`convertFromString<NodeStatus>`).
fn parse_status_name(name: &str) -> Option<Status> {
    [
        Status::Idle,
        Status::Running,
        Status::Success,
        Status::Failure,
        Status::Skipped,
    ]
    .into_iter()
    .find(|s| s.as_str() == name)
}

fn parse_json(what: &'static str, body: &[u8]) -> Result<serde_json::Value, ProtocolError> {
    serde_json::from_slice(body).map_err(|e| ProtocolError::malformed(what, e.to_string()))
}

/// Decodes the body of HOOK_INSERT: one hook or an array of hooks.
///
/// # Errors
/// [`ProtocolError::Malformed`] naming the member that is missing or wrong.
pub fn decode_hooks(body: &[u8]) -> Result<Vec<Hook>, ProtocolError> {
    match parse_json("a hook", body)? {
        serde_json::Value::Array(items) => items.iter().map(Hook::from_value).collect(),
        one => Ok(vec![Hook::from_value(&one)?]),
    }
}

/// The body of HOOK_REMOVE: which hook.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HookRemoval {
    /// The node.
    pub uid: u16,
    /// The hook's position.
    pub position: HookPosition,
}

fn json_uid_position(
    what: &'static str,
    obj: &serde_json::Map<String, serde_json::Value>,
) -> Result<(u16, HookPosition), ProtocolError> {
    let bad = |reason: String| ProtocolError::malformed(what, reason);
    let uid = obj
        .get("uid")
        .and_then(serde_json::Value::as_i64)
        .ok_or_else(|| bad("\"uid\" is missing or not an integer".to_owned()))?;
    let uid = u16::try_from(uid).map_err(|_| bad(format!("uid {uid} is not a node uid")))?;
    let position = obj
        .get("position")
        .and_then(serde_json::Value::as_i64)
        .ok_or_else(|| bad("\"position\" is missing or not an integer".to_owned()))?;
    let position = HookPosition::from_code(position)
        .ok_or_else(|| bad(format!("position {position} (0 or 1)")))?;
    Ok((uid, position))
}

/// Decodes the body of HOOK_REMOVE.
///
/// # Errors
/// [`ProtocolError::Malformed`].
pub fn decode_hook_removal(body: &[u8]) -> Result<HookRemoval, ProtocolError> {
    let v = parse_json("a hook removal", body)?;
    let obj = v.as_object().ok_or_else(|| {
        ProtocolError::malformed("a hook removal", format!("{v} is not a JSON object"))
    })?;
    let (uid, position) = json_uid_position("a hook removal", obj)?;
    Ok(HookRemoval { uid, position })
}

/// The body of BREAKPOINT_UNLOCK.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BreakpointUnlock {
    /// The node.
    pub uid: u16,
    /// The hook's position.
    pub position: HookPosition,
    /// What the node returns: success or failure; anything else means "tick it"
    /// (skipped), as BehaviorTree.CPP reads it.
    pub desired_status: Status,
    /// Remove the hook after this.
    pub remove_when_done: bool,
}

/// Decodes the body of BREAKPOINT_UNLOCK.
///
/// # Errors
/// [`ProtocolError::Malformed`].
pub fn decode_breakpoint_unlock(body: &[u8]) -> Result<BreakpointUnlock, ProtocolError> {
    const WHAT: &str = "a breakpoint unlock";
    let v = parse_json(WHAT, body)?;
    let obj = v
        .as_object()
        .ok_or_else(|| ProtocolError::malformed(WHAT, format!("{v} is not a JSON object")))?;
    let (uid, position) = json_uid_position(WHAT, obj)?;
    let status = obj
        .get("desired_status")
        .and_then(serde_json::Value::as_str)
        .ok_or_else(|| {
            ProtocolError::malformed(WHAT, "\"desired_status\" is missing or not a string")
        })?;
    let remove_when_done = obj
        .get("remove_when_done")
        .and_then(serde_json::Value::as_bool)
        .ok_or_else(|| {
            ProtocolError::malformed(WHAT, "\"remove_when_done\" is missing or not a boolean")
        })?;
    let desired_status = match status {
        "SUCCESS" => Status::Success,
        "FAILURE" => Status::Failure,
        _ => Status::Skipped,
    };
    Ok(BreakpointUnlock {
        uid,
        position,
        desired_status,
        remove_when_done,
    })
}

// ---------------------------------------------------------------------------------------------
// MessagePack (BLACKBOARD replies)

/// A MessagePack value, as a client decodes a BLACKBOARD reply.
#[derive(Clone, Debug, PartialEq)]
pub enum MsgValue {
    /// `nil`: a blackboard entry without a value (or of a type the server cannot export).
    Nil,
    /// A boolean.
    Bool(bool),
    /// A negative integer (non-negative integers are [`MsgValue::UInt`]).
    Int(i64),
    /// A non-negative integer.
    UInt(u64),
    /// A 32-bit float (nlohmann::json writes a double that a float represents exactly so).
    F32(f32),
    /// A 64-bit float.
    F64(f64),
    /// Text.
    Str(String),
    /// Bytes.
    Bin(Vec<u8>),
    /// An array.
    Array(Vec<MsgValue>),
    /// A map, in wire order.
    Map(Vec<(MsgValue, MsgValue)>),
    /// An extension type and its bytes.
    Ext(i8, Vec<u8>),
}

impl MsgValue {
    /// The value under `key` of a map with string keys.
    pub fn get(&self, key: &str) -> Option<&MsgValue> {
        match self {
            MsgValue::Map(entries) => entries
                .iter()
                .find(|(k, _)| matches!(k, MsgValue::Str(s) if s == key))
                .map(|(_, v)| v),
            _ => None,
        }
    }
}

struct MsgReader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> MsgReader<'a> {
    fn fail(&self, reason: &str) -> ProtocolError {
        ProtocolError::malformed("MessagePack", format!("{reason} at byte {}", self.pos))
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], ProtocolError> {
        if self.bytes.len() - self.pos < n {
            return Err(self.fail(&format!("{n} bytes needed, the data ends")));
        }
        let out = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    fn uint(&mut self, n: usize) -> Result<u64, ProtocolError> {
        Ok(self
            .take(n)?
            .iter()
            .fold(0u64, |acc, &b| (acc << 8) | u64::from(b)))
    }

    fn len(&mut self, n: usize, per_item: usize) -> Result<usize, ProtocolError> {
        let len = self.uint(n)?;
        let left = (self.bytes.len() - self.pos) as u64;
        // Every item takes at least `per_item` bytes: a length beyond what is left is an error
        // before anything is allocated for it.
        if len.saturating_mul(per_item as u64) > left {
            return Err(self.fail(&format!("a length of {len} exceeds the data")));
        }
        Ok(len as usize)
    }

    fn value(&mut self, depth: usize) -> Result<MsgValue, ProtocolError> {
        if depth > MAX_MSGPACK_DEPTH {
            return Err(self.fail(&format!("nested deeper than {MAX_MSGPACK_DEPTH} levels")));
        }
        let b = self.take(1)?[0];
        Ok(match b {
            0x00..=0x7f => MsgValue::UInt(u64::from(b)),
            0x80..=0x8f => self.map(usize::from(b & 0x0f), depth)?,
            0x90..=0x9f => self.array(usize::from(b & 0x0f), depth)?,
            0xa0..=0xbf => self.string(usize::from(b & 0x1f))?,
            0xc0 => MsgValue::Nil,
            0xc2 => MsgValue::Bool(false),
            0xc3 => MsgValue::Bool(true),
            0xc4..=0xc6 => {
                let n = self.len(1 << (b - 0xc4), 1)?;
                MsgValue::Bin(self.take(n)?.to_vec())
            }
            0xc7..=0xc9 => {
                let n = self.len(1 << (b - 0xc7), 1)?;
                let t = self.take(1)?[0] as i8;
                MsgValue::Ext(t, self.take(n)?.to_vec())
            }
            0xca => MsgValue::F32(f32::from_bits(self.uint(4)? as u32)),
            0xcb => MsgValue::F64(f64::from_bits(self.uint(8)?)),
            0xcc..=0xcf => MsgValue::UInt(self.uint(1 << (b - 0xcc))?),
            0xd0..=0xd3 => {
                let n = 1usize << (b - 0xd0);
                let raw = self.uint(n)?;
                let shift = 64 - 8 * n as u32;
                MsgValue::Int(((raw << shift) as i64) >> shift)
            }
            0xd4..=0xd8 => {
                let t = self.take(1)?[0] as i8;
                MsgValue::Ext(t, self.take(1 << (b - 0xd4))?.to_vec())
            }
            0xd9..=0xdb => {
                let n = self.len(1 << (b - 0xd9), 1)?;
                self.string(n)?
            }
            0xdc | 0xdd => {
                let n = self.len(2 << (b - 0xdc), 1)?;
                self.array(n, depth)?
            }
            0xde | 0xdf => {
                let n = self.len(2 << (b - 0xde), 2)?;
                self.map(n, depth)?
            }
            0xe0..=0xff => MsgValue::Int(i64::from(b as i8)),
            0xc1 => return Err(self.fail("the unused byte 0xc1")),
        })
    }

    fn string(&mut self, n: usize) -> Result<MsgValue, ProtocolError> {
        let start = self.pos;
        let bytes = self.take(n)?;
        std::str::from_utf8(bytes)
            .map(|s| MsgValue::Str(s.to_owned()))
            .map_err(|_| {
                ProtocolError::malformed(
                    "MessagePack",
                    format!("text at byte {start} is not UTF-8"),
                )
            })
    }

    fn array(&mut self, n: usize, depth: usize) -> Result<MsgValue, ProtocolError> {
        let mut items = Vec::with_capacity(n.min(self.bytes.len() - self.pos));
        for _ in 0..n {
            items.push(self.value(depth + 1)?);
        }
        Ok(MsgValue::Array(items))
    }

    fn map(&mut self, n: usize, depth: usize) -> Result<MsgValue, ProtocolError> {
        let mut entries = Vec::with_capacity(n.min((self.bytes.len() - self.pos) / 2));
        for _ in 0..n {
            let k = self.value(depth + 1)?;
            let v = self.value(depth + 1)?;
            entries.push((k, v));
        }
        Ok(MsgValue::Map(entries))
    }
}

/// Decodes one MessagePack value that fills `bytes` (a BLACKBOARD reply: a map from
/// blackboard name to a map from key to value).
///
/// # Errors
/// [`ProtocolError::Malformed`] with the byte offset: truncated data, lengths beyond the
/// data, text that is not UTF-8, nesting deeper than [`MAX_MSGPACK_DEPTH`], bytes after the
/// value.
pub fn decode_msgpack(bytes: &[u8]) -> Result<MsgValue, ProtocolError> {
    let mut r = MsgReader { bytes, pos: 0 };
    let v = r.value(0)?;
    if r.pos != bytes.len() {
        return Err(r.fail("bytes after the value"));
    }
    Ok(v)
}
