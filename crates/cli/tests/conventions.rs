//! The command line's conventions: negative values without `--`, device options only where a
//! device is reached, `frame` naming its model once, the line format options, raw access by
//! address, units converted by SI prefix, `scan`'s output and stop, the built-in simulator's
//! short memory, and the exit codes.

mod common;

use common::{json, ok, outcome, refused, words, Served, FAILED, REFUSED, USAGE};

/// The device options, as `--help` shows them.
const DEVICE_OPTIONS: [&str; 10] = [
    "--serial",
    "--baud",
    "--parity",
    "--data-bits",
    "--stop-bits",
    "--tcp",
    "--slave",
    "--timeout",
    "--any-baud",
    "--verbose",
];

fn help(command: &str) -> String {
    let mut args = words(command);
    args.push("--help");
    ok(&args)
}

#[test]
fn negative_values_need_no_double_dash() {
    let values = json(&["set", "position_1_offset", "-1.5"]);
    assert_eq!(values["position_1_offset"]["value"], "-1.500000");
    let values = json(&["set", "position_1_offset", "-1500um"]);
    assert_eq!(values["position_1_offset"]["value"], "-1.500000");
    let text = ok(&[
        "frame",
        "encode",
        "p-series",
        "set",
        "position_1_offset",
        "-1",
    ]);
    // -1 mm is -1000000 nm: 0xFFF0BDC0 as two FC06 writes.
    assert!(text.contains("FF F0") && text.contains("BD C0"), "{text}");
}

#[test]
fn device_options_show_only_on_commands_that_reach_a_device() {
    for command in [
        "models",
        "registers",
        "frame encode",
        "frame decode",
        "plot",
    ] {
        let text = help(command);
        for option in DEVICE_OPTIONS {
            assert!(!text.contains(option), "`{command} --help` shows {option}");
        }
    }
    // Nor `--model` where no model is taken, or where `frame` names it itself.
    for command in ["models", "plot", "frame", "frame encode", "frame decode"] {
        assert!(
            !help(command).contains("--model"),
            "`{command} --help` shows --model"
        );
    }
    assert!(help("read").contains("--model"));
    for command in [
        "read",
        "watch",
        "dump",
        "set",
        "do",
        "buffer",
        "scan",
        "simulate",
        "raw read",
        "raw write",
    ] {
        let text = help(command);
        for option in DEVICE_OPTIONS {
            assert!(text.contains(option), "`{command} --help` lacks {option}");
        }
    }
    // Given to a command that reaches no device, a device option is a usage error.
    refused(
        &words("registers --serial /dev/ttyUSB0"),
        USAGE,
        "'--serial'",
    );
    refused(&words("models --tcp 127.0.0.1"), USAGE, "'--tcp'");
}

#[test]
fn point_8_an_option_of_other_commands_names_them() {
    let stderr = refused(
        &words("read distance_1 --interval 100ms"),
        USAGE,
        "unexpected argument '--interval': it belongs to `watch` and `record`",
    );
    assert!(!stderr.contains("similar argument"), "{stderr}");
    refused(
        &words("dump --chart"),
        USAGE,
        "unexpected argument '--chart': it belongs to `watch`",
    );
    // A subcommand's own option is named with its path; `=value` is the same option.
    refused(
        &words("read distance_1 --count=3"),
        USAGE,
        "it belongs to `watch`, `record`, `buffer` and `raw read`",
    );
}

#[test]
fn frame_names_its_model_once() {
    for command in ["frame encode", "frame decode"] {
        let text = help(command);
        assert!(text.contains("<MODEL>"), "{text}");
        assert!(!text.contains("--model"), "`{command} --help`: {text}");
    }
    // --slave of an encoded frame belongs to the request, not to a device.
    let text = ok(&words("frame encode ccs read distance_1 --slave 7"));
    assert!(
        text.lines().any(|l| l == "07 04 00 00 00 02 71 AD"),
        "{text}"
    );
}

#[test]
fn data_and_stop_bits_shape_the_line() {
    for (args, message) in [
        ("read distance_1 --data-bits 4", "'--data-bits <DATA_BITS>'"),
        ("read distance_1 --data-bits 9", "5..=8"),
        ("read distance_1 --stop-bits 0", "1..=2"),
        ("read distance_1 --stop-bits 3", "1..=2"),
    ] {
        refused(&words(args), USAGE, message);
    }
    // The timed line of the simulator reports the format it was given, from the factory 8N1.
    let (code, _, stderr) = outcome(&words(
        "simulate p-series --pty --line-timing --data-bits 7 --parity even --stop-bits 2 --duration 0",
    ));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.contains("line timed at 115200 baud 7E2"), "{stderr}");
    let (_, _, stderr) = outcome(&words("simulate p-series --pty --line-timing --duration 0"));
    assert!(stderr.contains("line timed at 115200 baud 8N1"), "{stderr}");
}

