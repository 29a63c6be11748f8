//! Live monitors of behavior trees over the Groot2 protocol (`chronomap serve --bt-monitor
//! HOST:PORT`): any number of trees of any size, side by side — the free edition of Groot2
//! shows one tree of at most 20 nodes.
//!
//! Each monitor attaches to one Groot2 publisher (BehaviorTree.CPP's `Groot2Publisher`,
//! Nav2's, or `chronomap bt run --groot2`) with [`chronomap_groot2::client::Client`] on a
//! thread of its own: it reads the tree (`FULLTREE`) when it connects and again whenever the
//! tree changes, the node statuses (`STATUS`) [`STATUS_PERIOD`] apart, turns recording on and
//! collects the recorded transitions (`GET_TRANSITIONS`), and reads the blackboards when asked.
//! A publisher that goes away is tried again, sooner at first, then every
//! [`MAX_RETRY_DELAY`]; one that answers garbage is reported by the same error and tried the
//! same way. What a monitor keeps is bounded ([`MAX_EVENTS`], [`MAX_EVENT_CHANGES`],
//! [`MAX_TRANSITIONS`]; the client bounds each reply).
//!
//! * `GET /v1/bt/monitors`: every monitor, its connection and last error.
//! * `GET /v1/bt/monitors/{id}`: the tree, every node's status and the last error.
//! * `GET /v1/bt/monitors/{id}/events?after=SEQ&wait=SECS`: the status changes (and tree and
//!   connection changes) after `SEQ`, waiting up to `wait` seconds for one; with
//!   `Accept: text/event-stream`, the same as server-sent events.
//! * `GET /v1/bt/monitors/{id}/transitions?after=N`: the transitions the publisher recorded.
//! * `GET /v1/bt/monitors/{id}/blackboard`: every blackboard of the tree, read now.

use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, mpsc};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use axum::extract::rejection::{PathRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use chronomap_groot2::client::{
    Client, ClientError, ClientOptions, MsgValue, Status, StatusEntry, Tree,
};
use serde::{Deserialize, Serialize};
use utoipa::{IntoParams, ToSchema};

use crate::server::ApiError;

/// Time between two `STATUS` requests (20 Hz).
pub const STATUS_PERIOD: Duration = Duration::from_millis(50);
/// Time between two `GET_TRANSITIONS` requests (BehaviorTree.CPP keeps the last 1000: a
/// tree of 40 nodes ticked at 20 Hz makes about 300 a second).
pub const TRANSITIONS_PERIOD: Duration = Duration::from_millis(200);
/// Time between two `FULLTREE` requests while connected: a publisher restarted with another
/// tree between two status requests is noticed within this time (BehaviorTree.CPP's tree
/// UUID is the same in every process, so it cannot tell).
pub const TREE_PERIOD: Duration = Duration::from_secs(5);
/// First wait before connecting again to a publisher that went away; doubled up to
/// [`MAX_RETRY_DELAY`].
pub const FIRST_RETRY_DELAY: Duration = Duration::from_millis(250);
/// Longest wait before connecting again.
pub const MAX_RETRY_DELAY: Duration = Duration::from_secs(3);
/// Events kept per monitor (older ones are dropped; a reader that asks for them is told).
pub const MAX_EVENTS: usize = 4096;
/// Node status changes kept in the events of one monitor, all events together.
pub const MAX_EVENT_CHANGES: usize = 200_000;
/// Transitions kept per monitor.
pub const MAX_TRANSITIONS: usize = 20_000;
/// Longest `wait` of an events request (s).
pub const MAX_WAIT_SECS: f64 = 10.0;
/// Longest wait for a blackboard read by the monitor's thread.
pub const BLACKBOARD_TIMEOUT: Duration = Duration::from_secs(5);
/// Longest time a stream of server-sent events stays open; the browser's `EventSource`
/// connects again by itself, with `Last-Event-ID`.
pub const MAX_STREAM: Duration = Duration::from_secs(300);

/// One publisher to monitor: `--bt-monitor [NAME=]HOST:PORT`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MonitorTarget {
    /// The monitor's id in the API: NAME, or `HOST:PORT`.
    pub id: String,
    /// `HOST:PORT` of the publisher's request port (its PUB port is PORT + 1).
    pub address: String,
}

impl MonitorTarget {
    /// Reads `[NAME=]HOST:PORT`: NAME of letters, digits, `-`, `_`, `.` and `:`; a port
    /// from 1 to 65534 (the publisher also binds PORT + 1).
    ///
    /// # Errors
    /// The text names no host or port, or a malformed name, with what was wrong.
    pub fn parse(text: &str) -> Result<Self, String> {
        let (name, address) = match text.split_once('=') {
            Some((name, address)) => (Some(name), address),
            None => (None, text),
        };
        let (host, port) = address.rsplit_once(':').ok_or_else(|| {
            format!(
                "{text:?} is not [NAME=]HOST:PORT (a Groot2 publisher's port, e.g. 127.0.0.1:1667)"
            )
        })?;
        let host_ok = !host.is_empty()
            && host.len() <= 253
            && host
                .bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"-._:[]".contains(&b));
        if !host_ok {
            return Err(format!("{text:?}: {host:?} is not a host name or address"));
        }
        match port.parse::<u32>() {
            Ok(p) if (1..=65534).contains(&p) => {}
            _ => {
                return Err(format!(
                    "{text:?}: the port {port:?} is not a number from 1 to 65534 (the publisher \
                     also uses the next port)"
                ));
            }
        }
        let id = match name {
            Some(name) => {
                let ok = !name.is_empty()
                    && name.len() <= 64
                    && name
                        .bytes()
                        .all(|b| b.is_ascii_alphanumeric() || b"-_.:".contains(&b));
                if !ok {
                    return Err(format!(
                        "{text:?}: the name {name:?} must be 1 to 64 letters, digits, '-', '_', \
                         '.' or ':'"
                    ));
                }
                name.to_owned()
            }
            None => address.to_owned(),
        };
        Ok(MonitorTarget {
            id,
            address: address.to_owned(),
        })
    }
}

