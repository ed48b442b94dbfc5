//! `optobus bus check` and `optobus run`: a bus file checked as a whole, the demo bus polled
//! live, as JSON lines and as a CSV per device, and its gateway read by mbpoll.

mod common;

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

use common::{ok, outcome, REFUSED};

fn scratch(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("optobus-bus-{}-{name}", std::process::id()))
}

#[test]
fn bus_check_passes_a_good_file_and_lists_every_problem_of_a_bad_one() {
    let good = scratch("good.yaml");
    std::fs::write(
        &good,
        "lines: [{ name: rs485, serial: /dev/ttyUSB0 }]\ndevices:\n  - { name: a, model: p-series, slave: 1, poll: [{ read: measurements, every: 100ms }] }\n  - { name: b, model: p-series, slave: 2 }\n",
    )
    .unwrap();
    let stdout = ok(&["bus", "check", good.to_str().unwrap()]);
    assert!(
        stdout.ends_with("1 lines, 2 devices, 1 polls: ok\n"),
        "{stdout}"
    );
    let bad = scratch("bad.yaml");
    std::fs::write(
        &bad,
        "lines: [{ name: rs485, serial: /dev/ttyUSB0 }]\ndevices:\n  - { name: a, model: p-series, slave: 1, poll: [{ read: distanse_1 }] }\n  - { name: a, model: p-series, slave: 1 }\n",
    )
    .unwrap();
    let (code, _, stderr) = outcome(&["bus", "check", bad.to_str().unwrap()]);
    assert_eq!(code, Some(REFUSED), "{stderr}");
    for expected in [
        "does not pass the bus file checks",
        "error[duplicate-device]: two devices are called `a`",
        "error[duplicate-slave]: two devices on line `rs485` are slave 1",
        "p-series has no register or group `distanse_1`",
        "bad.yaml:3:",
    ] {
        assert!(
            stderr.contains(expected),
            "missing {expected:?} in {stderr}"
        );
    }
    let _ = std::fs::remove_file(good);
    let _ = std::fs::remove_file(bad);
}

#[test]
fn a_bus_takes_no_spec_option() {
    let (code, _, stderr) = outcome(&["run", "--demo", "--spec", "specs/ccs.yaml"]);
    assert_eq!(code, Some(REFUSED), "{stderr}");
    assert!(
        stderr.contains("each device of the bus file names its `model` or `spec`"),
        "{stderr}"
    );
}

#[test]
fn run_demo_prints_a_json_line_per_sample_of_every_device() {
    let stdout = ok(&[
        "run",
        "--demo",
        "--gateway",
        "127.0.0.1:0",
        "--duration",
        "1500ms",
        "--json",
    ]);
    let mut devices = BTreeSet::new();
    let mut models = BTreeSet::new();
    for line in stdout.lines() {
        let sample: serde_json::Value = serde_json::from_str(line).expect("one JSON object a line");
        for key in [
            "device", "model", "line", "slave", "register", "value", "time",
        ] {
            assert!(sample.get(key).is_some(), "{key} missing in {line}");
        }
        assert_eq!(sample["line"], "rs485");
        // RFC 3339 with the date, microseconds and an offset.
        let time = sample["time"].as_str().unwrap();
        assert_eq!(
            time.len(),
            "2026-11-25T14:29:34.782201+00:00".len(),
            "{time}"
        );
        devices.insert(sample["device"].as_str().unwrap().to_owned());
        models.insert(sample["model"].as_str().unwrap().to_owned());
    }
    assert_eq!(models.len(), 5, "every built-in model: {models:?}");
    assert_eq!(devices.len(), 5, "{devices:?}");
}

