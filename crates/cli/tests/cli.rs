//! Every command of `optobus` against the built-in simulator (or one it serves): output,
//! exit codes, JSON, and invalid input refused before anything is sent.

mod common;

use common::{fails, json, ok, outcome, refused, run, words, Served, FAILED, REFUSED};
use std::sync::{Arc, Mutex};

/// Runs each command line, which must succeed and print the line given.
fn prints(cases: &[(&[&str], &str)]) {
    for (args, expected) in cases {
        assert_eq!(ok(args).trim(), *expected, "{args:?}");
    }
}

#[test]
fn models_lists_every_spec() {
    let text = ok(&["models"]);
    for family in ["p-series", "rangefinder", "ccs", "lc-rs", "ccf"] {
        assert!(text.contains(family), "{text}");
    }
    assert!(text.contains("115200"), "P-series default baud: {text}");
    let list = json(&["models"]);
    let list = list.as_array().expect("array");
    let specs = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/../../specs"))
        .expect("specs/")
        .filter(|e| {
            e.as_ref()
                .is_ok_and(|e| e.path().extension().is_some_and(|x| x == "yaml"))
        })
        .count();
    assert_eq!(list.len(), specs);
    assert_eq!(list[0]["model"], "p_series");
    assert_eq!(list[0]["tcp"]["port"], 502);
}

#[test]
fn registers_prints_the_map_from_the_spec() {
    let text = ok(&["registers", "p-series"]);
    let line = text
        .lines()
        .find(|l| l.starts_with("light_power "))
        .expect("light_power row");
    for part in [
        "holding",
        "0x0002 (2)",
        "rw",
        "u16",
        "%",
        "0.5 % ..= 100.0 %",
    ] {
        assert!(line.contains(part), "{line}");
    }
    let map = json(&["registers", "ccf"]);
    let registers = map["registers"].as_array().expect("registers");
    assert_eq!(registers.len(), 48);
    assert!(registers
        .iter()
        .any(|r| r["name"] == "channel_4_exposure_time"));
    // Model aliases.
    assert_eq!(json(&["registers", "LC_RS"])["model"], "lc_rs");
    let error = fails(&["registers", "nosuch"]);
    assert!(error.contains("unknown model `nosuch`"), "{error}");
}

#[test]
fn read_prints_values_with_units() {
    let output = run(&["read", "measurements"]);
    assert!(output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(
        stderr
            .lines()
            .filter(|l| l.contains("built-in p-series simulator"))
            .count(),
        1,
        "{stderr}"
    );
    let text = String::from_utf8_lossy(&output.stdout);
    assert_eq!(text.lines().count(), 5, "{text}");
    assert!(text.lines().all(|l| l.ends_with(" mm")), "{text}");
    let values = json(&["read", "distance_1", "laser", "ip_address"]);
    assert_eq!(values["distance_1"]["unit"], "mm");
    // The exact decimal text, not a rounded float.
    let exact = values["distance_1"]["value"].as_str().expect("exact text");
    assert!(exact.parse::<f64>().is_ok(), "{exact}");
    assert_eq!(values["ip_address"], "192.168.0.10");
    assert!(values["laser_enabled"].is_boolean());
    // Per-channel registers and groups.
    let ccf = json(&["--model", "ccf", "read", "measurements", "--channel", "3"]);
    assert!(
        ccf["channel_3_distance_1"]["value"].is_string()
            && ccf["channel_3_distance_1"]["unit"] == "mm",
        "{ccf}"
    );
    let error = fails(&["read", "distance_9"]);
    assert!(
        error.contains("`distance_9` is no register or group"),
        "{error}"
    );
}

#[test]
fn dump_reads_everything_in_few_requests() {
    let dump = json(&["dump"]);
    // 106 readable registers, less the 60 buffered values whose read turns the page.
    assert_eq!(dump["values"].as_object().expect("values").len(), 46);
    assert_eq!(
        dump["requests"], 3,
        "holding, input up to the buffer, input after it over reserved rows (4.2.2 note 1)"
    );
    let rangefinder = json(&["--model", "rangefinder", "dump"]);
    // 26 fields, one of them write-only: one request per field.
    assert_eq!(rangefinder["requests"], 25);
}

#[test]
fn watch_charts_each_number_beside_it() {
    let text = ok(&[
        "watch",
        "distance_1",
        "light_power",
        "--chart",
        "--count",
        "5",
        "--interval",
        "1ms",
    ]);
    let last = |name: &str| text.lines().rev().find(|l| l.starts_with(name)).unwrap();
    // The simulated distance moves: five readings between the lowest and the highest.
    let distance: Vec<char> = last("distance_1")
        .split_whitespace()
        .last()
        .unwrap()
        .chars()
        .collect();
    assert_eq!(distance.len(), 5, "{text}");
    assert!(distance.contains(&'▁') && distance.contains(&'█'), "{text}");
    // The light power holds still: a flat line.
    let power = last("light_power");
    assert!(
        power.contains("0.5 %") && power.ends_with("  ▄▄▄▄▄"),
        "{text}"
    );
    refused(
        &words("--json watch distance_1 --chart"),
        REFUSED,
        "--chart draws for people",
    );
}

#[test]
fn watch_refreshes_and_stops() {
    let text = ok(&["watch", "distance_1", "--count", "3", "--interval", "20ms"]);
    assert_eq!(
        text.lines().filter(|l| l.starts_with("distance_1")).count(),
        3
    );
    let lines = ok(&[
        "watch",
        "measurements",
        "--count",
        "2",
        "--interval",
        "20ms",
        "--json",
    ]);
    let refreshes: Vec<serde_json::Value> = lines
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object per refresh"))
        .collect();
    assert_eq!(refreshes.len(), 2);
    assert!(refreshes[1]["values"]["thickness"]["value"].is_string());
    // A device that does not answer: watch carries on; piped, the failure goes to stderr once
    // while it stays the same, and stdout keeps only values.
    let served = Served::start(&["p-series", "--pty", "--slave", "3"]);
    let (code, stdout, stderr) = outcome(&words(
        &served.serial("watch distance_1 --count 3 --interval 10ms --slave 9 --timeout 50ms"),
    ));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stdout.trim().is_empty(), "{stdout}");
    assert_eq!(
        stderr
            .lines()
            .filter(|l| l.contains("! no reply within 50 ms") && l.ends_with("retrying"))
            .count(),
        1,
        "{stderr}"
    );
}

