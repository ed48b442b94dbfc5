//! The console listener's limits over real sockets (issue 28, point 4): silent connections
//! closed, slow requests answered 408, connections beyond the cap refused.

mod common;

use common::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn silent_http_connections_are_closed_after_the_header_timeout() {
    use tokio::io::AsyncWriteExt;
    let running = start(TWO);
    let config = HttpConfig::new("127.0.0.1:0".parse().unwrap());
    let server = optobus_console::serve_with_limits(&running, &config, short(16))
        .await
        .unwrap();
    let address = server.address();
    // Says nothing.
    let mut silent = tokio::net::TcpStream::connect(address).await.unwrap();
    assert_eq!(until_closed(&mut silent).await, "");
    // Half a head, never finished.
    let mut half = tokio::net::TcpStream::connect(address).await.unwrap();
    half.write_all(format!("GET /api/status HTTP/1.1\r\nHost: {address}\r\n").as_bytes())
        .await
        .unwrap();
    assert_eq!(until_closed(&mut half).await, "");
    // A kept-alive connection, idle after its answer.
    let mut idle = tokio::net::TcpStream::connect(address).await.unwrap();
    idle.write_all(format!("GET /api/status HTTP/1.1\r\nHost: {address}\r\n\r\n").as_bytes())
        .await
        .unwrap();
    assert!(until_closed(&mut idle).await.starts_with("HTTP/1.1 200"));
    let counts = server.connections();
    assert_eq!(counts.header_timeouts, 2, "{counts:?}");
    assert_eq!(counts.idle_closed, 1, "{counts:?}");
    // The live stream is long-lived: it outlasts the request timeout.
    let mut stream = tokio::net::TcpStream::connect(address).await.unwrap();
    stream
        .write_all(format!("GET /api/stream HTTP/1.1\r\nHost: {address}\r\n\r\n").as_bytes())
        .await
        .unwrap();
    let mut seen = Vec::new();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(3);
    while tokio::time::Instant::now() < deadline {
        use tokio::io::AsyncReadExt;
        let mut buffer = [0; 4096];
        match tokio::time::timeout_at(deadline, stream.read(&mut buffer)).await {
            Ok(Ok(0)) => panic!("the stream was closed"),
            Ok(Ok(n)) => seen.extend_from_slice(&buffer[..n]),
            Ok(Err(error)) => panic!("{error}"),
            Err(_) => break,
        }
    }
    let seen = String::from_utf8_lossy(&seen);
    assert!(seen.starts_with("HTTP/1.1 200"), "{seen}");
    assert!(seen.matches("data: {").count() >= 3, "{seen}");
    let status = over_socket(address, &status_request(address)).await;
    let body: Value = serde_json::from_str(status.split_once("\r\n\r\n").unwrap().1).unwrap();
    assert_eq!(body["connections"]["header_timeouts"], 2, "{body}");
    assert_eq!(body["connections"]["request_timeouts"], 0, "{body}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_request_not_answered_in_time_is_answered_408() {
    let running = start(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 3s }
",
    );
    running.simulator("head").unwrap().set_silent(true);
    let config = HttpConfig::new("127.0.0.1:0".parse().unwrap());
    let server = optobus_console::serve_with_limits(&running, &config, short(16))
        .await
        .unwrap();
    let address = server.address();
    let body = r#"{"register": "light_power"}"#;
    let reply = over_socket(
        address,
        &format!(
            "POST /api/devices/head/read HTTP/1.1\r\nHost: {address}\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\r\n{body}",
            body.len()
        ),
    )
    .await;
    assert!(reply.starts_with("HTTP/1.1 408"), "{reply}");
    assert!(
        reply.ends_with(r#"{"error": "the request was not answered within 0.5 s"}"#),
        "{reply}"
    );
    assert_eq!(server.connections().request_timeouts, 1);
}

/// The descriptors this process has open.
fn descriptors() -> usize {
    std::fs::read_dir("/proc/self/fd").map_or(0, |dir| dir.count())
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn http_connections_beyond_the_cap_do_not_exhaust_descriptors() {
    let running = start(TWO);
    let config = HttpConfig::new("127.0.0.1:0".parse().unwrap());
    let mut limits = short(4);
    limits.header_read = Duration::from_secs(60);
    let server = optobus_console::serve_with_limits(&running, &config, limits)
        .await
        .unwrap();
    let address = server.address();
    let before = descriptors();
    let mut silent = Vec::new();
    for _ in 0..40 {
        silent.push(tokio::net::TcpStream::connect(address).await.unwrap());
    }
    for _ in 0..1000 {
        let counts = server.connections();
        if counts.accepted + counts.refused == 40 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let counts = server.connections();
    // 40 client sockets of the test, 4 on the server's side: the refused are closed.
    let held = descriptors() - before;
    assert!(held <= 40 + 4 + 4, "{held} descriptors for 40 connections");
    assert_eq!((counts.open, counts.refused), (4, 36), "{counts:?}");
    let refused = until_closed(silent.last_mut().unwrap()).await;
    assert!(refused.starts_with("HTTP/1.1 503"), "{refused}");
    assert!(refused.contains("retry-after: 1"), "{refused}");
    drop(silent);
    // Once they are gone, a client is served again.
    for _ in 0..1000 {
        if server.connections().open == 0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let status = over_socket(address, &status_request(address)).await;
    assert!(status.starts_with("HTTP/1.1 200"), "{status}");
}
