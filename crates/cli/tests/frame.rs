//! `optobus frame encode` and `optobus frame decode`, run as a user runs them. Expected bytes
//! are the manuals' own frames (tests/golden/*.yaml).

mod common;

use common::{fails, ok, refused, words, USAGE};
use serde_json::Value;

/// Stdout of a successful `optobus frame decode args…`.
fn decode(args: &[&str]) -> String {
    ok(&[&["frame", "decode"], args].concat())
}

/// The hex lines of `frame encode` text output, in order.
fn hex_lines(stdout: &str) -> Vec<&str> {
    stdout
        .lines()
        .filter(|line| !line.starts_with('#') && !line.trim().is_empty())
        .collect()
}

/// `optobus frame encode ARGS` prints exactly `frames` (hex lines), in order; gives stdout.
fn encodes(args: &[&str], frames: &[&str]) -> String {
    let mut command = vec!["frame", "encode"];
    command.extend(args);
    let stdout = ok(&command);
    assert_eq!(hex_lines(&stdout), frames, "{args:?}");
    stdout
}

fn json(stdout: &str) -> Value {
    serde_json::from_str(stdout).unwrap_or_else(|error| panic!("not JSON ({error}): {stdout}"))
}

#[test]
fn encode_read_of_a_register() {
    let stdout = encodes(
        &["p-series", "read", "distance_1"],
        &["01 04 00 00 00 02 71 CB"],
    );
    assert!(stdout.contains("# read input 0-1 (distance_1)"), "{stdout}");
}

#[test]
fn encode_read_of_a_group_is_the_manuals_5_4_request() {
    encodes(
        &["p-series", "read", "buffer_page"],
        &["01 04 00 10 00 7A 70 2C"],
    );
}

#[test]
fn encode_json_lists_frames_with_descriptions() {
    let stdout = ok(&["--json", "frame", "encode", "p", "read", "measurements"]);
    let value = json(&stdout);
    assert_eq!(value["frames"][0]["hex"], "01 04 00 00 00 0A 70 0D");
    let description = value["frames"][0]["description"]
        .as_str()
        .unwrap_or_default();
    assert!(
        description.contains("distance_1 .. statistic_2"),
        "{description}"
    );
    assert_eq!(value["frames"].as_array().map(Vec::len), Some(1));
}

#[test]
fn encode_rangefinder_group_is_one_request_per_field() {
    // 3.1 and 3.4: the rangefinder's example slave is its default, 25.
    let stdout = ok(&["frame", "encode", "rangefinder", "read", "status"]);
    let lines = hex_lines(&stdout);
    assert_eq!(lines.first(), Some(&"19 03 00 00 00 01 87 D2"));
    assert!(lines.contains(&"19 03 00 02 00 02 66 13"), "{stdout}");
}

#[test]
fn encode_writes_as_the_manuals_do() {
    let cases: [(&[&str], &[&str]); 4] = [
        // 5.2.1.
        (
            &["p-series", "set", "sampling_interval", "100us"],
            &["01 06 00 06 00 14 69 C4"],
        ),
        // 4.1.2 note 4: slope 2.0 = 0x0020_0000, register 28 (low word) first, then 27.
        (
            &["p-series", "set", "position_1_slope", "2"],
            &["01 06 00 1C 00 00 48 0C", "01 06 00 1B 00 20 F8 15"],
        ),
        // Negative values are values, not options: -0.5 mm = -500000 nm, low word first.
        (
            &["p-series", "set", "position_1_offset", "-0.5"],
            &["01 06 00 1E 5E E0 D0 24", "01 06 00 1D FF F8 59 BE"],
        ),
        // Rangefinder 3.7: odd parity, 57600 baud, one FC06 with 4 data bytes.
        (
            &[
                "rangefinder",
                "set",
                "serial_parameters",
                "parity=odd,baud_rate=57600",
            ],
            &["19 06 00 04 01 00 E1 00 5F 01"],
        ),
    ];
    for (args, frames) in cases {
        encodes(args, frames);
    }
    let value = json(&ok(&words(
        "frame encode p-series set position_1_slope 2 --json",
    )));
    let first = value["frames"][0]["description"]
        .as_str()
        .unwrap_or_default();
    assert!(
        first.contains("low word") && first.contains("1 of 2"),
        "{first}"
    );
}

#[test]
fn encode_refuses_invalid_requests() {
    for (line, message) in [
        ("p-series set light_power 250", "0.5 % ..= 100.0 %"),
        ("p-series set distance_1 1", "read-only"),
        ("p-series read no_such_register", "no_such_register"),
        ("p-series set laser 1", "is a group"),
        ("ccf set exposure_time 100us", "--channel 1 to 4"),
    ] {
        let args = words(line);
        let mut command = vec!["frame", "encode"];
        command.extend(&args);
        let stderr = fails(&command);
        assert!(stderr.contains(message), "{args:?}: {stderr}");
    }
    encodes(
        &["ccf", "set", "exposure_time", "100us", "--channel", "2"],
        &["01 06 00 0A 03 E8 A9 76"],
    );
}

#[test]
fn encode_slave_and_channel() {
    let frame = ["07 03 00 12 00 01 24 69"];
    encodes(
        &[
            "ccf",
            "read",
            "exposure_time",
            "--channel",
            "3",
            "--slave",
            "7",
        ],
        &frame,
    );
    let stdout = ok(&words(
        "frame encode ccf read exposure_time --channel 3 --slave 7",
    ));
    assert_eq!(hex_lines(&stdout), frame);
}

