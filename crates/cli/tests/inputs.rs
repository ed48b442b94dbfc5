//! Inputs that never panic and never reach the wire wrong: durations, slave addresses
//! (broadcast writes only), the device's own address, drastic registers, baud rates, parity
//! and scan lists. Every refusal is checked to come before anything is sent: with --verbose,
//! a frame sent would show as ` -> `, and a connection as the built-in simulator's line or a
//! "cannot open" / "cannot connect" error.

mod common;

use common::{ok, outcome, refused, words, Served, FAILED, REFUSED, USAGE};

/// `read distance_1 --sim-speed full --timeout text`: a refused timeout stops it before
/// anything is opened.
fn read_with_timeout(text: &str) -> [&str; 6] {
    // At memory speed: a 1 ms timeout is shorter than the simulated line's exchange.
    [
        "read",
        "distance_1",
        "--sim-speed",
        "full",
        "--timeout",
        text,
    ]
}

#[test]
fn durations_are_bounded_and_strict() {
    for (line, message) in [
        (
            "read distance_1 --timeout 9999999999999999999s",
            "--timeout 9999999999999999999s is too long: at most 24h",
        ),
        (
            "watch distance_1 --interval 9223372036854775807s",
            "--interval 9223372036854775807s is too long: at most 24h",
        ),
        (
            "read distance_1 --timeout 0",
            "--timeout 0 is too short: at least 1ms",
        ),
        (
            "watch distance_1 --interval 0",
            "--interval 0 is too short: at least 1ms",
        ),
        ("read distance_1 --timeout 25h", "at most 24h"),
        (
            "read distance_1 --timeout -1s",
            "--timeout cannot be negative",
        ),
        ("read distance_1 --timeout NaN", "`NaN` is not a duration"),
        ("read distance_1 --timeout 1e400s", "is not a duration"),
        ("read distance_1 --timeout 1.5.2s", "is not a duration"),
        (
            "buffer --count 10 --wait 100000s",
            "--wait 100000s is too long: at most 24h",
        ),
        (
            "simulate --duration 2000m",
            "--duration 2000m is too long: at most 24h",
        ),
        ("simulate --duration -1s", "cannot be negative"),
    ] {
        refused(&words(line), USAGE, message);
    }
    // Anything else that is no duration within the bounds: refused as a usage error.
    for text in [
        "999us",
        "nan s",
        "inf",
        "1e3",
        "",
        ".5s",
        "1.s",
        "1..2s",
        "24.000001h",
        "340282366920938463463374607431768211456s",
        "99999999999999999999999999999999999999999999",
        "1 fortnight",
    ] {
        refused(&read_with_timeout(text), USAGE, "--timeout");
    }
    // Exact to the nanosecond, a bare number is milliseconds; the bounds themselves are fine.
    for text in ["200ms", "1.5s", "250", "2m", "0.1s", "1000us", "1s 500ms"] {
        ok(&read_with_timeout(text));
    }
    ok(&["read", "distance_1", "--timeout", "24h"]);
    // The value itself, as `watch` shows its interval.
    for (text, shown) in [
        ("1.5s", "every 1500 ms"),
        ("250", "every 250 ms"),
        ("2000us", "every 2 ms"),
    ] {
        let stdout = ok(&["watch", "distance_1", "--count", "1", "--interval", text]);
        assert!(stdout.contains(shown), "{text}: {stdout}");
    }
    ok(&read_with_timeout("1ms"));
    ok(&["watch", "distance_1", "--count", "1", "--interval", "0.5s"]);
}

#[test]
fn slaves_248_to_255_are_refused() {
    for slave in 248..=255u16 {
        let slave = slave.to_string();
        refused(
            &["read", "distance_1", "--slave", &slave],
            USAGE,
            "Modbus reserves 248 to 255",
        );
        refused(
            &["set", "light_power", "42", "--slave", &slave],
            USAGE,
            "Modbus reserves 248 to 255",
        );
    }
    for (line, message) in [
        (
            "frame encode p-series set light_power 42 --slave 248",
            "Modbus reserves 248 to 255",
        ),
        ("read distance_1 --slave 256", "addresses are 0 to 247"),
        ("read distance_1 --slave -1", "`-1` is not a slave address"),
    ] {
        refused(&words(line), USAGE, message);
    }
}

