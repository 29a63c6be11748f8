//! Hooks acting on the ticks of a tree served by a [`Publisher`], driven by a ZeroMQ client
//! as Groot2 drives BehaviorTree.CPP's `Groot2Publisher`: a breakpoint holds the ticking
//! thread (the server answers meanwhile) until it is unlocked, until the client has been
//! silent for the heartbeat delay, or until the publisher is dropped; a replacement gives the
//! node's result; every hook that acts is announced on the PUB socket.

use std::sync::mpsc;
use std::time::{Duration, Instant};

use chronomap_bt::{BtDocument, NodeDef, Registry, Status, TreeDef};
use chronomap_groot2::protocol::{RequestType, encode_request};
use chronomap_groot2::publisher::Publisher;
use chronomap_testutil::free_port_pair;

/// Sequence(1) of AlwaysSuccess(2) and AlwaysSuccess(3).
fn doc() -> BtDocument {
    BtDocument::single(TreeDef::new(
        "Main",
        NodeDef::control("Sequence")
            .child(NodeDef::action("AlwaysSuccess"))
            .child(NodeDef::action("AlwaysSuccess")),
    ))
}

struct Client {
    req: zmq::Socket,
    sub: zmq::Socket,
    _ctx: zmq::Context,
    next: u32,
}

impl Client {
    fn new(port: u16) -> Client {
        let ctx = zmq::Context::new();
        let sub = ctx.socket(zmq::SUB).unwrap();
        sub.set_subscribe(b"").unwrap();
        sub.set_rcvtimeo(5000).unwrap();
        sub.connect(&format!("tcp://127.0.0.1:{}", port + 1))
            .unwrap();
        let req = ctx.socket(zmq::REQ).unwrap();
        req.set_linger(0).unwrap();
        req.set_rcvtimeo(5000).unwrap();
        req.connect(&format!("tcp://127.0.0.1:{port}")).unwrap();
        // Let the subscription reach the publisher before anything is published.
        std::thread::sleep(Duration::from_millis(200));
        Client {
            req,
            sub,
            _ctx: ctx,
            next: 1,
        }
    }

    /// The payload of the reply (empty when there is none), or the error text prefixed by
    /// "error: ".
    fn ask(&mut self, kind: RequestType, body: Option<&str>) -> String {
        self.next += 1;
        self.req
            .send_multipart(encode_request(kind, self.next, body.map(str::as_bytes)), 0)
            .unwrap();
        let reply = self.req.recv_multipart(0).expect("a reply within 5 s");
        if reply[0] == b"error" {
            return format!("error: {}", String::from_utf8_lossy(&reply[1]));
        }
        reply
            .get(1)
            .map(|p| String::from_utf8_lossy(p).into_owned())
            .unwrap_or_default()
    }

    /// The uid of the next BREAKPOINT_REACHED notification, after checking its header.
    fn reached(&self) -> u16 {
        let parts = self
            .sub
            .recv_multipart(0)
            .expect("a notification within 5 s");
        assert_eq!(parts.len(), 2);
        assert_eq!(&parts[0][..2], &[2, b'N'], "protocol 2, BREAKPOINT_REACHED");
        assert_eq!(parts[0].len(), 6);
        String::from_utf8(parts[1].clone())
            .unwrap()
            .parse()
            .unwrap()
    }
}

fn hook(uid: u16, mode: u8, status: &str) -> String {
    format!(
        r#"{{"enabled":true,"uid":{uid},"mode":{mode},"once":false,"desired_status":"{status}","position":0}}"#
    )
}

