//! The MQTT publisher's counts on the Prometheus exporter's `/metrics`: the one place where
//! the two outputs meet (neither crate knows the other). A run with both adds them itself
//! ([`Service::start`](crate::Service::start)).

use optobus_metrics::{Metrics, Reading, SourceError};
use optobus_mqtt::{Counts, CountsReader};

/// Adds the publisher's counts to `metrics`, read at every scrape.
pub fn add(metrics: &Metrics, counts: CountsReader) -> Result<(), SourceError> {
    metrics.add_source(move || readings(&counts.counts()))
}

/// The series of one look at the counts (counters named without `_total`, which the
/// exposition adds).
fn readings(counts: &Counts) -> Vec<Reading> {
    let gauge = |count: usize| i64::try_from(count).unwrap_or(i64::MAX);
    vec![
        Reading::counter(
            "optobus_mqtt_samples_published",
            "Samples the MQTT broker took (acknowledged at QoS 1, written at QoS 0).",
            counts.published,
        ),
        Reading::counter(
            "optobus_mqtt_samples_dropped",
            "Samples dropped, oldest first, because the queue was full while the broker was away.",
            counts.dropped,
        ),
        Reading::counter(
            "optobus_mqtt_samples_requeued",
            "Samples sent again after a broken connection, the broker not having acknowledged them.",
            counts.requeued,
        ),
        Reading::gauge(
            "optobus_mqtt_queue_samples",
            "Samples waiting in the queue for the broker.",
            gauge(counts.queued),
        ),
        Reading::gauge(
            "optobus_mqtt_in_flight_samples",
            "Samples handed to the MQTT client and not yet taken by the broker.",
            gauge(counts.in_flight),
        ),
        Reading::gauge(
            "optobus_mqtt_connected",
            "1 while the MQTT broker is connected.",
            i64::from(counts.connected),
        ),
        Reading::counter(
            "optobus_mqtt_connections",
            "Connections made to the MQTT broker.",
            counts.connections,
        ),
        Reading::counter(
            "optobus_mqtt_events_missed",
            "Bus events the MQTT publisher fell too far behind to see.",
            counts.missed_events,
        ),
        Reading::counter(
            "optobus_mqtt_writes_taken",
            "Writes from MQTT topics handed to the bus (which may still refuse them).",
            counts.writes_taken,
        ),
        Reading::counter(
            "optobus_mqtt_writes_too_large",
            "Writes from MQTT refused because their payload was over the limit.",
            counts.writes_too_large,
        ),
        Reading::counter(
            "optobus_mqtt_writes_busy",
            "Writes from MQTT refused as busy: the queue of writes was full.",
            counts.writes_busy,
        ),
        Reading::counter(
            "optobus_mqtt_writes_retained",
            "Writes from MQTT refused because they came retained.",
            counts.writes_retained,
        ),
        Reading::counter(
            "optobus_mqtt_replies_dropped",
            "Answers to MQTT writes dropped, oldest first, because the queue of answers was full.",
            counts.replies_dropped,
        ),
        Reading::counter(
            "optobus_mqtt_oversize_dropped",
            "MQTT messages dropped unsent because their packet was over the client's limit.",
            counts.oversize_dropped,
        ),
        Reading::counter(
            "optobus_mqtt_incoming_too_large",
            "MQTT connections broken because the broker sent a packet over the client's limit.",
            counts.incoming_too_large,
        ),
        Reading::counter(
            "optobus_mqtt_homeassistant_births",
            "Times Home Assistant announced itself online.",
            counts.homeassistant_births,
        ),
        Reading::counter(
            "optobus_mqtt_rediscoveries_coalesced",
            "Home Assistant births folded into a re-announcement already waiting.",
            counts.rediscoveries_coalesced,
        ),
        Reading::gauge(
            "optobus_mqtt_control_queue_messages",
            "MQTT announcements and answers to writes waiting.",
            gauge(counts.control_queued),
        ),
        Reading::counter(
            "optobus_mqtt_states_published",
            "States the broker took on the state topics Home Assistant reads.",
            counts.states_published,
        ),
        Reading::counter(
            "optobus_mqtt_states_skipped",
            "Samples left off the state topics: a newer one came within state_every.",
            counts.states_skipped,
        ),
        Reading::counter(
            "optobus_mqtt_state_reads",
            "Reads of Home Assistant controls for their state topics, at start and each refresh.",
            counts.state_reads,
        ),
        Reading::counter(
            "optobus_mqtt_state_reads_busy",
            "Reads for the state topics the line refused as busy, tried again at the next refresh.",
            counts.state_reads_busy,
        ),
        Reading::counter(
            "optobus_mqtt_state_reads_failed",
            "Reads for the state topics the device or the line failed.",
            counts.state_reads_failed,
        ),
        Reading::counter(
            "optobus_mqtt_state_reads_after_writes",
            "Reads of controls another path (console, gateway, program) wrote, made at once.",
            counts.state_reads_after_writes,
        ),
        Reading::counter(
            "optobus_mqtt_state_rereads_coalesced",
            "Writes of a control by another path that found its read already due.",
            counts.state_rereads_coalesced,
        ),
    ]
}
