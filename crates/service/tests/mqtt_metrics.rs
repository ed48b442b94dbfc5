//! The MQTT publisher's counts on the Prometheus exporter's `/metrics`, exactly, after an
//! outage of the broker that overflowed the publisher's queue.

use std::path::PathBuf;
use std::process::Child;
use std::time::Duration;

use optobus_bus::{Bus, Catalogue};
use optobus_metrics::Exporter;
use optobus_mqtt::Counts;
use optobus_mqtt::Publisher;
use optobus_service::mqtt_metrics::add;
use optobus_service::ServiceFile;
use tokio::io::{AsyncReadExt, AsyncWriteExt};

/// A mosquitto on a free 127.0.0.1 port, killed when dropped.
struct Broker {
    port: u16,
    dir: PathBuf,
    child: Child,
}

impl Broker {
    async fn start() -> Self {
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("a free port")
            .port();
        let dir = std::env::temp_dir().join(format!(
            "optobus-service-mqtt-metrics-{}-{port}",
            std::process::id()
        ));
        std::fs::create_dir_all(&dir).unwrap();
        let config = dir.join("mosquitto.conf");
        std::fs::write(
            &config,
            format!("listener {port} 127.0.0.1\nallow_anonymous true\n"),
        )
        .unwrap();
        let child = optobus_testkit::spawn_mosquitto(&config);
        // Killed when dropped, also when it never listens.
        let broker = Self { port, dir, child };
        for _ in 0..200 {
            if tokio::net::TcpStream::connect(("127.0.0.1", port))
                .await
                .is_ok()
            {
                return broker;
            }
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        panic!("mosquitto does not listen on {port}");
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Broker {
    fn drop(&mut self) {
        self.kill();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// The body of `GET /metrics` in the Prometheus text format.
async fn scrape(address: std::net::SocketAddr) -> String {
    let mut stream = tokio::net::TcpStream::connect(address).await.unwrap();
    let request = format!("GET /metrics HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n");
    stream.write_all(request.as_bytes()).await.unwrap();
    let mut reply = String::new();
    stream.read_to_string(&mut reply).await.unwrap();
    let (head, body) = reply.split_once("\r\n\r\n").expect("an HTTP reply");
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    body.to_owned()
}

/// The value of the series `name` (no labels) in Prometheus text.
fn series(text: &str, name: &str) -> Option<f64> {
    text.lines()
        .find_map(|line| line.strip_prefix(&format!("{name} ")))
        .and_then(|value| value.parse().ok())
}

async fn wait_for(what: &str, publisher: &Publisher, done: impl Fn(&Counts) -> bool) {
    for _ in 0..500 {
        if done(&publisher.counts()) {
            return;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    panic!("{what}: {:?}", publisher.counts());
}

#[tokio::test]
#[cfg_attr(
    not(all(peer_mosquitto, peer_promtool)),
    ignore = "mosquitto or promtool is not installed (Debian packages mosquitto, prometheus)"
)]
async fn mqtt_counts_are_on_metrics_exactly_after_an_outage_that_overflowed_the_queue() {
    let mut broker = Broker::start().await;
    let text = format!(
        "
lines: [{{ name: rs485, simulated: true }}]
devices:
  - {{ name: top, model: p-series, slave: 1, poll: [{{ read: measurements, every: 10ms }}] }}
outputs:
  mqtt: {{ broker: 127.0.0.1:{}, queue: 20 }}
  metrics: 0
",
        broker.port
    );
    let ServiceFile { bus: file, outputs } = ServiceFile::parse(
        "bus.yaml",
        &text,
        ".".as_ref(),
        &Catalogue::new([&optobus_p_series::DEVICE]),
    )
    .unwrap_or_else(|e| panic!("{}", e.render()));
    let bus = Bus::new(file.clone());
    let metrics_config = outputs.metrics.clone().expect("metrics");
    let exporter = Exporter::start(&metrics_config, &file, bus.subscribe())
        .await
        .expect("listens");
    let mqtt_events = bus.subscribe();
    let running = bus.start().expect("starts");
    let mqtt_config = outputs.mqtt.as_ref().expect("mqtt");
    let publisher = Publisher::start(mqtt_config, &file, mqtt_events, None).expect("starts");
    add(exporter.metrics(), publisher.counts_reader()).expect("the names are free");

    wait_for("samples published", &publisher, |c| c.published >= 50).await;
    broker.kill();
    wait_for("the queue overflowed", &publisher, |c| {
        !c.connected && c.dropped >= 20
    })
    .await;
    running.stop();
    // The counts stand still once the bus has stopped and the broker is away: a scrape
    // between two equal looks at them shows them.
    let mut looks = 0;
    let (counts, text) = loop {
        let before = publisher.counts();
        let text = scrape(exporter.address()).await;
        if publisher.counts() == before {
            break (before, text);
        }
        looks += 1;
        assert!(looks < 100, "the counts never stood still");
    };
    println!(
        "{counts:?}\n{}",
        text.lines()
            .filter(|l| l.starts_with("optobus_mqtt_"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    assert!(counts.dropped > 0 && counts.queued == 20, "{counts:?}");
    // Each series of the counts, its name after `optobus_mqtt_`, and the count it shows.
    let expected = [
        ("samples_published_total", counts.published),
        ("samples_dropped_total", counts.dropped),
        ("samples_requeued_total", counts.requeued),
        ("queue_samples", counts.queued as u64),
        ("in_flight_samples", counts.in_flight as u64),
        ("connected", u64::from(counts.connected)),
        ("connections_total", counts.connections),
        ("events_missed_total", counts.missed_events),
        ("writes_taken_total", counts.writes_taken),
        ("writes_too_large_total", counts.writes_too_large),
        ("writes_busy_total", counts.writes_busy),
        ("writes_retained_total", counts.writes_retained),
        ("replies_dropped_total", counts.replies_dropped),
        ("oversize_dropped_total", counts.oversize_dropped),
        ("incoming_too_large_total", counts.incoming_too_large),
        ("homeassistant_births_total", counts.homeassistant_births),
        (
            "rediscoveries_coalesced_total",
            counts.rediscoveries_coalesced,
        ),
        ("control_queue_messages", counts.control_queued as u64),
        ("states_published_total", counts.states_published),
        ("states_skipped_total", counts.states_skipped),
        ("state_reads_total", counts.state_reads),
        ("state_reads_busy_total", counts.state_reads_busy),
        ("state_reads_failed_total", counts.state_reads_failed),
        (
            "state_reads_after_writes_total",
            counts.state_reads_after_writes,
        ),
        (
            "state_rereads_coalesced_total",
            counts.state_rereads_coalesced,
        ),
    ];
    for (name, value) in expected {
        let name = format!("optobus_mqtt_{name}");
        assert_eq!(
            series(&text, &name),
            Some(value as f64),
            "{name} in\n{text}\n{counts:?}"
        );
    }
    for counter in [
        "optobus_mqtt_samples_published_total",
        "optobus_mqtt_samples_dropped_total",
        "optobus_mqtt_connections_total",
    ] {
        assert!(
            text.contains(&format!("# TYPE {counter} counter")),
            "{text}"
        );
    }
    assert!(text.contains("# TYPE optobus_mqtt_queue_samples gauge"));

    optobus_testkit::assert_promtool_accepts(&text);
}
