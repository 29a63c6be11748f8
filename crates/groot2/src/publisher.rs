//! The server side of Groot2's live protocol: BehaviorTree.CPP's `Groot2Publisher` for a
//! chronomap tree.
//!
//! A [`Publisher`] binds a ZeroMQ REP socket at a port and a PUB socket at the next port (as
//! BehaviorTree.CPP) and answers requests in a thread of its own from a snapshot of the tree:
//! the XML (fixed), the status of every node, the blackboards and the recorded transitions.
//! Whoever ticks the tree calls [`Publisher::update`] after each tick; the tree itself is
//! never touched by the server thread, so a slow, silent or hostile client cannot stop the
//! ticks.
//!
//! Hooks act on the ticks through the [`TickMonitor`] of [`Publisher::tick_monitor`], which
//! whoever ticks installs in the tree: a replacement gives a node's result, a breakpoint holds
//! the ticking thread (never the server's) until a client unlocks it, removes or disables it
//! (the `hooks` module has the rules). A held tick is released, as BehaviorTree.CPP releases it,
//! when no request came for [`Publisher::max_heartbeat_delay`] (5 s unless set: the client
//! went away; its hooks stay, disabled, until a client speaks again), and when the publisher
//! is dropped. While a tick is held, STATUS answers the statuses at the end of the last whole
//! tick (the tree hands its changes over after each tick; BehaviorTree.CPP's show the held
//! tick's changes up to the breakpoint).
//!
//! Bounds: a request part larger than [`MAX_REQUEST_PART_SIZE`] makes libzmq drop the
//! connection that sent it (`ZMQ_MAXMSGSIZE`), parts beyond [`MAX_REQUEST_PARTS`] are read and
//! discarded (the request gets an error reply), at most [`MAX_RECORDED_TRANSITIONS`]
//! transitions are kept, and a reply waits at most a second to be sent.
//!
//! Answers are BehaviorTree.CPP 4.8.2's, byte for byte except the tree UUID (random here, the
//! same for every tree there) and the times. Where BehaviorTree.CPP's server would end the
//! process (hook JSON that does not parse throws out of its server thread), this one answers
//! `error` with the reason.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use chronomap_bt::{BtDocument, Status, TickMonitor, Transition, Tree};
use thiserror::Error;

use crate::hooks::{Check, Hooks};
use crate::protocol::{
    BlackboardSnapshot, MAX_RECORDED_TRANSITIONS, MAX_REQUEST_PART_SIZE, MAX_REQUEST_PARTS,
    ProtocolError, RecordedTransition, ReplyHeader, RequestHeader, RequestType, StatusBuffer,
    TreeUuid, check_parts, decode_breakpoint_unlock, decode_hook_removal, decode_hooks,
    encode_error_reply, encode_full_tree, encode_transitions,
};

/// How long the clients may stay silent before the hooks are disabled and a held tick goes
/// on: BehaviorTree.CPP's `max_heartbeat_delay` (5000 ms).
pub const DEFAULT_MAX_HEARTBEAT_DELAY: Duration = Duration::from_millis(5000);

/// How often a held tick looks at the stop flag, and the server thread at the heartbeat (its
/// receive timeout, as BehaviorTree.CPP's).
const POLL: Duration = Duration::from_millis(100);

/// Why a publisher could not start.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum PublisherError {
    /// The port and the next one must be free and below 65535.
    #[error("port {port}: the publisher needs it and port {port} + 1 (at most 65534)")]
    Port {
        /// The port asked for.
        port: u16,
    },
    /// A socket could not be made or bound.
    #[error("cannot {action}: {source}")]
    Socket {
        /// What was being done.
        action: String,
        /// libzmq's error.
        source: zmq::Error,
    },
    /// The server thread could not be started.
    #[error("cannot start the server thread: {0}")]
    Thread(std::io::Error),
}

/// What the server answers from: updated by the tick loop, read by the server thread.
struct State {
    status: StatusBuffer,
    blackboards: BlackboardSnapshot,
    recording: bool,
    recording_start: Instant,
    transitions: VecDeque<RecordedTransition>,
    hooks: Hooks,
}

