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
//! | `B` BLACKBOARD | names separated by `;` | MessagePack map of name → blackboard (the publisher's `blackboards`) |
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

// ---------------------------------------------------------------------------------------------
// FULLTREE: the tree as BehaviorTree.CPP's `WriteTreeToXML(tree, true, true)` writes it

/// The order in which a libstdc++ `std::unordered_map` with unique keys yields its elements
/// after a sequence of insertions — the order in which BehaviorTree.CPP iterates its port maps
/// (`PortsList`, `PortsRemapping`) and so writes ports. Rules of libstdc++ (`_Hashtable` and
/// `_Prime_rehash_policy`, maximum load factor 1): a new element goes to the front of its
/// bucket, or to the front of the whole list when its bucket was empty; the table grows to the
/// next prime of libstdc++'s list at least twice as large when the elements would exceed the
/// buckets (a default-constructed map starts at 13 buckets with its first element; a map
/// built from an initializer list of *n* elements at the smallest listed bucket count ≥ *n*);
/// growing relinks the elements bucket by bucket in list order. Hashes are libstdc++'s
/// `std::hash<std::string>` ([`std_hash_bytes`]).
#[derive(Clone, Debug)]
pub(crate) struct StdUnorderedOrder<K> {
    /// Elements in iteration order with their hash codes.
    list: Vec<(K, u64)>,
    buckets: u64,
    next_resize: u64,
}

/// libstdc++'s `__fast_bkt` table for bucket requests below 14.
const FAST_BUCKETS: [u64; 14] = [2, 2, 2, 3, 5, 5, 7, 7, 11, 11, 11, 11, 13, 13];

/// The start of libstdc++'s `__prime_list` (enough for a million elements).
const PRIMES: [u64; 130] = [
    2, 3, 5, 7, 11, 13, 17, 19, 23, 29, 31, 37, 41, 43, 47, 53, 59, 61, 67, 71, 73, 79, 83, 89, 97,
    103, 109, 113, 127, 137, 139, 149, 157, 167, 179, 193, 199, 211, 227, 241, 257, 277, 293, 313,
    337, 359, 383, 409, 439, 467, 503, 541, 577, 619, 661, 709, 761, 823, 887, 953, 1031, 1109,
    1193, 1289, 1381, 1493, 1613, 1741, 1879, 2029, 2179, 2357, 2549, 2753, 2971, 3209, 3469, 3739,
    4027, 4349, 4703, 5087, 5503, 5953, 6427, 6949, 7517, 8123, 8783, 9497, 10273, 11113, 12011,
    12983, 14033, 15173, 16411, 17749, 19183, 20753, 22447, 24281, 26267, 28411, 30727, 33223,
    35933, 38873, 42043, 45481, 49201, 53201, 57557, 62233, 67307, 72817, 78779, 85229, 92203,
    99733, 107897, 116731, 126271, 136607, 147793, 159871, 172933, 187091, 202409, 218971,
];

impl<K: PartialEq> StdUnorderedOrder<K> {
    /// A default-constructed map (one bucket, nothing allocated).
    pub(crate) fn new() -> Self {
        StdUnorderedOrder {
            list: Vec::new(),
            buckets: 1,
            next_resize: 0,
        }
    }

    /// A map about to be filled from an initializer list of `n` elements.
    pub(crate) fn for_elements(n: usize) -> Self {
        let mut map = StdUnorderedOrder::new();
        let wanted = map.next_bucket_count(n as u64);
        map.buckets = map.buckets.max(wanted);
        map
    }

    /// `_Prime_rehash_policy::_M_next_bkt`.
    fn next_bucket_count(&mut self, n: u64) -> u64 {
        if n < FAST_BUCKETS.len() as u64 {
            if n == 0 {
                return 1;
            }
            let b = FAST_BUCKETS[n as usize];
            self.next_resize = b;
            return b;
        }
        let k = PRIMES[6..].partition_point(|&p| p < n) + 6;
        let b = PRIMES.get(k).copied().unwrap_or(PRIMES[PRIMES.len() - 1]);
        self.next_resize = b;
        b
    }

    /// `_Prime_rehash_policy::_M_need_rehash` for one more element: the new bucket count.
    fn need_rehash(&mut self) -> Option<u64> {
        let n = self.list.len() as u64 + 1;
        if n <= self.next_resize {
            return None;
        }
        let min_buckets = n.max(if self.next_resize == 0 { 11 } else { 0 });
        if min_buckets >= self.buckets {
            return Some(self.next_bucket_count((min_buckets + 1).max(self.buckets * 2)));
        }
        self.next_resize = self.buckets;
        None
    }

