//! `optobus run … --prometheus / --mqtt / --homeassistant`: outputs added from the command
//! line, without editing a bus file.

mod common;

use std::io::{Read, Write};
use std::process::Stdio;
use std::time::Duration;

use common::{outcome, REFUSED};

#[test]
fn run_demo_with_prometheus_serves_metrics_of_every_device() {
    let common::Demo {
        child: mut bus,
        first_line: line,
        stderr: _stderr,
    } = common::demo_with(
        &["--gateway", "127.0.0.1:0", "--prometheus", "127.0.0.1:0"],
        Stdio::null(),
    );
    // The outputs are named on the first line of stderr.
    let address = line
        .split("http://")
        .nth(1)
        .and_then(|rest| rest.split('/').next())
        .unwrap_or_else(|| panic!("no metrics address in {line:?}"))
        .to_owned();
    std::thread::sleep(Duration::from_millis(1500));
    let mut stream = std::net::TcpStream::connect(&address).expect("metrics listen");
    write!(
        stream,
        "GET /metrics HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut reply = String::new();
    stream.read_to_string(&mut reply).unwrap();
    let _ = bus.kill();
    let _ = bus.wait();
    assert!(reply.starts_with("HTTP/1.1 200"), "{reply}");
    for device in [
        "head",
        "rangefinder",
        "confocal",
        "distance",
        "four-channel",
    ] {
        let up = format!("optobus_device_up{{device=\"{device}\",");
        assert!(
            reply
                .lines()
                .any(|l| l.starts_with(&up) && l.ends_with(" 1")),
            "{device} not up in:\n{reply}"
        );
    }
    assert!(reply.contains("optobus_reading_meters{device=\"head\",register=\"distance_1\""));
}

#[test]
fn home_assistant_discovery_needs_a_broker() {
    let (code, _, stderr) = outcome(&["run", "--demo", "--homeassistant", "--duration", "1s"]);
    assert_eq!(code, Some(REFUSED), "{stderr}");
    assert!(
        stderr.contains("--homeassistant needs a broker: give --mqtt HOST:PORT"),
        "{stderr}"
    );
    let (code, _, stderr) = outcome(&["run", "--demo", "--mqtt", "no:such:broker"]);
    assert_eq!(code, Some(REFUSED), "{stderr}");
    assert!(
        stderr.contains("--mqtt: `no:such:broker` is no broker address"),
        "{stderr}"
    );
    let (code, _, stderr) = outcome(&["run", "--demo", "--prometheus", "everywhere"]);
    assert_eq!(code, Some(REFUSED), "{stderr}");
    assert!(
        stderr.contains("--prometheus: `everywhere` is no address"),
        "{stderr}"
    );
}