struct Shared {
    xml: String,
    uuid: TreeUuid,
    state: Mutex<State>,
    /// Wakes ticks held at breakpoints after a change of the hooks.
    wakeup: Condvar,
    /// The PUB socket (port + 1): breakpoint notifications, sent by the ticking thread.
    /// Taken (closed) when the publisher is dropped.
    notifier: Mutex<Option<zmq::Socket>>,
    stop: AtomicBool,
    requests: AtomicU64,
    max_heartbeat_ms: AtomicU64,
}

impl Shared {
    fn lock(&self) -> std::sync::MutexGuard<'_, State> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }
}

/// A Groot2 server for one tree (BehaviorTree.CPP's `Groot2Publisher`).
pub struct Publisher {
    shared: Arc<Shared>,
    port: u16,
    thread: Option<JoinHandle<()>>,
    _context: zmq::Context,
}

/// A tree UUID (version 4 layout) from the clock, the process id and the standard library's
/// random hash keys.
fn random_uuid() -> TreeUuid {
    let mut out = [0u8; 16];
    for (k, chunk) in out.chunks_mut(8).enumerate() {
        chunk.copy_from_slice(&random_u64(k as u64).to_le_bytes());
    }
    out[6] = (out[6] & 0x0f) | 0x40;
    out[8] = (out[8] & 0x3f) | 0x80;
    out
}

/// A random number from the clock, the process id, `salt` and the standard library's random
/// hash keys.
fn random_u64(salt: u64) -> u64 {
    use std::hash::{BuildHasher, Hasher};
    let mut h = std::collections::hash_map::RandomState::new().build_hasher();
    h.write_u128(
        SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default()
            .as_nanos(),
    );
    h.write_u32(std::process::id());
    h.write_u64(salt);
    h.finish()
}

fn socket_error(action: impl Into<String>) -> impl FnOnce(zmq::Error) -> PublisherError {
    let action = action.into();
    move |source| PublisherError::Socket { action, source }
}

impl Publisher {
    /// Starts serving `tree` (built from `doc`) on `port` (REP) and `port + 1` (PUB), on all
    /// interfaces, as BehaviorTree.CPP binds them.
    ///
    /// # Errors
    /// [`PublisherError`] if a port is taken or out of range, or the thread cannot start.
    pub fn start(tree: &Tree, doc: &BtDocument, port: u16) -> Result<Publisher, PublisherError> {
        Publisher::start_on(tree, doc, "*", port)
    }

    /// As [`Publisher::start`], bound to `interface` (`*` for all, `127.0.0.1` for this
    /// machine only).
    ///
    /// # Errors
    /// As [`Publisher::start`].
    pub fn start_on(
        tree: &Tree,
        doc: &BtDocument,
        interface: &str,
        port: u16,
    ) -> Result<Publisher, PublisherError> {
        let pub_port = port.checked_add(1).ok_or(PublisherError::Port { port })?;
        if port == 0 {
            return Err(PublisherError::Port { port });
        }
        let context = zmq::Context::new();
        let server = context
            .socket(zmq::REP)
            .map_err(socket_error("create the REP socket"))?;
        let publisher = context
            .socket(zmq::PUB)
            .map_err(socket_error("create the PUB socket"))?;
        for s in [&server, &publisher] {
            s.set_linger(0).map_err(socket_error("set ZMQ_LINGER"))?;
            s.set_rcvtimeo(100)
                .map_err(socket_error("set ZMQ_RCVTIMEO"))?;
            s.set_sndtimeo(1000)
                .map_err(socket_error("set ZMQ_SNDTIMEO"))?;
            s.set_maxmsgsize(MAX_REQUEST_PART_SIZE as i64)
                .map_err(socket_error("set ZMQ_MAXMSGSIZE"))?;
        }
        server
            .bind(&format!("tcp://{interface}:{port}"))
            .map_err(socket_error(format!("bind the REP socket to port {port}")))?;
        publisher
            .bind(&format!("tcp://{interface}:{pub_port}"))
            .map_err(socket_error(format!(
                "bind the PUB socket to port {pub_port}"
            )))?;
        let shared = Arc::new(Shared {
            xml: encode_full_tree(tree, doc),
            uuid: random_uuid(),
            state: Mutex::new(State {
                status: StatusBuffer::new(tree),
                blackboards: BlackboardSnapshot::new(tree, doc),
                recording: false,
                recording_start: Instant::now(),
                transitions: VecDeque::new(),
                hooks: Hooks::new(tree.nodes().len()),
            }),
            wakeup: Condvar::new(),
            notifier: Mutex::new(Some(publisher)),
            stop: AtomicBool::new(false),
            requests: AtomicU64::new(0),
            max_heartbeat_ms: AtomicU64::new(DEFAULT_MAX_HEARTBEAT_DELAY.as_millis() as u64),
        });
        let thread = std::thread::Builder::new()
            .name("groot2".into())
            .spawn({
                let shared = Arc::clone(&shared);
                move || serve(&server, &shared)
            })
            .map_err(PublisherError::Thread)?;
        Ok(Publisher {
            shared,
            port,
            thread: Some(thread),
            _context: context,
        })
    }

