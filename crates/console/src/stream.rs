//! The live stream: server-sent events, one batch of samples, health changes and line
//! statistics every [`BATCH_EVERY`], so that a browser gets a few messages a second however
//! fast the bus polls. Each client reads from a queue of [`BATCH_QUEUE`] batches; a client
//! that falls further behind loses the oldest, is told how many (a `dropped` event) and the
//! console counts them.

use std::convert::Infallible;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::State;
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use futures_util::Stream;
use serde_json::Value as Json;
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::{broadcast, watch};

use crate::state::{Kind, Shared};

/// How often a batch is sent.
pub const BATCH_EVERY: Duration = Duration::from_millis(100);

/// Batches queued for each client before it loses the oldest.
pub const BATCH_QUEUE: usize = 64;

/// Entries of one batch beyond which the oldest samples are dropped (and counted).
const BATCH_LIMIT: usize = 20_000;

/// What happened since the last batch.
#[derive(Debug, Default)]
pub(crate) struct Batch {
    samples: Vec<Json>,
    health: Vec<Json>,
    lines: Vec<Json>,
    /// Samples dropped because the batch was full.
    overflow: u64,
}

impl Batch {
    pub(crate) fn add(&mut self, kind: Kind, json: Json) {
        match kind {
            Kind::Sample => {
                if self.samples.len() == BATCH_LIMIT {
                    self.samples.remove(0);
                    self.overflow += 1;
                }
                self.samples.push(json);
            }
            Kind::Health => self.health.push(json),
            Kind::Line => self.lines.push(json),
        }
    }

    /// The batch as JSON text, if anything happened; it starts again empty.
    pub(crate) fn take(&mut self) -> Option<Arc<str>> {
        if self.samples.is_empty() && self.health.is_empty() && self.lines.is_empty() {
            return None;
        }
        let batch = std::mem::take(self);
        let json = serde_json::json!({
            "samples": batch.samples,
            "health": batch.health,
            "lines": batch.lines,
            "overflow": batch.overflow,
        });
        Some(Arc::from(json.to_string()))
    }
}

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