#[test]
fn raw_access_reads_and_writes_words_by_address() {
    let served = Served::start(&["p-series", "--tcp", "127.0.0.1:0"]);
    let at = served.at.as_str();
    // light_power is holding 2 in steps of 0.1 %.
    ok(&words(&format!(
        "--model p-series set light_power 42.5 --tcp {at}"
    )));
    let text = ok(&[
        "--model", "p-series", "raw", "read", "holding", "2", "--tcp", at,
    ]);
    assert_eq!(text.trim(), "holding 0x0002 (2)  0x01A9 (425)");
    let read = json(&[
        "--model", "p-series", "raw", "read", "holding", "0x1", "--count", "2", "--tcp", at,
    ]);
    assert_eq!(read["table"], "holding");
    assert_eq!(read["words"][1]["address"], 2);
    assert_eq!(read["words"][1]["value"], 425);
    let text = ok(&[
        "--model", "p-series", "raw", "write", "20", "1", "--yes", "--tcp", at,
    ]);
    assert_eq!(text.trim(), "holding 0x0014 (20)  0x0001 (1): written");
    let text = ok(&[
        "--model", "p-series", "raw", "write", "0x0002", "300", "--tcp", at,
    ]);
    assert_eq!(text.trim(), "holding 0x0002 (2)  0x012C (300): written");
    let values = json(&["--model", "p-series", "read", "light_power", "--tcp", at]);
    assert_eq!(values["light_power"]["value"], "30.0");
    // The device's own refusal (an address it lacks) is the device's failure, exit 1.
    let (code, _, stderr) = outcome(&[
        "--model", "p-series", "raw", "read", "input", "0x7000", "--tcp", at,
    ]);
    assert_eq!(code, Some(FAILED), "{stderr}");
    assert!(stderr.contains("input 0x7000 (28672)"), "{stderr}");
}

#[test]
fn raw_access_refuses_before_the_wire() {
    for (args, message) in [
        (
            "raw read holding 0 --count 0",
            "--count 0: p-series reads 1 to 125 words",
        ),
        ("raw read holding 0 --count 126", "--count 126"),
        (
            "raw read input 0xFFFF --count 2",
            "2 words from 0xFFFF (65535) run past the last address",
        ),
        (
            "raw read holding 65536",
            "`65536` is too large for a register address",
        ),
        (
            "raw read holding twelve",
            "`twelve` is not a register address",
        ),
        (
            "raw write 2 0x10000",
            "`0x10000` is too large for a register value",
        ),
        ("raw write 2 -1", "`-1` is not a register value"),
        ("raw write 2 1.5", "`1.5` is not a register value"),
        // Holding 20 is `save_parameters`: a raw write there is a save, and needs --yes.
        (
            "raw write 20 1",
            "writing 1 to `save_parameters` runs `save_parameters`",
        ),
        ("raw write 0x14 7", "add --yes to go ahead"),
    ] {
        refused(&words(args), REFUSED, message);
    }
    refused(&words("raw read coils 0"), USAGE, "'coils'");
}

#[test]
fn units_convert_by_si_prefix() {
    let values = json(&["--model", "ccs", "set", "exposure_time", "0.2ms"]);
    assert_eq!(values["exposure_time"]["value"], "200.0");
    assert_eq!(values["exposure_time"]["unit"], "us");
    refused(
        &["--model", "ccs", "set", "exposure_time", "0.00001ms"],
        REFUSED,
        "whole steps",
    );
    let values = json(&["set", "position_1_offset", "1.5 mm"]);
    assert_eq!(values["position_1_offset"]["value"], "1.500000");
}

#[test]
fn scan_json_is_json_only_and_stops_at_the_first_device() {
    let served = Served::start(&["p-series", "--pty", "--slave", "3"]);
    let scan = |extra: &[&str]| {
        let mut args = vec![
            "--model",
            "p-series",
            "scan",
            "--serial",
            &served.at,
            "--bauds",
            "115200",
            "--slaves",
            "2-5",
            "--json",
            "--verbose",
        ];
        args.extend(extra);
        outcome(&args)
    };
    // Found: the P series at slave 3, and only it; on stdout, JSON only.
    let found_slave_3 = |(code, stdout, stderr): (Option<i32>, String, String)| {
        assert_eq!(code, Some(0), "{stderr}");
        let found: serde_json::Value = serde_json::from_str(&stdout).expect("stdout is JSON only");
        assert_eq!(
            found,
            serde_json::json!([{"baud": 115200, "slave": 3, "model": "p-series"}])
        );
        stderr
    };
    let stderr = found_slave_3(scan(&[]));
    assert!(stderr.contains("found: slave 3 at 115200 baud"), "{stderr}");
    // Slave 2 and 3 were asked, 4 and 5 not.
    assert!(stderr.contains(" -> 02 03"), "{stderr}");
    assert!(stderr.contains(" -> 03 03"), "{stderr}");
    assert!(!stderr.contains(" -> 04 03"), "{stderr}");
    // --all goes on to the end of the list.
    let stderr = found_slave_3(scan(&["--all"]));
    assert!(stderr.contains(" -> 05 03"), "{stderr}");
}