    /// The REP port.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// The tree UUID every reply carries.
    pub fn tree_uuid(&self) -> TreeUuid {
        self.shared.uuid
    }

    /// The number of requests received so far (answered or refused).
    pub fn requests(&self) -> u64 {
        self.shared.requests.load(Ordering::Relaxed)
    }

    /// Updates the snapshot after a tick: the status changes of the tick (in order; recorded
    /// with the time of this call while a client records) and the blackboards.
    pub fn update(&self, tree: &Tree, doc: &BtDocument, transitions: &[Transition]) {
        let blackboards = BlackboardSnapshot::new(tree, doc);
        let mut state = self.shared.lock();
        let now = Instant::now();
        for t in transitions {
            state.status.apply(t.uid, t.from, t.to);
            if state.recording {
                let time_us = u64::try_from(now.duration_since(state.recording_start).as_micros())
                    .unwrap_or(u64::MAX);
                state.transitions.push_back(RecordedTransition {
                    time_us,
                    uid: t.uid,
                    status: t.to.code(),
                });
                while state.transitions.len() > MAX_RECORDED_TRANSITIONS {
                    state.transitions.pop_front();
                }
            }
        }
        state.blackboards = blackboards;
    }

    /// How long the clients may stay silent (no request) before the hooks are disabled and
    /// a held tick goes on ([`DEFAULT_MAX_HEARTBEAT_DELAY`] unless set; BehaviorTree.CPP's
    /// `setMaxHeartbeatDelay`). Seen within 0.1 s.
    pub fn set_max_heartbeat_delay(&self, delay: Duration) {
        let ms = u64::try_from(delay.as_millis()).unwrap_or(u64::MAX);
        self.shared.max_heartbeat_ms.store(ms, Ordering::Relaxed);
    }

    /// The delay of [`Publisher::set_max_heartbeat_delay`].
    pub fn max_heartbeat_delay(&self) -> Duration {
        Duration::from_millis(self.shared.max_heartbeat_ms.load(Ordering::Relaxed))
    }

    /// The hooks' pre-tick callbacks, to install in the tree this publisher serves
    /// ([`Tree::set_tick_monitor`]): a node with an enabled hook notifies the clients, then
    /// a replacement gives its result and a breakpoint holds the calling thread until a
    /// client lets it go, the clients go silent for [`Publisher::max_heartbeat_delay`], or
    /// the publisher is dropped.
    pub fn tick_monitor(&self) -> Box<dyn TickMonitor> {
        Box::new(HookMonitor {
            shared: Arc::clone(&self.shared),
            notices: 0,
        })
    }
}

impl Drop for Publisher {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        // BehaviorTree.CPP's destructor removes every hook (releasing held ticks).
        self.shared.lock().hooks.remove_all();
        self.shared.wakeup.notify_all();
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
        // Close the PUB socket now (a monitor may outlive the publisher).
        drop(
            self.shared
                .notifier
                .lock()
                .unwrap_or_else(PoisonError::into_inner)
                .take(),
        );
    }
}

/// The hooks of a [`Publisher`] acting before each node's tick: BehaviorTree.CPP's pre-tick
/// callback of `Groot2Publisher::insertHook`.
struct HookMonitor {
    shared: Arc<Shared>,
    notices: u64,
}