// ---------------------------------------------------------------------------------------------
// What the API answers

/// A node's status as the API says it: `idle`, `running`, `success`, `failure` or `skipped`.
/// A node that finished and went back to idle has `status` `idle` and its result in `last`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct BtNodeStatus {
    /// The node's `_uid`.
    pub uid: u16,
    /// Its status now.
    pub status: String,
    /// For an idle node, the status it had before it went back to idle (if any).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub last: Option<String>,
}

/// A node of a monitored tree.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct BtNode {
    /// The `_uid` the publisher gave it.
    pub uid: u16,
    /// Its type (the XML element: `Sequence`, `MoveTo`, ...).
    #[serde(rename = "type")]
    pub type_id: String,
    /// Its `name` attribute (the type when it has none).
    pub name: String,
    /// `Action`, `Condition`, `Control`, `Decorator` or `SubTree`, where the tree's model
    /// says.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub kind: Option<String>,
    /// Its parent (`null` for the root); a subtree's root has the `SubTree` node as parent.
    pub parent: Option<u16>,
    /// Its children in order.
    pub children: Vec<u16>,
    /// The path of the (sub)tree it belongs to (`""` for the main tree).
    pub tree: String,
    /// Its other attributes (ports, preconditions).
    pub ports: BTreeMap<String, String>,
}

/// A (sub)tree of a monitored tree.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct BtSubtree {
    /// Its `ID`.
    pub id: String,
    /// Its path (`_fullpath`; `""` for the main tree): the name of its blackboard, with `ID`
    /// for the main tree.
    pub path: String,
    /// Its root node.
    pub root: Option<u16>,
}

/// A monitored tree.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, ToSchema)]
pub struct BtTree {
    /// The main tree's `ID`.
    pub main: String,
    /// The root node (of the main tree).
    pub root: u16,
    /// The main tree, then its subtrees, in the publisher's order.
    pub trees: Vec<BtSubtree>,
    /// Every node, in the publisher's order.
    pub nodes: Vec<BtNode>,
}

/// A monitor in `GET /v1/bt/monitors`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BtMonitorSummary {
    /// Its id (`--bt-monitor NAME=...`, or `HOST:PORT`).
    pub id: String,
    /// The publisher's `HOST:PORT`.
    pub address: String,
    /// `connecting` (no answer yet), `connected` or `disconnected` (it answered before, and
    /// has stopped answering or answers garbage).
    pub state: String,
    /// The last error (`null` while connected).
    pub error: Option<String>,
    /// When `state` last changed (unix seconds).
    pub since: f64,
    /// The publisher's tree UUID (hex), once it answered.
    pub tree_uuid: Option<String>,
    /// The main tree's `ID`, once known.
    pub main_tree: Option<String>,
    /// Nodes of the tree (0 before it is known).
    pub nodes: usize,
    /// The last event's number (see `/events`).
    pub seq: u64,
    /// Increases each time another tree is read.
    pub tree_version: u64,
    /// `STATUS` replies received.
    pub status_polls: u64,
    /// Connections made again after one was lost.
    pub reconnects: u64,
}

/// Answer of `GET /v1/bt/monitors`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BtMonitorsResponse {
    /// In the order of the flags.
    pub monitors: Vec<BtMonitorSummary>,
}

/// Answer of `GET /v1/bt/monitors/{id}`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BtMonitorView {
    /// Connection, last error, counters.
    #[serde(flatten)]
    pub summary: BtMonitorSummary,
    /// The tree (`null` before the publisher answered).
    pub tree: Option<BtTree>,
    /// Every node's status, in the publisher's order, as of `status_time`.
    pub statuses: Vec<BtNodeStatus>,
    /// When the statuses were read (unix seconds).
    pub status_time: Option<f64>,
}

/// Something that happened to a monitor.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BtEvent {
    /// Its number: 1, 2, ... for each monitor.
    pub seq: u64,
    /// When (unix seconds).
    pub time: f64,
    /// `status` (nodes changed status: `changes`), `tree` (another tree was read),
    /// `connected`, `disconnected` or `error` (`message` says why).
    pub kind: String,
    /// The nodes whose status changed, with their new status.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub changes: Vec<BtNodeStatus>,
    /// What happened, for `tree`, `disconnected` and `error`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub message: Option<String>,
}

/// Answer of `GET /v1/bt/monitors/{id}/events`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BtEventsResponse {
    /// The last event's number: ask for `after` it next.
    pub seq: u64,
    /// Events after `after` were dropped (more than [`MAX_EVENTS`] since): read the whole
    /// view again.
    pub missed: bool,
    /// The events after `after`, oldest first.
    pub events: Vec<BtEvent>,
}