    /// `_Hashtable::_M_rehash_aux` (unique keys).
    fn rehash(&mut self, buckets: u64) {
        let old = std::mem::take(&mut self.list);
        // A bucket's first element, as an index into `self.list`.
        let mut first: std::collections::HashMap<u64, usize> = std::collections::HashMap::new();
        for (key, hash) in old {
            let b = hash % buckets;
            match first.get(&b) {
                None => {
                    self.list.insert(0, (key, hash));
                    for v in first.values_mut() {
                        *v += 1;
                    }
                    first.insert(b, 0);
                }
                Some(&at) => {
                    // After the bucket's "before" node: at the front of the bucket.
                    self.list.insert(at, (key, hash));
                    for (_, v) in first.iter_mut() {
                        if *v > at {
                            *v += 1;
                        }
                    }
                }
            }
        }
        self.buckets = buckets;
    }

    /// Inserts `key` with hash code `hash` (nothing if it is present).
    pub(crate) fn insert(&mut self, key: K, hash: u64) {
        if self.list.iter().any(|(k, _)| *k == key) {
            return;
        }
        if let Some(buckets) = self.need_rehash() {
            self.rehash(buckets);
        }
        let b = hash % self.buckets;
        let at = self
            .list
            .iter()
            .position(|(_, h)| h % self.buckets == b)
            .unwrap_or(0);
        self.list.insert(at, (key, hash));
    }

    /// Removes `key` (`erase`: the others keep their order).
    pub(crate) fn remove(&mut self, key: &K) {
        self.list.retain(|(k, _)| k != key);
    }

    /// The keys in iteration order.
    pub(crate) fn keys(&self) -> impl Iterator<Item = &K> {
        self.list.iter().map(|(k, _)| k)
    }
}

/// libstdc++'s `std::_Hash_bytes` on 64-bit targets with the seed of `std::hash<std::string>`
/// (0xc70f6907): a variant of MurmurHash64A.
pub(crate) fn std_hash_bytes(bytes: &[u8]) -> u64 {
    const MUL: u64 = (0xc6a4_a793_u64 << 32) + 0x5bd1_e995;
    let shift_mix = |v: u64| v ^ (v >> 47);
    let mut hash = 0xc70f_6907_u64 ^ (bytes.len() as u64).wrapping_mul(MUL);
    let mut chunks = bytes.chunks_exact(8);
    for chunk in &mut chunks {
        let mut word = [0; 8];
        word.copy_from_slice(chunk);
        let data = shift_mix(u64::from_le_bytes(word).wrapping_mul(MUL)).wrapping_mul(MUL);
        hash ^= data;
        hash = hash.wrapping_mul(MUL);
    }
    let rest = chunks.remainder();
    if !rest.is_empty() {
        let data = rest
            .iter()
            .rev()
            .fold(0u64, |acc, &b| (acc << 8) | u64::from(b));
        hash ^= data;
        hash = hash.wrapping_mul(MUL);
    }
    hash = shift_mix(hash).wrapping_mul(MUL);
    shift_mix(hash)
}

/// A string-keyed map with libstdc++'s iteration order and values.
#[derive(Clone, Debug)]
struct StdStringMap {
    order: StdUnorderedOrder<String>,
    values: std::collections::HashMap<String, String>,
}

impl StdStringMap {
    fn new() -> StdStringMap {
        StdStringMap {
            order: StdUnorderedOrder::new(),
            values: std::collections::HashMap::new(),
        }
    }

    /// `insert`: keeps an existing value.
    fn insert(&mut self, key: &str, value: &str) {
        if !self.values.contains_key(key) {
            self.order
                .insert(key.to_owned(), std_hash_bytes(key.as_bytes()));
            self.values.insert(key.to_owned(), value.to_owned());
        }
    }

    /// `operator[] =`: replaces an existing value.
    fn assign(&mut self, key: &str, value: &str) {
        self.insert(key, value);
        self.values.insert(key.to_owned(), value.to_owned());
    }

    fn contains(&self, key: &str) -> bool {
        self.values.contains_key(key)
    }

    fn iter(&self) -> impl Iterator<Item = (&str, &str)> {
        self.order
            .keys()
            .map(|k| (k.as_str(), self.values[k].as_str()))
    }
}

