//! The live stream: server-sent events, one batch of samples, health changes and line
//! statistics every [`BATCH_EVERY`](crate::BATCH_EVERY), so that a browser gets a few
//! messages a second however fast the bus polls. Each client has its own queue of
//! [`BATCH_QUEUE`](crate::BATCH_QUEUE) batches, filled by the task that makes the batches; a
//! client that falls further behind loses the oldest, counted by the console as they are
//! dropped (`GET /api/status`), and is told how many (a `dropped` event) when it reads again.

use std::convert::Infallible;
use std::sync::Arc;

use axum::extract::State;
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use futures_util::Stream;
use tokio::sync::watch;

use crate::state::{ClientQueue, Next, Shared};

/// One client of the stream, listed while it is connected.
struct Client {
    queue: Arc<ClientQueue>,
    stopped: watch::Receiver<bool>,
    shared: Arc<Shared>,
}

impl Drop for Client {
    fn drop(&mut self) {
        self.shared.leave(&self.queue);
    }
}

/// `GET /api/stream`.
pub(crate) async fn stream(
    State(shared): State<Arc<Shared>>,
) -> Sse<impl Stream<Item = Result<SseEvent, Infallible>>> {
    let client = Client {
        queue: shared.join(),
        stopped: shared.stopped.subscribe(),
        shared,
    };
    let events = futures_util::stream::unfold(client, |mut client| async move {
        let next = loop {
            let ready = client.queue.ready.notified();
            if let Some(next) = client.queue.next() {
                break next;
            }
            tokio::select! {
                _ = ready => {}
                // The server stopped (or is gone): the stream ends.
                _ = client.stopped.wait_for(|stopped| *stopped) => return None,
            }
        };
        let event = match next {
            Next::Batch(text) => SseEvent::default().data(&*text),
            Next::Dropped(missed) => SseEvent::default()
                .event("dropped")
                .data(missed.to_string()),
        };
        Some((Ok(event), client))
    });
    Sse::new(events).keep_alive(KeepAlive::default())
}