/// One recorded transition.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BtTransition {
    /// Its number among this monitor's transitions: 0, 1, ...
    pub n: u64,
    /// When (unix seconds: the publisher's recording start plus its offset).
    pub time: f64,
    /// The node's `_uid`.
    pub uid: u16,
    /// The status it went to (`idle`, `running`, `success`, `failure`, `skipped`).
    pub status: String,
}

/// Answer of `GET /v1/bt/monitors/{id}/transitions`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BtTransitionsResponse {
    /// When the publisher started recording (unix seconds, its clock), `null` if it is not.
    pub recording_since: Option<f64>,
    /// The next transition's number: ask for `after` it next.
    pub next: u64,
    /// Transitions numbered `after` or later that are still kept, oldest first.
    pub transitions: Vec<BtTransition>,
}

/// Answer of `GET /v1/bt/monitors/{id}/blackboard`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, ToSchema)]
pub struct BtBlackboardResponse {
    /// When it was read (unix seconds).
    pub time: f64,
    /// Each blackboard by the path of its (sub)tree (the main tree's `ID` for the main
    /// tree): its entries as JSON values.
    #[schema(value_type = Object)]
    pub blackboards: serde_json::Value,
}

/// Query of `/events`.
#[derive(Clone, Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
pub struct EventsQuery {
    /// Only events after this number (default: 0, every event kept).
    pub after: Option<u64>,
    /// Seconds to wait for an event when there is none yet (0 to 10; default 0).
    pub wait: Option<f64>,
}

/// Query of `/transitions`.
#[derive(Clone, Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
pub struct TransitionsQuery {
    /// Only transitions numbered this or later (default 0).
    pub after: Option<u64>,
}

// ---------------------------------------------------------------------------------------------
// The monitors

fn now_secs() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

fn status_name(status: Status) -> &'static str {
    match status {
        Status::Idle => "idle",
        Status::Running => "running",
        Status::Success => "success",
        Status::Failure => "failure",
        Status::Skipped => "skipped",
    }
}

fn status_view(entry: &StatusEntry) -> BtNodeStatus {
    BtNodeStatus {
        uid: entry.uid,
        status: status_name(entry.status).to_owned(),
        last: entry.last.map(|s| status_name(s).to_owned()),
    }
}

fn tree_view(tree: &Tree) -> BtTree {
    BtTree {
        main: tree.main.clone(),
        root: tree.root,
        trees: tree
            .trees
            .iter()
            .map(|t| BtSubtree {
                id: t.id.clone(),
                path: t.path.clone(),
                root: t.root,
            })
            .collect(),
        nodes: tree
            .nodes
            .iter()
            .map(|n| BtNode {
                uid: n.uid,
                type_id: n.type_id.clone(),
                name: n.name.clone(),
                kind: n.kind.clone(),
                parent: n.parent,
                children: n.children.clone(),
                tree: n.tree.clone(),
                ports: n.ports.iter().cloned().collect(),
            })
            .collect(),
    }
}