#[test]
fn writes_to_the_built_in_simulator_say_they_do_not_last() {
    for args in [
        &["set", "light_power", "42.5"][..],
        &["do", "zero_position_1"][..],
        &["raw", "write", "2", "300"][..],
    ] {
        let (code, _, stderr) = outcome(args);
        assert_eq!(code, Some(0), "{stderr}");
        assert!(
            stderr.contains("lasts for this") && stderr.contains("`optobus simulate`"),
            "{args:?}: {stderr}"
        );
    }
    // Reads say nothing of it; a served simulator keeps its state.
    let (_, _, stderr) = outcome(&["read", "light_power"]);
    assert!(!stderr.contains("lasts for this"), "{stderr}");
    let served = Served::start(&["p-series", "--tcp", "127.0.0.1:0"]);
    let (_, _, stderr) = outcome(&words(&format!(
        "--model p-series set light_power 42.5 --tcp {}",
        served.at
    )));
    assert!(!stderr.contains("lasts for this"), "{stderr}");
}

#[test]
fn exit_codes_tell_failure_usage_and_refusal_apart() {
    let text = ok(&["--help"]);
    assert!(text.contains("Exit codes: 0 done; 1 the device"), "{text}");
    assert_eq!(outcome(&["read", "distance_1"]).0, Some(0));
    // Usage: clap's code.
    assert_eq!(outcome(&["read"]).0, Some(USAGE));
    assert_eq!(
        outcome(&["read", "distance_1", "--baud", "fast"]).0,
        Some(USAGE)
    );
    // Refused before anything was sent.
    assert_eq!(outcome(&["read", "no_such_register"]).0, Some(REFUSED));
    assert_eq!(outcome(&["set", "light_power", "101"]).0, Some(REFUSED));
    assert_eq!(outcome(&["do", "reboot"]).0, Some(REFUSED));
    // The device or the line failed: nothing listens on port 1; a silent slave times out.
    let (code, _, stderr) = outcome(&[
        "--model",
        "p-series",
        "read",
        "distance_1",
        "--tcp",
        "127.0.0.1:1",
    ]);
    assert_eq!(code, Some(FAILED), "{stderr}");
    let served = Served::start(&["p-series", "--pty", "--slave", "3"]);
    let (code, _, stderr) = outcome(&words(
        &served.serial("read laser --slave 9 --timeout 50ms"),
    ));
    assert_eq!(code, Some(FAILED), "{stderr}");
    assert!(stderr.contains("no reply within 50 ms"), "{stderr}");
}

#[test]
fn point_10_files_and_ports_the_system_cannot_give_exit_1() {
    // A listen port another server holds.
    let busy = std::net::TcpListener::bind("127.0.0.1:0").expect("a free port");
    let at = busy.local_addr().expect("its address").to_string();
    let (code, _, stderr) = outcome(&["simulate", "--tcp", &at, "--duration", "1s"]);
    assert_eq!(code, Some(FAILED), "{stderr}");
    assert!(
        stderr.contains(&format!("cannot listen on {at}")),
        "{stderr}"
    );
    // A --spec file that is not there.
    let (code, _, stderr) = outcome(&["--spec", "/nonexistent/spec.yaml", "registers"]);
    assert_eq!(code, Some(FAILED), "{stderr}");
    assert!(
        stderr.contains("cannot read /nonexistent/spec.yaml"),
        "{stderr}"
    );
    // A recording that is not there.
    let missing = std::env::temp_dir().join("optobus-no-such-recording.csv");
    let missing = missing.display().to_string();
    let out = std::env::temp_dir().join("optobus-never-drawn.svg");
    let (code, _, stderr) = outcome(&["plot", &missing, "--out", &out.display().to_string()]);
    assert_eq!(code, Some(FAILED), "{stderr}");
    assert!(
        stderr.contains(&format!("cannot read {missing}")),
        "{stderr}"
    );
}
