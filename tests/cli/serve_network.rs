//! `chronomap serve` against hostile networks: DNS rebinding (the `Host` check), cross-origin
//! writes (CSRF: JSON only, no CORS), `--no-token` off loopback, what `/v1/health` shows, the
//! bearer scheme in any case, and slow or idle connections (timeouts, the connection limit).

use crate::service;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};

use service::{Backend, free_port, raw_http, scratch, serve_once, start, token};

fn request(method: &str, path: &str, host: Option<&str>, headers: &[&str], body: &str) -> String {
    let mut text = format!("{method} {path} HTTP/1.1\r\n");
    if let Some(host) = host {
        text.push_str(&format!("Host: {host}\r\n"));
    }
    for header in headers {
        text.push_str(header);
        text.push_str("\r\n");
    }
    text.push_str(&format!(
        "Content-Length: {}\r\nConnection: close\r\n\r\n{body}",
        body.len()
    ));
    text
}

#[test]
fn hosts_content_types_cors_and_the_bearer_scheme_follow_the_security_model() {
    let data = scratch("serve_network_model");
    let port = free_port();
    let _server = start(&data, port, &Backend::Redb, &["--allow-host", "robot.lan"]);
    let token = token(&data);
    let auth = format!("Authorization: Bearer {token}");
    let here = format!("127.0.0.1:{port}");

    // DNS rebinding: a name the service was not given is refused, reads included.
    for host in [
        "evil.example",
        "evil.example:80",
        "127.0.0.1.nip.io",
        "localhost.evil",
    ] {
        for path in ["/v1/models", "/", "/v1/health"] {
            let (status, _, body) = raw_http(port, &request("GET", path, Some(host), &[], ""));
            assert_eq!(status, 421, "Host {host} {path}: {body}");
        }
    }
    let (status, _, body) = raw_http(
        port,
        &request("GET", "/v1/models", None, &[], "").replace("HTTP/1.1", "HTTP/1.0"),
    );
    assert_eq!(status, 400, "no Host: {body}");
    assert!(body.contains("Host"), "{body}");
    // Addresses, localhost and --allow-host names are served (the viewer uses 127.0.0.1:PORT).
    for host in [
        here.as_str(),
        &format!("localhost:{port}"),
        "LOCALHOST",
        &format!("[::1]:{port}"),
        "192.168.1.20:8470",
        "robot.lan",
        &format!("Robot.LAN:{port}"),
    ] {
        let (status, _, body) = raw_http(port, &request("GET", "/v1/models", Some(host), &[], ""));
        assert_eq!(status, 200, "Host {host}: {body}");
    }

    // CSRF: writes need JSON, whatever the token; form and text bodies are simple requests.
    let add = r#"{"id":"door","times":[100],"states":[true],"model":"fremen:1"}"#;
    for content_type in [
        None,
        Some("Content-Type: text/plain"),
        Some("Content-Type: application/x-www-form-urlencoded"),
        Some("Content-Type: multipart/form-data; boundary=x"),
    ] {
        let headers: Vec<&str> = [Some(auth.as_str()), content_type]
            .into_iter()
            .flatten()
            .collect();
        let (status, _, body) = raw_http(
            port,
            &request("POST", "/v1/add", Some(&here), &headers, add),
        );
        assert_eq!(status, 415, "{content_type:?}: {body}");
        assert!(body.contains("application/json"), "{body}");
    }
    // The bearer scheme is case-insensitive (RFC 9110 §11.1); JSON with a charset is JSON.
    let lower = format!("Authorization: bearer {token}");
    let (status, _, body) = raw_http(
        port,
        &request(
            "POST",
            "/v1/add",
            Some(&here),
            &[&lower, "Content-Type: application/json; charset=utf-8"],
            add,
        ),
    );
    assert_eq!(status, 200, "{body}");
    let upper = format!("Authorization: BEARER {token}");
    let (status, _, body) = raw_http(
        port,
        &request("DELETE", "/v1/models/door", Some(&here), &[&upper], ""),
    );
    assert_eq!(status, 200, "{body}");

    // No CORS: a preflight from another origin gets no permission, answers carry no
    // Access-Control-* headers.
    let (status, head, _) = raw_http(
        port,
        &request(
            "OPTIONS",
            "/v1/add",
            Some(&here),
            &[
                "Origin: http://evil.example",
                "Access-Control-Request-Method: POST",
                "Access-Control-Request-Headers: content-type, authorization",
            ],
            "",
        ),
    );
    assert!(!(200..300).contains(&status), "preflight answered {status}");
    assert!(!head.contains("access-control-"), "{head}");
    let (_, head, _) = raw_http(
        port,
        &request(
            "GET",
            "/v1/models",
            Some(&here),
            &["Origin: http://evil.example"],
            "",
        ),
    );
    assert!(!head.contains("access-control-"), "{head}");

    // /v1/health names the store's kind to everyone, its path only with the token.
    let (_, _, body) = raw_http(port, &request("GET", "/v1/health", Some(&here), &[], ""));
    let health: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(health["store"], "redb", "{body}");
    let (_, _, body) = raw_http(
        port,
        &request("GET", "/v1/health", Some(&here), &[&auth], ""),
    );
    let health: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert!(
        health["store"].as_str().unwrap().contains("chronomap.redb"),
        "{body}"
    );
}

