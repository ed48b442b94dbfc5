//! `optobus simulate` serving several devices on one RTU line (a list of MODEL@SLAVE, or a
//! line of a bus file with each device's faults), read over its pty by optobus, a bus run and
//! mbpoll; and `watch` keeping its interval on the wire after a stall.

mod common;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader, Read};
use std::process::{Child, Command, Stdio};

use common::{json, optobus, outcome};

fn scratch(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("optobus-line-{}-{name}", std::process::id()))
}

/// `optobus simulate args…` in the background: the pty path and the `slave N: …` lines it
/// printed; stopped when dropped.
struct Line {
    child: Child,
    path: String,
    slaves: Vec<String>,
}

impl Line {
    fn start(args: &[&str], devices: usize) -> Self {
        Self::start_logged(args, devices, Stdio::null())
    }

    fn start_logged(args: &[&str], devices: usize, stderr: Stdio) -> Self {
        let mut child = optobus()
            .arg("simulate")
            .args(args)
            .args(["--pty", "--duration", "60s"])
            .stdout(Stdio::piped())
            .stderr(stderr)
            .spawn()
            .expect("start optobus simulate");
        let mut lines = BufReader::new(child.stdout.take().expect("stdout")).lines();
        let mut next = || lines.next().expect("a line").expect("text");
        let path = next();
        let slaves = (0..devices).map(|_| next()).collect();
        Self {
            child,
            path,
            slaves,
        }
    }

    /// Stops serving and gives what was logged on stderr.
    fn log(mut self) -> String {
        let sent = Command::new("kill")
            .args(["-INT", &self.child.id().to_string()])
            .status()
            .expect("kill -INT");
        assert!(sent.success());
        let mut log = String::new();
        if let Some(mut stderr) = self.child.stderr.take() {
            stderr.read_to_string(&mut log).expect("stderr");
        }
        log
    }
}

