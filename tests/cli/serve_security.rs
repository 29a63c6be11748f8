//! Security of `chronomap serve`: writes without the right bearer token get 401, oversize
//! bodies 413, hostile ids and JSON 400 — and none of them changes anything or stops the
//! service. Run for the embedded store and for PostgreSQL.

use crate::service;

use chronomap_client::Client;
use chronomap_client::{Method, StatusCode};
use chronomap_serve::api::{Health, ListResponse};
use service::{Backend, free_port, scratch, start, token};

/// Everything a client can see of the service's state.
fn snapshot(runtime: &tokio::runtime::Runtime, client: &Client) -> (u64, ListResponse, Vec<f64>) {
    runtime.block_on(async {
        let health: Health = client.health().await.unwrap();
        let list = client.list().await.unwrap();
        let p = client
            .predict("door", &[0.0, 3600.0, 50_000.0], None)
            .await
            .unwrap()
            .values;
        (health.seq, list, p)
    })
}

fn security_test(name: &str, backend: Backend) {
    let data = scratch(name);
    let port = free_port();
    let server = start(&data, port, &backend, &["--max-body-bytes", "20000"]);
    let token = token(&data);
    let client = Client::new(&server.url, Some(token.clone())).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    runtime
        .block_on(client.add(
            "door",
            &[0.0, 43_200.0, 86_400.0, 129_600.0],
            &[false, true, false, true],
            Some("fremen:2"),
        ))
        .unwrap();
    let before = snapshot(&runtime, &client);
    let raw = |method: Method, path: &str, body: &[u8], token: Option<&str>| {
        runtime
            .block_on(client.raw(method, path, body.to_vec(), token))
            .unwrap()
    };
    let good_add = br#"{"id":"door","times":[200000],"states":[true]}"#;

    // 401: every write endpoint, without a token and with a wrong one.
    let writes: [(Method, &str, &[u8]); 7] = [
        (Method::POST, "/v1/add", good_add),
        (
            Method::POST,
            "/v1/addvalues",
            br#"{"id":"door","times":[200000],"values":[1]}"#,
        ),
        (
            Method::POST,
            "/v1/observations",
            br#"{"batches":[{"id":"door","times":[200000],"values":[1]}]}"#,
        ),
        (
            Method::PUT,
            "/v1/models/new-door",
            br#"{"model":"fremen:1"}"#,
        ),
        (Method::PUT, "/v1/models/door", br#"{"model":"hist:24"}"#),
        (Method::DELETE, "/v1/models/door", b""),
        (Method::POST, "/v1/models/door/refit", b"{}"),
    ];
    let wrong = "0".repeat(token.len());
    let mut unauthorised = 0;
    for (method, path, body) in &writes {
        for bad_token in [None, Some(wrong.as_str()), Some(&token[..token.len() - 1])] {
            let (status, text) = raw(method.clone(), path, body, bad_token);
            assert_eq!(status, StatusCode::UNAUTHORIZED, "{method} {path}: {text}");
            assert!(text.contains("\"error\":\"unauthorized\""), "{text}");
            unauthorised += 1;
        }
    }
    assert_eq!(
        snapshot(&runtime, &client),
        before,
        "a rejected write changed the service"
    );

    // 413: a body over --max-body-bytes, with the right token.
    let times: Vec<String> = (0..5000).map(|k| (300_000 + k).to_string()).collect();
    let states = vec!["true"; 5000].join(",");
    let big = format!(
        r#"{{"id":"door","times":[{}],"states":[{states}]}}"#,
        times.join(",")
    );
    assert!(big.len() > 20_000);
    let (status, text) = raw(Method::POST, "/v1/add", big.as_bytes(), Some(&token));
    assert_eq!(status, StatusCode::PAYLOAD_TOO_LARGE, "{text}");
    assert!(text.contains("payload_too_large"), "{text}");

    // 400: hostile ids and JSON, with the right token.
    let long_id = "x".repeat(257);
    let hostile: Vec<(Method, String, Vec<u8>)> = vec![
        (Method::POST, "/v1/add".into(), b"not json".to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[1"#.to_vec()),
        (Method::POST, "/v1/add".into(), b"\xff\xfe{}".to_vec()),
        (Method::POST, "/v1/add".into(), b"[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[".to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[NaN],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[1e999],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":["x"],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[1,2],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[-5],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[10],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[300000,200000],"states":[true,false]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"door","times":[300000],"states":[true],"admin":true}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"","times":[300000],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), format!(r#"{{"id":"{long_id}","times":[300000],"states":[true]}}"#).into_bytes()),
        (Method::POST, "/v1/add".into(), br#"{"id":"do\u0000or","times":[300000],"states":[true]}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"new","times":[300000],"states":[true],"model":"fremen:99999"}"#.to_vec()),
        (Method::POST, "/v1/add".into(), br#"{"id":"new","times":[300000],"states":[true],"model":"hyt-em:0"}"#.to_vec()),
        (Method::POST, "/v1/models/door/refit".into(), b"{}".to_vec()),
        (Method::POST, "/v1/models/door/refit".into(), br#"{"now":true}"#.to_vec()),
        (Method::POST, "/v1/addvalues".into(), br#"{"id":"door","times":[300000],"values":[1.5]}"#.to_vec()),
        (Method::POST, "/v1/addvalues".into(), br#"{"id":"door","times":[300000],"values":[-0.1]}"#.to_vec()),
        // One good batch and one bad one: all or nothing.
        (Method::POST, "/v1/observations".into(), br#"{"batches":[{"id":"door","times":[300000],"values":[1]},{"id":"door","times":[1],"values":[0]}]}"#.to_vec()),
        (Method::POST, "/v1/observations".into(), br#"{"batches":[{"id":"door","times":[300000],"values":[1]},{"id":"","times":[1],"values":[0]}]}"#.to_vec()),
        (Method::PUT, format!("/v1/models/{long_id}"), br#"{"model":"fremen:1"}"#.to_vec()),
        (Method::PUT, "/v1/models/a%00b".into(), br#"{"model":"fremen:1"}"#.to_vec()),
        (Method::PUT, "/v1/models/a%FFb".into(), br#"{"model":"fremen:1"}"#.to_vec()),
        (Method::PUT, "/v1/models/new".into(), br#"{"model":"fremen:1","range":[1,0]}"#.to_vec()),
        (Method::PUT, "/v1/models/new".into(), br#"{"model":"nonsense"}"#.to_vec()),
        (Method::PUT, "/v1/models/new".into(), br#"{"model":3}"#.to_vec()),
        (Method::POST, "/v1/predict".into(), br#"{"id":"door","times":[1],"order":1000}"#.to_vec()),
        (Method::POST, "/v1/predict".into(), br#"{"id":"door","times":[1],"order":-1}"#.to_vec()),
        (Method::POST, "/v1/forecast".into(), br#"{"ids":["door"],"time":1,"orders":[1,2]}"#.to_vec()),
        (Method::POST, "/v1/detect".into(), br#"{"id":"door","times":[1],"values":[1],"confidence":0}"#.to_vec()),
        (Method::POST, "/v1/evaluate".into(), br#"{"id":"door","times":[],"values":[]}"#.to_vec()),
    ];
    for (method, path, body) in &hostile {
        let (status, text) = raw(method.clone(), path, body, Some(&token));
        assert_eq!(
            status,
            StatusCode::BAD_REQUEST,
            "{method} {path} {}: {text}",
            String::from_utf8_lossy(body)
        );
        let error: chronomap_serve::api::ErrorBody = serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("{path}: the error is not JSON ({e}): {text}"));
        assert_eq!(error.error, "bad_request");
        assert!(!error.reason.is_empty());
    }
    // A deeply nested body is refused by the parser's depth limit, not by a stack overflow.
    let deep = "[".repeat(10_000);
    let (status, _) = raw(Method::POST, "/v1/predict", deep.as_bytes(), None);
    assert_eq!(status, StatusCode::BAD_REQUEST);

    let after = snapshot(&runtime, &client);
    assert_eq!(after, before, "a rejected request changed the service");
    // The service is still up and a good write still works.
    let (status, text) = raw(Method::POST, "/v1/add", good_add, Some(&token));
    assert_eq!(status, StatusCode::OK, "{text}");
    assert_eq!(snapshot(&runtime, &client).0, before.0 + 1);
    eprintln!(
        "{name}: {unauthorised} unauthorised writes -> 401, 1 oversize -> 413, {} hostile -> 400; \
         nothing changed",
        hostile.len() + 1
    );
}

service::on_each_backend!(
    security_test,
    "security",
    bad_tokens_oversize_bodies_and_hostile_input_change_nothing_redb,
    bad_tokens_oversize_bodies_and_hostile_input_change_nothing_postgres
);

/// Issue 22, defects 13 and 15: ids that display as other ids, times no later observation can
/// follow, ranges of infinite width are refused with a 400 naming the field; none changes
/// anything.
#[test]
fn invisible_ids_huge_times_and_infinite_ranges_are_refused() {
    let data = scratch("serve_security_values");
    let port = free_port();
    let server = start(&data, port, &Backend::Redb, &[]);
    let token = token(&data);
    let client = Client::new(&server.url, Some(token.clone())).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let raw = |method: Method, path: &str, body: &str| {
        runtime
            .block_on(client.raw(method, path, body.as_bytes().to_vec(), Some(&token)))
            .unwrap()
    };
    let refused: Vec<(Method, String, String, &str)> = vec![
        (
            Method::POST,
            "/v1/add".into(),
            "{\"id\":\"door\u{202E}rood\",\"times\":[1],\"states\":[true]}".into(),
            "U+202E",
        ),
        (
            Method::POST,
            "/v1/add".into(),
            "{\"id\":\"do\u{200B}or\",\"times\":[1],\"states\":[true]}".into(),
            "U+200B",
        ),
        (
            Method::POST,
            "/v1/add".into(),
            "{\"id\":\"\u{FEFF}door\",\"times\":[1],\"states\":[true]}".into(),
            "U+FEFF",
        ),
        (
            Method::PUT,
            "/v1/models/door%E2%80%AErood".into(),
            r#"{"model":"fremen:1"}"#.into(),
            "U+202E",
        ),
        (
            Method::POST,
            "/v1/add".into(),
            r#"{"id":"door","times":[1.797e308],"states":[true]}"#.into(),
            "1e11",
        ),
        (
            Method::POST,
            "/v1/addvalues".into(),
            r#"{"id":"door","times":[100000000001],"values":[1]}"#.into(),
            "1e11",
        ),
        (
            Method::PUT,
            "/v1/models/level".into(),
            r#"{"model":"fremen:1","range":[-1e308,1e308]}"#.into(),
            "finite width",
        ),
    ];
    runtime
        .block_on(client.add("door", &[1.0, 2.0], &[true, false], Some("fremen:2")))
        .unwrap();
    for (method, path, body, needed) in &refused {
        let (status, text) = raw(method.clone(), path, body);
        assert_eq!(status, StatusCode::BAD_REQUEST, "{path} {body}: {text}");
        assert!(text.contains(needed), "{path} {body}: {text}");
    }
    let list = runtime.block_on(client.list()).unwrap();
    assert_eq!(list.models.len(), 1);
    assert_eq!(list.models[0].observations, 2);
    // The largest time is accepted.
    let (status, text) = raw(
        Method::POST,
        "/v1/add",
        r#"{"id":"door","times":[100000000000],"states":[true]}"#,
    );
    assert_eq!(status, StatusCode::OK, "{text}");
}

/// Issue 22, defect 15: a token file others can read, or a short token, stops the start;
/// a new data directory is 0700, the store and the token 0600, also under umask 000.
#[cfg(unix)]
#[test]
fn token_files_must_be_private_and_long_and_new_files_are_private() {
    use std::os::unix::fs::PermissionsExt;
    let data = scratch("serve_security_files");
    let mode = |p: &std::path::Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    let token_file = data.join("shared-token");
    let strong = "a".repeat(64);
    std::fs::write(&token_file, &strong).unwrap();
    std::fs::set_permissions(&token_file, std::fs::Permissions::from_mode(0o644)).unwrap();
    let fresh = data.join("d");
    let (code, _, stderr) = service::serve_once(&[
        "--data".as_ref(),
        fresh.as_os_str(),
        "--token-file".as_ref(),
        token_file.as_os_str(),
        "--listen".as_ref(),
        "127.0.0.1:0".as_ref(),
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(
        stderr.contains("readable by others (mode 0644)"),
        "{stderr}"
    );
    assert!(
        stderr.contains(&format!("chmod 600 {}", token_file.display())),
        "{stderr}"
    );
    std::fs::set_permissions(&token_file, std::fs::Permissions::from_mode(0o600)).unwrap();
    std::fs::write(&token_file, "0123456789abcdef").unwrap();
    let (code, _, stderr) = service::serve_once(&[
        "--data".as_ref(),
        fresh.as_os_str(),
        "--token-file".as_ref(),
        token_file.as_os_str(),
        "--listen".as_ref(),
        "127.0.0.1:0".as_ref(),
    ]);
    assert_eq!(code, 1, "{stderr}");
    assert!(stderr.contains("at least 32"), "{stderr}");

    // Under umask 000 the new directory and files are still private.
    let port = free_port();
    let fresh = data.join("new-data");
    let mut child = std::process::Command::new("sh")
        .arg("-c")
        .arg(format!(
            "umask 000; exec \"$0\" serve --data {} --listen 127.0.0.1:{port}",
            fresh.display()
        ))
        .arg(env!("CARGO_BIN_EXE_chronomap"))
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let store = fresh.join("chronomap.redb");
    let begin = std::time::Instant::now();
    while !(store.exists() && fresh.join("token").exists())
        && begin.elapsed() < std::time::Duration::from_secs(20)
    {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
    assert_eq!(mode(&fresh), 0o700);
    assert_eq!(mode(&store), 0o600);
    assert_eq!(mode(&fresh.join("token")), 0o600);
}

/// Issue 22, defects 11 and 12: `client predict` ranges too fine for the 1,000,000 limit are
/// refused before any request (the float → integer cast used to saturate and wrap), and
/// `client create --range LO,HI` works as its help says.
#[test]
fn client_ranges_are_checked_and_create_takes_lo_comma_hi() {
    let client = |url: &str, token: &std::path::Path, args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_chronomap"))
            .args(["client", "--url", url, "--token-file"])
            .arg(token)
            .args(args)
            .output()
            .unwrap()
    };
    let nowhere = std::path::Path::new("no-such-token");
    for (from, to, step) in [
        ("0", "1e9", "1e-300"),
        ("0", "1e9", "1e-3"),
        ("-1e300", "1e300", "1"),
    ] {
        let (from, to) = (format!("--from={from}"), format!("--to={to}"));
        let output = client(
            "http://127.0.0.1:9",
            nowhere,
            &["predict", "door", &from, &to, "--step", step],
        );
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(
            output.status.code(),
            Some(2),
            "{from} {to} {step}: {stderr}"
        );
        assert!(stderr.contains("at most 1,000,000"), "{stderr}");
    }

    let data = scratch("serve_security_client");
    let port = free_port();
    let server = start(&data, port, &Backend::Redb, &[]);
    let token = data.join("token");
    for (id, range) in [
        ("level", vec!["--range", "0,10"]),
        ("temp", vec!["--range", "-5,5"]),
        ("depth", vec!["--range", "0,10", "--model", "fremen:1"]),
    ] {
        let mut args = vec!["create", id];
        args.extend(range);
        let output = client(&server.url, &token, &args);
        assert!(
            output.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let output = client(&server.url, &token, &["create", "x", "--range", "5"]);
    assert_eq!(output.status.code(), Some(2));
    // Two numbers are one argument: a second one is not taken (nor a flag after the range).
    let output = client(&server.url, &token, &["create", "x", "--range", "0", "10"]);
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("unexpected argument '10'"));
    let output = client(&server.url, &token, &["--json", "view", "temp"]);
    let view: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(view["range"], serde_json::json!([-5.0, 5.0]));
}

/// Deadline plans (`POST /v1/topo/{name}/plan` with `deadline_secs`): deadlines, confidences
/// and buckets that are not numbers in their range, options without a deadline and requests
/// whose time-augmented products exceed 10^6 cells are refused with a 400 naming the field,
/// before the work; the service still plans afterwards.
#[test]
fn hostile_deadline_plans_are_refused_naming_the_field() {
    let data = scratch("serve_security_deadline");
    let witham = data.join("witham.cmt").display().to_string();
    crate::common::fit_witham(&witham, &["--success-order", "1"]);
    let topo_flag = format!("witham={witham}");
    let server = start(&data, free_port(), &Backend::Redb, &["--topo", &topo_flag]);
    let client = Client::new(&server.url, None).unwrap();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap();
    let post = |body: &str| {
        runtime
            .block_on(client.raw(
                Method::POST,
                "/v1/topo/witham/plan",
                body.as_bytes().to_vec(),
                None,
            ))
            .unwrap()
    };
    let trip = r#""from":"Kitchen","task":"F Station","times":[1409839200]"#;
    let thousand = vec!["1409839200"; 1000].join(",");
    let refused: Vec<(String, &str)> = vec![
        (
            format!(r#"{{{trip},"deadline_secs":0}}"#),
            "field `deadline_secs`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":-100}}"#),
            "field `deadline_secs`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":-0.0}}"#),
            "field `deadline_secs`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":1e12}}"#),
            "field `deadline_secs`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":1.7e308}}"#),
            "field `deadline_secs`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":NaN}}"#),
            "malformed JSON",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":1e999}}"#),
            "malformed JSON",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":"100"}}"#),
            "invalid type: string",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":[100]}}"#),
            "invalid type: sequence",
        ),
        (
            format!(r#"{{{trip},"deadline":100}}"#),
            "unknown field `deadline`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":100,"confidence":1.5}}"#),
            "field `confidence`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":100,"confidence":-0.1}}"#),
            "field `confidence`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":100,"confidence":"high"}}"#),
            "invalid type: string",
        ),
        (
            format!(r#"{{{trip},"confidence":0.9}}"#),
            "field `confidence`: only with `deadline_secs`",
        ),
        (
            format!(r#"{{{trip},"bucket_secs":1}}"#),
            "field `bucket_secs`: only with `deadline_secs`",
        ),
        (
            format!(r#"{{{trip},"curve":true}}"#),
            "field `curve`: only with `deadline_secs`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":100,"curve":1}}"#),
            "invalid type: integer",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":100,"bucket_secs":0}}"#),
            "field `bucket_secs`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":100,"bucket_secs":-1}}"#),
            "field `bucket_secs`",
        ),
        (
            format!(r#"{{{trip},"deadline_secs":100,"bucket_secs":101}}"#),
            "field `bucket_secs`",
        ),
        // 10^306 buckets, refused before the product is built.
        (
            format!(r#"{{{trip},"deadline_secs":100,"bucket_secs":1e-304}}"#),
            "field `bucket_secs`: 1 start time(s) × at least 1 product state(s) × 1.000e306 buckets",
        ),
        // 100,001 buckets of 18 product states: refused by the planner before it allocates.
        (
            format!(r#"{{{trip},"deadline_secs":100,"bucket_secs":0.001}}"#),
            "field `bucket_secs`: 1 start time(s) × 18 product state(s) × 100001 buckets",
        ),
        // 1,000 start times × 18 states × 101 buckets.
        (
            format!(
                r#"{{"from":"Kitchen","task":"F Station","times":[{thousand}],"deadline_secs":100}}"#
            ),
            "field `times`: 1000 start time(s) × 18 product state(s) × 101 buckets = 1.818e6 cells",
        ),
        (
            format!(
                r#"{{"from":"Kitchen","task":"F Station","times":[{thousand},1],"deadline_secs":100}}"#
            ),
            "field `times`: give 1 to 1000",
        ),
        (
            r#"{"from":"Kitchen","task":"F Station","times":[1e12],"deadline_secs":100}"#
                .to_string(),
            "field `times[0]`",
        ),
        (
            r#"{"from":"Kitchn","task":"F Station","times":[1],"deadline_secs":100}"#.to_string(),
            "field `from`",
        ),
        (
            r#"{"from":"Kitchen","task":"F (Station","times":[1],"deadline_secs":100}"#.to_string(),
            "field `task`",
        ),
    ];
    for (body, needed) in &refused {
        let started = std::time::Instant::now();
        let (status, text) = post(body);
        let short = &body[..body.len().min(160)];
        assert_eq!(status, StatusCode::BAD_REQUEST, "{short}: {text}");
        let error: chronomap_serve::api::ErrorBody = serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("{short}: the error is not JSON ({e}): {text}"));
        assert_eq!(error.error, "bad_request");
        assert!(error.reason.contains(needed), "{short}: {}", error.reason);
        assert!(started.elapsed().as_secs_f64() < 5.0, "{short}");
    }
    // Still planning: the same trip within 100 s; as many start times as fit (550 × 18 states
    // × 101 buckets = 999,900 cells), and one more is too many.
    let times = |n: usize| vec!["1409839200"; n].join(",");
    let (status, text) = post(&format!(
        r#"{{"from":"Kitchen","task":"F Station","times":[{}],"deadline_secs":100}}"#,
        times(551)
    ));
    assert_eq!(status, StatusCode::BAD_REQUEST, "{text}");
    assert!(
        text.contains("field `times`: 551 start time(s) × 18 product state(s)"),
        "{text}"
    );
    for n in [1, 550] {
        let started = std::time::Instant::now();
        let (status, text) = post(&format!(
            r#"{{"from":"Kitchen","task":"F Station","times":[{}],"deadline_secs":100}}"#,
            times(n)
        ));
        assert_eq!(status, StatusCode::OK, "{n}: {text}");
        eprintln!(
            "deadline plans at {n} start time(s): {:.1} ms",
            started.elapsed().as_secs_f64() * 1e3
        );
        let answer: serde_json::Value = serde_json::from_str(&text).unwrap();
        let plans = answer["plans"].as_array().unwrap();
        assert_eq!(plans.len(), n);
        let p = plans[n - 1]["deadline"]["probability"].as_f64().unwrap();
        assert!(p > 0.5 && p < 0.6, "{n}: {p}");
    }
    eprintln!(
        "{} hostile deadline plans -> 400 naming the field",
        refused.len() + 1
    );
}
