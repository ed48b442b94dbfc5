//! A serial port that disappears (a USB adapter unplugged) closes its line; the other lines go
//! on, and the bus reopens the port when it comes back. Shown with pseudo-terminals behind a
//! link that is removed and made again.

use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;

use optobus_bus::{Bus, BusFile, Catalogue, Event, Health};
use optobus_simulator::Simulator;
use tokio::sync::broadcast::Receiver;

/// Waits for an event that `wanted` accepts, counting samples by device meanwhile.
async fn until(
    events: &mut Receiver<Event>,
    counts: &mut HashMap<String, u64>,
    mut wanted: impl FnMut(&Event) -> bool,
) {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    loop {
        let event = tokio::time::timeout_at(deadline, events.recv())
            .await
            .expect("the awaited event within 30 s")
            .expect("the bus runs");
        if let Event::Sample(sample) = &event {
            *counts.entry(sample.source.device.to_string()).or_default() += 1;
        }
        if wanted(&event) {
            return;
        }
    }
}

fn closed(line: &str) -> impl FnMut(&Event) -> bool + '_ {
    move |event| matches!(event, Event::Line(stats) if &*stats.line == line && !stats.open)
}

fn health_of(device: &str, health: Health) -> impl FnMut(&Event) -> bool + '_ {
    move |event| matches!(event, Event::Health(h) if &*h.source.device == device && h.health == health)
}

fn sample_of(device: &str) -> impl FnMut(&Event) -> bool + '_ {
    move |event| matches!(event, Event::Sample(sample) if &*sample.source.device == device)
}

#[tokio::test]
async fn a_vanished_port_takes_its_devices_down_at_once_and_is_reopened_when_it_returns() {
    let folder = std::env::temp_dir().join(format!("optobus-reopen-{}", std::process::id()));
    std::fs::create_dir_all(&folder).unwrap();
    let link = folder.join("ttyUSB0");
    let _ = std::fs::remove_file(&link);
    let head = Simulator::new(&optobus_p_series::DEVICE).slave(1);
    let confocal = Simulator::new(&optobus_ccs::DEVICE).slave(1);
    let unplugged = head.serve_pty().expect("a pty");
    std::os::unix::fs::symlink(unplugged.path(), &link).unwrap();
    let other = confocal.serve_pty().expect("a pty");
    let text = format!(
        "
lines:
  - {{ name: usb, serial: {}, baud: 115200, any_format: true }}
  - {{ name: other, serial: {}, baud: 115200, any_format: true }}
devices:
  - {{ name: head, model: p-series, line: usb, slave: 1, timeout: 100ms, poll: [{{ read: measurements, every: 20ms }}] }}
  - {{ name: confocal, model: ccs, line: other, slave: 1, timeout: 100ms, poll: [{{ read: measurements, every: 20ms }}] }}
",
        link.display(),
        other.path().display()
    );
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]);
    let file = BusFile::parse("bus.yaml", &text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    let bus = Bus::new(file);
    let mut events = bus.subscribe();
    let _running = bus.start().unwrap();
    let mut counts = HashMap::new();
    until(&mut events, &mut counts, sample_of("head")).await;

    // Unplugged: the pty goes away with its link.
    drop(unplugged);
    std::fs::remove_file(&link).unwrap();
    until(&mut events, &mut counts, closed("usb")).await;
    // Its device is down at once, told on the event stream every output follows (issue 28,
    // point 7: it stayed online with its last values while its port was gone).
    until(&mut events, &mut counts, health_of("head", Health::Offline)).await;
    counts.clear();
    // While it is gone the other line goes on, and nothing comes from the head.
    until(
        &mut events,
        &mut counts,
        |event| matches!(event, Event::Line(stats) if &*stats.line == "usb"),
    )
    .await;
    assert!(
        counts.get("confocal").copied().unwrap_or(0) > 0,
        "{counts:?}"
    );
    assert_eq!(counts.get("head"), None, "{counts:?}");

    // Plugged in again (a new terminal behind the same name): the head is read again.
    let replugged = head.serve_pty().expect("a pty");
    std::os::unix::fs::symlink(replugged.path(), &link).unwrap();
    until(&mut events, &mut counts, health_of("head", Health::Online)).await;
    until(&mut events, &mut counts, sample_of("head")).await;
    let _ = std::fs::remove_dir_all(&folder);
}
