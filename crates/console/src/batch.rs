//! What the live stream sends: one batch of samples, health changes and line statistics every
//! [`BATCH_EVERY`].

use std::sync::Arc;
use std::time::Duration;

use serde_json::Value as Json;

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

/// What a stream entry is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Kind {
    Sample,
    Health,
    Line,
}