impl Drop for Line {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `read slave_address` of `model` at `slave` over the line: the address it holds.
/// Asserts that a read of the P series' `slave_address` at `slave` on `line` gets no reply
/// within 200 ms (exit code 1).
fn assert_no_reply_at(line: &Line, slave: &str) {
    let (code, _, stderr) = outcome(&[
        "read",
        "slave_address",
        "--serial",
        &line.path,
        "--model",
        "p-series",
        "--slave",
        slave,
        "--timeout",
        "200ms",
    ]);
    assert_eq!(code, Some(1), "slave {slave}: {stderr}");
    assert!(stderr.contains("no reply within 200 ms"), "{stderr}");
}

fn slave_address(line: &Line, model: &str, slave: &str) -> serde_json::Value {
    let values = json(&[
        "read",
        "slave_address",
        "--serial",
        &line.path,
        "--model",
        model,
        "--slave",
        slave,
        "--baud",
        "115200",
        "--timeout",
        "300ms",
    ]);
    values["slave_address"].clone()
}

#[test]
fn each_listed_device_answers_its_own_address_only() {
    let line = Line::start(&["p-series@1", "rangefinder@5", "lc-rs@7"], 3);
    assert_eq!(
        line.slaves,
        [
            "slave 1: p-series",
            "slave 5: rangefinder",
            "slave 7: lc-rs"
        ]
    );
    // Each register holds the address the device was given: the answer came from that device.
    assert_eq!(slave_address(&line, "p-series", "1"), 1);
    assert_eq!(slave_address(&line, "rangefinder", "5"), 5);
    assert_eq!(slave_address(&line, "lc-rs", "7"), 7);
    // No device at 2: no reply, whatever the model asks.
    assert_no_reply_at(&line, "2");
}

#[test]
fn two_devices_at_one_slave_or_a_bad_address_are_refused() {
    for (args, message) in [
        (["p-series@1", "ccs@1"], "two devices at slave 1"),
        (["p-series@1", "ccs@248"], "slave address is 1 to 247"),
        (["p-series@1", "ccs"], "each named MODEL@SLAVE"),
    ] {
        let mut all = vec!["simulate"];
        all.extend(args);
        all.push("--pty");
        let (code, _, stderr) = outcome(&all);
        assert_eq!(code, Some(common::REFUSED), "{args:?}: {stderr}");
        assert!(stderr.contains(message), "{args:?}: {stderr}");
    }
}

/// Over Modbus TCP the line is served as a gateway in front of it would: the unit id picks the
/// device, and a unit id no device has is answered with exception 0B.
#[test]
fn over_tcp_the_unit_id_picks_the_device() {
    let mut child = optobus()
        .args([
            "simulate",
            "p-series@1",
            "p-series@2",
            "--tcp",
            "127.0.0.1:0",
        ])
        .args(["--duration", "60s"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start optobus simulate");
    let address = common::serves_at(&mut child);
    let read = |slave: &str| {
        outcome(&[
            "read",
            "slave_address",
            "--tcp",
            &address,
            "--model",
            "p-series",
            "--slave",
            slave,
            "--timeout",
            "500ms",
            "--json",
        ])
    };
    for slave in [1, 2] {
        let (code, stdout, stderr) = read(&slave.to_string());
        assert_eq!(code, Some(0), "{stderr}");
        let values: serde_json::Value = serde_json::from_str(&stdout).expect("JSON");
        assert_eq!(values["slave_address"], slave);
    }
    let (code, _, stderr) = read("3");
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stderr.contains("exception 0B"), "{stderr}");
    let _ = child.kill();
    let _ = child.wait();
}

/// A simulated line of three devices; `faults` per device by name.
fn simulated_bus(name: &str, faults: &[(&str, &str)]) -> std::path::PathBuf {
    let faults: BTreeMap<&str, &str> = faults.iter().copied().collect();
    let device = |name: &str, model: &str, slave: u8| {
        let faults = faults
            .get(name)
            .map(|f| format!(", faults: \"{f}\""))
            .unwrap_or_default();
        format!("  - {{ name: {name}, model: {model}, slave: {slave}, timeout: 200ms{faults} }}\n")
    };
    let text = format!(
        "lines: [{{ name: sim, simulated: true, baud: 115200, any_format: true }}]\ndevices:\n{}{}{}",
        device("head", "p-series", 1),
        device("ranger", "rangefinder", 5),
        device("probe", "lc-rs", 7),
    );
    let path = scratch(name);
    std::fs::write(&path, text).expect("bus file");
    path
}

#[test]
fn a_bus_run_reads_every_device_of_a_simulated_bus_line_over_its_pty() {
    let simulated = simulated_bus("served.yaml", &[]);
    let line = Line::start(&["--bus", simulated.to_str().unwrap(), "--line-timing"], 3);
    assert_eq!(
        line.slaves,
        [
            "slave 1: p-series head",
            "slave 5: rangefinder ranger",
            "slave 7: lc-rs probe"
        ]
    );
    let plant = scratch("plant.yaml");
    let poll = "poll: [{ read: slave_address, every: 100ms }]";
    std::fs::write(
        &plant,
        format!(
            "lines: [{{ name: rs485, serial: {}, baud: 115200, any_format: true }}]\ndevices:\n  \
             - {{ name: head, model: p-series, slave: 1, {poll} }}\n  \
             - {{ name: ranger, model: rangefinder, slave: 5, {poll} }}\n  \
             - {{ name: probe, model: lc-rs, slave: 7, {poll} }}\n",
            line.path
        ),
    )
    .expect("bus file");
    let stdout = common::ok(&[
        "run",
        plant.to_str().unwrap(),
        "--duration",
        "1500ms",
        "--json",
    ]);
    let mut seen = BTreeMap::new();
    for sample in stdout.lines() {
        let sample: serde_json::Value = serde_json::from_str(sample).expect("a JSON line");
        assert_eq!(sample["register"], "slave_address", "{sample}");
        // Every answer is the polled device's own address: no device answered for another.
        assert_eq!(sample["value"], sample["slave"], "{sample}");
        *seen
            .entry(sample["device"].as_str().unwrap().to_owned())
            .or_insert(0) += 1;
    }
    assert_eq!(
        seen.keys().collect::<Vec<_>>(),
        ["head", "probe", "ranger"],
        "{stdout}"
    );
    let _ = std::fs::remove_file(simulated);
    let _ = std::fs::remove_file(plant);
}

#[test]
fn a_dead_device_times_out_while_a_slow_and_a_garbling_one_answer_right() {
    let simulated = simulated_bus(
        "faulty.yaml",
        &[
            ("head", "drop=1"),
            ("ranger", "split=1,pause=20ms"),
            ("probe", "corrupt=0.5,seed=3"),
        ],
    );
    let line = Line::start(&["--bus", simulated.to_str().unwrap()], 3);
    // The dead device.
    assert_no_reply_at(&line, "1");
    // Each reply in three pieces 20 ms apart: slow, and right.
    assert_eq!(slave_address(&line, "rangefinder", "5"), 5);
    // Half the replies garbled: those are errors, the others the right value.
    let (mut answered, mut garbled) = (0, 0);
    for _ in 0..8 {
        let (code, stdout, stderr) = outcome(&[
            "read",
            "slave_address",
            "--serial",
            &line.path,
            "--model",
            "lc-rs",
            "--slave",
            "7",
            "--baud",
            "115200",
            "--timeout",
            "200ms",
            "--json",
        ]);
        match code {
            Some(0) => {
                let values: serde_json::Value = serde_json::from_str(&stdout).expect("JSON");
                assert_eq!(values["slave_address"], 7);
                answered += 1;
            }
            _ => {
                assert_eq!(code, Some(1), "{stderr}");
                garbled += 1;
            }
        }
    }
    assert!(
        answered > 0 && garbled > 0,
        "{answered} answered, {garbled} garbled"
    );
    let _ = std::fs::remove_file(simulated);
}

#[test]
#[cfg_attr(
    not(peer_mbpoll),
    ignore = "mbpoll is not installed (Debian package mbpoll)"
)]
fn mbpoll_reads_two_slaves_of_one_simulated_line() {
    let line = Line::start(&["p-series@1", "rangefinder@5"], 2);
    let mbpoll = |slave: &str, register: &str| -> Vec<i64> {
        // -0: PDU addresses; -t 4: holding; -1: poll once.
        common::mbpoll(&[
            "-m", "rtu", "-b", "115200", "-P", "none", "-a", slave, "-0", "-r", register, "-c",
            "1", "-t", "4", "-1", &line.path,
        ])
    };
    // Each device's slave-address register (P series 31, rangefinder 0x0003).
    assert_eq!(mbpoll("1", "31"), [1]);
    assert_eq!(mbpoll("5", "3"), [5]);
}

