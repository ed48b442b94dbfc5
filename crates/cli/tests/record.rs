//! `optobus record`: samples of registers or groups in a CSV file, against the built-in
//! simulator: the header names each column's unit, every row has an RFC 3339 time, the
//! elapsed seconds and one value per column.

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
/// value is a number or empty (a reading the device marked invalid); gives the elapsed
/// seconds.
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
        assert!(number.is_finite(), "{row:?}");
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
