//! The monitor's endpoints against a tree run by the real BehaviorTree.CPP 4.8.2 with its own
//! `Groot2Publisher` (`tests/bt/btcpp_groot2_tree.py`, skipped without `CHRONOMAP_BT_PYTHON`
//! unless `CHRONOMAP_REQUIRE_BT=1`), and against publishers that answer garbage.

use axum::body::{Body, to_bytes};
use axum::http::Request;
use serde_json::Value;
use tower::ServiceExt;

use chronomap_testutil::{BtcppTree, bt_python, free_port_pair};

use super::*;

struct Fixture {
    router: Router,
    runtime: tokio::runtime::Runtime,
}

impl Fixture {
    fn new(targets: &[&str], options: MonitorOptions) -> Fixture {
        let targets = targets
            .iter()
            .map(|t| MonitorTarget::parse(t).unwrap())
            .collect();
        let monitors = Arc::new(BtMonitors::start(targets, options).unwrap());
        Fixture {
            router: router(monitors),
            runtime: tokio::runtime::Builder::new_multi_thread()
                .worker_threads(2)
                .enable_all()
                .build()
                .unwrap(),
        }
    }

    fn get_with(&self, path: &str, accept: &str) -> (StatusCode, Vec<u8>) {
        let request = Request::builder()
            .uri(path)
            .header("accept", accept)
            .body(Body::empty())
            .unwrap();
        self.runtime.block_on(async {
            let response = self.router.clone().oneshot(request).await.unwrap();
            let status = response.status();
            let bytes = to_bytes(response.into_body(), 64 << 20).await.unwrap();
            (status, bytes.to_vec())
        })
    }

    /// The first `bytes` (or more) of a stream of server-sent events; then it is dropped.
    fn stream_start(&self, path: &str, bytes: usize) -> String {
        use hyper::body::Body as _;
        let request = Request::builder()
            .uri(path)
            .header("accept", "text/event-stream")
            .body(Body::empty())
            .unwrap();
        self.runtime.block_on(async {
            let response = self.router.clone().oneshot(request).await.unwrap();
            assert_eq!(response.status(), StatusCode::OK);
            assert_eq!(response.headers()["content-type"], "text/event-stream");
            let mut body = response.into_body();
            let mut text = Vec::new();
            while text.len() < bytes {
                let frame =
                    std::future::poll_fn(|cx| std::pin::Pin::new(&mut body).poll_frame(cx)).await;
                match frame {
                    Some(Ok(frame)) => text.extend_from_slice(&frame.into_data().unwrap()),
                    _ => break,
                }
            }
            String::from_utf8(text).unwrap()
        })
    }

    fn get(&self, path: &str) -> (StatusCode, Value) {
        let (status, bytes) = self.get_with(path, "application/json");
        (status, serde_json::from_slice(&bytes).unwrap())
    }

    fn ok(&self, path: &str) -> Value {
        let (status, body) = self.get(path);
        assert_eq!(status, StatusCode::OK, "{path}: {body}");
        body
    }

