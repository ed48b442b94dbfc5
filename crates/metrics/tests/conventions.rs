//! The Prometheus conventions of the exposition (issue 30, point 9): help texts end with one
//! period, code series name their code, the line's busy time is a counter, and
//! `optobus_build_info` names the build.

mod common;

use common::*;

/// Issue 30, point 9: prometheus-client ends each help text with a period of its own, so a
/// help written as a sentence came out as `A reading in metres..`.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
async fn prometheus_help_texts_end_with_one_period() {
    let bus = Bus::new(file());
    let exporter = exporter(&bus).await;
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

/// Issue 30, point 9: `optobus_build_info` says which build serves the metrics.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_promtool),
    ignore = "promtool is not installed (Debian package prometheus)"
)]
async fn prometheus_build_info_names_version_rust_and_target() {
    let bus = Bus::new(file());
    let exporter = exporter(&bus).await;
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