/// MessagePack (BehaviorTree.CPP's blackboard dump) as JSON; byte strings and extension
/// types become arrays of numbers, non-finite floats `null`, map keys that are not strings
/// their JSON text.
fn json_of(value: &MsgValue) -> serde_json::Value {
    use serde_json::Value;
    match value {
        MsgValue::Nil => Value::Null,
        MsgValue::Bool(b) => Value::Bool(*b),
        MsgValue::Int(i) => Value::from(*i),
        MsgValue::UInt(u) => Value::from(*u),
        MsgValue::F32(f) => {
            serde_json::Number::from_f64(f64::from(*f)).map_or(Value::Null, Value::Number)
        }
        MsgValue::F64(f) => serde_json::Number::from_f64(*f).map_or(Value::Null, Value::Number),
        MsgValue::Str(s) => Value::String(s.clone()),
        MsgValue::Bin(b) | MsgValue::Ext(_, b) => {
            Value::Array(b.iter().map(|&x| Value::from(x)).collect())
        }
        MsgValue::Array(items) => Value::Array(items.iter().map(json_of).collect()),
        MsgValue::Map(entries) => Value::Object(
            entries
                .iter()
                .map(|(k, v)| {
                    let key = match k {
                        MsgValue::Str(s) => s.clone(),
                        other => json_of(other).to_string(),
                    };
                    (key, json_of(v))
                })
                .collect(),
        ),
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Connection {
    Connecting,
    Connected,
    Disconnected,
}

impl Connection {
    fn name(self) -> &'static str {
        match self {
            Connection::Connecting => "connecting",
            Connection::Connected => "connected",
            Connection::Disconnected => "disconnected",
        }
    }
}

/// What one monitor knows; written by its thread, read by requests.
struct Data {
    connection: Connection,
    error: Option<String>,
    since: f64,
    tree_uuid: Option<[u8; 16]>,
    tree: Option<Arc<BtTree>>,
    tree_version: u64,
    statuses: Vec<StatusEntry>,
    status_time: Option<f64>,
    seq: u64,
    events: VecDeque<BtEvent>,
    event_changes: usize,
    transitions: VecDeque<BtTransition>,
    next_transition: u64,
    recording_since: Option<f64>,
    status_polls: u64,
    reconnects: u64,
}

impl Data {
    fn new() -> Self {
        Data {
            connection: Connection::Connecting,
            error: None,
            since: now_secs(),
            tree_uuid: None,
            tree: None,
            tree_version: 0,
            statuses: Vec::new(),
            status_time: None,
            seq: 0,
            events: VecDeque::new(),
            event_changes: 0,
            transitions: VecDeque::new(),
            next_transition: 0,
            recording_since: None,
            status_polls: 0,
            reconnects: 0,
        }
    }

    fn push_event(&mut self, kind: &str, changes: Vec<BtNodeStatus>, message: Option<String>) {
        self.seq += 1;
        self.event_changes += changes.len();
        self.events.push_back(BtEvent {
            seq: self.seq,
            time: now_secs(),
            kind: kind.to_owned(),
            changes,
            message,
        });
        while self.events.len() > MAX_EVENTS
            || (self.event_changes > MAX_EVENT_CHANGES && self.events.len() > 1)
        {
            if let Some(old) = self.events.pop_front() {
                self.event_changes -= old.changes.len();
            }
        }
    }

    fn set_connection(&mut self, connection: Connection, error: Option<String>) {
        if connection != self.connection {
            if connection == Connection::Connected && self.connection == Connection::Disconnected {
                self.reconnects += 1;
            }
            self.connection = connection;
            self.since = now_secs();
            let kind = match connection {
                Connection::Connected => "connected",
                _ => "disconnected",
            };
            self.push_event(kind, Vec::new(), error.clone());
        } else if error.is_some() && error != self.error {
            self.push_event("error", Vec::new(), error.clone());
        }
        if connection != Connection::Connected {
            self.recording_since = None;
        }
        self.error = error;
    }

    fn summary(&self, id: &str, address: &str) -> BtMonitorSummary {
        BtMonitorSummary {
            id: id.to_owned(),
            address: address.to_owned(),
            state: self.connection.name().to_owned(),
            error: self.error.clone(),
            since: self.since,
            tree_uuid: self
                .tree_uuid
                .map(|u| u.iter().map(|b| format!("{b:02x}")).collect()),
            main_tree: self.tree.as_ref().map(|t| t.main.clone()),
            nodes: self.tree.as_ref().map_or(0, |t| t.nodes.len()),
            seq: self.seq,
            tree_version: self.tree_version,
            status_polls: self.status_polls,
            reconnects: self.reconnects,
        }
    }
}

type BlackboardReply = Result<serde_json::Value, String>;

enum Command {
    Blackboard(tokio::sync::oneshot::Sender<BlackboardReply>),
}

/// One monitor: its target, what it knows, and the way to its thread.
struct Monitor {
    target: MonitorTarget,
    data: Mutex<Data>,
    /// Sends the last event's number after each event.
    events: tokio::sync::watch::Sender<u64>,
    commands: Mutex<mpsc::Sender<Command>>,
}

impl Monitor {
    fn data(&self) -> std::sync::MutexGuard<'_, Data> {
        self.data.lock().expect("monitor data lock")
    }

    fn notify(&self, seq: u64) {
        self.events.send_replace(seq);
    }
}

/// Every monitor of a service; stops their threads when dropped.
pub struct BtMonitors {
    monitors: Vec<Arc<Monitor>>,
    stop: Arc<AtomicBool>,
    /// `true` once stopping: ends the streams of events.
    stopping: tokio::sync::watch::Sender<bool>,
    threads: Mutex<Vec<std::thread::JoinHandle<()>>>,
}

impl Default for BtMonitors {
    fn default() -> Self {
        BtMonitors {
            monitors: Vec::new(),
            stop: Arc::new(AtomicBool::new(false)),
            stopping: tokio::sync::watch::channel(false).0,
            threads: Mutex::new(Vec::new()),
        }
    }
}

impl std::fmt::Debug for BtMonitors {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list()
            .entries(self.monitors.iter().map(|m| &m.target))
            .finish()
    }
}

/// How monitors talk to publishers.
#[derive(Clone, Copy, Debug)]
pub struct MonitorOptions {
    /// Limits of each request (timeout, largest reply).
    pub client: ClientOptions,
    /// Time between two `STATUS` requests.
    pub status_period: Duration,
}

impl Default for MonitorOptions {
    fn default() -> Self {
        MonitorOptions {
            client: ClientOptions::default(),
            status_period: STATUS_PERIOD,
        }
    }
}

impl BtMonitors {
    /// Starts one monitor thread per target.
    ///
    /// # Errors
    /// Two targets have the same id, or a thread cannot be started.
    pub fn start(targets: Vec<MonitorTarget>, options: MonitorOptions) -> Result<Self, String> {
        // Dropped on an error: the threads started so far are stopped.
        let mut monitors = BtMonitors::default();
        for target in targets {
            if monitors.monitors.iter().any(|m| m.target.id == target.id) {
                return Err(format!(
                    "--bt-monitor {}: two monitors have this id; name them (NAME=HOST:PORT)",
                    target.id
                ));
            }
            let (commands, received) = mpsc::channel();
            let monitor = Arc::new(Monitor {
                target,
                data: Mutex::new(Data::new()),
                events: tokio::sync::watch::channel(0).0,
                commands: Mutex::new(commands),
            });
            let (thread_monitor, stop) = (Arc::clone(&monitor), Arc::clone(&monitors.stop));
            let handle = std::thread::Builder::new()
                .name(format!("bt-monitor {}", monitor.target.id))
                .spawn(move || watch(&thread_monitor, &received, &stop, options))
                .map_err(|e| format!("cannot start a monitor thread: {e}"))?;
            monitors.threads.lock().expect("threads lock").push(handle);
            monitors.monitors.push(monitor);
        }
        Ok(monitors)
    }