/// BehaviorTree.CPP's `IsAllowedPortName`: starts with a letter, and not `name`, `ID`,
/// `_autoremap` or a pre-/post-condition attribute.
fn is_allowed_port_name(name: &str) -> bool {
    name.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
        && !matches!(name, "name" | "ID" | "_autoremap")
}

/// The pre-condition attributes in BehaviorTree.CPP's `PreCond` order, then the
/// post-conditions in `PostCond` order: the order in which `WriteTreeToXML` writes them.
const CONDITION_ATTRIBUTES: [&str; 8] = [
    "_failureIf",
    "_successIf",
    "_skipIf",
    "_while",
    "_onHalted",
    "_onFailure",
    "_onSuccess",
    "_post",
];

/// A port of a node type as the XML writer needs it.
#[derive(Clone, Debug)]
struct ModelPort {
    direction: chronomap_bt::PortDirection,
    name: String,
    type_name: Option<String>,
    default: Option<String>,
    description: Option<String>,
}

/// A node type: category, ID and ports in BehaviorTree.CPP's iteration order.
#[derive(Clone, Debug)]
struct Model {
    category: chronomap_bt::NodeCategory,
    id: String,
    ports: Vec<ModelPort>,
}

impl Model {
    fn builtin(m: &crate::builtins::BuiltinModel) -> Model {
        Model {
            category: m.category,
            id: m.id.to_owned(),
            ports: m
                .ports
                .iter()
                .map(|p| ModelPort {
                    direction: p.direction,
                    name: p.name.to_owned(),
                    type_name: p.type_name.map(str::to_owned),
                    default: p.default.map(str::to_owned),
                    description: p.description.map(str::to_owned),
                })
                .collect(),
        }
    }

    /// A model of chronomap's (a user node): its ports in the order a port map built from
    /// an initializer list in declaration order yields them (`providedPorts() { return {…}; }`).
    fn user(m: &chronomap_bt::NodeModel) -> Model {
        let mut order = StdUnorderedOrder::for_elements(m.ports.len());
        for (k, p) in m.ports.iter().enumerate() {
            order.insert(k, std_hash_bytes(p.name.as_bytes()));
        }
        Model {
            category: m.category,
            id: m.id.clone(),
            ports: order
                .keys()
                .map(|&k| {
                    let p = &m.ports[k];
                    ModelPort {
                        direction: p.direction,
                        name: p.name.clone(),
                        type_name: p.type_name.clone(),
                        default: p.default.clone(),
                        description: p.description.clone(),
                    }
                })
                .collect(),
        }
    }

    fn port(&self, name: &str) -> Option<&ModelPort> {
        self.ports.iter().find(|p| p.name == name)
    }
}

/// The models a tree's `<TreeNodesModel>` lists, sorted by ID: every built-in node type of
/// BehaviorTree.CPP 4.8.2, and the tree's other (user) node types.
fn tree_models(tree: &chronomap_bt::Tree) -> std::collections::BTreeMap<String, Model> {
    let mut models: std::collections::BTreeMap<String, Model> = crate::builtins::BUILTIN_MODELS
        .iter()
        .map(|m| (m.id.to_owned(), Model::builtin(m)))
        .collect();
    for m in tree.node_models() {
        if m.category != chronomap_bt::NodeCategory::SubTree && !models.contains_key(&m.id) {
            models.insert(m.id.clone(), Model::user(m));
        }
    }
    models
}

/// TinyXML2's `XMLPrinter` (not compact): 4 spaces of indentation a level, one element a
/// line, `/>` for empty elements, text on the line of its element, a newline at the end.
struct XmlPrinter {
    out: String,
    depth: usize,
    /// The open element has not been sealed with `>` yet.
    just_opened: bool,
    first: bool,
    /// The depth of the element whose text was just written, if any.
    text_depth: Option<usize>,
    stack: Vec<String>,
}

impl XmlPrinter {
    fn new() -> XmlPrinter {
        XmlPrinter {
            out: String::new(),
            depth: 0,
            just_opened: false,
            first: true,
            text_depth: None,
            stack: Vec::new(),
        }
    }

    fn seal(&mut self) {
        if self.just_opened {
            self.just_opened = false;
            self.out.push('>');
        }
    }

    fn indent(&mut self, depth: usize) {
        for _ in 0..depth {
            self.out.push_str("    ");
        }
    }