#[test]
fn run_records_a_csv_per_device_in_the_record_format() {
    let dir = scratch("recording");
    let _ = std::fs::remove_dir_all(&dir);
    ok(&[
        "run",
        "--demo",
        "--gateway",
        "127.0.0.1:0",
        "--duration",
        "1s",
        "--record",
        dir.to_str().unwrap(),
    ]);
    let head = std::fs::read_to_string(dir.join("head.csv")).expect("a CSV for the head");
    let mut lines = head.lines();
    let header = lines.next().unwrap();
    assert!(
        header.starts_with("time,elapsed [s],distance_1 [mm]"),
        "{header}"
    );
    let row = lines.next().expect("a row per poll");
    let cells: Vec<&str> = row.split(',').collect();
    assert_eq!(cells.len(), header.split(',').count());
    assert!(cells[2].parse::<f64>().is_ok(), "{row}");
    for device in ["rangefinder", "confocal", "distance", "four-channel"] {
        assert!(dir.join(format!("{device}.csv")).exists(), "{device}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
#[cfg_attr(
    not(peer_mbpoll),
    ignore = "mbpoll is not installed (Debian package mbpoll)"
)]
fn the_demo_gateway_serves_mbpoll_while_the_bus_polls() {
    let mut bus = common::optobus()
        .args([
            "run",
            "--demo",
            "--gateway",
            "127.0.0.1:0",
            "--duration",
            "20s",
            "--json",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run the demo");
    // The gateway's address is the first line on stderr.
    let mut stderr = BufReader::new(bus.stderr.take().unwrap());
    let mut line = String::new();
    stderr.read_line(&mut line).unwrap();
    let address = line.trim().rsplit(' ').next().unwrap().to_owned();
    let (host, port) = address.rsplit_once(':').unwrap();
    // The P series' light power (holding register 2, 0-based) of slave 1, as mbpoll reads it.
    let output = Command::new("mbpoll")
        .args([
            "-m", "tcp", "-p", port, "-a", "1", "-0", "-r", "2", "-t", "4", "-c", "1", "-1", host,
        ])
        .output()
        .expect("run mbpoll");
    let _ = bus.kill();
    let _ = bus.wait();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(output.status.success(), "mbpoll: {stdout}");
    let value: i64 = stdout
        .lines()
        .find_map(|l| l.trim().strip_prefix("[2]:"))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("no value in {stdout}"));
    // The simulator's light power is in range: 0.5 ..= 100.0 % in tenths.
    assert!((5..=1000).contains(&value), "{value}");
    let samples = BufReader::new(bus.stdout.take().unwrap()).lines().count();
    assert!(samples > 0, "the bus kept polling");
}

/// A bare HTTP/1.1 GET to the console at `address`: the status code and the body.
fn http_get(address: &str, path: &str) -> (u16, String) {
    use std::io::{Read, Write};
    let mut stream = std::net::TcpStream::connect(address).expect("the console listens");
    write!(
        stream,
        "GET {path} HTTP/1.1\r\nHost: {address}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut reply = String::new();
    stream.read_to_string(&mut reply).unwrap();
    let (head, body) = reply.split_once("\r\n\r\n").expect("a head and a body");
    let status = head.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap();
    (status, body.to_owned())
}

/// Starts `optobus args…`, waits for the console's address on `stdout` or `stderr`, and gives
/// the device names `/api/devices` lists.
fn console_devices(args: &[&str]) -> Vec<String> {
    let mut child = common::optobus()
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start optobus");
    let stderr = BufReader::new(child.stderr.take().unwrap());
    let mut address = None;
    for line in stderr.lines() {
        let line = line.unwrap();
        if let Some(url) = line.strip_prefix("optobus: the console is on http://") {
            address = Some(url.trim_end_matches('/').to_owned());
            break;
        }
    }
    let address = address.expect("the console's address on stderr");
    let (status, body) = http_get(&address, "/api/devices");
    let _ = child.kill();
    let _ = child.wait();
    assert_eq!(status, 200, "{body}");
    let json: serde_json::Value = serde_json::from_str(&body).unwrap();
    json["devices"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["device"].as_str().unwrap().to_owned())
        .collect()
}

#[test]
fn ui_serves_the_demo_bus_and_says_where() {
    let devices = console_devices(&["ui", "--http", "127.0.0.1:0", "--duration", "20s"]);
    assert_eq!(
        devices,
        [
            "head",
            "rangefinder",
            "confocal",
            "distance",
            "four-channel"
        ]
    );
}

#[test]
fn ui_makes_one_device_given_by_its_model_into_a_bus() {
    let devices = console_devices(&[
        "ui",
        "--model",
        "ccs",
        "--http",
        "127.0.0.1:0",
        "--duration",
        "20s",
    ]);
    assert_eq!(devices, ["ccs"]);
}

#[test]
fn run_with_http_serves_the_console_of_the_bus() {
    let devices = console_devices(&[
        "run",
        "--demo",
        "--gateway",
        "127.0.0.1:0",
        "--http",
        "127.0.0.1:0",
        "--duration",
        "20s",
        "--json",
    ]);
    assert_eq!(devices.len(), 5, "{devices:?}");
}
