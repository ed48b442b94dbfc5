//! A service run end to end on a simulated line: started, followed, stopped, its recording
//! read back by the same module that wrote it.

use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};

use optobus_bus::{BusFile, Catalogue, Event, Follower};
use optobus_service::recording::{self, csv_cells, csv_headers, ReadRefused, RecordingFile};
use optobus_service::{Options, Say, Service};

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("optobus-service-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn bus() -> BusFile {
    parse("
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 200ms, poll: [{ read: measurements, every: 20ms }] }
")
}

/// `text` read as a bus file of P series heads; a mistake in it fails the test.
fn parse(text: &str) -> BusFile {
    BusFile::parse(
        "bus.yaml",
        text,
        ".".as_ref(),
        &Catalogue::new([&optobus_p_series::DEVICE]),
    )
    .unwrap_or_else(|e| panic!("{}", e.render()))
}

/// Everything the service said, kept.
fn heard() -> (Say, Arc<Mutex<Vec<String>>>) {
    let said = Arc::new(Mutex::new(Vec::new()));
    let kept = Arc::clone(&said);
    let say: Say = Arc::new(move |text: &str| kept.lock().unwrap().push(text.to_owned()));
    (say, said)
}

#[tokio::test]
async fn a_service_records_every_sample_its_caller_saw_and_the_recording_reads_back() {
    let dir = scratch("record");
    let (say, said) = heard();
    let options = Options {
        record: Some(dir.clone()),
    };
    let mut service = Service::start(bus().into(), options, say)
        .await
        .expect("starts");
    let events = service.events().expect("the caller's subscription");
    assert!(service.events().is_none(), "given once");
    // Follow until the samples of five polls have come (a generous deadline, no timing).
    let mut seen = 0usize;
    let mut polls = std::collections::BTreeSet::new();
    let mut missed = 0;
    let (enough, mut enough_rx) = tokio::sync::watch::channel(false);
    let stop = async move {
        let _ = tokio::time::timeout(Duration::from_secs(60), enough_rx.wait_for(|e| *e)).await;
    };
    Follower::new(events, |count| missed += count)
        .until(stop, |event| {
            if let Event::Sample(sample) = event {
                seen += 1;
                polls.insert(sample.requested);
                if polls.len() >= 5 {
                    let _ = enough.send(true);
                }
            }
        })
        .await;
    assert!(polls.len() >= 5, "polls seen: {}", polls.len());
    service.stop().await.expect("a clean stop");
    assert_eq!(missed, 0);
    // Nothing dropped or failed: the run said nothing beyond its start.
    let said = said.lock().unwrap().clone();
    assert!(said.iter().all(|s| !s.contains("record")), "{said:?}");

    let read = recording::read(&dir.join("head.csv")).expect("reads back");
    assert_eq!(read.x_label, "elapsed [s]");
    let labels: Vec<&str> = read.columns.iter().map(|c| c.label.as_str()).collect();
    assert!(
        labels.iter().any(|l| l.ends_with("[mm]")),
        "a column with its unit: {labels:?}"
    );
    // Every row the caller saw the samples of is in the file (the last poll's too).
    let rows = read.columns[0].points.len();
    assert!(
        rows >= polls.len(),
        "{rows} rows, {} polls seen",
        polls.len()
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_recording_format_is_written_and_read_back_by_one_module() {
    let dir = scratch("format");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("one.csv");
    let register = optobus_p_series::DEVICE
        .registers
        .iter()
        .find(|r| r.unit == Some("mm"))
        .expect("a register in mm");
    let columns = csv_headers(register);
    let mut file = RecordingFile::create(&path, &columns).unwrap();
    let at = SystemTime::now();
    let value = optobus_inspect::Value::Invalid;
    file.row(at, 0.0, &vec!["1.5".to_owned(); columns.len()])
        .unwrap();
    file.row(at, 0.5, &csv_cells(register, &value)).unwrap();
    file.row(at, 1.0, &vec![String::new(); columns.len()])
        .unwrap();
    file.row(at, 1.5, &vec!["2".to_owned(); columns.len()])
        .unwrap();
    file.flush().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.starts_with(&format!("time,elapsed [s],{}\n", columns.join(","))),
        "{text}"
    );
    let read = recording::read(&path).unwrap();
    assert_eq!(read.x_label, "elapsed [s]");
    // NaN is a gap; an empty cell (a column not read) is no point at all.
    assert_eq!(
        read.columns[0].points,
        [(0.0, Some(1.5)), (0.5, None), (1.5, Some(2.0))]
    );
    std::fs::write(&path, "a,b\n1,2\n").unwrap();
    assert!(matches!(
        recording::read(&path),
        Err(ReadRefused::NotARecording)
    ));
    std::fs::write(&path, "index,value\n0,text\n").unwrap();
    assert!(matches!(
        recording::read(&path),
        Err(ReadRefused::NoNumbers)
    ));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A decimal's text (`10.061630`) in millionths, exactly.
fn millionths(text: &str) -> i64 {
    let (whole, fraction) = text.split_once('.').unwrap_or((text, ""));
    assert!(fraction.len() <= 6, "{text}");
    let negative = whole.starts_with('-');
    let whole: i64 = whole.trim_start_matches('-').parse().unwrap();
    let fraction: i64 = format!("{fraction:0<6}").parse().unwrap();
    let magnitude = whole * 1_000_000 + fraction;
    if negative {
        -magnitude
    } else {
        magnitude
    }
}

#[tokio::test]
async fn a_recording_has_a_csv_per_measurement_with_its_value_judgement_skew_and_inputs() {
    let dir = scratch("measurements");
    let file = parse(
        &optobus_testkit::bus_files::two_heads_gap()
            .timeout("200ms")
            .text(),
    );
    let (say, _) = heard();
    let options = Options {
        record: Some(dir.clone()),
    };
    let mut service = Service::start(file.into(), options, say)
        .await
        .expect("starts");
    let events = service.events().expect("the caller's subscription");
    let mut values = 0;
    let (enough, mut enough_rx) = tokio::sync::watch::channel(false);
    let stop = async move {
        let _ = tokio::time::timeout(Duration::from_secs(60), enough_rx.wait_for(|e| *e)).await;
    };
    Follower::new(events, |_| {})
        .until(stop, |event| {
            if let Event::Measurement(_) = event {
                values += 1;
                if values >= 5 {
                    let _ = enough.send(true);
                }
            }
        })
        .await;
    service.stop().await.expect("a clean stop");
    assert!(values >= 5);

    let path = dir.join("gap.measurement.csv");
    let mut reader = csv::Reader::from_path(&path).expect("the measurement's CSV");
    let headers: Vec<String> = reader.headers().unwrap().iter().map(String::from).collect();
    assert_eq!(
        headers,
        [
            "time",
            "elapsed [s]",
            "gap [mm]",
            "judgement",
            "skew [us]",
            "reason",
            "top.distance_1 [mm]",
            "bottom.distance_1 [mm]"
        ]
    );
    let mut valid = 0;
    for row in reader.records() {
        let row = row.unwrap();
        let (gap, judgement, skew, reason) = (&row[2], &row[3], &row[4], &row[5]);
        assert!(skew.parse::<u64>().is_ok(), "{row:?}");
        if gap == recording::INVALID_CELL {
            assert!(!reason.is_empty() && judgement.is_empty(), "{row:?}");
            continue;
        }
        valid += 1;
        assert!(reason.is_empty(), "{row:?}");
        assert!(["lo", "go", "hi"].contains(&judgement), "{row:?}");
        // The value is the exact arithmetic of the inputs on its row.
        assert_eq!(
            millionths(gap),
            20_000_000 - millionths(&row[6]) - millionths(&row[7]),
            "{row:?}"
        );
    }
    assert!(valid >= 1, "no valid value recorded");
    // `optobus plot`'s reader takes it as it is: the value and the inputs as series.
    let read = recording::read(&path).expect("reads back");
    assert_eq!(read.x_label, "elapsed [s]");
    let labels: Vec<&str> = read.columns.iter().map(|c| c.label.as_str()).collect();
    assert!(labels.contains(&"gap [mm]"), "{labels:?}");
    assert!(labels.contains(&"top.distance_1 [mm]"), "{labels:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
