//! `optobus record` and `optobus run --record`: samples of registers or groups in a CSV
//! file, against the built-in simulator or a device that answers zeros: the header names each
//! column's unit (a column per field of a record or packed register), every row has an RFC
//! 3339 time, the elapsed seconds and one value per column, `NaN` where a reading is invalid
//! and nothing where the row's poll did not read the column.

mod common;

use common::{ok, outcome, refused, REFUSED, USAGE};

/// A file in the temporary directory, unique to this test process.
fn scratch(name: &str) -> String {
    std::env::temp_dir()
        .join(format!("optobus-record-{}-{name}", std::process::id()))
        .display()
        .to_string()
}

/// The rows of a recorded file, split into cells; the header first.
fn rows(path: &str) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(path).expect("the file was written");
    let _ = std::fs::remove_file(path);
    text.lines()
        .map(|line| line.split(',').map(str::to_owned).collect())
        .collect()
}

/// Checks a data row: its time, its elapsed seconds (not before `after`), and that every
/// value is a number (`NaN` for a reading the device marked invalid) or empty (not read); gives
/// the elapsed seconds.
fn sample(row: &[String], columns: usize, after: f64) -> f64 {
    assert_eq!(row.len(), columns, "{row:?}");
    let time: Result<jiff::Timestamp, _> = row[0].parse();
    assert!(time.is_ok(), "not RFC 3339: {}", row[0]);
    let elapsed: f64 = row[1].parse().expect("elapsed seconds");
    assert!(elapsed >= after, "{row:?}");
    for value in row[2..].iter().filter(|v| !v.is_empty()) {
        let number: f64 = value
            .parse()
            .unwrap_or_else(|_| panic!("{value} in {row:?}"));
        assert!(number.is_finite() || value == "NaN", "{row:?}");
    }
    elapsed
}

#[test]
fn count_samples_of_a_group_with_units_in_the_header() {
    let out = scratch("group.csv");
    ok(&["record", "measurements", "--count", "5", "--out", &out]);
    let rows = rows(&out);
    assert_eq!(
        rows[0].join(","),
        "time,elapsed [s],distance_1 [mm],distance_2 [mm],thickness [mm],statistic_1 [mm],statistic_2 [mm]"
    );
    assert_eq!(rows.len(), 6, "{rows:?}");
    let mut after = 0.0;
    for row in &rows[1..] {
        after = sample(row, 7, after);
    }
}

#[test]
fn a_duration_at_an_interval() {
    let out = scratch("interval.csv");
    ok(&[
        "record",
        "distance_1",
        "--duration",
        "450ms",
        "--interval",
        "100ms",
        "--out",
        &out,
    ]);
    let rows = rows(&out);
    assert_eq!(rows[0].join(","), "time,elapsed [s],distance_1 [mm]");
    // Samples start 100 ms apart: at 0, 0.1, 0.2, 0.3 and 0.4 s (a slow machine may fit fewer).
    assert!((3..=6).contains(&rows.len()), "{rows:?}");
    let mut after = 0.0;
    for row in &rows[1..] {
        let elapsed = sample(row, 3, after);
        assert!(elapsed < 0.45, "{row:?}");
        after = elapsed + 0.099;
    }
}

#[test]
fn an_end_is_required_and_checked() {
    let out = scratch("refused.csv");
    refused(
        &["record", "distance_1", "--out", &out],
        USAGE,
        "--duration",
    );
    refused(
        &["record", "distance_1", "--count", "0", "--out", &out],
        USAGE,
        "--count",
    );
    refused(
        &[
            "record",
            "distance_1",
            "--count",
            "2",
            "--duration",
            "1s",
            "--out",
            &out,
        ],
        USAGE,
        "cannot be used with",
    );
    assert!(!std::path::Path::new(&out).exists(), "nothing was written");
}

#[test]
fn ctrl_c_ends_the_recording_with_a_complete_file() {
    let out = scratch("interrupted.csv");
    let args = [
        "record",
        "distance_1",
        "--duration",
        "20s",
        "--interval",
        "10ms",
    ];
    let output = common::interrupted(
        &[&args[..], &["--out", &out]].concat(),
        std::time::Duration::from_millis(600),
    );
    assert!(output.status.success(), "{:?}", output.status);
    let text = std::fs::read_to_string(&out).expect("the file");
    assert!(text.ends_with('\n'), "the last row is whole");
    let rows = rows(&out);
    assert!(rows.len() > 2, "{rows:?}");
    let mut after = 0.0;
    for row in &rows[1..] {
        after = sample(row, 3, after);
    }
    assert!(after < 20.0);
}

