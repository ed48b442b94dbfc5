//! Serving an axum [`Router`] with the limits every optobus HTTP listener has (the console
//! and `/metrics`), so that silent, slow or too many clients cost a listener a bounded number
//! of sockets for a bounded time:
//!
//! - a **header read timeout** ([`Limits::header_read`]): a request's head (its request line
//!   and headers) is complete within it, counted from its first byte, or from the
//!   connection's start for its first request: a connection that says nothing is closed;
//! - an **idle timeout** ([`Limits::idle`]): a kept-alive connection whose next request does
//!   not begin within it after a response is closed;
//! - a **request timeout** ([`Limits::request`]) for ordinary requests: a handler that has not
//!   answered by then is answered `408 Request Timeout` for it, and a client that has not taken
//!   a streamed response within it is closed (a body given whole is in hyper's hands at once:
//!   a client that does not take it is closed at the idle timeout); a response of server-sent
//!   events (`text/event-stream`) is long-lived by design and exempt, but holds its
//!   connection;
//! - a **cap on open connections** ([`Limits::max_connections`]), well below the process's
//!   file descriptors: a connection beyond it is answered `503` at once (best effort, not
//!   read) and closed.
//!
//! Every closing is counted ([`Counts`]). HTTP/1 only, on hyper's server with tokio's timer.
//!
//! ```no_run
//! # async fn demo() -> std::io::Result<()> {
//! let router = axum::Router::new().route("/", axum::routing::get(|| async { "hello" }));
//! let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await?;
//! let server = optobus_http::Server::start(listener, router, optobus_http::Limits::DEFAULT)?;
//! println!("on http://{}/, {:?}", server.address(), server.counts());
//! # Ok(())
//! # }
//! ```
#![forbid(unsafe_code)]

mod connection;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use tokio::net::TcpListener;
use tokio::sync::Semaphore;
use tokio::task::{JoinHandle, JoinSet};

/// The limits of one listener.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Time for a request's head from its first byte (from the connection's start for the
    /// first request of a connection).
    pub header_read: Duration,
    /// Time a kept-alive connection may wait, after a response, for its next request to begin.
    pub idle: Duration,
    /// Time a handler has to answer an ordinary request (then `408`), and, once answered, the
    /// client has to take the whole response (then the connection is closed).
    pub request: Duration,
    /// Connections open at once; one more is answered `503` and closed.
    pub max_connections: usize,
}

impl Limits {
    /// What a listener has unless told otherwise: a silent socket or a half-sent head is closed
    /// within 10 s, an idle kept-alive connection after 15 s, a handler answers within 20 s,
    /// and at most 128 connections are open (a process commonly has 1,024 descriptors).
    pub const DEFAULT: Self = Self {
        header_read: Duration::from_secs(10),
        idle: Duration::from_secs(15),
        request: Duration::from_secs(20),
        max_connections: 128,
    };
}

impl Default for Limits {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// What a listener has done with its connections, since it started.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Counts {
    /// Connections open now.
    pub open: usize,
    /// Connections taken in.
    pub accepted: u64,
    /// Connections refused beyond [`Limits::max_connections`].
    pub refused: u64,
    /// Connections closed because a request's head was not complete in time.
    pub header_timeouts: u64,
    /// Kept-alive connections closed after [`Limits::idle`] without a next request.
    pub idle_closed: u64,
    /// Requests answered `408` because the handler took too long, and connections closed
    /// because the client did not take its response in time.
    pub request_timeouts: u64,
}

/// Why a connection was closed by the listener.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Closed {
    Header,
    Idle,
    Request,
}

/// The counters behind [`Counts`], shared with every connection.
#[derive(Debug)]
pub(crate) struct Counters {
    limits: Limits,
    permits: Arc<Semaphore>,
    accepted: AtomicU64,
    refused: AtomicU64,
    header_timeouts: AtomicU64,
    idle_closed: AtomicU64,
    request_timeouts: AtomicU64,
}

impl Counters {
    fn new(limits: Limits) -> Self {
        Self {
            limits,
            permits: Arc::new(Semaphore::new(limits.max_connections)),
            accepted: AtomicU64::new(0),
            refused: AtomicU64::new(0),
            header_timeouts: AtomicU64::new(0),
            idle_closed: AtomicU64::new(0),
            request_timeouts: AtomicU64::new(0),
        }
    }