    fn open(&mut self, name: &str) {
        self.seal();
        self.stack.push(name.to_owned());
        if self.text_depth.is_none() && !self.first {
            self.out.push('\n');
        }
        self.indent(self.depth);
        self.out.push('<');
        self.out.push_str(name);
        self.just_opened = true;
        self.first = false;
        self.depth += 1;
    }

    fn attribute(&mut self, name: &str, value: &str) {
        self.out.push(' ');
        self.out.push_str(name);
        self.out.push_str("=\"");
        escape(&mut self.out, value, true);
        self.out.push('"');
    }

    fn text(&mut self, text: &str) {
        self.seal();
        self.text_depth = Some(self.depth - 1);
        escape(&mut self.out, text, false);
    }

    fn close(&mut self) {
        self.depth -= 1;
        let name = self.stack.pop().unwrap_or_default();
        if self.just_opened {
            self.out.push_str("/>");
        } else {
            if self.text_depth.is_none() {
                self.out.push('\n');
                self.indent(self.depth);
            }
            self.out.push_str("</");
            self.out.push_str(&name);
            self.out.push('>');
        }
        if self.text_depth == Some(self.depth) {
            self.text_depth = None;
        }
        if self.depth == 0 {
            self.out.push('\n');
        }
        self.just_opened = false;
    }
}

/// TinyXML2's entities: in attribute values `"`, `&`, `'`, `<`, `>`; in text `&`, `<`, `>`.
fn escape(out: &mut String, text: &str, attribute: bool) {
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' if attribute => out.push_str("&quot;"),
            '\'' if attribute => out.push_str("&apos;"),
            c => out.push(c),
        }
    }
}

/// The description of each node of `tree` (by uid − 1) in `doc`, found by walking each tree
/// instance's definition along the runtime nodes.
fn node_defs<'d>(
    tree: &chronomap_bt::Tree,
    doc: &'d chronomap_bt::BtDocument,
) -> Vec<Option<&'d chronomap_bt::NodeDef>> {
    let nodes = tree.nodes();
    let mut defs = vec![None; nodes.len()];
    for instance in tree.subtrees() {
        let Some(def) = doc.tree(&instance.tree_id) else {
            continue;
        };
        let mut stack = vec![(usize::from(instance.root_uid) - 1, &def.root)];
        while let Some((i, d)) = stack.pop() {
            defs[i] = Some(d);
            if nodes[i].category() == chronomap_bt::NodeCategory::SubTree {
                continue;
            }
            for (&c, cd) in nodes[i].children().iter().zip(&d.children) {
                stack.push((c, cd));
            }
        }
    }
    defs
}

/// The ports BehaviorTree.CPP writes for a node: its `input_ports` map, then the entries of
/// its `output_ports` map that are not inputs (`createNodeFromXML` builds both from the
/// attributes and the model's defaults).
fn node_ports(
    attributes: &[(String, String)],
    model: Option<&Model>,
    subtree: bool,
) -> Vec<(String, String)> {
    let mut remap = StdStringMap::new();
    for (k, v) in attributes {
        if is_allowed_port_name(k) {
            remap.assign(k, v);
        }
    }
    if subtree {
        return remap
            .iter()
            .map(|(k, v)| (k.to_owned(), v.to_owned()))
            .collect();
    }
    let Some(model) = model else {
        return remap
            .iter()
            .map(|(k, v)| (k.to_owned(), v.to_owned()))
            .collect();
    };
    use chronomap_bt::PortDirection::{Input, Output};
    let mut inputs = StdStringMap::new();
    let mut outputs = StdStringMap::new();
    for (k, v) in remap.iter() {
        if let Some(port) = model.port(k) {
            if port.direction != Output {
                inputs.insert(k, v);
            }
            if port.direction != Input {
                outputs.insert(k, v);
            }
        }
    }
    for port in &model.ports {
        let Some(default) = port.default.as_deref().filter(|d| !d.is_empty()) else {
            continue;
        };
        if port.direction != Output && !inputs.contains(&port.name) {
            inputs.insert(&port.name, default);
        }
        if port.direction != Input
            && !outputs.contains(&port.name)
            && chronomap_bt::blackboard_pointer(default).is_some()
        {
            outputs.insert(&port.name, default);
        }
    }
    let mut out: Vec<(String, String)> = inputs
        .iter()
        .map(|(k, v)| (k.to_owned(), v.to_owned()))
        .collect();
    out.extend(
        outputs
            .iter()
            .filter(|(k, _)| !inputs.contains(k))
            .map(|(k, v)| (k.to_owned(), v.to_owned())),
    );
    out
}

