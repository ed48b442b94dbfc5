//! The limits over real sockets, on a router of the test's own: a handler too slow is answered
//! 408, a client that does not take its response is closed, a long-lived event stream is not,
//! and each closing is counted as what it was.

use std::time::Duration;

use axum::http::header::CONTENT_TYPE;
use axum::routing::get;
use axum::Router;
use optobus_http::{Counts, Limits, Server};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

fn limits() -> Limits {
    Limits {
        header_read: Duration::from_millis(300),
        idle: Duration::from_millis(300),
        request: Duration::from_millis(500),
        max_connections: 8,
    }
}

async fn server() -> Server {
    let router = Router::new()
        .route(
            "/slow",
            get(|| async {
                tokio::time::sleep(Duration::from_secs(30)).await;
                "late"
            }),
        )
        .route(
            "/big",
            get(|| async {
                // 32 chunks of 1 MiB: hyper takes the body as the client takes it.
                let chunk = axum::body::Bytes::from(vec![b'x'; 1 << 20]);
                let chunks = (0..32).map(move |_| Ok::<_, std::convert::Infallible>(chunk.clone()));
                axum::body::Body::from_stream(Chunks(chunks.collect()))
            }),
        )
        .route(
            "/events",
            get(|| async {
                let ticks = Ticks(tokio::time::interval(Duration::from_millis(100)));
                (
                    [(CONTENT_TYPE, "text/event-stream")],
                    axum::body::Body::from_stream(ticks),
                )
            }),
        );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    Server::start(listener, router, limits()).unwrap()
}

/// `data: tick` every 100 ms, for ever.
struct Ticks(tokio::time::Interval);

impl futures_core::Stream for Ticks {
    type Item = Result<&'static str, std::convert::Infallible>;
    fn poll_next(
        mut self: std::pin::Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> std::task::Poll<Option<Self::Item>> {
        self.0.poll_tick(cx).map(|_| Some(Ok("data: tick\n\n")))
    }
}

/// A stream of the chunks given.
struct Chunks(std::collections::VecDeque<Result<axum::body::Bytes, std::convert::Infallible>>);

impl futures_core::Stream for Chunks {
    type Item = Result<axum::body::Bytes, std::convert::Infallible>;
    fn poll_next(
        mut self: std::pin::Pin<&mut Self>,
        _: &mut std::task::Context<'_>,
    ) -> std::task::Poll<Option<Self::Item>> {
        std::task::Poll::Ready(self.0.pop_front())
    }
}

/// Waits (20 s at most) until the counts are what `done` accepts.
async fn until(server: &Server, done: impl Fn(&Counts) -> bool) -> Counts {
    for _ in 0..2000 {
        let counts = server.counts();
        if done(&counts) {
            return counts;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    panic!("never: {:?}", server.counts());
}

async fn send(server: &Server, path: &str) -> TcpStream {
    let mut stream = TcpStream::connect(server.address()).await.unwrap();
    let request = format!("GET {path} HTTP/1.1\r\nHost: test\r\n\r\n");
    stream.write_all(request.as_bytes()).await.unwrap();
    stream
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_handler_too_slow_is_answered_408_and_the_connection_closed() {
    let server = server().await;
    let mut stream = send(&server, "/slow").await;
    let mut reply = String::new();
    let read = tokio::time::timeout(Duration::from_secs(20), stream.read_to_string(&mut reply));
    read.await.expect("answered and closed").unwrap();
    assert!(
        reply.starts_with("HTTP/1.1 408 Request Timeout\r\n"),
        "{reply}"
    );
    assert!(reply.ends_with(r#"{"error": "the request was not answered within 0.5 s"}"#));
    let counts = until(&server, |c| c.open == 0).await;
    assert_eq!(
        (counts.accepted, counts.request_timeouts),
        (1, 1),
        "{counts:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_client_that_does_not_take_its_response_is_closed() {
    let server = server().await;
    // Asks for 32 MiB and reads none of it.
    let _stalled = send(&server, "/big").await;
    // (A body given whole is in hyper's hands at once: the idle timeout closes that one.)
    let counts = until(&server, |c| c.request_timeouts == 1).await;
    assert_eq!(counts.header_timeouts + counts.idle_closed, 0, "{counts:?}");
    until(&server, |c| c.open == 0).await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_event_stream_outlives_the_request_timeout() {
    let server = server().await;
    let mut stream = send(&server, "/events").await;
    let mut seen = Vec::new();
    // Three request timeouts long.
    let deadline = tokio::time::Instant::now() + Duration::from_millis(1500);
    let mut buffer = [0; 1024];
    while let Ok(read) = tokio::time::timeout_at(deadline, stream.read(&mut buffer)).await {
        let n = read.unwrap();
        assert!(n > 0, "closed after {}", String::from_utf8_lossy(&seen));
        seen.extend_from_slice(&buffer[..n]);
    }
    let seen = String::from_utf8_lossy(&seen);
    assert!(seen.matches("data: tick").count() >= 5, "{seen}");
    let counts = server.counts();
    assert_eq!(counts.open, 1, "{counts:?}");
    assert_eq!(counts.request_timeouts, 0, "{counts:?}");
    // Dropping the server closes it.
    drop(server);
    let mut rest = Vec::new();
    let closed = tokio::time::timeout(Duration::from_secs(20), stream.read_to_end(&mut rest));
    closed.await.expect("closed with the server").unwrap();
}