impl HookMonitor {
    /// BREAKPOINT_REACHED on the PUB socket: a request header (protocol 2, `N`, a random
    /// id) and the node's uid in decimal. Never waits: PUB drops what it cannot send.
    fn notify_reached(&mut self, uid: u16) {
        self.notices += 1;
        let header = RequestHeader::new(
            RequestType::BreakpointReached,
            random_u64(self.notices) as u32,
        )
        .encode();
        let notifier = self
            .shared
            .notifier
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        if let Some(socket) = notifier.as_ref() {
            let _ = socket.send_multipart([&header[..], uid.to_string().as_bytes()], zmq::DONTWAIT);
        }
    }
}

impl TickMonitor for HookMonitor {
    fn pre_tick(&mut self, uid: u16, _status: Status) -> Option<Status> {
        let shared = Arc::clone(&self.shared);
        let mut state = shared.lock();
        let reached = state.hooks.reach(uid)?;
        self.notify_reached(uid);
        if reached.breakpoint {
            let mut seen = None;
            loop {
                match state.hooks.check(uid, reached.id, &mut seen) {
                    Check::Go => break,
                    Check::Skip => return None,
                    Check::Wait => {}
                }
                if shared.stop.load(Ordering::Relaxed) {
                    return None;
                }
                state = shared
                    .wakeup
                    .wait_timeout(state, POLL)
                    .unwrap_or_else(PoisonError::into_inner)
                    .0;
            }
        }
        state.hooks.finish(uid, reached.id)
    }
}

/// Receives one multipart message: at most [`MAX_REQUEST_PARTS`] parts kept, the rest read
/// and counted. `None` when nothing came within the receive timeout.
fn receive(socket: &zmq::Socket) -> Option<(Vec<Vec<u8>>, usize)> {
    let first = socket.recv_bytes(0).ok()?;
    let mut parts = vec![first];
    let mut count = 1;
    while socket.get_rcvmore().unwrap_or(false) {
        match socket.recv_bytes(0) {
            Ok(part) => {
                count += 1;
                if parts.len() < MAX_REQUEST_PARTS {
                    parts.push(part);
                }
            }
            Err(_) => break,
        }
    }
    Some((parts, count))
}

fn serve(socket: &zmq::Socket, shared: &Shared) {
    // BehaviorTree.CPP's `heartbeatLoop`: when the clients go silent (or speak again) the
    // hooks are disabled (enabled); seen after the request that ended the silence is answered.
    let mut last_request = Instant::now();
    let mut heartbeat = true;
    while !shared.stop.load(Ordering::Relaxed) {
        let alive = last_request.elapsed().as_millis()
            < u128::from(shared.max_heartbeat_ms.load(Ordering::Relaxed));
        if alive != heartbeat {
            heartbeat = alive;
            shared.lock().hooks.enable_all(alive);
            shared.wakeup.notify_all();
        }
        let Some((parts, count)) = receive(socket) else {
            continue;
        };
        last_request = Instant::now();
        shared.requests.fetch_add(1, Ordering::Relaxed);
        let reply = if count > MAX_REQUEST_PARTS {
            encode_error_reply(
                &ProtocolError::TooManyParts {
                    got: count,
                    max: MAX_REQUEST_PARTS,
                }
                .to_string(),
            )
        } else {
            answer(&parts, shared)
        };
        if kind_changes_hooks(&parts) {
            shared.wakeup.notify_all();
        }
        // A reply that cannot be sent within the send timeout is dropped (the REP socket
        // forgets the request either way).
        let _ = socket.send_multipart(reply, 0);
    }
}

/// Whether a request may have changed the hooks (ticks held at breakpoints look again).
fn kind_changes_hooks(parts: &[Vec<u8>]) -> bool {
    parts
        .first()
        .and_then(|p| RequestHeader::decode(p).ok())
        .and_then(|h| h.kind())
        .is_some_and(|k| {
            matches!(
                k,
                RequestType::HookInsert
                    | RequestType::HookRemove
                    | RequestType::BreakpointUnlock
                    | RequestType::RemoveAllHooks
                    | RequestType::DisableAllHooks
            )
        })
}

