//! `optobus bus check` and `optobus run`: a bus file checked as a whole, the demo bus polled
//! live, as JSON lines and as a CSV per device, and its gateway read by mbpoll.

mod common;

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

use common::{ok, outcome, REFUSED, USAGE};

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
        stdout.ends_with("1 line, 2 devices, 1 poll: ok\n"),
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
    let common::Demo {
        child: mut bus,
        first_line: line,
        stderr: _stderr,
    } = common::demo_with(&["--gateway", "127.0.0.1:0"], Stdio::piped());
    // The gateway's address is the first line on stderr.
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
    let (status, body) = common::get(&address, "/api/devices");
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

/// The file of issue 30's point 4: a misspelt model, the slave of another device, `every: fast`.
const MISSPELT: &str = "lines:
  - name: rs485
    serial: /dev/ttyUSB0
devices:
  - name: top
    model: p-series
    slave: 1
  - name: range
    model: rangefinde
    slave: 1
    timout: 200ms
    poll:
      - read: measurements
        every: fast
";

/// Point 4 of issue 30: `bus check` counts in the singular and the plural ("1 lines" was).
#[test]
fn bus_check_says_1_line_and_2_lines() {
    let one = scratch("one.yaml");
    std::fs::write(
        &one,
        "lines: [{ name: a, simulated: true }]\ndevices: [{ name: x, model: ccs, poll: [{ read: measurements }] }]\n",
    )
    .unwrap();
    let stdout = ok(&["bus", "check", one.to_str().unwrap()]);
    assert!(
        stdout.ends_with(": 1 line, 1 device, 1 poll: ok\n"),
        "{stdout}"
    );
    let two = scratch("two.yaml");
    std::fs::write(
        &two,
        "lines: [{ name: a, simulated: true }, { name: b, simulated: true }]\ndevices:\n  - { name: x, model: ccs, line: a, poll: [{ read: measurements }, { read: measurements, every: 1s }] }\n  - { name: y, model: ccs, line: b }\n",
    )
    .unwrap();
    let stdout = ok(&["bus", "check", two.to_str().unwrap()]);
    assert!(
        stdout.ends_with(": 2 lines, 2 devices, 2 polls: ok\n"),
        "{stdout}"
    );
    let _ = std::fs::remove_file(one);
    let _ = std::fs::remove_file(two);
}

/// Point 4 of issue 30: `bus check --json` prints JSON on stdout, each diagnostic with its
/// severity, message, file, line, column and help; a file that does not pass is still refused.
#[test]
fn bus_check_json_prints_each_diagnostic_as_json() {
    let bad = scratch("misspelt.yaml");
    std::fs::write(&bad, MISSPELT).unwrap();
    let path = bad.to_str().unwrap();
    let (code, stdout, stderr) = outcome(&["bus", "check", path, "--json"]);
    assert_eq!(code, Some(REFUSED), "{stderr}");
    assert!(
        stderr.contains("does not pass the bus file checks: 4 errors"),
        "{stderr}"
    );
    let report: serde_json::Value = serde_json::from_str(&stdout).expect("JSON on stdout");
    assert_eq!(report["ok"], false);
    assert_eq!(report["file"], path);
    let diagnostics = report["diagnostics"].as_array().expect("a list");
    assert_eq!(diagnostics.len(), 4, "{stdout}");
    let model = diagnostics
        .iter()
        .find(|d| d["message"] == "there is no built-in model `rangefinde`")
        .expect("the model's diagnostic");
    assert_eq!(model["severity"], "error");
    assert_eq!(model["file"], path);
    assert_eq!(
        (model["line"].as_u64(), model["column"].as_u64()),
        (Some(9), Some(12))
    );
    assert!(
        model["help"]
            .as_str()
            .unwrap()
            .starts_with("did you mean `rangefinder`?"),
        "{model}"
    );
    let slave = diagnostics
        .iter()
        .find(|d| d["rule"] == "duplicate-slave")
        .expect("the taken slave");
    assert_eq!(
        (slave["line"].as_u64(), slave["column"].as_u64()),
        (Some(10), Some(12))
    );
    assert_eq!(slave["related"][0]["line"], 7);
    for message in [
        "a device has no key `timout`",
        "`every` `fast` is neither a duration nor `fastest`",
    ] {
        assert!(
            diagnostics.iter().any(|d| d["message"] == message),
            "{message}: {stdout}"
        );
    }
    let good = scratch("good-json.yaml");
    std::fs::write(
        &good,
        "lines: [{ name: a, simulated: true }]\ndevices: [{ name: x, model: ccs }]\n",
    )
    .unwrap();
    let report: serde_json::Value =
        serde_json::from_str(&ok(&["bus", "check", good.to_str().unwrap(), "--json"]))
            .expect("JSON");
    assert_eq!(report["ok"], true);
    assert_eq!(
        (report["lines"].as_u64(), report["devices"].as_u64()),
        (Some(1), Some(1))
    );
    let _ = std::fs::remove_file(bad);
    let _ = std::fs::remove_file(good);
}

