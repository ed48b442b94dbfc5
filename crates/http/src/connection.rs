//! One connection: hyper's HTTP/1 server over the socket, and a watchdog that knows what the
//! connection is doing (waiting for a request, reading its head, in a handler, sending the
//! response) and closes it when that takes longer than its limit.

use std::convert::Infallible;
use std::io;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};

use axum::body::Body;
use axum::extract::ConnectInfo;
use axum::http::header::{CONNECTION, CONTENT_TYPE};
use axum::http::{HeaderValue, Request, Response, StatusCode};
use axum::Router;
use http_body::Frame;
use hyper::body::Incoming;
use hyper_util::rt::{TokioIo, TokioTimer};
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::TcpStream;
use tokio::sync::Notify;
use tokio::time::Instant;
use tower::ServiceExt;

use crate::{Closed, Counters, Limits};

/// What a connection is doing, and since when.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Waiting for a request to begin: its first (`first`) since the connection started, or the
    /// next after a response.
    Waiting { since: Instant, first: bool },
    /// A request's head is arriving.
    Head { since: Instant },
    /// A handler is at work (its own timeout bounds it).
    Handling,
    /// The response is being sent.
    Responding { since: Instant },
    /// A long-lived response (server-sent events) is being sent.
    Streaming,
}

/// The connection's phase, watched.
#[derive(Debug)]
struct Watch {
    phase: Mutex<Phase>,
    changed: Notify,
}

impl Watch {
    fn new() -> Self {
        Self {
            phase: Mutex::new(Phase::Waiting {
                since: Instant::now(),
                first: true,
            }),
            changed: Notify::new(),
        }
    }

    fn set(&self, change: impl FnOnce(Phase) -> Option<Phase>) {
        let mut phase = self.phase.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(next) = change(*phase) {
            *phase = next;
            self.changed.notify_one();
        }
    }

    /// Bytes arrived: a request begins, if none was under way.
    fn read(&self) {
        self.set(|phase| match phase {
            // The first request's head is timed from the connection's start.
            Phase::Waiting { since, first: true } => Some(Phase::Head { since }),
            Phase::Waiting { first: false, .. } => Some(Phase::Head {
                since: Instant::now(),
            }),
            _ => None,
        });
    }

    fn handling(&self) {
        self.set(|_| Some(Phase::Handling));
    }

    fn responding(&self, long_lived: bool) {
        self.set(|_| {
            Some(if long_lived {
                Phase::Streaming
            } else {
                Phase::Responding {
                    since: Instant::now(),
                }
            })
        });
    }

    fn finished(&self) {
        self.set(|_| {
            Some(Phase::Waiting {
                since: Instant::now(),
                first: false,
            })
        });
    }

    /// When the phase now runs out, and what closing then counts as.
    fn deadline(&self, limits: &Limits) -> Option<(Instant, Closed)> {
        match *self.phase.lock().unwrap_or_else(|e| e.into_inner()) {
            Phase::Waiting { since, first: true } | Phase::Head { since } => {
                Some((since + limits.header_read, Closed::Header))
            }
            Phase::Waiting {
                since,
                first: false,
            } => Some((since + limits.idle, Closed::Idle)),
            Phase::Responding { since } => Some((since + limits.request, Closed::Request)),
            Phase::Handling | Phase::Streaming => None,
        }
    }

    /// Returns once the connection has overstayed its phase.
    async fn expired(&self, limits: &Limits) -> Closed {
        loop {
            let changed = self.changed.notified();
            tokio::pin!(changed);
            changed.as_mut().enable();
            match self.deadline(limits) {
                Some((at, why)) if at <= Instant::now() => return why,
                Some((at, _)) => {
                    tokio::select! {
                        _ = tokio::time::sleep_until(at) => {}
                        _ = changed => {}
                    }
                }
                None => changed.await,
            }
        }
    }
}

/// The socket, telling the watch when bytes arrive.
struct Watched {
    stream: TcpStream,
    watch: Arc<Watch>,
}

impl AsyncRead for Watched {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        let this = &mut *self;
        let poll = Pin::new(&mut this.stream).poll_read(cx, buf);
        if matches!(poll, Poll::Ready(Ok(()))) && buf.filled().len() > before {
            this.watch.read();
        }
        poll
    }
}

impl AsyncWrite for Watched {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.stream).poll_write(cx, buf)
    }

    fn poll_write_vectored(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.stream).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.stream).poll_shutdown(cx)
    }
}

/// A response's body, telling the watch when hyper is done with it (sent, or given up).
struct Finishing {
    body: Body,
    watch: Arc<Watch>,
}

impl http_body::Body for Finishing {
    type Data = axum::body::Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Self::Data>, Self::Error>>> {
        Pin::new(&mut self.body).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.body.size_hint()
    }
}

impl Drop for Finishing {
    fn drop(&mut self) {
        self.watch.finished();
    }
}

/// Whether a response is long-lived by design (server-sent events).
fn long_lived(response: &Response<Body>) -> bool {
    response
        .headers()
        .get(CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("text/event-stream"))
}

/// The answer of a handler that took too long.
fn timed_out(limits: &Limits) -> Response<Body> {
    let body = format!(
        "{{\"error\": \"the request was not answered within {} s\"}}",
        limits.request.as_secs_f64()
    );
    let mut response = Response::new(Body::from(body));
    *response.status_mut() = StatusCode::REQUEST_TIMEOUT;
    let headers = response.headers_mut();
    headers.insert(CONTENT_TYPE, HeaderValue::from_static("application/json"));
    headers.insert(CONNECTION, HeaderValue::from_static("close"));
    response
}

/// Serves one connection until the client closes it, it fails, or it overstays a limit. Each
/// request carries the client's address as axum's `ConnectInfo`.
pub(crate) async fn serve(
    stream: TcpStream,
    peer: SocketAddr,
    router: Router,
    counters: &Arc<Counters>,
) {
    let limits = counters.limits;
    let watch = Arc::new(Watch::new());
    let io = TokioIo::new(Watched {
        stream,
        watch: Arc::clone(&watch),
    });
    let service = {
        let watch = Arc::clone(&watch);
        let counters = Arc::clone(counters);
        hyper::service::service_fn(move |request: Request<Incoming>| {
            let router = router.clone();
            let watch = Arc::clone(&watch);
            let counters = Arc::clone(&counters);
            async move {
                watch.handling();
                let mut request = request.map(Body::new);
                request.extensions_mut().insert(ConnectInfo(peer));
                let response =
                    match tokio::time::timeout(limits.request, router.oneshot(request)).await {
                        Ok(Ok(response)) => response,
                        Ok(Err(never)) => match never {},
                        Err(_) => {
                            counters.closed(Closed::Request);
                            timed_out(&limits)
                        }
                    };
                watch.responding(long_lived(&response));
                let response = response.map(|body| Body::new(Finishing { body, watch }));
                Ok::<_, Infallible>(response)
            }
        })
    };
    let mut builder = hyper::server::conn::http1::Builder::new();
    // hyper's own head timer runs from the end of a response to the next head: past the idle
    // and header limits together it is only a backstop for the watch.
    builder
        .timer(TokioTimer::new())
        .header_read_timeout(limits.idle + limits.header_read);
    let connection = builder.serve_connection(io, service);
    tokio::select! {
        result = connection => {
            if let Err(error) = result {
                tracing::debug!(target: "optobus_http", %error, "connection ended");
            }
        }
        why = watch.expired(&limits) => counters.closed(why),
    }
}