#[test]
fn point_2_the_built_in_simulator_runs_at_line_speed_or_full_speed_on_request() {
    // Both speeds give the device's values; only the built-in simulator takes the option.
    for speed in ["line", "full"] {
        let out = ok(&["read", "laser_enabled", "--sim-speed", speed]);
        assert!(out.starts_with("laser_enabled"), "{out}");
    }
    let (code, _, stderr) = outcome(&[
        "read",
        "distance_1",
        "--sim-speed",
        "full",
        "--tcp",
        "127.0.0.1:1",
    ]);
    assert_eq!(code, Some(USAGE), "{stderr}");
    let stderr = refused(
        &["simulate", "--sim-speed", "full", "--duration", "0"],
        REFUSED,
        "--sim-speed",
    );
    assert!(stderr.contains("--line-timing"), "{stderr}");
    let help = ok(&["read", "--help"]);
    assert!(
        help.contains("--sim-speed") && help.contains("serial line"),
        "{help}"
    );
}

#[test]
fn point_5_record_and_packed_registers_are_a_column_per_field_with_its_unit() {
    let out = scratch("fields.csv");
    ok(&[
        "--model",
        "rangefinder",
        "record",
        "measurement_results",
        "serial_parameters",
        "--count",
        "5",
        "--out",
        &out,
    ]);
    let rows = rows(&out);
    // The fields of the spec's record and packed descriptions, each with its own unit.
    assert_eq!(
        rows[0].join(","),
        "time,elapsed [s],measurement_results.distance [mm],measurement_results.signal_strength [uV],\
         measurement_results.temperature [degC],serial_parameters.parity,serial_parameters.baud_rate"
    );
    assert_eq!(rows.len(), 6, "{rows:?}");
    let mut after = 0.0;
    for row in &rows[1..] {
        after = sample(row, 7, after);
        // A number in every column (the simulator's temperature is some 35 degC, its link
        // without parity at 115200 bit/s); the distance may be invalid in one sample of 50.
        let temperature: f64 = row[4].parse().unwrap();
        assert!((0.0..100.0).contains(&temperature), "{row:?}");
        assert_eq!(&row[5..], ["0", "115200"], "{row:?}");
        assert!(row[3].parse::<u32>().is_ok(), "{row:?}");
    }
}

/// A Modbus TCP device that answers every read with zeros (the rangefinder's distance
/// sentinel, so its distance is always invalid); gives its address. It serves until the test
/// process ends.
fn zero_device() -> String {
    use std::io::{Read, Write};
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    std::thread::spawn(move || {
        for connection in listener.incoming() {
            let Ok(mut connection) = connection else {
                return;
            };
            std::thread::spawn(move || {
                let mut head = [0u8; 7];
                while connection.read_exact(&mut head).is_ok() {
                    let length = usize::from(u16::from_be_bytes([head[4], head[5]]));
                    let mut pdu = vec![0u8; length.saturating_sub(1)];
                    if connection.read_exact(&mut pdu).is_err() {
                        return;
                    }
                    let reply = match pdu.as_slice() {
                        [function @ (3 | 4), _, _, high, low] => {
                            let bytes = 2 * u16::from_be_bytes([*high, *low]) as usize;
                            let mut reply = vec![*function, bytes as u8];
                            reply.resize(2 + bytes, 0);
                            reply
                        }
                        [function, ..] => vec![function | 0x80, 1],
                        [] => return,
                    };
                    let mut frame = head[..4].to_vec();
                    frame.extend_from_slice(&(reply.len() as u16 + 1).to_be_bytes());
                    frame.push(head[6]);
                    frame.extend_from_slice(&reply);
                    if connection.write_all(&frame).is_err() {
                        return;
                    }
                }
            });
        }
    });
    address
}

#[test]
fn point_6_polls_at_different_rates_leave_unread_cells_empty_and_mark_invalid_ones() {
    let dir = std::path::PathBuf::from(scratch("rates"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let bus = dir.join("bus.yaml");
    std::fs::write(
        &bus,
        format!(
            "lines: [{{ name: plant, tcp: \"{}\" }}]\ndevices:\n  - {{ name: ranger, model: rangefinder, slave: 1, timeout: 500ms, poll: [{{ read: [error_status, distance], every: 50ms }}, {{ read: run_state, every: 300ms }}] }}\n",
            zero_device()
        ),
    )
    .unwrap();
    let recorded = dir.join("recorded");
    ok(&[
        "run",
        bus.to_str().unwrap(),
        "--duration",
        "1500ms",
        "--record",
        recorded.to_str().unwrap(),
    ]);
    let path = recorded.join("ranger.csv").display().to_string();
    let rows = rows(&path);
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(
        rows[0].join(","),
        "time,elapsed [s],error_status,run_state,distance [mm]"
    );
    // A row per poll: the fast poll's row has its own columns, the invalid distance marked
    // `NaN`, and nothing in the slow poll's column; the slow poll's row the other way round.
    let (mut fast, mut slow) = (0, 0);
    let mut after = 0.0;
    for row in &rows[1..] {
        after = sample(row, 5, after);
        match &row[2..] {
            [status, run_state, distance] if [status, run_state, distance] == ["0", "", "NaN"] => {
                fast += 1
            }
            [status, run_state, distance] if [status, run_state, distance] == ["", "0", ""] => {
                slow += 1
            }
            _ => panic!("a row of neither poll: {row:?}"),
        }
    }
    assert!(
        slow >= 2 && fast > slow,
        "{fast} fast rows, {slow} slow rows"
    );
}
