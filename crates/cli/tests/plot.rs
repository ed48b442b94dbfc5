//! `optobus plot` and `optobus buffer --plot`: SVG charts of recorded values, one panel per
//! column over the elapsed time (or the index), with the units on the axes.

mod common;

use common::{fails, ok, run, Served};

/// A file in the temporary directory, unique to this test process.
fn scratch(name: &str) -> String {
    std::env::temp_dir()
        .join(format!("optobus-plot-{}-{name}", std::process::id()))
        .display()
        .to_string()
}

/// The SVG text of `path`, which is then removed.
fn svg(path: &str) -> String {
    let text = std::fs::read_to_string(path).expect("the chart was written");
    let _ = std::fs::remove_file(path);
    text
}

#[test]
fn a_recording_is_drawn_with_its_units() {
    let (csv, out) = (scratch("run.csv"), scratch("run.svg"));
    ok(&[
        "record",
        "distance_1",
        "thickness",
        "--count",
        "40",
        "--out",
        &csv,
    ]);
    ok(&["plot", &csv, "--out", &out]);
    let _ = std::fs::remove_file(&csv);
    let chart = svg(&out);
    assert!(
        chart.starts_with("<svg"),
        "{}",
        &chart[..chart.len().min(200)]
    );
    for label in ["distance_1 [mm]", "thickness [mm]", "elapsed [s]"] {
        assert!(chart.contains(label), "{label} missing");
    }
    // One line per run of valid readings, in each of the two panels.
    assert!(chart.matches("<polyline").count() >= 2);
}

#[test]
fn a_recording_is_drawn_as_png_with_its_text() {
    let (csv, out) = (scratch("png.csv"), scratch("run.png"));
    ok(&["record", "distance_1", "--count", "20", "--out", &csv]);
    ok(&["plot", &csv, "--out", &out]);
    let _ = std::fs::remove_file(&csv);
    let bytes = std::fs::read(&out).expect("the chart was written");
    let _ = std::fs::remove_file(&out);
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "a PNG signature");
    // IHDR: width and height, big-endian, right after the signature and the chunk header.
    let width = u32::from_be_bytes([bytes[16], bytes[17], bytes[18], bytes[19]]);
    let height = u32::from_be_bytes([bytes[20], bytes[21], bytes[22], bytes[23]]);
    assert_eq!((width, height), (1000, 260), "one panel");
}

#[test]
fn a_buffer_download_is_drawn_over_time() {
    let out = scratch("buffer.svg");
    ok(&["buffer", "--count", "120", "--wait", "0", "--plot", &out]);
    let chart = svg(&out);
    assert!(chart.contains("distance_1 [mm]") && chart.contains("time ["));
    assert!(chart.contains("<polyline"));
}

#[test]
fn a_saved_buffer_download_is_drawn_over_its_index() {
    let (csv, out) = (scratch("buffer.csv"), scratch("saved-buffer.svg"));
    ok(&["buffer", "--count", "50", "--wait", "0", "--out", &csv]);
    let text = std::fs::read_to_string(&csv).expect("the download was saved");
    assert!(text.starts_with("index,value_mm\n"), "{text}");
    ok(&["plot", &csv, "--out", &out]);
    let _ = std::fs::remove_file(&csv);
    let chart = svg(&out);
    let texts = tick_labels(&chart);
    let has = |label: &str| texts.iter().any(|t| t == label);
    assert!(has("value_mm") && has("index") && has("40"), "{texts:?}");
    assert!(chart.contains("<polyline"));
}

/// The texts of an SVG chart: axis descriptions and tick labels.
fn tick_labels(chart: &str) -> Vec<String> {
    chart
        .split("<text")
        .skip(1)
        .filter_map(|text| {
            let label = text.split('>').nth(1)?.split('<').next()?;
            Some(label.trim().to_owned())
        })
        .collect()
}