#[test]
fn slave_0_is_for_writes_only() {
    // Reads need a reply: refused before connecting (a missing port would say so first).
    for args in [
        vec!["read", "distance_1"],
        vec!["watch", "distance_1", "--count", "1"],
        vec!["dump"],
        vec!["buffer", "--count", "10"],
        vec![
            "--model",
            "p-series",
            "read",
            "distance_1",
            "--serial",
            "/dev/nonexistent-port",
        ],
        vec!["--model", "p-series", "dump", "--tcp", "127.0.0.1:1"],
    ] {
        let mut args = args.clone();
        args.extend(["--slave", "0"]);
        refused(
            &args,
            REFUSED,
            "no device answers slave 0, the broadcast address",
        );
    }
    refused(
        &[
            "--model",
            "p-series",
            "scan",
            "--serial",
            "/dev/nonexistent-port",
            "--slave",
            "0",
        ],
        REFUSED,
        "no device answers slave 0",
    );
    refused(
        &["simulate", "--tcp", "127.0.0.1:0", "--slave", "0"],
        REFUSED,
        "a device never has slave address 0",
    );
    refused(
        &[
            "frame",
            "encode",
            "p-series",
            "read",
            "distance_1",
            "--slave",
            "0",
        ],
        REFUSED,
        "a read sent to slave 0, the broadcast address, gets no reply",
    );
    // A broadcast write is encoded like any write.
    let text = ok(&[
        "frame",
        "encode",
        "p-series",
        "set",
        "light_power",
        "42.5",
        "--slave",
        "0",
    ]);
    assert!(text.contains("\n00 06 00 02 01 A9 E8 35"), "{text}");
    // Modbus TCP has no broadcast: refused before connecting.
    refused(
        &[
            "--model",
            "p-series",
            "set",
            "light_power",
            "42",
            "--tcp",
            "127.0.0.1:1",
            "--slave",
            "0",
        ],
        REFUSED,
        "Modbus TCP has no broadcast",
    );
}

#[test]
fn broadcast_writes_are_sent_once_and_not_waited_for() {
    let served = Served::start(&["p-series", "--pty", "--slave", "3"]);
    let (code, stdout, stderr) = outcome(&words(
        &served.serial("set light_power 42.5 --verbose --slave 0"),
    ));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        stdout.trim(),
        "light_power  42.5 %: broadcast sent, no reply expected"
    );
    assert_eq!(stderr.matches(" -> ").count(), 1, "one frame: {stderr}");
    assert!(stderr.contains(" -> 00 06 00 02 01 A9 E8 35"), "{stderr}");
    assert!(!stderr.contains(" <- "), "no reply read: {stderr}");
    // The device at slave 3 carried it out.
    let values = common::json(&words(&served.serial("read light_power --slave 3")));
    assert_eq!(values["light_power"]["value"], "42.5");
    let (code, stdout, stderr) = outcome(&words(&served.serial("do zero_position_1 --slave 0")));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(
        stdout.trim(),
        "zero_position_1: broadcast sent, no reply expected"
    );
    let json = common::json(&["do", "zero_position_1", "--slave", "0"]);
    assert_eq!(json["broadcast"], true);
    // Drastic commands still need --yes when broadcast.
    refused(&["do", "reboot", "--slave", "0"], REFUSED, "--yes");
}

/// `set slave_address 7 --verbose` on `model` served at slave 3 over a pty: the device
/// (kept alive) and the tool's stderr, after checking the printed read-back.
fn set_slave_address_7(model: &str) -> (Served, String) {
    let served = Served::start(&[model, "--pty", "--slave", "3"]);
    let line = format!(
        "--model {model} set slave_address 7 --verbose --serial {} --slave 3",
        served.at
    );
    let (code, stdout, stderr) = outcome(&words(&line));
    assert_eq!(code, Some(0), "{stderr}");
    assert_eq!(stdout.trim(), "slave_address  7");
    (served, stderr)
}

#[test]
fn a_new_slave_address_is_read_back_where_the_device_answers() {
    // P series: the address applies at once; the read-back goes to the new address.
    let (served, stderr) = set_slave_address_7("p-series");
    assert!(stderr.contains(" -> 03 06 00 1F 00 07"), "{stderr}");
    assert!(stderr.contains(" -> 07 03 00 1F 00 01"), "{stderr}");
    assert!(stderr.contains("now answers at slave 7"), "{stderr}");
    let values = common::json(&words(&served.serial("read slave_address --slave 7")));
    assert_eq!(values["slave_address"], 7);
    // LC-RS: only after save and a power cycle; the read-back goes to the old address.
    let (_served, stderr) = set_slave_address_7("lc-rs");
    assert!(stderr.contains(" -> 03 03 00 85 00 01"), "{stderr}");
    assert!(
        stderr.contains("the new address 7 applies after save") && stderr.contains("power cycle"),
        "{stderr}"
    );
    // Addresses a device cannot have.
    for value in ["0", "248", "255", "256"] {
        refused(
            &["set", "slave_address", value],
            REFUSED,
            "`slave_address` does not take",
        );
    }
}

#[test]
fn set_of_a_drastic_register_needs_yes() {
    refused(
        &["set", "save_parameters", "1"],
        REFUSED,
        "writing 1 to `save_parameters` runs `save_parameters`",
    );
    refused(
        &["set", "network_reset_or_reboot", "170"],
        REFUSED,
        "runs `reboot`",
    );
    refused(
        &["set", "network_reset_or_reboot", "1"],
        REFUSED,
        "runs `reset_network`",
    );
    let error = refused(
        &["--model", "lc-rs", "set", "factory_reset", "5"],
        REFUSED,
        "`factory_reset` is the register of `factory_reset`",
    );
    assert!(error.contains("--yes"), "{error}");
    assert_eq!(
        ok(&["set", "save_parameters", "1", "--yes"]).trim(),
        "save_parameters  idle (0)"
    );
    // Other registers need no confirmation.
    ok(&["set", "light_power", "42.5"]);
}