    fn wait_until(&self, what: &str, path: &str, check: impl Fn(&Value) -> bool) -> Value {
        let deadline = Instant::now() + Duration::from_secs(30);
        loop {
            let body = self.ok(path);
            if check(&body) {
                return body;
            }
            assert!(Instant::now() < deadline, "{what}: not within 30 s: {body}");
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

fn quick() -> MonitorOptions {
    MonitorOptions {
        client: ClientOptions {
            timeout: Duration::from_millis(500),
            max_reply_bytes: 1 << 20,
        },
        status_period: STATUS_PERIOD,
    }
}

#[test]
fn targets_are_named_or_named_by_their_address() {
    let t = MonitorTarget::parse("127.0.0.1:1667").unwrap();
    assert_eq!(
        (t.id.as_str(), t.address.as_str()),
        ("127.0.0.1:1667", "127.0.0.1:1667")
    );
    let t = MonitorTarget::parse("nav2=robot.lab:1667").unwrap();
    assert_eq!(
        (t.id.as_str(), t.address.as_str()),
        ("nav2", "robot.lab:1667")
    );
    assert!(
        MonitorTarget::parse("robot")
            .unwrap_err()
            .contains("not [NAME=]HOST:PORT")
    );
    assert!(
        MonitorTarget::parse("x:65535")
            .unwrap_err()
            .contains("1 to 65534")
    );
    assert!(
        MonitorTarget::parse("a b=x:1")
            .unwrap_err()
            .contains("the name \"a b\"")
    );
    let twice = BtMonitors::start(
        vec![
            MonitorTarget::parse("a=x:1").unwrap(),
            MonitorTarget::parse("a=x:2").unwrap(),
        ],
        quick(),
    );
    assert!(twice.unwrap_err().contains("two monitors have this id"));
}

#[test]
fn the_endpoints_follow_a_real_behaviortree_cpp_tree() {
    let Some(python) = bt_python() else { return };
    let port = free_port_pair();
    let started = BtcppTree::start(&python, port, None);
    assert_eq!(started.ready, format!("ready port={port} nodes=43"));
    let mut tree = Some(started);
    let address = format!("127.0.0.1:{port}");
    let f = Fixture::new(&[&format!("patrol={address}")], quick());
    let view = f.wait_until("connected", "/v1/bt/monitors/patrol", |v| {
        v["state"] == "connected" && v["statuses"].as_array().is_some_and(|s| s.len() == 43)
    });
    assert_eq!(view["address"], address.as_str());
    assert_eq!(view["main_tree"], "Patrol");
    let nodes = view["tree"]["nodes"].as_array().unwrap();
    assert_eq!(nodes.len(), 43);
    let node = |uid: u64| nodes.iter().find(|n| n["uid"] == uid).unwrap();
    assert_eq!(node(1)["name"], "patrol_round");
    assert_eq!(node(1)["children"].as_array().unwrap().len(), 12);
    assert_eq!(node(5)["type"], "SubTree");
    assert_eq!(node(5)["children"], serde_json::json!([6]));
    assert_eq!(node(6)["tree"], "dock");
    assert_eq!(view["tree"]["trees"][1]["path"], "dock");
    for s in view["statuses"].as_array().unwrap() {
        let status = s["status"].as_str().unwrap();
        assert!(
            ["idle", "running", "success", "failure"].contains(&status),
            "{s}"
        );
    }
    // The list says the same.
    let list = f.ok("/v1/bt/monitors");
    assert_eq!(list["monitors"][0]["nodes"], 43);
    assert_eq!(list["monitors"][0]["state"], "connected");

    // Events: the tree, its first statuses, the connection, then status changes; waiting for
    // the next ones.
    let events = f.ok("/v1/bt/monitors/patrol/events?after=0");
    let kinds: Vec<&str> = events["events"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["kind"].as_str().unwrap())
        .collect();
    assert_eq!(&kinds[..3], ["tree", "status", "connected"]);
    let seq = events["seq"].as_u64().unwrap();
    let next = f.ok(&format!("/v1/bt/monitors/patrol/events?after={seq}&wait=5"));
    let first = &next["events"][0];
    assert!(first["seq"].as_u64().unwrap() > seq, "{next}");
    assert_eq!(first["kind"], "status");
    assert!(!first["changes"].as_array().unwrap().is_empty());
    // The same as server-sent events.
    let text = f.stream_start("/v1/bt/monitors/patrol/events?after=0", 300);
    assert!(
        text.starts_with("id: 1\nevent: tree\ndata: {\"seq\":1,"),
        "{}",
        &text[..200]
    );
    assert!(text.contains("\nid: 2\nevent: status\n"), "{text}");

    // Transitions: recorded by BT.CPP, of nodes of the tree, in time order, numbered.
    let t = f.wait_until("transitions", "/v1/bt/monitors/patrol/transitions", |t| {
        t["transitions"].as_array().is_some_and(|t| t.len() > 50)
    });
    let list = t["transitions"].as_array().unwrap();
    assert!(
        list.windows(2)
            .all(|w| w[0]["time"].as_f64() <= w[1]["time"].as_f64())
    );
    assert!(
        list.iter()
            .all(|t| (1..=43).contains(&t["uid"].as_u64().unwrap()))
    );
    assert!(
        list.windows(2)
            .all(|w| w[1]["n"].as_u64().unwrap() == w[0]["n"].as_u64().unwrap() + 1)
    );
    let since = t["recording_since"].as_f64().unwrap();
    assert!(list[0]["time"].as_f64().unwrap() >= since);
    let later = f.ok(&format!(
        "/v1/bt/monitors/patrol/transitions?after={}",
        t["next"]
    ));
    assert!(
        later["transitions"]
            .as_array()
            .unwrap()
            .iter()
            .all(|x| x["n"].as_u64() >= t["next"].as_u64())
    );

    // Blackboards of the main tree and of the subtree, read now.
    let board = f.ok("/v1/bt/monitors/patrol/blackboard");
    assert_eq!(board["blackboards"]["Patrol"]["robot"], "tiago");
    let round = board["blackboards"]["Patrol"]["round"].as_u64().unwrap();
    let battery = board["blackboards"]["Patrol"]["battery"].as_f64().unwrap();
    assert!(round >= 1);
    // The script sets battery = 100 - (round mod 5) * 20 before each round.
    assert!(
        [20.0, 40.0, 60.0, 80.0, 100.0].contains(&battery),
        "{board}"
    );

    // Bad requests and unknown monitors.
    let (status, body) = f.get("/v1/bt/monitors/nope");
    assert_eq!(status, StatusCode::NOT_FOUND);
    assert_eq!(
        body["reason"],
        "no behavior-tree monitor \"nope\" (monitored: patrol)"
    );
    let (status, body) = f.get("/v1/bt/monitors/patrol/events?wait=11");
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        body["reason"].as_str().unwrap().contains("from 0 to 10"),
        "{body}"
    );
    let (status, _) = f.get("/v1/bt/monitors/patrol/transitions?after=-1");
    assert_eq!(status, StatusCode::BAD_REQUEST);

    // The tree goes away, and comes back on the same port.
    tree.take();
    let gone = f.wait_until("disconnected", "/v1/bt/monitors/patrol", |v| {
        v["state"] == "disconnected"
    });
    assert!(
        gone["error"].as_str().unwrap().contains("did not answer"),
        "{gone}"
    );
    let (status, body) = f.get("/v1/bt/monitors/patrol/blackboard");
    assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE, "{body}");
    let _tree = BtcppTree::start(&python, port, None);
    assert_eq!(_tree.ready, format!("ready port={port} nodes=43"));
    let back = f.wait_until("connected again", "/v1/bt/monitors/patrol", |v| {
        v["state"] == "connected"
    });
    assert_eq!(back["reconnects"], 1);
    assert_eq!(back["error"], Value::Null);
    assert_eq!(back["nodes"], 43);
}

/// A REP server on `port` answering every request with `reply(request)`, until `stop`.
fn fake_publisher(
    port: u16,
    stop: Arc<AtomicBool>,
    reply: impl Fn(&[Vec<u8>]) -> Vec<Vec<u8>> + Send + 'static,
) -> std::thread::JoinHandle<()> {
    let context = zmq::Context::new();
    let socket = context.socket(zmq::REP).unwrap();
    socket.set_linger(0).unwrap();
    socket.set_rcvtimeo(100).unwrap();
    socket.bind(&format!("tcp://127.0.0.1:{port}")).unwrap();
    std::thread::spawn(move || {
        while !stop.load(Ordering::Acquire) {
            if let Ok(request) = socket.recv_multipart(0) {
                let _ = socket.send_multipart(reply(&request), 0);
            }
        }
    })
}

fn header(request: &[Vec<u8>]) -> Vec<u8> {
    let mut header = request[0].clone();
    header.extend([7; 16]);
    header
}

#[test]
fn garbage_oversized_and_inconsistent_publishers_are_reported_and_bounded() {
    let stop = Arc::new(AtomicBool::new(false));
    let (garbage, huge, mismatch) = (free_port_pair(), free_port_pair(), free_port_pair());
    let servers = [
        fake_publisher(garbage, Arc::clone(&stop), |request| {
            vec![header(request), b"<root><BehaviorTree".to_vec()]
        }),
        // 4 MiB of XML to a monitor that takes 1 MiB.
        fake_publisher(huge, Arc::clone(&stop), |request| {
            vec![header(request), vec![b' '; 4 << 20]]
        }),
        // A good tree of two nodes, and statuses of three.
        fake_publisher(mismatch, Arc::clone(&stop), |request| {
            match request[0][1] {
            b'T' => vec![
                header(request),
                br#"<root><BehaviorTree ID="M" _fullpath=""><Sequence name="s" _uid="1"><Act _uid="2"/></Sequence></BehaviorTree></root>"#.to_vec(),
            ],
            b'r' => vec![header(request), b"1700000000000000".to_vec()],
            _ => vec![header(request), vec![1, 0, 1, 2, 0, 2, 3, 0, 0]],
        }
        }),
    ];
    let f = Fixture::new(
        &[
            &format!("garbage=127.0.0.1:{garbage}"),
            &format!("huge=127.0.0.1:{huge}"),
            &format!("mismatch=127.0.0.1:{mismatch}"),
        ],
        quick(),
    );
    let error = |id: &str, expected: &str| {
        let v = f.wait_until(id, &format!("/v1/bt/monitors/{id}"), |v| {
            v["error"].as_str().is_some_and(|e| e.contains(expected))
        });
        assert_ne!(v["state"], "connected", "{v}");
        v
    };
    error(
        "garbage",
        &format!(
            "the publisher at 127.0.0.1:{garbage} sent a malformed FULLTREE reply: the tree's \
             XML does not parse"
        ),
    );
    error("huge", "did not answer FULLTREE within 0.5 s");
    error(
        "mismatch",
        "sent a malformed STATUS reply: 3 node statuses that do not match the 2 nodes",
    );
    // Seconds of retries keep what the monitors hold small, and the service answers.
    std::thread::sleep(Duration::from_secs(2));
    for id in ["garbage", "huge", "mismatch"] {
        let events = f.ok(&format!("/v1/bt/monitors/{id}/events"));
        assert!(events["events"].as_array().unwrap().len() <= 8, "{events}");
        let (status, _) = f.get(&format!("/v1/bt/monitors/{id}/blackboard"));
        assert_eq!(status, StatusCode::SERVICE_UNAVAILABLE);
    }
    assert_eq!(
        f.ok("/v1/bt/monitors")["monitors"]
            .as_array()
            .unwrap()
            .len(),
        3
    );
    stop.store(true, Ordering::Release);
    for server in servers {
        server.join().unwrap();
    }
}
