//! `/metrics` of a running bus, scraped over HTTP: readings in base units with their labels,
//! device and line metrics under the names Prometheus conventions ask for, and a body that
//! Prometheus's own `promtool check metrics` accepts.

use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;

use optobus_bus::{Bus, BusFile, Catalogue, Event};
use optobus_inspect::Value;
use optobus_metrics::{Exporter, Metrics, Reading, SourceError};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::sync::broadcast::error::RecvError;

const BUS: &str = "
lines:
  - { name: rs485, simulated: true, baud: 115200, any_format: true }
devices:
  - name: top
    model: p-series
    slave: 1
    timeout: 200ms
    poll: [{ read: [light_power, laser_enabled, measurements, temperature], every: 20ms }]
  - name: confocal
    model: ccs
    slave: 3
    timeout: 200ms
    poll: [{ read: [measurements, exposure_time], every: 20ms }]
outputs:
  metrics: 0
";

fn file() -> BusFile {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]);
    BusFile::parse("bus.yaml", BUS, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()))
}

/// `GET /metrics` with `accept`, as (head, body).
async fn scrape(address: std::net::SocketAddr, accept: &str) -> (String, String) {
    let mut stream = tokio::net::TcpStream::connect(address)
        .await
        .expect("connects");
    let request = format!(
        "GET /metrics HTTP/1.1\r\nHost: {address}\r\nAccept: {accept}\r\nConnection: close\r\n\r\n"
    );
    stream.write_all(request.as_bytes()).await.unwrap();
    let mut reply = String::new();
    stream.read_to_string(&mut reply).await.unwrap();
    let (head, body) = reply.split_once("\r\n\r\n").expect("an HTTP reply");
    (head.to_owned(), body.to_owned())
}

/// The value of the series `name{labels}` in Prometheus text.
fn series(text: &str, name: &str, labels: &str) -> Option<f64> {
    let prefix = if labels.is_empty() {
        format!("{name} ")
    } else {
        format!("{name}{{{labels}}} ")
    };
    text.lines()
        .find_map(|line| line.strip_prefix(&prefix))
        .map(|value| value.parse().expect("a number"))
}