#[test]
fn a_buffer_at_ratio_10_is_drawn_at_ten_times_the_sampling_interval() {
    let served = Served::start(&["p-series", "--tcp", "127.0.0.1:0"]);
    let at = served.at.clone();
    let model = ["--model", "p-series", "--tcp", &at];
    ok(&[&["set", "sampling_interval", "100us"][..], &model].concat());
    ok(&[&["set", "sampled_data_ratio", "10"][..], &model].concat());
    let out = scratch("ratio.svg");
    let output = run(&[
        &["buffer", "--count", "20", "--wait", "100ms", "--plot", &out][..],
        &model,
    ]
    .concat());
    assert!(output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("values 1ms apart (sampling interval 100µs × ratio 10)"),
        "{stderr}"
    );
    // 20 values 1 ms apart: 0 to 19 ms (at ratio 1 they would span 0 to 1.9 ms).
    let chart = svg(&out);
    let texts = tick_labels(&chart);
    let has = |label: &str| texts.iter().any(|t| t == label);
    assert!(has("time [ms]") && has("0") && has("18"), "{texts:?}");
    assert!(!has("1.8"), "{texts:?}");
}

#[test]
fn what_cannot_be_drawn_is_refused() {
    let csv = scratch("not-a-recording.csv");
    std::fs::write(&csv, "when,what\nnoon,1.0\n").expect("write");
    let stderr = fails(&["plot", &csv, "--out", &scratch("x.svg")]);
    assert!(stderr.contains("no recording"), "{stderr}");
    let stderr = fails(&["plot", &csv, "--out", &scratch("x.pdf")]);
    assert!(stderr.contains("written as SVG or PNG"), "{stderr}");
    let _ = std::fs::remove_file(&csv);
    let stderr = fails(&["plot", &scratch("missing.csv"), "--out", &scratch("x.svg")]);
    assert!(stderr.contains("cannot read"), "{stderr}");
    // Refused before the download starts.
    let stderr = fails(&["buffer", "--count", "10", "--plot", &scratch("x.pdf")]);
    assert!(
        stderr.contains("written as SVG or PNG") && !stderr.contains("buffering"),
        "{stderr}"
    );
}

#[test]
fn a_device_or_an_oversized_recording_is_refused_with_the_limit() {
    let stderr = fails(&["plot", "/dev/zero", "--out", &scratch("z.svg")]);
    assert!(
        stderr.contains("cannot read /dev/zero: not a regular file"),
        "{stderr}"
    );
    // Sparse: one byte over the 256 MiB limit costs no disk.
    let csv = scratch("huge.csv");
    let file = std::fs::File::create(&csv).expect("create");
    file.set_len(256 * 1024 * 1024 + 1).expect("grow");
    let stderr = fails(&["plot", &csv, "--out", &scratch("huge.svg")]);
    let _ = std::fs::remove_file(&csv);
    assert!(
        stderr.contains("larger than the limit of 256 MiB"),
        "{stderr}"
    );
}

/// The y pixel coordinates of every line point in an SVG chart.
fn line_ys(chart: &str) -> Vec<f64> {
    chart
        .split("<polyline")
        .skip(1)
        .filter_map(|line| line.split("points=\"").nth(1)?.split('"').next())
        .flat_map(|points| points.split_whitespace())
        .filter_map(|point| point.split(',').nth(1)?.parse().ok())
        .collect()
}

/// A recording of `values`, one row per value (a millisecond apart).
fn recording(path: &str, values: impl Iterator<Item = f64>) {
    let mut text = String::from("time,elapsed [s],distance_1 [mm]\n");
    for (i, value) in values.enumerate() {
        text.push_str(&format!(",{},{value}\n", i as f64 / 1000.0));
    }
    std::fs::write(path, text).expect("write the recording");
}

