//! The metrics listener over real sockets: silent connections closed after the header
//! timeout and counted (issue 28, point 4), connections beyond the cap answered 503, and `/`
//! a page that links `/metrics`.

mod common;

use common::*;

/// Point 4 of issue 28: `/metrics` closes a connection that says nothing, or half a request,
/// after its header timeout, and counts it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
async fn silent_http_connections_are_closed_after_the_header_timeout() {
    let bus = Bus::new(file());
    let exporter = exporter_with_limits(&bus, short(8)).await;
    let address = exporter.address();
    let mut silent = tokio::net::TcpStream::connect(address).await.unwrap();
    assert_eq!(until_closed(&mut silent).await, "");
    let mut half = tokio::net::TcpStream::connect(address).await.unwrap();
    half.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n")
        .await
        .unwrap();
    assert_eq!(until_closed(&mut half).await, "");
    assert_eq!(exporter.connections().header_timeouts, 2);
    let (head, text) = scrape(address, "text/plain").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert_eq!(
        series(
            &text,
            "optobus_metrics_http_connections_timed_out_total",
            ""
        ),
        Some(2.0),
        "{text}"
    );
    assert_promtool_accepts(&text);
}

/// The sockets this process holds on the server side of `address` (the listener and the
/// connections it accepted), from `/proc`: the descriptors of the tests running beside this
/// one are not counted.
fn server_sockets(address: std::net::SocketAddr) -> usize {
    let inodes: std::collections::HashSet<String> = std::fs::read_dir("/proc/self/fd")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| std::fs::read_link(entry.path()).ok())
        .filter_map(|link| {
            let inode = link.to_str()?.strip_prefix("socket:[")?.strip_suffix(']')?;
            Some(inode.to_owned())
        })
        .collect();
    let port = format!(":{:04X}", address.port());
    ["/proc/self/net/tcp", "/proc/self/net/tcp6"]
        .iter()
        .filter_map(|table| std::fs::read_to_string(table).ok())
        .flat_map(|table| {
            table
                .lines()
                .skip(1)
                .map(|line| {
                    line.split_whitespace()
                        .map(str::to_owned)
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
        })
        .filter(|columns| {
            columns.len() > 9 && columns[1].ends_with(&port) && inodes.contains(&columns[9])
        })
        .count()
}

/// Point 4 of issue 28: beyond its cap `/metrics` answers 503 and closes at once, so a flood of
/// silent sockets holds no more descriptors than the cap.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn http_connections_beyond_the_cap_do_not_exhaust_descriptors() {
    let bus = Bus::new(file());
    let mut limits = short(4);
    limits.header_read = Duration::from_secs(60);
    let exporter = exporter_with_limits(&bus, limits).await;
    let address = exporter.address();
    let mut silent = Vec::new();
    for _ in 0..40 {
        silent.push(tokio::net::TcpStream::connect(address).await.unwrap());
    }
    for _ in 0..1000 {
        let counts = exporter.connections();
        if counts.accepted + counts.refused == 40 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let counts = exporter.connections();
    // The listener, the 4 connections the cap lets in, and a few refused ones being closed.
    let held = server_sockets(address);
    assert!(
        (1 + 4..=1 + 4 + 4).contains(&held),
        "{held} server sockets for 40 connections"
    );
    assert_eq!((counts.open, counts.refused), (4, 36), "{counts:?}");
    let refused = until_closed(silent.last_mut().unwrap()).await;
    assert!(refused.starts_with("HTTP/1.1 503"), "{refused}");
    drop(silent);
    for _ in 0..1000 {
        if exporter.connections().open == 0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let (head, text) = scrape(address, "text/plain").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert_eq!(
        series(&text, "optobus_metrics_http_connections_refused_total", ""),
        Some(36.0),
        "{text}"
    );
}

/// Issue 30, point 9: `/` of the metrics listener is a page linking `/metrics`, and any
/// other path a 404 that says where the metrics are.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn prometheus_listener_root_links_to_metrics() {
    let bus = Bus::new(file());
    let exporter = exporter(&bus).await;
    let (head, body) = get(exporter.address(), "/").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert!(
        head.contains("content-type: text/html; charset=utf-8"),
        "{head}"
    );
    assert!(body.contains("<a href=\"/metrics\">/metrics</a>"), "{body}");
    let (head, body) = get(exporter.address(), "/metric").await;
    assert!(head.starts_with("HTTP/1.1 404"), "{head}");
    assert_eq!(body, "Not found: the metrics are at /metrics.\n");
}