#[test]
fn encode_modbus_tcp_frames() {
    // 5.2.2's frame, with transaction 1 rather than the manual's 0.
    encodes(
        &["p-series", "set", "sampling_interval", "100us", "--mbap"],
        &["00 01 00 00 00 06 01 06 00 06 00 14"],
    );
    // Transaction ids count up.
    let stdout = ok(&words(
        "frame encode p-series set position_1_slope 2 --mbap",
    ));
    assert_eq!(
        hex_lines(&stdout),
        [
            "00 01 00 00 00 06 01 06 00 1C 00 00",
            "00 02 00 00 00 06 01 06 00 1B 00 20"
        ]
    );
    // --tcp names a device to talk to, which `frame` never does: no framing switch.
    refused(
        &words("frame encode p-series set position_1_slope 2 --tcp 192.0.2.1"),
        USAGE,
        "unexpected argument '--tcp': it says how to reach a device, and this command reaches \
         none (`frame` writes Modbus TCP frames with --mbap)",
    );
    let stderr = fails(&["frame", "encode", "p-series", "read", "laser", "--tcp=x"]);
    assert!(!stderr.contains("tip:"), "{stderr}");
}

#[test]
fn decode_names_registers_of_a_golden_reply() {
    // 5.3.1: the request and its reply, as captured on the line.
    let stdout = decode(&[
        "p-series",
        "01 04 00 00 00 06 70 08",
        "01 04 0C 00 36 B0 BE 00 20 24 5C 00 56 D3 04 41 47",
    ]);
    assert!(stdout.contains("distance_1 = 3.584190 mm"), "{stdout}");
    assert!(stdout.contains("thickness = 5.690116 mm"), "{stdout}");
    // The README's example: the reply alone, placed at the first address that fits.
    let stdout = decode(&[
        "p-series", "01", "04", "0C", "00", "36", "B0", "BE", "00", "20", "24", "5C", "00", "56",
        "D3", "04", "41", "47",
    ]);
    assert!(
        stdout.contains("input 0-1: distance_1 = 3.584190 mm"),
        "{stdout}"
    );
    assert!(stdout.contains("assumed"), "{stdout}");
    // A lone reply, placed with --address, in one string without spaces.
    let stdout = decode(&[
        "p-series",
        "01040C0036B0BE0020245C0056D3044147",
        "--address",
        "0",
        "--json",
    ]);
    let value = json(&stdout);
    let frame = &value["frames"][0];
    assert_eq!(frame["kind"], "read_reply");
    assert_eq!(frame["registers"][0]["name"], "distance_1");
    assert_eq!(frame["registers"][0]["text"], "3.584190 mm");
    assert_eq!(frame["crc"]["ok"], true);
}

#[test]
fn decode_flags_a_wrong_crc_and_gives_the_right_one() {
    let stdout = decode(&["p-series", "0x01 0x04 0x00 0x00 0x00 0x02 0x71 0xCC"]);
    assert!(stdout.contains("CRC wrong"), "{stdout}");
    assert!(stdout.contains("71 CB"), "{stdout}");
    let value = json(&decode(&["p-series", "01 04 00 00 00 02 71 CC", "--json"]));
    assert_eq!(value["frames"][0]["crc"]["ok"], false);
    assert_eq!(value["frames"][0]["crc"]["expected"], "71 CB");
}

#[test]
fn decode_a_write_and_its_echo() {
    let stdout = decode(&[
        "p-series",
        "01 06 00 06 00 14 69 C4 01 06 00 06 00 14 69 C4",
    ]);
    assert!(
        stdout.contains("sampling_interval = us_100 (20)"),
        "{stdout}"
    );
    assert!(stdout.contains("write reply (echo)"), "{stdout}");
}

#[test]
fn decode_rangefinder_four_byte_write() {
    let value = json(&decode(&[
        "rangefinder",
        "19 06 00 04 01 00 E1 00 5F 01",
        "--json",
    ]));
    let frame = &value["frames"][0];
    assert_eq!(frame["hex"], "19 06 00 04 01 00 E1 00 5F 01");
    assert_eq!(frame["crc"]["ok"], true);
    assert_eq!(frame["registers"][0]["name"], "serial_parameters");
    assert_eq!(frame["registers"][0]["value"]["baud_rate"], 57600);
}

#[test]
fn decode_lc_rs_seven_byte_exception() {
    let stdout = ok(&["frame", "decode", "lc-rs", "01 83 02 00 01 50 44"]);
    assert!(stdout.contains("exception reply"), "{stdout}");
    assert!(stdout.contains("register_address_error"), "{stdout}");
    assert!(stdout.contains("correct"), "{stdout}");
}

#[test]
fn decode_modbus_tcp_pair() {
    // 5.3.2: request and reply with their MBAP headers.
    let stdout = decode(&[
        "p-series",
        "--mbap",
        "00 00 00 00 00 06 01 04 00 00 00 06",
        "00 00 00 00 00 0F 01 04 0C 00 35 CB 69 00 1F 3A 6C 00 2A 05 D5",
    ]);
    assert!(stdout.contains("transaction 0"), "{stdout}");
    assert!(stdout.contains("distance_1 = 3.525481 mm"), "{stdout}");
}

#[test]
fn decode_refuses_bad_input_clearly() {
    for (model, bytes, message) in [
        ("p-series", "01 0G", "not hex"),
        ("p-series", "01 04 00", "too short"),
        (
            "p-series",
            "01 04 00 00 00 02",
            "too short for a read request",
        ),
        ("p-series", "00 00 00 00 00 06 01 03 00 00 00 03", "--mbap"),
        ("no-such-model", "01", "unknown model"),
    ] {
        let stderr = fails(&["frame", "decode", model, bytes]);
        assert!(stderr.contains(message), "{bytes}: {stderr}");
    }
}