#[test]
fn point_2_a_million_rows_plot_as_a_bounded_chart_that_keeps_the_extremes() {
    const ROWS: usize = 1_000_000;
    let (big, big_svg) = (scratch("million.csv"), scratch("million.svg"));
    // A slow wave with one spike and one dip, each a single sample wide.
    recording(
        &big,
        (0..ROWS).map(|i| match i {
            400_000 => 987.5,
            700_001 => -654.25,
            i => (i % 1000) as f64 / 100.0,
        }),
    );
    ok(&["plot", &big, "--out", &big_svg]);
    let _ = std::fs::remove_file(&big);
    let chart = svg(&big_svg);
    assert!(chart.len() < 200_000, "{} bytes", chart.len());
    // The same extremes drawn from three rows over the same time: the same axis, so the
    // thinned line must reach the same top and bottom pixels.
    let (small, small_svg) = (scratch("three.csv"), scratch("three.svg"));
    let mut text = String::from("time,elapsed [s],distance_1 [mm]\n");
    for (x, y) in [
        (0.0, 0.0),
        (400.0, 987.5),
        (700.001, -654.25),
        (999.999, 9.99),
    ] {
        text.push_str(&format!(",{x},{y}\n"));
    }
    std::fs::write(&small, text).expect("write");
    ok(&["plot", &small, "--out", &small_svg]);
    let _ = std::fs::remove_file(&small);
    let reference = line_ys(&svg(&small_svg));
    let ys = line_ys(&chart);
    let extremes = |ys: &[f64]| {
        ys.iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &y| {
                (lo.min(y), hi.max(y))
            })
    };
    assert_eq!(extremes(&ys), extremes(&reference));
}

#[test]
fn point_5_a_record_register_is_drawn_as_a_panel_per_field() {
    let (csv, out) = (scratch("fields.csv"), scratch("fields.svg"));
    ok(&[
        "--model",
        "rangefinder",
        "record",
        "measurement_results",
        "--count",
        "20",
        "--out",
        &csv,
    ]);
    ok(&["plot", &csv, "--out", &out]);
    let _ = std::fs::remove_file(&csv);
    let chart = svg(&out);
    let texts = tick_labels(&chart);
    for label in [
        "measurement_results.distance [mm]",
        "measurement_results.signal_strength [uV]",
        "measurement_results.temperature [degC]",
    ] {
        assert!(texts.iter().any(|t| t == label), "{label} in {texts:?}");
    }
    assert_eq!(line_lengths(&chart).len(), 3, "a line in each panel");
    // A column of text (an IP address) is left out, and said so.
    ok(&[
        "record",
        "distance_1",
        "ip_address",
        "--count",
        "5",
        "--out",
        &csv,
    ]);
    let output = run(&["plot", &csv, "--out", &out]);
    let _ = std::fs::remove_file(&csv);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(
        stderr.contains("left out, no numbers in them: ip_address"),
        "{stderr}"
    );
    assert_eq!(line_lengths(&svg(&out)), [5]);
}

/// The number of points of each value line (blue, not the axes' black) in an SVG chart, in
/// the order drawn.
fn line_lengths(chart: &str) -> Vec<usize> {
    chart
        .split("<polyline")
        .skip(1)
        .filter(|line| line.contains("stroke=\"#0000FF\""))
        .filter_map(|line| line.split("points=\"").nth(1)?.split('"').next())
        .map(|points| points.split_whitespace().count())
        .collect()
}

#[test]
fn point_6_cells_a_row_did_not_read_are_no_gap_and_invalid_readings_are() {
    // Two polls at different rates: the slow one's column is empty in the fast one's rows
    // and the other way round; one fast reading invalid.
    let (csv, out) = (scratch("rates.csv"), scratch("rates.svg"));
    std::fs::write(
        &csv,
        "time,elapsed [s],fast [mm],slow [mm]\n\
         ,0.0,1.0,\n,0.1,2.0,\n,0.2,,5.0\n,0.3,3.0,\n,0.4,NaN,\n\
         ,0.5,4.0,\n,0.6,,6.0\n,0.7,5.0,\n,0.8,,7.0\n",
    )
    .expect("write");
    ok(&["plot", &csv, "--out", &out]);
    let _ = std::fs::remove_file(&csv);
    // The fast column: 1, 2, 3, then a gap at the invalid reading, then 4, 5; the slow one
    // drawn whole, 5, 6, 7.
    assert_eq!(line_lengths(&svg(&out)), [3, 2, 3]);
    // A recording from before `NaN` (an invalid reading was an empty cell) is still drawn.
    std::fs::write(
        &csv,
        "time,elapsed [s],distance_1 [mm],measurement_results\n\
         ,0.0,1.0,\"distance=1.0 mm\"\n,0.1,,\"distance=invalid\"\n,0.2,2.0,\"distance=2.0 mm\"\n",
    )
    .expect("write");
    ok(&["plot", &csv, "--out", &out]);
    let _ = std::fs::remove_file(&csv);
    assert_eq!(line_lengths(&svg(&out)), [2]);
}