#[test]
fn set_takes_engineering_units_and_code_names() {
    prints(&[
        (&["set", "light_power", "42.5"], "light_power  42.5 %"),
        (&["set", "light_power", "42.5%"], "light_power  42.5 %"),
        (
            &["set", "sampling_interval", "100us"],
            "sampling_interval  us_100 (20)",
        ),
        (
            &["--model", "rangefinder", "set", "dac_range_max", "654321"],
            "dac_range_max  654321",
        ),
    ]);
    let set = json(&[
        "--model",
        "ccf",
        "set",
        "exposure_time",
        "204.7us",
        "--channel",
        "2",
    ]);
    assert_eq!(set["channel_2_exposure_time"]["value"], "204.7");
}

#[test]
fn invalid_values_are_refused_before_anything_is_sent() {
    for (line, message) in [
        ("set light_power 100.1", "allowed 0.5 % ..= 100.0 %"),
        ("set light_power 50.05", "whole steps of 0.1 %"),
        ("set sampling_interval 7us", "codes are us_6_25 (8)"),
        ("set distance_1 1", "read-only"),
        ("--model ccf set exposure_time 1", "--channel"),
    ] {
        let args = words(line);
        refused(&args, REFUSED, message);
    }
}

#[test]
fn commands_run_and_drastic_ones_need_yes() {
    prints(&[
        (&["do", "zero_position_1"], "zero_position_1 done"),
        (&["do", "save_parameters", "--yes"], "save_parameters done"),
        (
            &["--model", "ccf", "do", "zero_position", "--channel", "4"],
            "zero_position done",
        ),
    ]);
    refused(&["do", "save_parameters"], REFUSED, "--yes");
    let error = fails(&["do", "self_destruct"]);
    assert!(error.contains("commands: zero_position_1"), "{error}");
}