/// The tree as the FULLTREE reply carries it: BehaviorTree.CPP 4.8.2's
/// `WriteTreeToXML(tree, add_metadata = true, add_builtin_models = true)` for the same tree,
/// byte for byte. One `<BehaviorTree ID _fullpath>` per tree instance (main tree first); every
/// node under the tag of its registration ID with `name` (a `SubTree` node with `ID` and
/// `_fullpath` instead), `_uid`, its ports (input ports, then output-only ports, with the
/// model's defaults, in the order of BehaviorTree.CPP's hash maps) and its pre- and
/// post-condition scripts; then a `<TreeNodesModel>` of all built-in node types and the
/// tree's own, sorted by ID; printed as TinyXML2 prints. `doc` is the document the tree was
/// built from (for the scripts).
pub fn encode_full_tree(tree: &chronomap_bt::Tree, doc: &chronomap_bt::BtDocument) -> String {
    use chronomap_bt::NodeCategory;
    let models = tree_models(tree);
    let defs = node_defs(tree, doc);
    let nodes = tree.nodes();
    let mut p = XmlPrinter::new();
    p.open("root");
    p.attribute("BTCPP_format", "4");
    for instance in tree.subtrees() {
        p.open("BehaviorTree");
        p.attribute("ID", &instance.tree_id);
        p.attribute("_fullpath", &instance.path);
        // Depth-first through the instance: (node index, whether it is being closed).
        let mut stack = vec![(usize::from(instance.root_uid) - 1, false)];
        while let Some((i, closing)) = stack.pop() {
            if closing {
                p.close();
                continue;
            }
            let node = &nodes[i];
            let def = defs[i];
            let subtree = node.category() == NodeCategory::SubTree;
            if subtree {
                p.open("SubTree");
                p.attribute("ID", node.id());
                let containing = instance.path.as_str();
                let name = def.and_then(|d| d.name.as_deref()).unwrap_or(node.id());
                let mut path = if containing.is_empty() {
                    name.to_owned()
                } else {
                    format!("{containing}/{name}")
                };
                if name == node.id() {
                    path.push_str(&format!("::{}", node.uid()));
                }
                p.attribute("_fullpath", &path);
            } else {
                p.open(node.id());
                p.attribute("name", node.name());
            }
            p.attribute("_uid", &node.uid().to_string());
            for (k, v) in node_ports(node.attributes(), models.get(node.id()), subtree) {
                p.attribute(&k, &v);
            }
            if let Some(def) = def {
                for attribute in CONDITION_ATTRIBUTES {
                    if let Some((_, code)) = def.scripts.iter().find(|(a, _)| a == attribute) {
                        p.attribute(attribute, code);
                    }
                }
            }
            stack.push((i, true));
            if !subtree {
                stack.extend(node.children().iter().rev().map(|&c| (c, false)));
            }
        }
        p.close();
    }
    p.open("TreeNodesModel");
    for model in models.values() {
        p.open(model.category.tag());
        p.attribute("ID", &model.id);
        for port in &model.ports {
            p.open(port.direction.tag());
            p.attribute("name", &port.name);
            if let Some(t) = &port.type_name {
                p.attribute("type", t);
            }
            if let Some(d) = port.default.as_deref().filter(|d| !d.is_empty()) {
                p.attribute("default", d);
            }
            if let Some(text) = port.description.as_deref().filter(|t| !t.is_empty()) {
                p.text(text);
            }
            p.close();
        }
        p.close();
    }
    p.close();
    p.close();
    p.out
}

// ---------------------------------------------------------------------------------------------
// BLACKBOARD