fn unlock(uid: u16, status: &str) -> String {
    format!(r#"{{"uid":{uid},"position":0,"desired_status":"{status}","remove_when_done":false}}"#)
}

#[test]
fn breakpoint_holds_the_tick_until_unlocked_and_replacement_gives_the_result() {
    let doc = doc();
    let mut tree = chronomap_bt::Tree::new(&doc, &Registry::new()).unwrap();
    let port = free_port_pair();
    let publisher = Publisher::start_on(&tree, &doc, "127.0.0.1", port).unwrap();
    tree.set_tick_monitor(Some(publisher.tick_monitor()));
    let mut client = Client::new(port);
    let hooks = format!("[{},{}]", hook(2, 0, "SKIPPED"), hook(3, 1, "FAILURE"));
    assert_eq!(client.ask(RequestType::HookInsert, Some(&hooks)), "");
    let (done, result) = mpsc::channel();
    std::thread::scope(|s| {
        s.spawn(|| {
            let status = tree.tick_exactly_once(Duration::ZERO).unwrap();
            done.send(status).unwrap();
        });
        assert_eq!(client.reached(), 2);
        // Held: no result, and the server answers meanwhile.
        assert!(result.recv_timeout(Duration::from_millis(500)).is_err());
        assert_eq!(client.ask(RequestType::Status, None).len(), 9);
        assert_eq!(
            client.ask(RequestType::BreakpointUnlock, Some(&unlock(2, ""))),
            ""
        );
        // The first leaf is ticked (SUCCESS), the second replaced by FAILURE.
        assert_eq!(client.reached(), 3);
        assert_eq!(
            result.recv_timeout(Duration::from_secs(5)).unwrap(),
            Status::Failure
        );
    });
    // Without hooks the tree succeeds.
    assert_eq!(client.ask(RequestType::RemoveAllHooks, None), "");
    assert_eq!(
        tree.tick_exactly_once(Duration::ZERO).unwrap(),
        Status::Success
    );
}

#[test]
fn an_unlock_with_a_status_replaces_the_held_nodes_tick() {
    let doc = doc();
    let mut tree = chronomap_bt::Tree::new(&doc, &Registry::new()).unwrap();
    let port = free_port_pair();
    let publisher = Publisher::start_on(&tree, &doc, "127.0.0.1", port).unwrap();
    tree.set_tick_monitor(Some(publisher.tick_monitor()));
    let mut client = Client::new(port);
    assert_eq!(
        client.ask(RequestType::HookInsert, Some(&hook(2, 0, "SKIPPED"))),
        ""
    );
    let (done, result) = mpsc::channel();
    std::thread::scope(|s| {
        s.spawn(|| {
            done.send(tree.tick_exactly_once(Duration::ZERO).unwrap())
                .unwrap();
        });
        assert_eq!(client.reached(), 2);
        client.ask(RequestType::BreakpointUnlock, Some(&unlock(2, "FAILURE")));
        assert_eq!(
            result.recv_timeout(Duration::from_secs(5)).unwrap(),
            Status::Failure
        );
    });
}

#[test]
fn a_silent_client_lets_the_held_tick_go_after_the_heartbeat_delay() {
    let doc = doc();
    let mut tree = chronomap_bt::Tree::new(&doc, &Registry::new()).unwrap();
    let port = free_port_pair();
    let publisher = Publisher::start_on(&tree, &doc, "127.0.0.1", port).unwrap();
    let delay = Duration::from_millis(400);
    publisher.set_max_heartbeat_delay(delay);
    assert_eq!(publisher.max_heartbeat_delay(), delay);
    tree.set_tick_monitor(Some(publisher.tick_monitor()));
    let mut client = Client::new(port);
    assert_eq!(
        client.ask(RequestType::HookInsert, Some(&hook(1, 0, "SKIPPED"))),
        ""
    );
    let (done, result) = mpsc::channel();
    std::thread::scope(|s| {
        s.spawn(|| {
            done.send(tree.tick_exactly_once(Duration::ZERO).unwrap())
                .unwrap();
        });
        assert_eq!(client.reached(), 1);
        // A client that keeps asking keeps the breakpoint (3 delays long).
        let start = Instant::now();
        while start.elapsed() < 3 * delay {
            client.ask(RequestType::Status, None);
            assert!(result.recv_timeout(Duration::from_millis(100)).is_err());
        }
        // Silence: released after the delay (seen within 0.1 s), the node ticked normally.
        let silent = Instant::now();
        let status = result.recv_timeout(Duration::from_secs(5)).unwrap();
        let held = silent.elapsed();
        assert_eq!(status, Status::Success);
        assert!(held >= delay - Duration::from_millis(150), "{held:?}");
        assert!(held < delay + Duration::from_secs(2), "{held:?}");
    });
    // The hook stays, disabled; the request that ends the silence is answered first, then the
    // hooks are enabled again (BehaviorTree.CPP's heartbeat thread).
    let disabled = client.ask(RequestType::HooksDump, None);
    assert!(disabled.contains(r#""enabled":false"#), "{disabled}");
    std::thread::sleep(Duration::from_millis(250));
    let enabled = client.ask(RequestType::HooksDump, None);
    assert!(enabled.contains(r#""enabled":true"#), "{enabled}");
}

#[test]
fn dropping_the_publisher_lets_a_held_tick_go() {
    let doc = doc();
    let mut tree = chronomap_bt::Tree::new(&doc, &Registry::new()).unwrap();
    let port = free_port_pair();
    let publisher = Publisher::start_on(&tree, &doc, "127.0.0.1", port).unwrap();
    tree.set_tick_monitor(Some(publisher.tick_monitor()));
    let mut client = Client::new(port);
    client.ask(RequestType::HookInsert, Some(&hook(1, 0, "SKIPPED")));
    let (done, result) = mpsc::channel();
    std::thread::scope(|s| {
        s.spawn(|| {
            done.send(tree.tick_exactly_once(Duration::ZERO).unwrap())
                .unwrap();
        });
        assert_eq!(client.reached(), 1);
        assert!(result.recv_timeout(Duration::from_millis(300)).is_err());
        drop(publisher);
        assert_eq!(
            result.recv_timeout(Duration::from_secs(5)).unwrap(),
            Status::Success
        );
    });
    // The monitor outlives the publisher: ticks go on, nothing is published.
    assert_eq!(
        tree.tick_exactly_once(Duration::ZERO).unwrap(),
        Status::Success
    );
}