#[test]
fn baud_rates_come_from_the_manual_unless_any_baud() {
    // A port that does not exist: a refusal must come before trying to open it.
    let port = "/dev/nonexistent-port";
    for (line, message) in [
        (
            "read distance_1 --baud 1",
            "--baud 1 is no baud rate a serial line can use: 50 to 4000000",
        ),
        (
            "read distance_1 --baud 0 --any-baud",
            "--baud 0 is no baud rate",
        ),
        (
            "read distance_1 --baud 5000000 --any-baud",
            "--baud 5000000 is no baud rate",
        ),
        (
            "read distance_1 --baud 14400",
            "its manual lists 9600, 19200, 38400, 57600, 115200; --any-baud",
        ),
        (
            "--model ccf dump --baud 9600",
            "ccf does not list 9600 baud",
        ),
        ("set light_power 42 --baud 1", "--baud 1 is no baud rate"),
        ("buffer --count 10 --baud 1", "--baud 1 is no baud rate"),
        ("scan --bauds 9600,1", "--bauds 1 is no baud rate"),
        ("scan --bauds 14400", "p-series does not list 14400 baud"),
        ("scan --baud 1", "--baud 1 is no baud rate"),
    ] {
        let args = words(line);
        let mut args = args.clone();
        if !args.contains(&"--model") {
            args.extend(["--model", "p-series"]);
        }
        args.extend(["--serial", port]);
        refused(&args, REFUSED, message);
    }
    for (line, message) in [
        ("simulate --pty --baud 0", "--baud 0 is no baud rate"),
        ("simulate --pty --baud 14400", "does not list 14400 baud"),
    ] {
        refused(&words(line), REFUSED, message);
    }
    refused(
        &["read", "distance_1", "--baud", "nine"],
        USAGE,
        "invalid value 'nine'",
    );
    // Accepted rates get as far as the port.
    for args in [
        vec!["read", "distance_1", "--baud", "14400", "--any-baud"],
        vec![
            "--model",
            "rangefinder",
            "read",
            "distance",
            "--baud",
            "14400",
        ],
        vec!["read", "distance_1", "--baud", "9600"],
    ] {
        let mut args = args.clone();
        if !args.contains(&"--model") {
            args.extend(["--model", "p-series"]);
        }
        args.extend(["--serial", port]);
        let (code, _, stderr) = outcome(&args);
        assert_eq!(code, Some(FAILED), "{args:?}");
        assert!(stderr.contains("cannot open"), "{args:?}: {stderr}");
    }
}

#[test]
fn parity_is_checked_without_serial_too() {
    refused(
        &["read", "distance_1", "--parity", "x"],
        USAGE,
        "invalid value 'x' for '--parity <PARITY>'",
    );
    for parity in ["none", "n", "Even", "e", "ODD", "o"] {
        ok(&["read", "distance_1", "--parity", parity]);
    }
}

#[test]
fn scan_lists_are_strict() {
    let port = "/dev/nonexistent-port";
    for (list, message) in [
        ("", "--slaves is empty"),
        ("1,", "has an empty item"),
        ("1,,3", "has an empty item"),
        ("10-1", "the range `10-1` runs backwards"),
        ("1,1", "lists address 1 twice"),
        ("1-5,3", "lists address 3 twice"),
        ("0-3", "0 is no device address"),
        ("240-250", "250 is no device address"),
        ("x", "`x` is not an address or a range"),
    ] {
        refused(
            &[
                "--model", "p-series", "scan", "--serial", port, "--slaves", list,
            ],
            REFUSED,
            message,
        );
    }
    for (list, message) in [
        ("9600,", "has an empty item"),
        ("", "has an empty item"),
        ("9600,9600", "lists 9600 twice"),
        ("fast", "`fast` is not a baud rate"),
    ] {
        refused(
            &[
                "--model", "p-series", "scan", "--serial", port, "--bauds", list,
            ],
            REFUSED,
            message,
        );
    }
    // A good list gets as far as the port.
    let (code, _, stderr) = outcome(&[
        "--model",
        "p-series",
        "scan",
        "--serial",
        port,
        "--bauds",
        "9600,115200",
        "--slaves",
        "1-3,7",
    ]);
    assert_eq!(code, Some(FAILED));
    assert!(stderr.contains("cannot open"), "{stderr}");
}

#[test]
fn buffer_counts_and_sources_are_checked_before_connecting() {
    for count in ["0", "2501", "65535", "65536"] {
        refused(
            &["buffer", "--count", count],
            REFUSED,
            "the P series buffers 1 to 2500 values",
        );
    }
    refused(
        &["buffer", "--count", "10", "--source", "nothing"],
        REFUSED,
        "`buffer_data_type` does not take `nothing`",
    );
    refused(
        &["buffer", "--count", "4294967296"],
        USAGE,
        "invalid value '4294967296'",
    );
}