/// Point 9 of issue 30: `--gateway` with a bus file moves the file's gateway (or gives its one
/// RTU line one), and says so; where it cannot tell which line is meant it is refused.
#[test]
fn run_gateway_moves_the_gateway_of_a_bus_file() {
    // Port 1 is one an ordinary user cannot listen on: the file's address is not the one used.
    let with_gateway = scratch("with-gateway.yaml");
    std::fs::write(
        &with_gateway,
        "lines: [{ name: rs485, simulated: true, gateway: 127.0.0.1:1 }]\ndevices: [{ name: x, model: ccs, poll: [{ read: measurements, every: 200ms }] }]\n",
    )
    .unwrap();
    let without = scratch("without-gateway.yaml");
    std::fs::write(
        &without,
        "lines: [{ name: rs485, simulated: true }]\ndevices: [{ name: x, model: ccs, poll: [{ read: measurements, every: 200ms }] }]\n",
    )
    .unwrap();
    for file in [&with_gateway, &without] {
        let (code, _, stderr) = outcome(&[
            "run",
            file.to_str().unwrap(),
            "--gateway",
            "127.0.0.1:0",
            "--duration",
            "300ms",
            "--json",
        ]);
        assert_eq!(code, Some(0), "{stderr}");
        let note = stderr
            .lines()
            .find(|l| l.contains("gateway of rs485 on 127.0.0.1:"))
            .unwrap_or_else(|| panic!("no gateway note: {stderr}"));
        assert!(!note.ends_with("127.0.0.1:1"), "{note}");
    }
    let two_lines = scratch("two-lines.yaml");
    std::fs::write(
        &two_lines,
        "lines: [{ name: a, simulated: true }, { name: b, simulated: true }]\ndevices: [{ name: x, model: ccs, line: a }]\n",
    )
    .unwrap();
    let (code, _, stderr) = outcome(&[
        "run",
        two_lines.to_str().unwrap(),
        "--gateway",
        "127.0.0.1:0",
        "--duration",
        "300ms",
    ]);
    assert_eq!(code, Some(REFUSED), "{stderr}");
    assert!(
        stderr
            .contains("--gateway: which line should it serve? The bus file has RTU lines `a`, `b`"),
        "{stderr}"
    );
    for file in [with_gateway, without, two_lines] {
        let _ = std::fs::remove_file(file);
    }
}

/// Point 9 of issue 30: `optobus run` alone says how to start the demo.
#[test]
fn run_without_a_bus_file_says_how_to_start_the_demo() {
    let (code, _, stderr) = outcome(&["run"]);
    assert_eq!(code, Some(USAGE), "{stderr}");
    assert!(stderr.contains("optobus run --demo"), "{stderr}");
    assert!(stderr.contains("needs a bus file"), "{stderr}");
}

/// Point 9 of issue 30: the help of `run` and `bus check` points at documentation an
/// installed tool has (`optobus bus schema`), not at a file of the source tree; the schema it
/// prints names every key, `faults:` among them.
#[test]
fn run_help_names_docs_an_installed_tool_has() {
    for args in [
        &["run", "--help"][..],
        &["bus", "check", "--help"],
        &["simulate", "--help"],
    ] {
        let help = ok(args);
        assert!(!help.contains("README"), "{args:?}: {help}");
        assert!(!help.contains("crates/"), "{args:?}: {help}");
        assert!(help.contains("optobus bus schema"), "{args:?}: {help}");
    }
    let schema = ok(&["bus", "schema"]);
    assert_eq!(schema.trim_end(), optobus_bus::file::SCHEMA.trim_end());
    for key in [
        "lines:",
        "gateway:",
        "devices:",
        "poll:",
        "every:",
        "writable:",
        "faults:",
        "outputs:",
    ] {
        assert!(schema.contains(key), "{key}: {schema}");
    }
}