    /// Number of monitors.
    pub fn len(&self) -> usize {
        self.monitors.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.monitors.is_empty()
    }

    /// Stops every monitor (each says `stop` to its publisher's recording) and ends the
    /// streams of events; returns at once.
    pub fn stop(&self) {
        self.stop.store(true, Ordering::Release);
        self.stopping.send_replace(true);
    }

    fn get(&self, id: &str) -> Result<&Arc<Monitor>, ApiError> {
        self.monitors
            .iter()
            .find(|m| m.target.id == id)
            .ok_or_else(|| {
                let known: Vec<&str> = self.monitors.iter().map(|m| m.target.id.as_str()).collect();
                ApiError::not_found(format!(
                    "no behavior-tree monitor {id:?} (monitored: {})",
                    if known.is_empty() {
                        "none; start the service with --bt-monitor HOST:PORT".to_owned()
                    } else {
                        known.join(", ")
                    }
                ))
            })
    }
}

impl Drop for BtMonitors {
    fn drop(&mut self) {
        self.stop();
        let threads = std::mem::take(&mut *self.threads.lock().expect("threads lock"));
        for handle in threads {
            let _ = handle.join();
        }
    }
}

/// Sleeps until `deadline`, answering commands meanwhile; `false` once stopping.
fn wait_until(
    deadline: Instant,
    commands: &mpsc::Receiver<Command>,
    pending: &mut Vec<Command>,
    stop: &AtomicBool,
) -> bool {
    loop {
        if stop.load(Ordering::Acquire) {
            return false;
        }
        let now = Instant::now();
        if now >= deadline {
            return true;
        }
        // Woken at least every 100 ms to see `stop`.
        let slice = (deadline - now).min(Duration::from_millis(100));
        match commands.recv_timeout(slice) {
            Ok(command) => {
                pending.push(command);
                return true;
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => std::thread::sleep(slice),
        }
    }
}

/// The monitor's thread: connect, read the tree, poll, reconnect, until `stop`.
fn watch(
    monitor: &Monitor,
    commands: &mpsc::Receiver<Command>,
    stop: &AtomicBool,
    options: MonitorOptions,
) {
    let mut retry = FIRST_RETRY_DELAY;
    let mut pending = Vec::new();
    while !stop.load(Ordering::Acquire) {
        let outcome = match Client::new(&monitor.target.address, options.client) {
            Ok(mut client) => {
                let outcome = session(monitor, &mut client, commands, &mut pending, stop, options);
                if outcome.is_ok() {
                    // Stopping: leave the publisher as it was found.
                    let _ = client.stop_recording();
                }
                outcome
            }
            Err(e) => Err(e),
        };
        let Err(error) = outcome else { break };
        let was_connected = {
            let mut data = monitor.data();
            let was = data.connection == Connection::Connected;
            let next = if data.connection == Connection::Connecting {
                Connection::Connecting
            } else {
                Connection::Disconnected
            };
            data.set_connection(next, Some(error.to_string()));
            monitor.notify(data.seq);
            was
        };
        if was_connected {
            retry = FIRST_RETRY_DELAY;
        }
        for command in pending.drain(..) {
            let Command::Blackboard(reply) = command;
            let _ = reply.send(Err(error.to_string()));
        }
        let deadline = Instant::now() + retry;
        retry = (retry * 2).min(MAX_RETRY_DELAY);
        while wait_until(deadline, commands, &mut pending, stop) && Instant::now() < deadline {
            for command in pending.drain(..) {
                let Command::Blackboard(reply) = command;
                let _ = reply.send(Err(format!(
                    "the publisher at {} does not answer: {error}",
                    monitor.target.address
                )));
            }
        }
    }
    for command in pending.drain(..) {
        let Command::Blackboard(reply) = command;
        let _ = reply.send(Err("the service is stopping".into()));
    }
}

/// Reads the tree and makes it the monitor's if it is another one; `true` if it changed.
fn read_tree(monitor: &Monitor, client: &mut Client) -> Result<bool, ClientError> {
    let reply = client.full_tree()?;
    let view = tree_view(&reply.tree);
    let mut data = monitor.data();
    let changed = data.tree.as_deref() != Some(&view) || data.tree_uuid != Some(reply.uuid);
    if changed {
        let message = format!(
            "tree {} with {} nodes{}",
            view.main,
            view.nodes.len(),
            if data.tree.is_some() {
                " (another tree than before)"
            } else {
                ""
            }
        );
        data.tree = Some(Arc::new(view));
        data.tree_uuid = Some(reply.uuid);
        data.tree_version += 1;
        data.statuses.clear();
        data.status_time = None;
        data.push_event("tree", Vec::new(), Some(message));
        monitor.notify(data.seq);
    }
    Ok(changed)
}

/// One connection's life: `Ok` when stopping, the error that ended it otherwise.
fn session(
    monitor: &Monitor,
    client: &mut Client,
    commands: &mpsc::Receiver<Command>,
    pending: &mut Vec<Command>,
    stop: &AtomicBool,
    options: MonitorOptions,
) -> Result<(), ClientError> {
    read_tree(monitor, client)?;
    let started = client.start_recording()?;
    // Connected once the statuses fit the tree: a publisher that sends a tree and then
    // garbage is retried with growing delays, not reported connected again and again.
    poll_status(monitor, client)?;
    {
        let mut data = monitor.data();
        data.set_connection(Connection::Connected, None);
        data.recording_since = Some(started as f64 / 1e6);
        monitor.notify(data.seq);
    }
    let mut next_status = Instant::now();
    let mut next_transitions = Instant::now() + TRANSITIONS_PERIOD;
    let mut next_tree = Instant::now() + TREE_PERIOD;
    loop {
        for command in pending.drain(..) {
            let Command::Blackboard(reply) = command;
            let names: Vec<String> = {
                let data = monitor.data();
                data.tree.as_ref().map_or_else(Vec::new, |t| {
                    t.trees
                        .iter()
                        .map(|s| {
                            if s.path.is_empty() {
                                s.id.clone()
                            } else {
                                s.path.clone()
                            }
                        })
                        .collect()
                })
            };
            match client.blackboard(&names) {
                Ok(value) => {
                    let _ = reply.send(Ok(json_of(&value)));
                }
                Err(e) => {
                    let _ = reply.send(Err(e.to_string()));
                    return Err(e);
                }
            }
        }
        let now = Instant::now();
        if now >= next_tree {
            next_tree = now + TREE_PERIOD;
            if read_tree(monitor, client)? {
                let started = client.start_recording()?;
                monitor.data().recording_since = Some(started as f64 / 1e6);
            }
        }
        if now >= next_status {
            next_status = now + options.status_period;
            poll_status(monitor, client)?;
        }
        if now >= next_transitions {
            next_transitions = now + TRANSITIONS_PERIOD;
            poll_transitions(monitor, client)?;
        }
        let deadline = next_status.min(next_transitions).min(next_tree);
        if !wait_until(deadline, commands, pending, stop) {
            return Ok(());
        }
    }
}

fn poll_status(monitor: &Monitor, client: &mut Client) -> Result<(), ClientError> {
    let reply = client.status()?;
    let mut tree_checked = false;
    loop {
        let mut data = monitor.data();
        let Some(tree) = data.tree.clone() else {
            return Ok(());
        };
        // The same uids as the tree's nodes (BehaviorTree.CPP sends them in the tree's
        // order; another publisher may not).
        let matches = data.tree_uuid == Some(reply.uuid)
            && reply.entries.len() == tree.nodes.len()
            && (reply
                .entries
                .iter()
                .zip(&tree.nodes)
                .all(|(e, n)| e.uid == n.uid)
                || {
                    let mut sent: Vec<u16> = reply.entries.iter().map(|e| e.uid).collect();
                    let mut known: Vec<u16> = tree.nodes.iter().map(|n| n.uid).collect();
                    sent.sort_unstable();
                    known.sort_unstable();
                    sent == known
                });
        if !matches {
            drop(data);
            if tree_checked {
                return Err(client.malformed(
                    "STATUS",
                    format!(
                        "{} node statuses that do not match the {} nodes of the tree it sends",
                        reply.entries.len(),
                        tree.nodes.len()
                    ),
                ));
            }
            // The publisher runs another tree now: read it, then take these statuses if
            // they are the new tree's.
            tree_checked = true;
            if read_tree(monitor, client)? {
                let started = client.start_recording()?;
                monitor.data().recording_since = Some(started as f64 / 1e6);
            }
            continue;
        }
        let changes: Vec<BtNodeStatus> = if data.statuses.len() == reply.entries.len() {
            reply
                .entries
                .iter()
                .zip(&data.statuses)
                .filter(|(new, old)| new != old)
                .map(|(new, _)| status_view(new))
                .collect()
        } else {
            reply.entries.iter().map(status_view).collect()
        };
        data.statuses = reply.entries;
        data.status_time = Some(now_secs());
        data.status_polls += 1;
        if !changes.is_empty() {
            data.push_event("status", changes, None);
            monitor.notify(data.seq);
        }
        return Ok(());
    }
}

fn poll_transitions(monitor: &Monitor, client: &mut Client) -> Result<(), ClientError> {
    let transitions = client.transitions()?;
    let mut data = monitor.data();
    let Some(since) = data.recording_since else {
        return Ok(());
    };
    for t in transitions {
        let n = data.next_transition;
        data.next_transition += 1;
        data.transitions.push_back(BtTransition {
            n,
            time: since + t.usec as f64 / 1e6,
            uid: t.uid,
            status: status_name(t.status).to_owned(),
        });
    }
    while data.transitions.len() > MAX_TRANSITIONS {
        data.transitions.pop_front();
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// HTTP

/// The routes of `/v1/bt/monitors`.
pub fn router(monitors: Arc<BtMonitors>) -> Router {
    Router::new()
        .route("/v1/bt/monitors", get(list))
        .route("/v1/bt/monitors/{id}", get(view))
        .route("/v1/bt/monitors/{id}/events", get(events))
        .route("/v1/bt/monitors/{id}/transitions", get(transitions))
        .route("/v1/bt/monitors/{id}/blackboard", get(blackboard))
        .with_state(monitors)
}

fn path_id(path: Result<Path<String>, PathRejection>) -> Result<String, ApiError> {
    let Path(id) =
        path.map_err(|e| ApiError::bad_request(format!("monitor id in the path: {e}")))?;
    Ok(id)
}

fn query<T>(query: Result<Query<T>, QueryRejection>) -> Result<T, ApiError> {
    query
        .map(|Query(q)| q)
        .map_err(|e| ApiError::bad_request(format!("query: {}", e.body_text())))
}

/// Every monitored behavior tree: its publisher, connection, last error and counters.
#[utoipa::path(get, path = "/v1/bt/monitors",
    responses((status = 200, body = BtMonitorsResponse)))]
pub(crate) async fn list(State(monitors): State<Arc<BtMonitors>>) -> Json<BtMonitorsResponse> {
    Json(BtMonitorsResponse {
        monitors: monitors
            .monitors
            .iter()
            .map(|m| m.data().summary(&m.target.id, &m.target.address))
            .collect(),
    })
}

/// A monitored tree: its nodes, every node's status now and the last error.
#[utoipa::path(get, path = "/v1/bt/monitors/{id}",
    params(("id" = String, Path, description = "monitor id")),
    responses((status = 200, body = BtMonitorView), (status = 404, body = crate::api::ErrorBody)))]