/// The times of day (ms) at which the simulator saw each request, from its log.
fn request_times(log: &str) -> Vec<u64> {
    log.lines()
        .filter(|line| line.contains(" read input "))
        .filter_map(|line| {
            let clock = line.split_whitespace().next()?;
            let (hms, ms) = clock.split_once('.')?;
            let mut parts = hms.split(':').map(|p| p.parse::<u64>().ok());
            let (h, m, s) = (parts.next()??, parts.next()??, parts.next()??);
            Some(((h * 60 + m) * 60 + s) * 1000 + ms.parse::<u64>().ok()?)
        })
        .collect()
}

#[test]
fn watch_skips_the_ticks_a_stall_missed_and_never_sends_two_reads_closer_than_its_interval() {
    // A third of the replies come 300 ms late, after watch's 200 ms timeout: the client then
    // waits for a quiet line (200 ms after the late reply) before its next request, far past
    // the next tick.
    let line = Line::start_logged(
        &["p-series@1", "--faults", "delay=0.34,late=300ms,seed=5"],
        1,
        Stdio::piped(),
    );
    let (code, _, stderr) = outcome(&[
        "watch",
        "distance_1",
        "--interval",
        "100ms",
        "--count",
        "12",
        "--serial",
        &line.path,
        "--model",
        "p-series",
        "--slave",
        "1",
        "--timeout",
        "200ms",
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("no reply within 200 ms"),
        "a stall happened: {stderr}"
    );
    let times = request_times(&line.log());
    assert_eq!(times.len(), 12, "one request per refresh: {times:?}");
    // A burst shows as reads 0 to 3 ms apart (as before the fix: gaps of 1 and 0 ms after
    // the stalls); a loaded machine shifts a stamp by a few ms, so half the interval tells
    // the two apart without timing anything.
    let gaps: Vec<u64> = times
        .windows(2)
        .map(|w| w[1].saturating_sub(w[0]))
        .collect();
    assert!(
        gaps.iter().all(|&gap| gap >= 50),
        "a burst: gaps {gaps:?} ms"
    );
    assert!(
        gaps.iter().any(|&gap| gap > 400),
        "no stall seen: {gaps:?} ms"
    );
}
