//! Issue 32 on Prometheus: a measurement in its base unit, its judgements counted, an invalid
//! value removing the series (no stale number) and counted; `promtool` accepts the text.

use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, SystemTime};

use optobus_bus::{Bus, BusFile, Catalogue, Event, MeasurementEvent};
use optobus_metrics::Metrics;

/// The value of the series `name{labels}` in Prometheus text.
fn series(text: &str, name: &str, labels: &str) -> Option<f64> {
    let prefix = format!("{name}{{{labels}}} ");
    text.lines()
        .find_map(|line| line.strip_prefix(&prefix))
        .map(|value| value.parse().expect("a number"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
async fn a_measurement_is_exported_in_base_units_with_its_judgements_counted() {
    let gap = optobus_testkit::bus_files::two_heads_gap()
        .outputs("{ metrics: 0 }")
        .text();
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    let file = BusFile::parse("bus.yaml", &gap, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    let metrics = Metrics::new(&file);
    let bus = Bus::new(file);
    let mut events = bus.subscribe();
    let _running = bus.start().expect("starts");
    let mut values = Vec::new();
    while values.len() < 5 {
        let event = tokio::time::timeout(Duration::from_secs(10), events.recv())
            .await
            .expect("events come")
            .expect("the bus runs");
        metrics.observe(&event);
        if let Event::Measurement(measurement) = event {
            values.push(measurement);
        }
    }
    let text = metrics.prometheus();
    let last = values.last().unwrap();
    let millimetres = last.value.clone().expect("a value").to_f64();
    let metres = series(&text, "optobus_measurement_meters", "measurement=\"gap\"").expect(&text);
    assert!(
        (metres - millimetres / 1000.0).abs() < 1e-12,
        "{metres} {millimetres}"
    );
    let judged: f64 = ["ll", "lo", "go", "hi", "hh"]
        .iter()
        .filter_map(|j| {
            series(
                &text,
                "optobus_measurement_judgements_total",
                &format!("measurement=\"gap\",judgement=\"{j}\""),
            )
        })
        .sum();
    assert_eq!(judged, 5.0, "{text}");
    optobus_testkit::assert_promtool_accepts(&text);

    // An invalid value: the series goes, the count of invalid values grows.
    let invalid = MeasurementEvent {
        value: Err("top.distance_1: top is offline".into()),
        judgement: None,
        time: SystemTime::now(),
        ..(**last).clone()
    };
    metrics.observe(&Event::Measurement(Arc::new(invalid)));
    let text = metrics.prometheus();
    assert_eq!(
        series(&text, "optobus_measurement_meters", "measurement=\"gap\""),
        None
    );
    assert_eq!(
        series(
            &text,
            "optobus_measurement_invalid_total",
            "measurement=\"gap\""
        ),
        Some(1.0)
    );
    optobus_testkit::assert_promtool_accepts(&text);
}