#[test]
fn buffer_downloads_to_csv() {
    let dir = std::env::temp_dir().join(format!("optobus-buffer-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let csv = dir.join("buffer.csv");
    let path = csv.to_string_lossy().into_owned();
    ok(&[
        "buffer", "--count", "150", "--wait", "100ms", "--out", &path,
    ]);
    let text = std::fs::read_to_string(&csv).expect("csv");
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("index,value_mm"));
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), 150);
    assert!(rows[149].starts_with("149,"));
    let value: f64 = rows[0]
        .split(',')
        .nth(1)
        .and_then(|v| v.parse().ok())
        .expect("a number in mm");
    assert!((1.0..10.0).contains(&value), "{value}");
    let _ = std::fs::remove_dir_all(&dir);
    // JSON: the unit once, each value as exact text, as the CSV has it.
    let download = json(&["buffer", "--count", "3", "--wait", "100ms"]);
    assert_eq!(download["unit"], "mm");
    let first = download["values"][0].as_str().expect("exact text");
    assert_eq!(first.split('.').nth(1).map(str::len), Some(6), "{first}");
    let error = fails(&["--model", "ccs", "buffer", "--count", "10"]);
    assert!(error.contains("no data buffer"), "{error}");
}

#[test]
fn verbose_shows_every_frame() {
    let output = run(&["read", "laser_enabled", "--verbose"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    // The request of 5.1.1's shape, and a reply.
    assert!(stderr.contains(" -> 01 03 00 00 00 01 84 0A"), "{stderr}");
    assert!(stderr.contains(" <- 01 03 02"), "{stderr}");
}

#[test]
fn simulate_over_tcp_serves_other_clients() {
    let served = Served::start(&["p-series", "--tcp", "127.0.0.1:0"]);
    let address = served.at.clone();
    assert!(address.starts_with("127.0.0.1:"), "{address}");
    ok(&[
        "--model",
        "p-series",
        "set",
        "light_power",
        "33.3",
        "--tcp",
        &address,
    ]);
    let values = json(&[
        "--model",
        "p-series",
        "read",
        "light_power",
        "--tcp",
        &address,
    ]);
    assert_eq!(values["light_power"]["value"], "33.3");
}

#[test]
fn scan_finds_the_device_on_a_pty() {
    let served = Served::start(&["p-series", "--pty", "--slave", "3"]);
    let text = ok(&[
        "--model", "p-series", "scan", "--serial", &served.at, "--bauds", "115200", "--slaves",
        "1-4",
    ]);
    assert_eq!(text.trim(), "found: slave 3 at 115200 baud: p-series");
}

#[test]
fn connection_errors_are_one_clear_line() {
    // Nothing listens on port 1.
    let error = fails(&words("--model p-series read distance_1 --tcp 127.0.0.1:1"));
    assert!(
        error.starts_with("optobus: cannot connect to 127.0.0.1:1"),
        "{error}"
    );
    assert_eq!(error.lines().count(), 1, "{error}");
    let error = fails(&words(
        "--model p-series read distance_1 --serial /dev/nonexistent-port",
    ));
    assert!(
        error.contains("cannot open /dev/nonexistent-port"),
        "{error}"
    );
    // A device at another slave address stays silent: a timeout that says what to check.
    let served = Served::start(&["p-series", "--pty", "--slave", "3"]);
    let error = fails(&words(
        &served.serial("read laser --slave 9 --timeout 100ms"),
    ));
    assert!(
        error.starts_with("optobus: no reply within 100 ms for `laser_enabled"),
        "{error}"
    );
    assert!(error.contains("--slave"), "{error}");
    assert_eq!(error.lines().count(), 1, "{error}");
}

#[test]
fn ctrl_c_ends_watch_cleanly() {
    let output = common::interrupted(
        &["watch", "distance_1", "--interval", "20ms"],
        std::time::Duration::from_millis(500),
    );
    assert!(output.status.success(), "{:?}", output.status);
    let text = String::from_utf8_lossy(&output.stdout);
    assert!(text.lines().any(|l| l.starts_with("distance_1")), "{text}");
}

#[test]
fn watch_over_tcp_carries_on_after_the_server_restarts() {
    let served = Served::start(&["p-series", "--tcp", "127.0.0.1:0"]);
    let address = served.at.clone();
    let watch = common::optobus()
        .args([
            "--model",
            "p-series",
            "watch",
            "laser",
            "--interval",
            "100ms",
        ])
        .args(["--count", "40"])
        .args(["--tcp", &address, "--json", "--timeout", "200ms"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("start watch");
    std::thread::sleep(std::time::Duration::from_millis(800));
    drop(served);
    std::thread::sleep(std::time::Duration::from_millis(800));
    let _again = Served::start(&["p-series", "--tcp", &address]);
    let output = watch.wait_with_output().expect("watch ends");
    assert!(output.status.success());
    let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&output.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect();
    let first_error = lines
        .iter()
        .position(|l| l.get("error").is_some())
        .expect("the outage shows");
    let error = lines[first_error]["error"].as_str().unwrap_or_default();
    assert!(
        error.contains("closed") || error.contains("cannot connect"),
        "a clear reason: {error}"
    );
    assert!(
        lines[first_error..]
            .iter()
            .any(|l| l["values"]["laser_enabled"].is_boolean()),
        "values again after the restart: {lines:?}"
    );
}

#[test]
fn dump_json_keeps_the_register_order() {
    let dump = json(&["dump"]);
    let dumped: Vec<&String> = dump["values"].as_object().expect("values").keys().collect();
    let map = json(&["registers"]);
    let listed: Vec<&str> = map["registers"]
        .as_array()
        .expect("registers")
        .iter()
        .filter_map(|r| r["name"].as_str())
        .filter(|name| dumped.iter().any(|d| d == name))
        .collect();
    assert_eq!(dumped, listed);
    // Not alphabetical: distance_1 (input 0) before buffer_read_count (input 16).
    let at = |name: &str| dumped.iter().position(|d| *d == name).expect(name);
    assert!(at("distance_1") < at("buffer_read_count"));
    let mut sorted = dumped.clone();
    sorted.sort();
    assert_ne!(dumped, sorted);
}

#[test]
fn watch_times_are_dated_with_their_offset() {
    let line = ok(&["watch", "distance_1", "--count", "1", "--json"]);
    let refresh: serde_json::Value = serde_json::from_str(line.trim()).expect("JSON");
    let time = refresh["time"].as_str().expect("a time");
    // RFC 3339: a date, a time to the millisecond and an offset; and it is now.
    let when: jiff::Timestamp = time.parse().expect(time);
    let age = jiff::Timestamp::now().duration_since(when).as_secs_f64();
    assert!((0.0..60.0).contains(&age), "{time} is {age} s old");
    assert_eq!(
        time.len(),
        "2026-11-23T14:23:54.822153+01:00".len(),
        "{time}"
    );
    let text = ok(&["watch", "distance_1", "--count", "1"]);
    let first = text.lines().next().expect("a heading");
    // `14:23:54.822 +01:00  p-series · …`: the time of day labelled with its offset.
    let (clock, offset) = (&first[..12], &first[12..19]);
    assert!(
        clock.as_bytes()[2] == b':' && clock.as_bytes()[8] == b'.',
        "{first}"
    );
    assert!(
        offset.starts_with(" +") || offset.starts_with(" -"),
        "{first}"
    );
    assert_eq!(&offset[4..5], ":", "{first}");
}

#[test]
fn verbose_frames_carry_the_local_time_and_the_reply_delay() {
    let output = run(&["read", "laser_enabled", "--verbose"]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    let reply = stderr
        .lines()
        .find(|l| l.contains(" <- 01 03 02"))
        .unwrap_or_else(|| panic!("{stderr}"));
    // `14:23:54.830 +01:00 <- 01 03 02 00 00 B8 44 (0.074 ms)`
    assert_eq!(&reply[12..14], " +", "{reply}");
    assert!(reply.ends_with(" ms)"), "{reply}");
}

#[test]
fn point_7_a_failed_dump_names_the_failing_requests_registers_only() {
    let served = Served::start(&["p-series", "--tcp", "127.0.0.1:0", "--faults", "drop=1"]);
    let (code, _, stderr) = outcome(&[
        "--model",
        "p-series",
        "dump",
        "--tcp",
        &served.at,
        "--timeout",
        "100ms",
    ]);
    assert_eq!(code, Some(FAILED), "{stderr}");
    // The first request reads the holding registers; the input registers come later.
    assert!(
        stderr.contains("no reply within 100 ms for `laser_enabled, "),
        "{stderr}"
    );
    assert!(!stderr.contains("distance_1"), "{stderr}");
}

#[test]
fn point_9_watch_reports_a_lasting_failure_once_then_its_recovery() {
    use std::io::{BufRead, BufReader, Read};
    let served = Served::start(&["p-series", "--tcp", "127.0.0.1:0"]);
    let at = served.at.clone();
    let mut watch = common::optobus()
        .args([
            "--model",
            "p-series",
            "watch",
            "distance_1",
            "--interval",
            "50ms",
            "--count",
            "60",
        ])
        .args(["--tcp", &at, "--timeout", "200ms"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start optobus watch");
    let mut stdout = BufReader::new(watch.stdout.take().expect("stdout"));
    let mut first = String::new();
    stdout.read_line(&mut first).expect("a first reading");
    // The device goes away for a while (several refreshes), then comes back at its address.
    drop(served);
    std::thread::sleep(std::time::Duration::from_millis(600));
    let _back = Served::start(&["p-series", "--tcp", &at]);
    let mut rest = String::new();
    stdout
        .read_to_string(&mut rest)
        .expect("the other readings");
    let mut stderr = String::new();
    let mut pipe = watch.stderr.take().expect("stderr");
    pipe.read_to_string(&mut stderr).expect("stderr");
    assert!(watch.wait().expect("watch ends").success(), "{stderr}");
    let lines = |sign: &str| stderr.lines().filter(|l| l.contains(sign)).count();
    // Each attempt's count differs (`(1 attempt)`, `(2 attempts)`…); the refusal is said once.
    assert_eq!(lines("Connection refused"), 1, "{stderr}");
    assert_eq!(lines("recovered after"), 1, "{stderr}");
    // A failure is said again only when its kind changes (a closed connection, then refused
    // ones, then perhaps a connection that timed out while the device came back).
    let failures: Vec<String> = stderr
        .lines()
        .filter_map(|line| line.split_once("  ! ").map(|(_, failure)| failure))
        .map(|failure| failure.chars().filter(|c| !c.is_ascii_digit()).collect())
        .collect();
    assert!(failures.windows(2).all(|w| w[0] != w[1]), "{stderr}");
    assert!(!failures.is_empty() && failures.len() <= 4, "{stderr}");
    assert!(
        rest.lines()
            .last()
            .is_some_and(|l| l.starts_with("distance_1")),
        "{rest}"
    );
}

/// Reads a simulator saw: first address, words, whether answered with words.
type SeenReads = Arc<Mutex<Vec<(u16, u16, bool)>>>;

/// A P series that refuses reads crossing reserved rows (exception 02), served over TCP from
/// a thread of this test, and the reads it saw with whether each was answered with words.
fn serve_refusing_reserved() -> (String, SeenReads) {
    use optobus_simulator::{Quirks, Reply, Simulator, UnreadableReads};
    let seen: SeenReads = Arc::default();
    let log = Arc::clone(&seen);
    let sim = Simulator::new(&optobus_p_series::DEVICE).observe(move |exchange| {
        if let Some(optobus_codec::Request::Read { address, count, .. }) = exchange.request {
            let answered = matches!(exchange.reply, Reply::Read { .. });
            log.lock().unwrap().push((*address, *count, answered));
        }
    });
    sim.set_quirks(Quirks {
        readable_reserved: UnreadableReads::Refused,
        ..sim.current_quirks()
    });
    let (sender, receiver) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("runtime");
        runtime.block_on(async move {
            let server = sim.serve_tcp("127.0.0.1:0").await.expect("serve");
            sender.send(server.local_addr().to_string()).unwrap();
            std::future::pending::<()>().await;
        });
    });
    (receiver.recv().expect("served"), seen)
}

#[test]
fn dump_of_a_device_refusing_reserved_rows_answers_in_full() {
    let (at, seen) = serve_refusing_reserved();
    let dump = json(&["dump", "--model", "p-series", "--tcp", &at]);
    let values = dump["values"].as_object().expect("values");
    assert_eq!(values.len(), 46, "every register a dump reads");
    assert!(values.contains_key("connected_host_port"));
    // Input 140-154 over the reserved 141-149 refused once, then read as 140 and 150-154:
    // four answered requests.
    assert_eq!(dump["requests"], 4);
    let refused: Vec<(u16, u16)> = seen
        .lock()
        .unwrap()
        .iter()
        .filter(|(_, _, answered)| !answered)
        .map(|&(address, count, _)| (address, count))
        .collect();
    assert_eq!(refused, [(140, 15)]);
}

#[test]
fn a_timeout_over_tcp_hints_at_the_connection_not_at_baud_rates() {
    // A server that accepts and never answers.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let address = listener.local_addr().expect("address").to_string();
    let held = std::thread::spawn(move || listener.accept().map(|(stream, _)| stream));
    let (code, _, stderr) = outcome(&[
        "read",
        "distance_1",
        "--tcp",
        &address,
        "--model",
        "p-series",
        "--timeout",
        "200ms",
    ]);
    assert_eq!(code, Some(FAILED), "{stderr}");
    assert!(
        stderr.contains("check the connection and --slave (on a serial line also --baud and --parity), or raise --timeout"),
        "{stderr}"
    );
    drop(held);
}
