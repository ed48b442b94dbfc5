//! `/metrics` of a running bus, scraped over HTTP: readings in base units with their labels,
//! device and line metrics under the names Prometheus conventions ask for, and a body that
//! Prometheus's own `promtool check metrics` accepts.

mod common;

use common::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
async fn metrics_give_readings_in_base_units_and_pass_promtool() {
    let bus = Bus::new(file());
    let mut events = bus.subscribe();
    let exporter = exporter(&bus).await;
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
    let (file, config) = with_metrics();
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
