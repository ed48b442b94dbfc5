//! The live stream: server-sent events, one batch of samples, health changes and line
//! statistics every [`BATCH_EVERY`](crate::BATCH_EVERY), so that a browser gets a few
//! messages a second however fast the bus polls. Each client reads from a queue of
//! [`BATCH_QUEUE`](crate::BATCH_QUEUE) batches; a client that falls further behind loses the oldest, is told how many (a `dropped` event) and the
//! console counts them.

use std::convert::Infallible;
use std::sync::atomic::Ordering;
use std::sync::Arc;

use axum::extract::State;
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use futures_util::Stream;
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::{broadcast, watch};

use crate::state::Shared;

/// One client of the stream, counted while it is connected.
struct Client {
    batches: broadcast::Receiver<Arc<str>>,
    stopped: watch::Receiver<bool>,
    shared: Arc<Shared>,
}

impl Drop for Client {
    fn drop(&mut self) {
        self.shared.clients.fetch_sub(1, Ordering::Relaxed);
    }
}

/// `GET /api/stream`.
pub(crate) async fn stream(
    State(shared): State<Arc<Shared>>,
) -> Sse<impl Stream<Item = Result<SseEvent, Infallible>>> {
    shared.clients.fetch_add(1, Ordering::Relaxed);
    let client = Client {
        batches: shared.batches.subscribe(),
        stopped: shared.stopped.subscribe(),
        shared,
    };
    let events = futures_util::stream::unfold(client, |mut client| async move {
        let batch = tokio::select! {
            batch = client.batches.recv() => batch,
            // The server stopped (or is gone): the stream ends.
            _ = client.stopped.wait_for(|stopped| *stopped) => return None,
        };
        let event = match batch {
            Ok(text) => SseEvent::default().data(&*text),
            Err(RecvError::Lagged(missed)) => {
                client.shared.dropped.fetch_add(missed, Ordering::Relaxed);
                SseEvent::default()
                    .event("dropped")
                    .data(missed.to_string())
            }
            Err(RecvError::Closed) => return None,
        };
        Some((Ok(event), client))
    });
    Sse::new(events).keep_alive(KeepAlive::default())
}