pub(crate) async fn view(
    State(monitors): State<Arc<BtMonitors>>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<BtMonitorView>, ApiError> {
    let id = path_id(path)?;
    let monitor = monitors.get(&id)?;
    let data = monitor.data();
    Ok(Json(BtMonitorView {
        summary: data.summary(&monitor.target.id, &monitor.target.address),
        tree: data.tree.as_deref().cloned(),
        statuses: data.statuses.iter().map(status_view).collect(),
        status_time: data.status_time,
    }))
}

fn events_after(data: &Data, after: u64) -> BtEventsResponse {
    let oldest = data.events.front().map_or(data.seq + 1, |e| e.seq);
    BtEventsResponse {
        seq: data.seq,
        missed: after + 1 < oldest && after < data.seq,
        events: data
            .events
            .iter()
            .filter(|e| e.seq > after)
            .cloned()
            .collect(),
    }
}

/// What happened to a monitor after event `after`: node status changes (as the monitor
/// sees them at 20 Hz), another tree, a connection made or lost. With `wait`, an answer
/// without events comes only after that many seconds. With `Accept: text/event-stream`,
/// server-sent events (`id:` the event's number, `event:` its kind, `data:` the event as
/// JSON), from `Last-Event-ID` or `after` on.
#[utoipa::path(get, path = "/v1/bt/monitors/{id}/events",
    params(("id" = String, Path, description = "monitor id"), EventsQuery),
    responses((status = 200, body = BtEventsResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody)))]