/// `promtool check metrics` accepts `text` (the tests calling it are ignored without promtool).
fn assert_promtool_accepts(text: &str) {
    optobus_testkit::assert_promtool_accepts(text);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
async fn metrics_give_readings_in_base_units_and_pass_promtool() {
    let file = file();
    let config = file.outputs.metrics.clone().expect("metrics are on");
    let bus = Bus::new(file.clone());
    let mut events = bus.subscribe();
    let exporter = Exporter::start(&config, &file, bus.subscribe())
        .await
        .expect("listens");
    assert!(
        exporter.address().ip().is_loopback(),
        "a port alone is 127.0.0.1"
    );
    let running = bus.start().expect("starts");
    running
        .simulator("top")
        .expect("simulated")
        .set("light_power", &[425])
        .unwrap();
    // Samples of both devices and a line statistic, then stop and keep the last values.
    let mut last: HashMap<(String, &'static str), Value> = HashMap::new();
    let mut lines = 0;
    while lines < 2 || last.len() < 8 {
        match tokio::time::timeout(Duration::from_secs(10), events.recv()).await {
            Ok(Ok(Event::Sample(sample))) => {
                last.insert(
                    (sample.source.device.to_string(), sample.register.name),
                    sample.value.clone(),
                );
            }
            Ok(Ok(Event::Line(_))) => lines += 1,
            Ok(Ok(Event::Health(_))) => {}
            Ok(Err(RecvError::Lagged(_))) => {}
            other => panic!("no events: {other:?}"),
        }
    }
    running.stop();
    tokio::time::sleep(Duration::from_millis(300)).await;
    while let Ok(event) = events.try_recv() {
        if let Event::Sample(sample) = event {
            last.insert(
                (sample.source.device.to_string(), sample.register.name),
                sample.value.clone(),
            );
        }
    }

    let (head, text) = scrape(exporter.address(), "text/plain").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert!(
        head.to_ascii_lowercase()
            .contains("content-type: text/plain; version=0.0.4"),
        "{head}"
    );
    let model = optobus_p_series::DEVICE.model_name().to_string();
    let labels = |device: &str, register: &str, model: &str| {
        format!("device=\"{device}\",register=\"{register}\",model=\"{model}\"")
    };
    // Millimetres in metres, exactly as the sample's decimal text shifted by three places.
    let Some(Value::Quantity(distance, Some("mm"))) = last.get(&("top".into(), "distance_1"))
    else {
        panic!("no distance_1 sample: {last:?}")
    };
    let metres: f64 = format!("{distance}e-3").parse().unwrap();
    assert_eq!(
        series(
            &text,
            "optobus_reading_meters",
            &labels("top", "distance_1", &model)
        ),
        Some(metres),
        "{text}"
    );
    assert_eq!(
        series(
            &text,
            "optobus_reading_ratio",
            &labels("top", "light_power", &model)
        ),
        Some(0.425),
        "42.5 % as a ratio"
    );
    let Some(Value::Quantity(celsius, Some("degC"))) = last.get(&("top".into(), "temperature"))
    else {
        panic!("no temperature sample")
    };
    assert_eq!(
        series(
            &text,
            "optobus_reading_celsius",
            &labels("top", "temperature", &model)
        ),
        Some(celsius.to_f64())
    );
    let ccs = optobus_ccs::DEVICE.model_name().to_string();
    let Some(Value::Quantity(exposure, Some("us"))) =
        last.get(&("confocal".into(), "exposure_time"))
    else {
        panic!("no exposure_time sample")
    };
    let seconds: f64 = format!("{exposure}e-6").parse().unwrap();
    assert_eq!(
        series(
            &text,
            "optobus_reading_seconds",
            &labels("confocal", "exposure_time", &ccs)
        ),
        Some(seconds)
    );
    assert_eq!(
        series(
            &text,
            "optobus_device_up",
            &format!("device=\"top\",model=\"{model}\",line=\"rs485\"")
        ),
        Some(1.0)
    );
    assert!(
        series(
            &text,
            "optobus_device_last_sample_timestamp_seconds",
            &format!("device=\"top\",model=\"{model}\",line=\"rs485\"")
        )
        .is_some_and(|t| t > 1.7e9),
        "{text}"
    );
    // Counters under their `_total` names, typed as counters.
    assert!(
        text.contains("# TYPE optobus_line_transactions_total counter"),
        "{text}"
    );
    assert!(
        series(&text, "optobus_line_transactions_total", "line=\"rs485\"").is_some_and(|n| n > 0.0),
        "{text}"
    );
    assert_eq!(
        series(
            &text,
            "optobus_line_errors_total",
            "line=\"rs485\",kind=\"timeout\""
        ),
        Some(0.0)
    );
    assert!(text.contains("# TYPE optobus_line_busy_seconds_total counter"));
    assert!(
        series(&text, "optobus_line_busy_seconds_total", "line=\"rs485\"").is_some_and(|s| s > 0.0)
    );

    assert_promtool_accepts(&text);

    // OpenMetrics for a scraper that asks for it: counters named as families, `# EOF` last.
    let (head, open) = scrape(exporter.address(), "application/openmetrics-text").await;
    assert!(head.contains("application/openmetrics-text"), "{head}");
    assert!(
        open.contains("# TYPE optobus_line_transactions counter"),
        "{open}"
    );
    assert!(open.ends_with("# EOF\n"));
}

#[test]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
fn sources_add_series_read_at_every_scrape_under_names_checked_once() {
    use std::sync::atomic::{AtomicU64, Ordering};
    use std::sync::Arc;

    let metrics = Metrics::new(&file());
    let sent = Arc::new(AtomicU64::new(7));
    let reader = Arc::clone(&sent);
    metrics
        .add_source(move || {
            vec![
                Reading::counter(
                    "optobus_test_messages_sent",
                    "Messages sent.",
                    reader.load(Ordering::SeqCst),
                ),
                Reading::gauge("optobus_test_queue_messages", "Messages waiting.", -3),
            ]
        })
        .expect("free names");
    let text = metrics.prometheus();
    assert!(
        text.contains(
            "# HELP optobus_test_messages_sent_total Messages sent.\n\
             # TYPE optobus_test_messages_sent_total counter\n\
             optobus_test_messages_sent_total 7\n"
        ),
        "{text}"
    );
    assert!(
        text.contains("# TYPE optobus_test_queue_messages gauge\noptobus_test_queue_messages -3\n"),
        "{text}"
    );
    assert_promtool_accepts(&text);
    sent.store(12, Ordering::SeqCst);
    assert_eq!(
        series(
            &metrics.prometheus(),
            "optobus_test_messages_sent_total",
            ""
        ),
        Some(12.0),
        "read again at the next scrape"
    );
    let open = metrics.openmetrics();
    assert!(
        open.contains("# TYPE optobus_test_messages_sent counter\n")
            && open.contains("\noptobus_test_messages_sent_total 12\n")
            && open.ends_with("# EOF\n"),
        "{open}"
    );

    // Names are checked when the source is added; nothing of a refused source is exposed.
    let refused = |name: &'static str, counter: bool| {
        metrics
            .add_source(move || {
                vec![if counter {
                    Reading::counter(name, "x", 1)
                } else {
                    Reading::gauge(name, "x", 1)
                }]
            })
            .unwrap_err()
    };
    assert_eq!(
        refused("9lives", false),
        SourceError::BadName("9lives".into())
    );
    assert_eq!(
        refused("with-dash", false),
        SourceError::BadName("with-dash".into())
    );
    assert_eq!(
        refused("__reserved", false),
        SourceError::BadName("__reserved".into())
    );
    assert_eq!(
        refused("optobus_test_frames_total", true),
        SourceError::Total("optobus_test_frames_total".into())
    );
    assert_eq!(
        refused("optobus_device_up", false),
        SourceError::Taken("optobus_device_up".into())
    );
    // A counter family is exposed as `<name>_total`: both forms are taken.
    assert_eq!(
        refused("optobus_line_transactions", true),
        SourceError::Taken("optobus_line_transactions".into())
    );
    assert_eq!(
        refused("optobus_test_queue_messages", false),
        SourceError::Taken("optobus_test_queue_messages".into())
    );
    assert_eq!(
        metrics
            .add_source(|| vec![Reading::gauge("optobus_test_two", "one\ntwo", 1)])
            .unwrap_err(),
        SourceError::BadHelp("optobus_test_two".into())
    );
    let after = metrics.prometheus();
    for name in [
        "9lives",
        "with-dash",
        "__reserved",
        "optobus_test_frames",
        "optobus_test_two",
    ] {
        assert!(!after.contains(name), "{name} in\n{after}");
    }
    assert_eq!(after.matches("\noptobus_device_up{").count(), 2, "{after}");
}

#[test]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
fn a_source_later_giving_a_series_it_did_not_declare_has_it_left_out() {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    let metrics = Metrics::new(&file());
    let later = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&later);
    metrics
        .add_source(move || {
            let mut readings = vec![Reading::gauge("optobus_test_state", "A state.", 1)];
            if flag.load(Ordering::SeqCst) {
                readings.push(Reading::gauge("optobus_device_up", "Not checked.", 5));
                // Declared as a gauge: a counter of the same name is not what was checked.
                readings[0] = Reading::counter("optobus_test_state", "A state.", 2);
            }
            readings
        })
        .unwrap();
    later.store(true, Ordering::SeqCst);
    let text = metrics.prometheus();
    assert!(!text.contains("optobus_test_state"), "{text}");
    assert!(!text.contains("Not checked."), "{text}");
    assert_promtool_accepts(&text);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_exporter_counts_the_bus_events_it_missed_exactly() {
    let file = file();
    let config = file.outputs.metrics.clone().expect("metrics are on");
    let capacity = 32;
    let bus = Bus::new(file.clone()).event_capacity(capacity);
    // Subscribed now, read only once the bus has stopped: far behind by then.
    let late = bus.subscribe();
    let mut events = bus.subscribe();
    let running = bus.start().expect("starts");
    // The test's own receiver counts every event sent: those it read, and those it fell behind
    // by (`Lagged` says how many) when the machine is loaded.
    let mut sent = 0u64;
    while sent < 200 {
        match tokio::time::timeout(Duration::from_secs(10), events.recv()).await {
            Ok(Ok(_)) => sent += 1,
            Ok(Err(RecvError::Lagged(skipped))) => sent += skipped,
            other => panic!("the bus sends events: {other:?}"),
        }
    }
    drop(running);
    loop {
        match tokio::time::timeout(Duration::from_secs(10), events.recv()).await {
            Ok(Ok(_)) => sent += 1,
            Ok(Err(RecvError::Lagged(skipped))) => sent += skipped,
            Ok(Err(RecvError::Closed)) => break,
            other => panic!("the bus sends events until it stops: {other:?}"),
        }
    }
    let exporter = Exporter::start(&config, &file, late)
        .await
        .expect("listens");
    // The channel kept the last `capacity` events; everything before them was missed.
    let missed = (sent - capacity as u64) as f64;
    let mut text = String::new();
    for _ in 0..100 {
        text = scrape(exporter.address(), "text/plain").await.1;
        if series(&text, "optobus_metrics_events_missed_total", "") == Some(missed) {
            break;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    assert_eq!(
        series(&text, "optobus_metrics_events_missed_total", ""),
        Some(missed),
        "{sent} events sent, {capacity} kept\n{text}"
    );
}

/// Point 7 of issue 28: while a device is down its readings are not exported (Home Assistant
/// or Grafana would show the last values as current); its next sample brings them back.
#[test]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
fn a_down_device_has_no_current_reading_on_metrics() {
    use std::sync::Arc;
    use std::time::SystemTime;

    use optobus_bus::{DeviceId, ErrorCounts, Health, HealthEvent, Sample};
    use optobus_codec::value::{Fixed, Scale};

    let metrics = Metrics::new(&file());
    let model = optobus_p_series::DEVICE.model_name().to_string();
    let top = Arc::new(DeviceId {
        device: "top".into(),
        model: model.as_str().into(),
        line: "rs485".into(),
        slave: 1,
    });
    let sample = |register: &str, value: Value| {
        Event::Sample(Arc::new(Sample {
            source: Arc::clone(&top),
            register: optobus_p_series::DEVICE.register(register).unwrap(),
            value,
            requested: SystemTime::now(),
            replied: SystemTime::now(),
        }))
    };
    let distance = Value::Quantity(Fixed::new(49_692, Scale::ONE), Some("um"));
    metrics.observe(&sample("distance_1", distance.clone()));
    metrics.observe(&sample("laser_enabled", Value::Bool(true)));
    let reading = format!("device=\"top\",register=\"distance_1\",model=\"{model}\"");
    let flag = format!("device=\"top\",register=\"laser_enabled\",model=\"{model}\"");
    let up = format!("device=\"top\",model=\"{model}\",line=\"rs485\"");
    let text = metrics.prometheus();
    assert_eq!(
        series(&text, "optobus_reading_meters", &reading),
        Some(0.049692)
    );
    assert_eq!(series(&text, "optobus_reading", &flag), Some(1.0));
    assert_eq!(series(&text, "optobus_device_up", &up), Some(1.0));

    metrics.observe(&Event::Health(Arc::new(HealthEvent {
        source: Arc::clone(&top),
        health: Health::Offline,
        errors: ErrorCounts::default(),
        reason: Some("the line's port is closed".into()),
    })));
    let text = metrics.prometheus();
    assert_eq!(series(&text, "optobus_device_up", &up), Some(0.0));
    assert_eq!(
        series(&text, "optobus_reading_meters", &reading),
        None,
        "{text}"
    );
    assert_eq!(series(&text, "optobus_reading", &flag), None, "{text}");
    assert!(!text.contains("device=\"top\",register="), "{text}");
    assert!(
        series(&text, "optobus_device_last_sample_timestamp_seconds", &up).is_some(),
        "when it last answered is still known"
    );
    assert_promtool_accepts(&text);

    metrics.observe(&sample("distance_1", distance));
    let text = metrics.prometheus();
    assert_eq!(series(&text, "optobus_device_up", &up), Some(1.0));
    assert_eq!(
        series(&text, "optobus_reading_meters", &reading),
        Some(0.049692)
    );
    assert_eq!(
        series(&text, "optobus_reading", &flag),
        None,
        "only what was sampled again"
    );
}

/// Short limits, so that the tests wait little.
fn short(max_connections: usize) -> optobus_http::Limits {
    optobus_http::Limits {
        header_read: Duration::from_millis(300),
        idle: Duration::from_millis(300),
        request: Duration::from_millis(500),
        max_connections,
    }
}

/// Reads until the server closes the connection (or 20 s pass): what it sent.
async fn until_closed(stream: &mut tokio::net::TcpStream) -> String {
    let mut reply = Vec::new();
    let read = tokio::time::timeout(Duration::from_secs(20), stream.read_to_end(&mut reply));
    match read.await {
        Ok(Ok(_)) => {}
        Ok(Err(error)) if error.kind() == std::io::ErrorKind::ConnectionReset => {}
        Ok(Err(error)) => panic!("{error}"),
        Err(_) => panic!("the server kept the connection open for 20 s"),
    }
    String::from_utf8_lossy(&reply).into_owned()
}

/// Point 4 of issue 28: `/metrics` closes a connection that says nothing, or half a request,
/// after its header timeout, and counts it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
async fn silent_http_connections_are_closed_after_the_header_timeout() {
    let file = file();
    let config = file.outputs.metrics.clone().expect("metrics are on");
    let bus = Bus::new(file.clone());
    let exporter = Exporter::start_with_limits(&config, &file, bus.subscribe(), short(8))
        .await
        .expect("listens");
    let address = exporter.address();
    let mut silent = tokio::net::TcpStream::connect(address).await.unwrap();
    assert_eq!(until_closed(&mut silent).await, "");
    let mut half = tokio::net::TcpStream::connect(address).await.unwrap();
    half.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n")
        .await
        .unwrap();
    assert_eq!(until_closed(&mut half).await, "");
    assert_eq!(exporter.connections().header_timeouts, 2);
    let (head, text) = scrape(address, "text/plain").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert_eq!(
        series(
            &text,
            "optobus_metrics_http_connections_timed_out_total",
            ""
        ),
        Some(2.0),
        "{text}"
    );
    assert_promtool_accepts(&text);
}

/// The sockets this process holds on the server side of `address` (the listener and the
/// connections it accepted), from `/proc`: the descriptors of the tests running beside this
/// one are not counted.
fn server_sockets(address: std::net::SocketAddr) -> usize {
    let inodes: std::collections::HashSet<String> = std::fs::read_dir("/proc/self/fd")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|entry| std::fs::read_link(entry.path()).ok())
        .filter_map(|link| {
            let inode = link.to_str()?.strip_prefix("socket:[")?.strip_suffix(']')?;
            Some(inode.to_owned())
        })
        .collect();
    let port = format!(":{:04X}", address.port());
    ["/proc/self/net/tcp", "/proc/self/net/tcp6"]
        .iter()
        .filter_map(|table| std::fs::read_to_string(table).ok())
        .flat_map(|table| {
            table
                .lines()
                .skip(1)
                .map(|line| {
                    line.split_whitespace()
                        .map(str::to_owned)
                        .collect::<Vec<_>>()
                })
                .collect::<Vec<_>>()
        })
        .filter(|columns| {
            columns.len() > 9 && columns[1].ends_with(&port) && inodes.contains(&columns[9])
        })
        .count()
}

/// Point 4 of issue 28: beyond its cap `/metrics` answers 503 and closes at once, so a flood of
/// silent sockets holds no more descriptors than the cap.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn http_connections_beyond_the_cap_do_not_exhaust_descriptors() {
    let file = file();
    let config = file.outputs.metrics.clone().expect("metrics are on");
    let bus = Bus::new(file.clone());
    let mut limits = short(4);
    limits.header_read = Duration::from_secs(60);
    let exporter = Exporter::start_with_limits(&config, &file, bus.subscribe(), limits)
        .await
        .expect("listens");
    let address = exporter.address();
    let mut silent = Vec::new();
    for _ in 0..40 {
        silent.push(tokio::net::TcpStream::connect(address).await.unwrap());
    }
    for _ in 0..1000 {
        let counts = exporter.connections();
        if counts.accepted + counts.refused == 40 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let counts = exporter.connections();
    // The listener, the 4 connections the cap lets in, and a few refused ones being closed.
    let held = server_sockets(address);
    assert!(
        (1 + 4..=1 + 4 + 4).contains(&held),
        "{held} server sockets for 40 connections"
    );
    assert_eq!((counts.open, counts.refused), (4, 36), "{counts:?}");
    let refused = until_closed(silent.last_mut().unwrap()).await;
    assert!(refused.starts_with("HTTP/1.1 503"), "{refused}");
    drop(silent);
    for _ in 0..1000 {
        if exporter.connections().open == 0 {
            break;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let (head, text) = scrape(address, "text/plain").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert_eq!(
        series(&text, "optobus_metrics_http_connections_refused_total", ""),
        Some(36.0),
        "{text}"
    );
}

/// `GET path` on `address`: the status line and headers, and the body.
async fn get(address: std::net::SocketAddr, path: &str) -> (String, String) {
    let mut stream = tokio::net::TcpStream::connect(address)
        .await
        .expect("connects");
    let request = format!("GET {path} HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n");
    stream.write_all(request.as_bytes()).await.unwrap();
    let mut reply = String::new();
    stream.read_to_string(&mut reply).await.unwrap();
    let (head, body) = reply.split_once("\r\n\r\n").expect("an HTTP reply");
    (head.to_owned(), body.to_owned())
}

/// A sample of `register` of the P series `top`, decoded from `words` as the bus does.
fn p_series_sample(register: &str, words: &[u16]) -> Event {
    use std::sync::Arc;
    let register = optobus_p_series::DEVICE.register(register).unwrap();
    Event::Sample(Arc::new(optobus_bus::Sample {
        source: Arc::new(optobus_bus::DeviceId {
            device: "top".into(),
            model: optobus_p_series::DEVICE.model_name().to_string().into(),
            line: "rs485".into(),
            slave: 1,
        }),
        register,
        value: optobus_inspect::decode_value(register, words),
        requested: std::time::SystemTime::now(),
        replied: std::time::SystemTime::now(),
    }))
}

/// Issue 30, point 9: prometheus-client ends each help text with a period of its own, so a
/// help written as a sentence came out as `A reading in metres..`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
async fn prometheus_help_texts_end_with_one_period() {
    let file = file();
    let config = file.outputs.metrics.clone().expect("metrics are on");
    let bus = Bus::new(file.clone());
    let exporter = Exporter::start(&config, &file, bus.subscribe())
        .await
        .expect("listens");
    exporter
        .metrics()
        .observe(&p_series_sample("median_filter_width", &[2]));
    for accept in ["text/plain", "application/openmetrics-text"] {
        let (_, text) = scrape(exporter.address(), accept).await;
        let helps: Vec<&str> = text
            .lines()
            .filter(|line| line.starts_with("# HELP "))
            .collect();
        // The families with series: the bus's, and those of the listener's own source.
        assert!(helps.len() >= 8, "{text}");
        for help in &helps {
            assert!(
                help.ends_with('.') && !help.ends_with(".."),
                "{accept}: {help}"
            );
        }
        assert!(
            helps.contains(
                &"# HELP optobus_device_up 1 while the device answers its polls, 0 before its \
                  first sample and while offline."
            ),
            "{text}"
        );
        if accept == "text/plain" {
            assert_promtool_accepts(&text);
        }
    }
}

/// Issue 30, point 9: an enumerated reading's series names its code, as the spec does.
#[test]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
fn prometheus_code_series_carry_the_code_name() {
    let metrics = Metrics::new(&file());
    let model = optobus_p_series::DEVICE.model_name().to_string();
    let labels = |name: &str| {
        format!("device=\"top\",register=\"median_filter_width\",model=\"{model}\",name=\"{name}\"")
    };
    metrics.observe(&p_series_sample("median_filter_width", &[2]));
    let text = metrics.prometheus();
    assert_eq!(
        series(&text, "optobus_code", &labels("width_5")),
        Some(2.0),
        "{text}"
    );
    assert_promtool_accepts(&text);
    // Another code: one series still, under the new name.
    metrics.observe(&p_series_sample("median_filter_width", &[3]));
    let text = metrics.prometheus();
    assert_eq!(
        series(&text, "optobus_code", &labels("width_9")),
        Some(3.0),
        "{text}"
    );
    assert_eq!(
        series(&text, "optobus_code", &labels("width_5")),
        None,
        "{text}"
    );
    assert_eq!(text.matches("\noptobus_code{").count(), 1, "{text}");
    // A code the spec does not name: an empty name.
    metrics.observe(&p_series_sample("median_filter_width", &[0x20]));
    let text = metrics.prometheus();
    assert_eq!(
        series(&text, "optobus_code", &labels("")),
        Some(32.0),
        "{text}"
    );
    assert_eq!(text.matches("\noptobus_code{").count(), 1, "{text}");
    // A device down has no code series either.
    metrics.observe(&p_series_sample("median_filter_width", &[1]));
    metrics.observe(&Event::Health(std::sync::Arc::new(
        optobus_bus::HealthEvent {
            source: std::sync::Arc::new(optobus_bus::DeviceId {
                device: "top".into(),
                model: model.as_str().into(),
                line: "rs485".into(),
                slave: 1,
            }),
            health: optobus_bus::Health::Offline,
            errors: optobus_bus::ErrorCounts::default(),
            reason: Some("no reply".into()),
        },
    )));
    let text = metrics.prometheus();
    assert!(!text.contains("\noptobus_code{"), "{text}");
}

/// Issue 30, point 9: the line's busy time is a counter whose `rate()` is its utilisation
/// over any window; the gauge that averaged since the start is gone.
#[test]
fn prometheus_line_busy_time_is_a_counter_for_rate() {
    use std::sync::Arc;
    let metrics = Metrics::new(&file());
    let stats = |busy_ms: u64, elapsed_s: u64| {
        Event::Line(Arc::new(optobus_bus::LineStats {
            line: "rs485".into(),
            transactions: 10,
            errors: optobus_bus::ErrorCounts::default(),
            busy: Duration::from_millis(busy_ms),
            elapsed: Duration::from_secs(elapsed_s),
            open: true,
        }))
    };
    metrics.observe(&stats(1_500, 10));
    let text = metrics.prometheus();
    let line = "line=\"rs485\"";
    assert_eq!(
        series(&text, "optobus_line_busy_seconds_total", line),
        Some(1.5)
    );
    metrics.observe(&stats(2_250, 11));
    let text = metrics.prometheus();
    assert_eq!(
        series(&text, "optobus_line_busy_seconds_total", line),
        Some(2.25)
    );
    assert!(
        text.contains("# TYPE optobus_line_busy_seconds_total counter"),
        "{text}"
    );
    assert!(
        text.lines()
            .any(|l| l.starts_with("# HELP optobus_line_busy_seconds_total ")
                && l.contains("rate()")),
        "{text}"
    );
    assert!(!text.contains("utilisation"), "{text}");
}

/// Issue 30, point 9: `/` of the metrics listener is a page linking `/metrics`, and any
/// other path a 404 that says where the metrics are.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn prometheus_listener_root_links_to_metrics() {
    let file = file();
    let config = file.outputs.metrics.clone().expect("metrics are on");
    let bus = Bus::new(file.clone());
    let exporter = Exporter::start(&config, &file, bus.subscribe())
        .await
        .expect("listens");
    let (head, body) = get(exporter.address(), "/").await;
    assert!(head.starts_with("HTTP/1.1 200"), "{head}");
    assert!(
        head.contains("content-type: text/html; charset=utf-8"),
        "{head}"
    );
    assert!(body.contains("<a href=\"/metrics\">/metrics</a>"), "{body}");
    let (head, body) = get(exporter.address(), "/metric").await;
    assert!(head.starts_with("HTTP/1.1 404"), "{head}");
    assert_eq!(body, "Not found: the metrics are at /metrics.\n");
}

/// Issue 30, point 9: `optobus_build_info` says which build serves the metrics.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
async fn prometheus_build_info_names_version_rust_and_target() {
    let file = file();
    let config = file.outputs.metrics.clone().expect("metrics are on");
    let bus = Bus::new(file.clone());
    let exporter = Exporter::start(&config, &file, bus.subscribe())
        .await
        .expect("listens");
    let (_, text) = scrape(exporter.address(), "text/plain").await;
    let rustc = std::process::Command::new("rustc")
        .arg("--version")
        .output()
        .expect("rustc runs");
    let rustc = String::from_utf8(rustc.stdout).unwrap();
    let rust_version = rustc.split_whitespace().nth(1).expect("rustc X.Y.Z (…)");
    let line = text
        .lines()
        .find(|line| line.starts_with("optobus_build_info{"))
        .unwrap_or_else(|| panic!("no optobus_build_info in\n{text}"));
    let prefix = format!(
        "optobus_build_info{{version=\"{}\",rust_version=\"{rust_version}\",target=\"{}-",
        env!("CARGO_PKG_VERSION"),
        std::env::consts::ARCH
    );
    assert!(line.starts_with(&prefix), "{line}\nwanted {prefix}…");
    assert!(line.contains(std::env::consts::OS), "{line}");
    assert!(line.ends_with("\"} 1"), "{line}");
    assert!(text.contains("# TYPE optobus_build_info gauge"), "{text}");
    assert_promtool_accepts(&text);
}