    pub(crate) fn closed(&self, why: Closed) {
        let counter = match why {
            Closed::Header => &self.header_timeouts,
            Closed::Idle => &self.idle_closed,
            Closed::Request => &self.request_timeouts,
        };
        counter.fetch_add(1, Ordering::Relaxed);
    }

    fn counts(&self) -> Counts {
        Counts {
            open: self.limits.max_connections - self.permits.available_permits(),
            accepted: self.accepted.load(Ordering::Relaxed),
            refused: self.refused.load(Ordering::Relaxed),
            header_timeouts: self.header_timeouts.load(Ordering::Relaxed),
            idle_closed: self.idle_closed.load(Ordering::Relaxed),
            request_timeouts: self.request_timeouts.load(Ordering::Relaxed),
        }
    }
}

/// A cloneable look at a listener's [`Counts`], for whoever reports them (a status route, a
/// metrics source).
#[derive(Clone, Debug)]
pub struct Tally(Arc<Counters>);

impl Tally {
    /// The counts now.
    pub fn counts(&self) -> Counts {
        self.0.counts()
    }
}

/// A router served on a listener with its [`Limits`]; dropping it stops the listener and
/// closes every connection it has open.
#[derive(Debug)]
pub struct Server {
    address: SocketAddr,
    tally: Tally,
    task: JoinHandle<()>,
}

impl Server {
    /// Serves `router` on `listener` with `limits`, on a task of the current tokio runtime.
    /// Fails only when the listener's address cannot be read.
    pub fn start(listener: TcpListener, router: Router, limits: Limits) -> std::io::Result<Self> {
        let address = listener.local_addr()?;
        let counters = Arc::new(Counters::new(limits));
        let tally = Tally(Arc::clone(&counters));
        let task = tokio::spawn(accept(listener, router, counters));
        Ok(Self {
            address,
            tally,
            task,
        })
    }

    /// Where it listens.
    pub fn address(&self) -> SocketAddr {
        self.address
    }

    /// What it did with its connections so far.
    pub fn counts(&self) -> Counts {
        self.tally.counts()
    }

    /// A cloneable look at its counts, for a status route or a metrics source.
    pub fn tally(&self) -> Tally {
        self.tally.clone()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Serves `router` on `listener` with `limits` in the caller's task, until it is dropped
/// (which closes every connection).
pub async fn serve(listener: TcpListener, router: Router, limits: Limits) {
    accept(listener, router, Arc::new(Counters::new(limits))).await;
}

/// Answer to a connection beyond the cap, written if the socket takes it at once.
const BUSY: &[u8] = b"HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/json\r\n\
retry-after: 1\r\nconnection: close\r\ncontent-length: 50\r\n\r\n\
{\"error\": \"too many connections: try again later\"}";

/// Takes connections in while it runs; the connections are its tasks and end with it.
async fn accept(listener: TcpListener, router: Router, counters: Arc<Counters>) {
    let mut connections = JoinSet::new();
    loop {
        let (stream, peer) = match listener.accept().await {
            Ok(accepted) => accepted,
            Err(error) => {
                // Out of descriptors or memory: wait rather than spin; a connection that
                // failed while being taken in is its client's problem.
                if !matches!(
                    error.kind(),
                    std::io::ErrorKind::ConnectionAborted | std::io::ErrorKind::ConnectionReset
                ) {
                    tracing::warn!(target: "optobus_http", %error, "cannot accept a connection");
                    tokio::time::sleep(Duration::from_millis(200)).await;
                }
                continue;
            }
        };
        while connections.try_join_next().is_some() {}
        match Arc::clone(&counters.permits).try_acquire_owned() {
            Ok(permit) => {
                counters.accepted.fetch_add(1, Ordering::Relaxed);
                let router = router.clone();
                let counters = Arc::clone(&counters);
                connections.spawn(async move {
                    connection::serve(stream, peer, router, &counters).await;
                    drop(permit);
                });
            }
            Err(_) => {
                counters.refused.fetch_add(1, Ordering::Relaxed);
                let _ = stream.try_write(BUSY);
            }
        }
    }
}