pub(crate) async fn events(
    State(monitors): State<Arc<BtMonitors>>,
    path: Result<Path<String>, PathRejection>,
    params: Result<Query<EventsQuery>, QueryRejection>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let id = path_id(path)?;
    let params = query(params)?;
    let monitor = Arc::clone(monitors.get(&id)?);
    let wait = params.wait.unwrap_or(0.0);
    if !(0.0..=MAX_WAIT_SECS).contains(&wait) {
        return Err(ApiError::bad_request(format!(
            "query `wait`: {wait} is not a number of seconds from 0 to {MAX_WAIT_SECS}"
        )));
    }
    let stream = headers
        .get(header::ACCEPT)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.contains("text/event-stream"));
    if stream {
        let last = headers
            .get("last-event-id")
            .and_then(|v| v.to_str().ok()?.trim().parse::<u64>().ok());
        let after = last.or(params.after).unwrap_or(0);
        return Ok(event_stream(monitor, monitors.stopping.subscribe(), after));
    }
    let after = params.after.unwrap_or(0);
    let mut changed = monitor.events.subscribe();
    let answer = events_after(&monitor.data(), after);
    if !answer.events.is_empty() || wait == 0.0 || answer.missed {
        return Ok(Json(answer).into_response());
    }
    let deadline = tokio::time::Instant::now() + Duration::from_secs_f64(wait);
    let mut stopping = monitors.stopping.subscribe();
    loop {
        tokio::select! {
            _ = tokio::time::sleep_until(deadline) => break,
            _ = stopping.wait_for(|&s| s) => break,
            changed = changed.changed() => if changed.is_err() { break },
        }
        if *changed.borrow_and_update() > after {
            break;
        }
    }
    Ok(Json(events_after(&monitor.data(), after)).into_response())
}

/// One server-sent event: `id:` its number, `event:` its kind, `data:` it as JSON.
fn sse_text(event: &BtEvent) -> String {
    let data = serde_json::to_string(event).unwrap_or_default();
    format!("id: {}\nevent: {}\ndata: {data}\n\n", event.seq, event.kind)
}