/// Writes `value` as nlohmann::json's `to_msgpack` writes the JSON BehaviorTree.CPP exports
/// for it (`ExportBlackboardToJSON`): booleans, integers in the smallest MessagePack form
/// (non-negative ones as unsigned), doubles as float 32 when that is exact, text as str;
/// lists (BehaviorTree.CPP's `SharedQueue`, which its JSON exporter does not know) as nil.
fn write_msgpack_value(out: &mut Vec<u8>, value: Option<&chronomap_bt::Value>) {
    use chronomap_bt::Value;
    match value {
        None | Some(Value::List(_)) => out.push(0xc0),
        Some(Value::Bool(b)) => out.push(if *b { 0xc3 } else { 0xc2 }),
        Some(Value::Int(i)) => write_msgpack_int(out, *i),
        Some(Value::Double(x)) => {
            let f = *x as f32;
            if x.is_finite() && f64::from(f) == *x {
                out.push(0xca);
                out.extend_from_slice(&f.to_be_bytes());
            } else {
                out.push(0xcb);
                out.extend_from_slice(&x.to_be_bytes());
            }
        }
        Some(Value::Str(s)) => write_msgpack_str(out, s),
    }
}

fn write_msgpack_int(out: &mut Vec<u8>, i: i64) {
    if i >= 0 {
        let u = i as u64;
        if u < 128 {
            out.push(u as u8);
        } else if u <= u64::from(u8::MAX) {
            out.extend_from_slice(&[0xcc, u as u8]);
        } else if u <= u64::from(u16::MAX) {
            out.push(0xcd);
            out.extend_from_slice(&(u as u16).to_be_bytes());
        } else if u <= u64::from(u32::MAX) {
            out.push(0xce);
            out.extend_from_slice(&(u as u32).to_be_bytes());
        } else {
            out.push(0xcf);
            out.extend_from_slice(&u.to_be_bytes());
        }
    } else if i >= -32 {
        out.push(i as i8 as u8);
    } else if i >= i64::from(i8::MIN) {
        out.extend_from_slice(&[0xd0, i as i8 as u8]);
    } else if i >= i64::from(i16::MIN) {
        out.push(0xd1);
        out.extend_from_slice(&(i as i16).to_be_bytes());
    } else if i >= i64::from(i32::MIN) {
        out.push(0xd2);
        out.extend_from_slice(&(i as i32).to_be_bytes());
    } else {
        out.push(0xd3);
        out.extend_from_slice(&i.to_be_bytes());
    }
}

fn write_msgpack_str(out: &mut Vec<u8>, s: &str) {
    let n = s.len();
    if n < 32 {
        out.push(0xa0 | n as u8);
    } else if n <= usize::from(u8::MAX) {
        out.extend_from_slice(&[0xd9, n as u8]);
    } else if n <= usize::from(u16::MAX) {
        out.push(0xda);
        out.extend_from_slice(&(n as u16).to_be_bytes());
    } else {
        out.push(0xdb);
        out.extend_from_slice(&(n as u32).to_be_bytes());
    }
    out.extend_from_slice(s.as_bytes());
}

fn write_msgpack_map_header(out: &mut Vec<u8>, n: usize) {
    if n < 16 {
        out.push(0x80 | n as u8);
    } else if n <= usize::from(u16::MAX) {
        out.push(0xde);
        out.extend_from_slice(&(n as u16).to_be_bytes());
    } else {
        out.push(0xdf);
        out.extend_from_slice(&(n as u32).to_be_bytes());
    }
}

/// A blackboard scope's parent scope, remapping (own key → parent key) and auto-remapping.
type ScopeLinks = (
    Option<usize>,
    std::collections::BTreeMap<String, String>,
    bool,
);

/// Each blackboard of a tree as a BLACKBOARD reply carries it, by the name a client asks for:
/// the main tree's ID for the main tree, the instance path (`open_it`, `Sub::4`, `a/b`) for a
/// subtree instance.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BlackboardSnapshot {
    /// Name → MessagePack of the blackboard (a map from key to value, or nil when empty).
    blackboards: std::collections::BTreeMap<String, Vec<u8>>,
}