#[test]
fn no_token_is_refused_off_loopback() {
    let data = scratch("serve_network_no_token");
    let port = free_port();
    for listen in [format!("0.0.0.0:{port}"), format!("[::]:{port}")] {
        let (code, _, stderr) = serve_once(&[
            "--data".as_ref(),
            data.as_os_str(),
            "--no-token".as_ref(),
            "--listen".as_ref(),
            listen.as_ref(),
        ]);
        assert_eq!(code, 2, "{listen}: {stderr}");
        assert!(stderr.contains("--no-token is refused"), "{stderr}");
    }
    // On loopback it starts.
    let server = start(&data, port, &Backend::Redb, &["--no-token"]);
    server.stop();
}

/// Opens `n` connections to `port`, each sending `first` (maybe nothing).
fn open(port: u16, n: usize, first: &str) -> Vec<TcpStream> {
    (0..n)
        .map(|_| {
            let mut stream = TcpStream::connect(("127.0.0.1", port)).unwrap();
            stream.write_all(first.as_bytes()).unwrap();
            stream
        })
        .collect()
}

/// Seconds until the server closes `stream` (reads until end of stream), at most `limit`.
fn closed_after(stream: &mut TcpStream, started: Instant, limit: Duration) -> Option<f64> {
    stream
        .set_read_timeout(Some(
            limit
                .saturating_sub(started.elapsed())
                .max(Duration::from_millis(10)),
        ))
        .unwrap();
    let mut buffer = [0u8; 4096];
    loop {
        match stream.read(&mut buffer) {
            Ok(0) => return Some(started.elapsed().as_secs_f64()),
            Ok(_) => continue,
            Err(e) if e.kind() == std::io::ErrorKind::ConnectionReset => {
                return Some(started.elapsed().as_secs_f64());
            }
            Err(_) => return None,
        }
    }
}

#[test]
fn slow_headers_partial_bodies_and_idle_connections_are_closed_and_the_service_answers() {
    let data = scratch("serve_network_timeouts");
    let port = free_port();
    let _server = start(
        &data,
        port,
        &Backend::Redb,
        &[
            "--header-timeout",
            "1",
            "--body-timeout",
            "1",
            "--max-connections",
            "300",
        ],
    );
    let token = token(&data);
    let here = format!("127.0.0.1:{port}");
    let started = Instant::now();
    let mut slow = open(
        port,
        10,
        &format!("GET /v1/models HTTP/1.1\r\nHost: {here}\r\nX-Slow: "),
    );
    let mut partial = open(
        port,
        10,
        &format!(
            "POST /v1/add HTTP/1.1\r\nHost: {here}\r\nAuthorization: Bearer {token}\r\n\
             Content-Type: application/json\r\nContent-Length: 1000\r\n\r\n{{\"id\": \"door\","
        ),
    );
    let mut idle = open(port, 200, "");
    // Meanwhile the service answers.
    let (status, _, body) = raw_http(port, &request("GET", "/v1/health", Some(&here), &[], ""));
    assert_eq!(status, 200, "{body}");
    let limit = Duration::from_secs(8);
    let mut latest: f64 = 0.0;
    for (kind, streams) in [
        ("slow header", &mut slow),
        ("partial body", &mut partial),
        ("idle", &mut idle),
    ] {
        for (i, stream) in streams.iter_mut().enumerate() {
            let seconds = closed_after(stream, started, limit)
                .unwrap_or_else(|| panic!("{kind} connection {i} still open after {limit:?}"));
            latest = latest.max(seconds);
        }
    }
    // A partial body is answered 408 before the connection closes.
    let mut answer = String::new();
    let mut late = open(
        port,
        1,
        &format!(
            "POST /v1/add HTTP/1.1\r\nHost: {here}\r\nAuthorization: Bearer {token}\r\n\
             Content-Type: application/json\r\nContent-Length: 100\r\n\r\n{{"
        ),
    );
    late[0].set_read_timeout(Some(limit)).unwrap();
    let _ = late[0].read_to_string(&mut answer);
    assert!(answer.starts_with("HTTP/1.1 408"), "{answer}");
    let (status, _, body) = raw_http(port, &request("GET", "/v1/health", Some(&here), &[], ""));
    assert_eq!(status, 200, "{body}");
    eprintln!(
        "10 slow headers, 10 partial bodies, 200 idle connections all closed by {latest:.1} s"
    );
}

#[test]
fn connections_over_the_limit_get_503_until_slots_free_up() {
    let data = scratch("serve_network_limit");
    let port = free_port();
    let _server = start(
        &data,
        port,
        &Backend::Redb,
        &["--header-timeout", "1", "--max-connections", "20"],
    );
    let here = format!("127.0.0.1:{port}");
    let started = Instant::now();
    let mut idle = open(port, 20, "");
    std::thread::sleep(Duration::from_millis(200));
    let (status, _, body) = raw_http(port, &request("GET", "/v1/health", Some(&here), &[], ""));
    assert_eq!(status, 503, "{body}");
    assert!(body.contains("--max-connections"), "{body}");
    for stream in &mut idle {
        closed_after(stream, started, Duration::from_secs(8))
            .expect("an idle connection is closed");
    }
    let (status, _, body) = raw_http(port, &request("GET", "/v1/health", Some(&here), &[], ""));
    assert_eq!(status, 200, "{body}");
}