/// Server-sent events from event `after` on, until the client goes, the service stops or
/// [`MAX_STREAM`] has passed; a comment line every 15 s keeps proxies from closing it.
fn event_stream(
    monitor: Arc<Monitor>,
    mut stopping: tokio::sync::watch::Receiver<bool>,
    after: u64,
) -> Response {
    let (send, receive) = tokio::sync::mpsc::channel::<String>(64);
    let mut changed = monitor.events.subscribe();
    tokio::spawn(async move {
        let end = tokio::time::Instant::now() + MAX_STREAM;
        let mut after = after;
        loop {
            let answer = events_after(&monitor.data(), after);
            if answer.missed {
                let gap = format!("event: missed\ndata: {{\"seq\":{}}}\n\n", answer.seq);
                if send.send(gap).await.is_err() {
                    return;
                }
            }
            for event in &answer.events {
                if send.send(sse_text(event)).await.is_err() {
                    return;
                }
            }
            after = after.max(answer.seq);
            let keep_alive = tokio::time::sleep(Duration::from_secs(15));
            // `true`: send a keep-alive comment; `false`: stop; `None`: new events.
            let quiet = tokio::select! {
                () = tokio::time::sleep_until(end) => Some(false),
                _ = stopping.wait_for(|&s| s) => Some(false),
                () = send.closed() => Some(false),
                () = keep_alive => Some(true),
                changed = changed.changed() => changed.is_err().then_some(false),
            };
            match quiet {
                Some(false) => return,
                Some(true) if send.send(":\n\n".into()).await.is_err() => return,
                _ => {}
            }
        }
    });
    let mut response = axum::body::Body::new(SseBody(receive)).into_response();
    let headers = response.headers_mut();
    headers.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("text/event-stream"),
    );
    headers.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-cache"));
    response
}

/// The body of a stream of events: what the task sends, until it ends.
struct SseBody(tokio::sync::mpsc::Receiver<String>);

impl hyper::body::Body for SseBody {
    type Data = axum::body::Bytes;
    type Error = std::convert::Infallible;

    fn poll_frame(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<Option<Result<hyper::body::Frame<Self::Data>, Self::Error>>> {
        self.0
            .poll_recv(cx)
            .map(|text| text.map(|t| Ok(hyper::body::Frame::data(t.into()))))
    }
}

/// The transitions the publisher recorded (the monitor turns recording on when it
/// connects and collects them five times a second), numbered `after` and later.
#[utoipa::path(get, path = "/v1/bt/monitors/{id}/transitions",
    params(("id" = String, Path, description = "monitor id"), TransitionsQuery),
    responses((status = 200, body = BtTransitionsResponse), (status = 400, body = crate::api::ErrorBody),
              (status = 404, body = crate::api::ErrorBody)))]
pub(crate) async fn transitions(
    State(monitors): State<Arc<BtMonitors>>,
    path: Result<Path<String>, PathRejection>,
    params: Result<Query<TransitionsQuery>, QueryRejection>,
) -> Result<Json<BtTransitionsResponse>, ApiError> {
    let id = path_id(path)?;
    let after = query(params)?.after.unwrap_or(0);
    let monitor = monitors.get(&id)?;
    let data = monitor.data();
    Ok(Json(BtTransitionsResponse {
        recording_since: data.recording_since,
        next: data.next_transition,
        transitions: data
            .transitions
            .iter()
            .filter(|t| t.n >= after)
            .cloned()
            .collect(),
    }))
}

/// Every blackboard of the monitored tree (the main tree's and each subtree's), read from
/// the publisher now. `503` while it does not answer.
#[utoipa::path(get, path = "/v1/bt/monitors/{id}/blackboard",
    params(("id" = String, Path, description = "monitor id")),
    responses((status = 200, body = BtBlackboardResponse), (status = 404, body = crate::api::ErrorBody),
              (status = 503, body = crate::api::ErrorBody)))]
pub(crate) async fn blackboard(
    State(monitors): State<Arc<BtMonitors>>,
    path: Result<Path<String>, PathRejection>,
) -> Result<Json<BtBlackboardResponse>, ApiError> {
    let id = path_id(path)?;
    let monitor = monitors.get(&id)?;
    let unavailable =
        |reason: String| ApiError::new(StatusCode::SERVICE_UNAVAILABLE, "unavailable", reason);
    {
        let data = monitor.data();
        if data.connection != Connection::Connected {
            return Err(unavailable(data.error.clone().unwrap_or_else(|| {
                format!(
                    "the publisher at {} has not answered yet",
                    monitor.target.address
                )
            })));
        }
    }
    let (send, receive) = tokio::sync::oneshot::channel();
    monitor
        .commands
        .lock()
        .expect("commands lock")
        .send(Command::Blackboard(send))
        .map_err(|_| unavailable("the monitor has stopped".into()))?;
    let answer = tokio::time::timeout(BLACKBOARD_TIMEOUT, receive)
        .await
        .map_err(|_| {
            unavailable(format!(
                "the publisher at {} did not send the blackboards within {} s",
                monitor.target.address,
                BLACKBOARD_TIMEOUT.as_secs()
            ))
        })?
        .map_err(|_| unavailable("the monitor has stopped".into()))?;
    let blackboards = answer.map_err(unavailable)?;
    Ok(Json(BtBlackboardResponse {
        time: now_secs(),
        blackboards,
    }))
}

#[cfg(test)]
#[path = "bt_monitor_tests.rs"]
mod tests;