/// The reply to one request, as BehaviorTree.CPP's `serverLoop` gives it.
fn answer(parts: &[Vec<u8>], shared: &Shared) -> Vec<Vec<u8>> {
    if let Err(e) = check_parts(parts) {
        return encode_error_reply(&e.reply_text());
    }
    let header = match RequestHeader::decode(&parts[0]) {
        Ok(h) => h,
        Err(e) => return encode_error_reply(&e.reply_text()),
    };
    let Some(kind) = header
        .kind()
        .filter(|k| *k != RequestType::BreakpointReached)
    else {
        return encode_error_reply(
            &ProtocolError::UnknownType {
                code: header.type_code,
            }
            .reply_text(),
        );
    };
    if kind.needs_body() && parts.len() != 2 {
        return encode_error_reply(
            &ProtocolError::PartCount {
                kind,
                got: parts.len(),
            }
            .reply_text(),
        );
    }
    let body = parts.get(1).map_or(&[][..], Vec::as_slice);
    let mut reply = vec![
        ReplyHeader::answering(&header, shared.uuid)
            .encode()
            .to_vec(),
    ];
    let payload: Result<Option<Vec<u8>>, String> = match kind {
        RequestType::FullTree => Ok(Some(shared.xml.as_bytes().to_vec())),
        RequestType::Status => Ok(Some(shared.lock().status.encode())),
        RequestType::Blackboard => {
            let names = String::from_utf8_lossy(body);
            Ok(Some(shared.lock().blackboards.encode(&names)))
        }
        RequestType::HookInsert => insert_hooks(body, shared).map(|()| None),
        RequestType::HookRemove => remove_hook(body, shared).map(|()| None),
        RequestType::BreakpointUnlock => unlock_breakpoint(body, shared).map(|()| None),
        RequestType::HooksDump => Ok(Some(shared.lock().hooks.dump().into_bytes())),
        RequestType::RemoveAllHooks => {
            shared.lock().hooks.remove_all();
            Ok(None)
        }
        RequestType::DisableAllHooks => {
            shared.lock().hooks.enable_all(false);
            Ok(None)
        }
        RequestType::ToggleRecording => {
            let mut state = shared.lock();
            match body {
                b"start" => {
                    state.recording = true;
                    state.recording_start = Instant::now();
                    state.transitions.clear();
                    let now = SystemTime::now()
                        .duration_since(UNIX_EPOCH)
                        .unwrap_or_default()
                        .as_micros();
                    Ok(Some(now.to_string().into_bytes()))
                }
                b"stop" => {
                    state.recording = false;
                    Ok(None)
                }
                _ => Ok(None),
            }
        }
        RequestType::GetTransitions => {
            let mut state = shared.lock();
            let list: Vec<RecordedTransition> = state.transitions.drain(..).collect();
            Ok(Some(encode_transitions(&list)))
        }
        RequestType::BreakpointReached => unreachable!("refused above"),
    };
    match payload {
        Ok(Some(bytes)) => {
            reply.push(bytes);
            reply
        }
        Ok(None) => reply,
        Err(message) => encode_error_reply(&message),
    }
}

fn insert_hooks(body: &[u8], shared: &Shared) -> Result<(), String> {
    let hooks = decode_hooks(body).map_err(|e| e.to_string())?;
    let mut state = shared.lock();
    for hook in hooks {
        state.hooks.insert(hook);
    }
    Ok(())
}

fn remove_hook(body: &[u8], shared: &Shared) -> Result<(), String> {
    let removal = decode_hook_removal(body).map_err(|e| e.to_string())?;
    if shared.lock().hooks.remove(removal.uid, removal.position) {
        Ok(())
    } else {
        Err("Node ID not found".to_owned())
    }
}

fn unlock_breakpoint(body: &[u8], shared: &Shared) -> Result<(), String> {
    let unlock = decode_breakpoint_unlock(body).map_err(|e| e.to_string())?;
    if shared.lock().hooks.unlock(&unlock) {
        Ok(())
    } else {
        Err("Node ID not found".to_owned())
    }
}