impl BlackboardSnapshot {
    /// The blackboards of `tree` now. Each is the instance's own entries (not those it reaches
    /// through remapping), sorted by key, plus — as nil until written — the entries
    /// BehaviorTree.CPP creates when it builds the tree, one for every port that points to
    /// the blackboard (`{key}` or `{=}`), placed where the key leads (remapped and
    /// auto-remapped keys in the parent's blackboard, `@key` in the root's).
    pub fn new(tree: &chronomap_bt::Tree, doc: &chronomap_bt::BtDocument) -> BlackboardSnapshot {
        use std::collections::{BTreeMap, BTreeSet};
        let nodes = tree.nodes();
        let defs = node_defs(tree, doc);
        let bb = tree.blackboard();
        // Scope index → (parent scope index, remapping, autoremap).
        let mut scopes: BTreeMap<usize, ScopeLinks> = BTreeMap::new();
        for instance in tree.subtrees() {
            let mut info = (None, BTreeMap::new(), false);
            if let Some(uid) = instance.subtree_uid
                && let Some(node) = tree.node(uid)
            {
                info.0 = Some(node.scope().index());
                for (k, v) in node.attributes() {
                    if !is_allowed_port_name(k) {
                        continue;
                    }
                    if v == "{=}" {
                        info.1.insert(k.clone(), k.clone());
                    } else if let Some(key) = chronomap_bt::blackboard_pointer(v) {
                        info.1.insert(k.clone(), key.to_owned());
                    }
                }
                info.2 = defs[usize::from(uid) - 1].is_some_and(|d| d.autoremap);
            }
            scopes.insert(instance.scope.index(), info);
        }
        let mut declared: BTreeSet<(usize, String)> = BTreeSet::new();
        let exists = |declared: &BTreeSet<(usize, String)>, scope: usize, key: &str| {
            declared.contains(&(scope, key.to_owned()))
                || tree
                    .subtrees()
                    .iter()
                    .any(|s| s.scope.index() == scope && bb.entries(s.scope).any(|(k, _)| k == key))
        };
        let models = tree_models(tree);
        for node in nodes {
            if node.category() == chronomap_bt::NodeCategory::SubTree {
                continue;
            }
            let Some(model) = models.get(node.id()) else {
                continue;
            };
            for (port, value) in node.attributes() {
                if !is_allowed_port_name(port) || model.port(port).is_none() {
                    continue;
                }
                let key = if value == "{=}" || value == "=" {
                    port.as_str()
                } else if let Some(key) = chronomap_bt::blackboard_pointer(value) {
                    key
                } else {
                    continue;
                };
                // `Blackboard::createEntryImpl`.
                let (mut scope, mut key) = (node.scope().index(), key.to_owned());
                if let Some(rest) = key.strip_prefix('@') {
                    (scope, key) = (0, rest.to_owned());
                }
                for _ in 0..=scopes.len() {
                    if exists(&declared, scope, &key) {
                        break;
                    }
                    let Some((Some(parent), remap, autoremap)) = scopes.get(&scope) else {
                        break;
                    };
                    if let Some(external) = remap.get(&key) {
                        (scope, key) = (*parent, external.clone());
                    } else if *autoremap && !key.starts_with('_') {
                        scope = *parent;
                    } else {
                        break;
                    }
                }
                declared.insert((scope, key));
            }
        }
        let mut blackboards = BTreeMap::new();
        for (k, instance) in tree.subtrees().iter().enumerate() {
            let name = if k == 0 {
                instance.tree_id.clone()
            } else {
                instance.path.clone()
            };
            let scope = instance.scope.index();
            let mut entries: BTreeMap<&str, Option<&chronomap_bt::Value>> = declared
                .iter()
                .filter(|(s, _)| *s == scope)
                .map(|(_, key)| (key.as_str(), None))
                .collect();
            for (key, value) in bb.entries(instance.scope) {
                entries.insert(key, Some(value));
            }
            let mut out = Vec::new();
            if entries.is_empty() {
                out.push(0xc0);
            } else {
                write_msgpack_map_header(&mut out, entries.len());
                for (key, value) in entries {
                    write_msgpack_str(&mut out, key);
                    write_msgpack_value(&mut out, value);
                }
            }
            blackboards.insert(name, out);
        }
        BlackboardSnapshot { blackboards }
    }

    /// The names a client may ask for.
    pub fn names(&self) -> impl Iterator<Item = &str> {
        self.blackboards.keys().map(String::as_str)
    }

    /// The BLACKBOARD reply to `names` (separated by `;`): a MessagePack map of the named
    /// blackboards that exist, sorted by name (nil if none does), as BehaviorTree.CPP's
    /// `generateBlackboardsDump`.
    pub fn encode(&self, names: &str) -> Vec<u8> {
        let wanted: std::collections::BTreeSet<&str> = names
            .split(';')
            .filter(|n| self.blackboards.contains_key(*n))
            .collect();
        let mut out = Vec::new();
        if wanted.is_empty() {
            out.push(0xc0);
            return out;
        }
        write_msgpack_map_header(&mut out, wanted.len());
        for name in wanted {
            write_msgpack_str(&mut out, name);
            out.extend_from_slice(&self.blackboards[name]);
        }
        out
    }
}
