//! What the live stream sends: one batch of samples, health changes, line statistics and
//! measurements every
//! [`BATCH_EVERY`].

use std::sync::Arc;
use std::time::Duration;

use crate::reply::{BatchJson, HealthJson, LineJson, MeasurementJson, SampleJson};

/// How often a batch is sent.
pub const BATCH_EVERY: Duration = Duration::from_millis(100);

/// Batches queued for each client before it loses the oldest.
pub const BATCH_QUEUE: usize = 64;

/// Entries of one batch beyond which the oldest samples are dropped (and counted).
const BATCH_LIMIT: usize = 20_000;

/// What happened since the last batch.
#[derive(Debug, Default)]
pub(crate) struct Batch(BatchJson);

impl Batch {
    pub(crate) fn add(&mut self, entry: Entry) {
        let batch = &mut self.0;
        match entry {
            Entry::Sample(sample) => {
                if batch.samples.len() == BATCH_LIMIT {
                    batch.samples.remove(0);
                    batch.overflow += 1;
                }
                batch.samples.push(sample);
            }
            Entry::Health(health) => batch.health.push(health),
            Entry::Line(line) => batch.lines.push(line),
            Entry::Measurement(measurement) => {
                if batch.measurements.len() == BATCH_LIMIT {
                    batch.measurements.remove(0);
                    batch.overflow += 1;
                }
                batch.measurements.push(measurement);
            }
        }
    }

    /// The batch as JSON text, if anything happened; it starts again empty.
    pub(crate) fn take(&mut self) -> Option<Arc<str>> {
        let batch = &self.0;
        if batch.samples.is_empty()
            && batch.health.is_empty()
            && batch.lines.is_empty()
            && batch.measurements.is_empty()
        {
            return None;
        }
        let batch = std::mem::take(&mut self.0);
        serde_json::to_string(&batch).ok().map(Arc::from)
    }
}

/// One entry of the stream.
#[derive(Debug)]
pub(crate) enum Entry {
    Sample(SampleJson),
    Health(HealthJson),
    Line(LineJson),
    Measurement(MeasurementJson),
}
