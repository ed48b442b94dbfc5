//! The recording format, its writers and its reader, side by side.
//!
//! # The format
//! A recording is a CSV file with a header line and a row per sample (`optobus record`) or per
//! poll of one device (`optobus run --record DIR`, a file per device, `DIR/<device>.csv`):
//! - column 1, `time`: when the sample was asked for, RFC 3339 with microseconds and the
//!   local offset (`2026-11-23T14:23:54.822153+01:00`);
//! - column 2, `elapsed [s]`: seconds since the recording started, six decimals;
//! - then a column per register, headed by its name and, in brackets, its unit
//!   (`distance_1 [mm]`), or for a packed or record register a column per field of its spec,
//!   named `register.field` (`measurement_results.distance [mm]`);
//! - a cell holds a quantity's exact number in the header's unit, a code's number, a flag as
//!   0 or 1, [`INVALID_CELL`] (`NaN`) for a reading the device marked invalid, quoted text for
//!   anything else (an address, a version); an empty cell is a column the row did not read
//!   (another poll's, or a read that failed).
//!
//! With measurements in the bus file (`measurements:`), `optobus run --record DIR` also writes
//! a CSV per measurement beside the devices', `DIR/<measurement>.measurement.csv`, a row per
//! value, in the same form (so [`read`] and `optobus plot` take it as they are):
//! - `time` (when the value was computed) and `elapsed [s]`, as above;
//! - `<measurement> [unit]`: the value's exact number in its unit, `NaN` when it has none;
//! - `judgement`: `ll`, `lo`, `go`, `hi` or `hh`, empty without limits or value;
//! - `skew [us]`: microseconds between its first and its last input's request;
//! - `reason`: why it has no value (quoted), empty when it has one;
//! - a column per input, `device.register [unit]`: the value it was computed from, `NaN` when
//!   the input had none.
//!
//! A buffer download (`optobus buffer`, [`buffer_csv`]) is `index,value_<unit>` and a row per
//! value, an empty cell where the device marked the value invalid.
//!
//! [`read`] reads it back (and a buffer download, `index,value`) as numeric series.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::SystemTime;

use optobus_bus::{BusFile, MeasurementEvent, Sample};
use optobus_device::{FieldInfo, RegisterInfo, ValueKind};
use optobus_driver::{BufferTiming, Fixed};
use optobus_inspect::Value;
use optobus_spec::source::{open_limited, size_text, ReadError};

use crate::outlet::Sink;
use crate::ServiceError;

/// The cell of a reading the device marked invalid: `NaN`, which pandas, numpy, R and gnuplot
/// read as not-a-number in a numeric column; an empty cell is a column the row did not read
/// (another poll's, or a read that failed).
pub const INVALID_CELL: &str = "NaN";

/// The first two columns' headers.
const TIME_COLUMNS: &str = "time,elapsed [s]";

/// A time in the recording's RFC 3339 form, with the local offset.
pub fn local_time(at: SystemTime) -> String {
    jiff::Timestamp::try_from(at)
        .map(|t| {
            t.to_zoned_datetime(jiff::tz::TimeZone::system())
                .strftime("%Y-%m-%dT%H:%M:%S%.6f%:z")
                .to_string()
        })
        .unwrap_or_default()
}

/// The fields the spec splits a packed or record register into; none for other registers.
fn fields_of(register: &RegisterInfo) -> &'static [FieldInfo] {
    match register.kind {
        ValueKind::Packed(fields) | ValueKind::Record(fields) => fields,
        _ => &[],
    }
}

/// One column's header: a name and, in brackets, its unit (`distance_1 [mm]`).
pub fn header(name: &str, unit: Option<&str>) -> String {
    match unit {
        Some(unit) => format!("{name} [{unit}]"),
        None => name.to_owned(),
    }
}

/// A register's columns: its name and unit (`distance_1 [mm]`), or for a packed or record
/// register one column per field of its spec, named `register.field`
/// (`measurement_results.distance [mm]`).
pub fn csv_headers(register: &RegisterInfo) -> Vec<String> {
    match fields_of(register) {
        [] => vec![header(register.name, register.unit)],
        fields => fields
            .iter()
            .map(|field| header(&format!("{}.{}", register.name, field.name), field.unit))
            .collect(),
    }
}

/// A register's cells, one per column of [`csv_headers`] (see the [format](self)).
pub fn csv_cells(register: &RegisterInfo, value: &Value) -> Vec<String> {
    match (fields_of(register), value) {
        ([], value) => vec![csv_cell(value)],
        (fields, Value::Fields(values)) => fields
            .iter()
            .map(|field| {
                values
                    .iter()
                    .find(|(name, _)| *name == field.name)
                    .map_or_else(String::new, |(_, value)| csv_cell(value))
            })
            .collect(),
        // The whole register invalid (or, never from the decoder, not split): each field is.
        (fields, _) => vec![INVALID_CELL.to_owned(); fields.len()],
    }
}

/// One cell of a value that is not split.
fn csv_cell(value: &Value) -> String {
    match value {
        Value::Invalid => INVALID_CELL.to_owned(),
        Value::Bool(flag) => u8::from(*flag).to_string(),
        Value::Integer(number) => number.to_string(),
        Value::Quantity(number, _) => number.to_string(),
        Value::Code(code, _) => code.to_string(),
        other => format!("\"{}\"", other.to_string().replace('"', "\"\"")),
    }
}

/// One recording file being written: the header at creation, then a row at a time.
pub struct RecordingFile {
    out: BufWriter<File>,
    path: PathBuf,
}

impl RecordingFile {
    /// Creates `path` and writes the header of `columns` (each register's [`csv_headers`]).
    pub fn create(path: &Path, columns: &[String]) -> Result<Self, ServiceError> {
        let file = File::create(path).map_err(|e| write_failed(path, e))?;
        let mut recording = Self {
            out: BufWriter::new(file),
            path: path.to_path_buf(),
        };
        let line = format!("{TIME_COLUMNS},{}", columns.join(","));
        writeln!(recording.out, "{line}").map_err(|e| write_failed(path, e))?;
        Ok(recording)
    }

    /// A row: the sample asked for `at`, `elapsed` seconds into the recording, its cells.
    pub fn row(
        &mut self,
        at: SystemTime,
        elapsed: f64,
        cells: &[String],
    ) -> Result<(), ServiceError> {
        writeln!(
            self.out,
            "{},{elapsed:.6},{}",
            local_time(at),
            cells.join(",")
        )
        .map_err(|e| write_failed(&self.path, e))
    }

    /// Writes what is buffered.
    pub fn flush(&mut self) -> Result<(), ServiceError> {
        self.out.flush().map_err(|e| write_failed(&self.path, e))
    }
}

fn write_failed(path: &Path, error: std::io::Error) -> ServiceError {
    ServiceError::new(format!("cannot write {}: {error}", path.display()))
}

/// A CSV per device of a bus: a row per poll, columns for every register the device's polls
/// read (a column per field of packed and record registers); a row leaves empty the columns
/// its poll does not read, and marks an invalid reading `NaN`.
/// It is an [`Outlet`](crate::outlet::Outlet)'s sink: a slow disk costs its own oldest
/// samples, never the runtime's time.
pub struct Recorder {
    started: SystemTime,
    files: HashMap<String, DeviceCsv>,
    /// Each measurement's CSV, and its inputs' names in the order of its columns.
    measurements: HashMap<String, (RecordingFile, Vec<String>)>,
    /// The first write that failed: the recording stopped there.
    failed: Option<ServiceError>,
    /// Says the failure when it happens (the run goes on for its other outputs).
    say: crate::Say,
}

struct DeviceCsv {
    file: RecordingFile,
    /// Each register's first column and its count (one per field of a packed or record
    /// register).
    columns: HashMap<&'static str, (usize, usize)>,
    /// Columns in all.
    width: usize,
    /// The poll being gathered: its request time and cells (empty until read).
    row: Option<(SystemTime, Vec<String>)>,
}

impl Recorder {
    /// Creates `dir` and a CSV with its header for each device of `bus`.
    pub fn create(dir: &Path, bus: &BusFile, say: crate::Say) -> Result<Self, ServiceError> {
        std::fs::create_dir_all(dir)
            .map_err(|e| ServiceError::new(format!("cannot create {}: {e}", dir.display())))?;
        let mut files = HashMap::new();
        for device in &bus.devices {
            let mut registers: Vec<&'static RegisterInfo> = device
                .polls
                .iter()
                .flat_map(|p| p.registers.iter().copied())
                .collect();
            registers.sort_by_key(|r| (r.table, r.address));
            registers.dedup_by_key(|r| r.name);
            let mut header = Vec::new();
            let mut columns = HashMap::new();
            for register in registers {
                let split = csv_headers(register);
                columns.insert(register.name, (header.len(), split.len()));
                header.extend(split);
            }
            let path = dir.join(format!("{}.csv", device.name));
            files.insert(
                device.name.clone(),
                DeviceCsv {
                    file: RecordingFile::create(&path, &header)?,
                    columns,
                    width: header.len(),
                    row: None,
                },
            );
        }
        let mut measurements = HashMap::new();
        let plan = &bus.measurements.plan;
        for formula in &plan.formulas {
            let inputs: Vec<String> = formula
                .inputs
                .iter()
                .map(|&input| plan.inputs[input].to_string())
                .collect();
            let unit = (!formula.unit.name.is_empty()).then_some(formula.unit.name.as_str());
            let mut header = vec![
                self::header(&formula.name, unit),
                "judgement".to_owned(),
                "skew [us]".to_owned(),
                "reason".to_owned(),
            ];
            for (input, name) in formula.inputs.iter().zip(&inputs) {
                let input = &plan.inputs[*input];
                let unit = bus
                    .devices
                    .iter()
                    .find(|d| d.name == input.device)
                    .and_then(|d| d.device.register(&input.register))
                    .and_then(|r| r.unit);
                header.push(self::header(name, unit));
            }
            let path = dir.join(format!("{}.measurement.csv", formula.name));
            let file = RecordingFile::create(&path, &header)?;
            measurements.insert(formula.name.clone(), (file, inputs));
        }
        Ok(Self {
            started: SystemTime::now(),
            files,
            measurements,
            failed: None,
            say,
        })
    }

    /// A row of a measurement's CSV (see the [format](self)).
    fn add_measurement(&mut self, event: &MeasurementEvent) -> Result<(), ServiceError> {
        let Some((file, inputs)) = self.measurements.get_mut(&*event.measurement) else {
            return Ok(());
        };
        let quoted = |text: &str| format!("\"{}\"", text.replace('"', "\"\""));
        let (value, reason) = match &event.value {
            Ok(value) => (value.to_string(), String::new()),
            Err(reason) => (INVALID_CELL.to_owned(), quoted(reason)),
        };
        let mut cells = vec![
            value,
            event
                .judgement
                .map(|j| j.name().to_owned())
                .unwrap_or_default(),
            event.skew.as_micros().to_string(),
            reason,
        ];
        for name in inputs.iter() {
            let input = event.inputs.iter().find(|i| *i.name == **name);
            cells.push(match input.and_then(|i| i.value) {
                Some(value) => value.to_string(),
                None => INVALID_CELL.to_owned(),
            });
        }
        let elapsed = (event.time)
            .duration_since(self.started)
            .unwrap_or_default()
            .as_secs_f64();
        file.row(event.time, elapsed, &cells)
    }

    fn add(&mut self, sample: &Sample) -> Result<(), ServiceError> {
        let Some(csv) = self.files.get_mut(&*sample.source.device) else {
            return Ok(());
        };
        if csv
            .row
            .as_ref()
            .is_some_and(|(at, _)| *at != sample.requested)
        {
            csv.flush_row(self.started)?;
        }
        let width = csv.width;
        let (_, cells) = csv
            .row
            .get_or_insert_with(|| (sample.requested, vec![String::new(); width]));
        if let Some(&(first, count)) = csv.columns.get(sample.register.name) {
            let split = csv_cells(sample.register, &sample.value);
            for (cell, value) in cells.iter_mut().skip(first).take(count).zip(split) {
                *cell = value;
            }
        }
        Ok(())
    }

    /// Writes the last rows; gives the first failure of the whole recording.
    pub fn finish(mut self) -> Result<(), ServiceError> {
        if let Some(failed) = self.failed {
            return Err(failed);
        }
        for csv in self.files.values_mut() {
            csv.flush_row(self.started)?;
            csv.file.flush()?;
        }
        for (file, _) in self.measurements.values_mut() {
            file.flush()?;
        }
        Ok(())
    }
}

/// What a recording takes from the bus: a sample, or a measurement's value.
#[derive(Clone, Debug)]
pub enum Recorded {
    /// A register's sample, for its device's CSV.
    Sample(Arc<Sample>),
    /// A measurement's value, for its CSV.
    Measurement(Arc<MeasurementEvent>),
}

impl Sink<Recorded> for Recorder {
    fn write(&mut self, items: Vec<Recorded>, _: u64) {
        if self.failed.is_some() {
            return;
        }
        for item in items {
            let written = match &item {
                Recorded::Sample(sample) => self.add(sample),
                Recorded::Measurement(event) => self.add_measurement(event),
            };
            if let Err(error) = written {
                // Said now (the run goes on for its other outputs), and again at the end.
                (self.say)(&format!("optobus: --record stopped: {error}"));
                self.failed = Some(error);
                return;
            }
        }
    }
}

impl DeviceCsv {
    fn flush_row(&mut self, started: SystemTime) -> Result<(), ServiceError> {
        let Some((at, cells)) = self.row.take() else {
            return Ok(());
        };
        let elapsed = at.duration_since(started).unwrap_or_default().as_secs_f64();
        self.file.row(at, elapsed, &cells)
    }
}

/// A buffer download as CSV: `index,value_<unit>` (`index,value` without a unit), then a row
/// per value, oldest first, its exact number or an empty cell where the device marked it
/// invalid.
pub fn buffer_csv(unit: &str, values: &[Option<Fixed>]) -> String {
    let mut csv = if unit.is_empty() {
        String::from("index,value\n")
    } else {
        format!("index,value_{unit}\n")
    };
    for (index, value) in values.iter().enumerate() {
        let value = value.as_ref().map(Fixed::to_string);
        csv.push_str(&format!("{index},{}\n", value.unwrap_or_default()));
    }
    csv
}

/// A buffer download as points for a chart: the x axis label and a point per value, at its
/// time since the first in a unit that suits the span (`time [ms]`), or at its index
/// (`index`) when the buffer's `timing` is unknown; `None` where a value is invalid.
pub fn buffer_points(
    timing: Option<BufferTiming>,
    values: &[Option<Fixed>],
) -> (String, Vec<(f64, Option<f64>)>) {
    let count = values.len();
    let last = timing.map_or(0.0, |t| t.time_of(count.saturating_sub(1)).as_secs_f64());
    let (unit, per_second) = match last {
        _ if timing.is_none() => ("", 1.0),
        last if last >= 10.0 => ("s", 1.0),
        last if last >= 0.01 => ("ms", 1e3),
        _ => ("µs", 1e6),
    };
    let label = match timing {
        Some(_) => format!("time [{unit}]"),
        None => "index".to_owned(),
    };
    let x = |index: usize| match timing {
        Some(timing) => timing.time_of(index).as_secs_f64() * per_second,
        None => index as f64,
    };
    let points = values.iter().enumerate();
    let points = points.map(|(i, v)| (x(i), v.map(Fixed::to_f64)));
    (label, points.collect())
}

/// The largest recording [`read`] takes: 256 MiB, some three million rows of five values
/// (hours of `optobus record` at the fastest serial line). Its points take about two and a
/// half times the file in memory (some 700 MB at the limit); a larger file is refused rather
/// than left to exhaust the machine.
pub const RECORDING_LIMIT: u64 = 256 * 1024 * 1024;

/// A value column read back: its header and its points over the x column, `None` a gap.
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    /// The column's header (`distance_1 [mm]`).
    pub label: String,
    /// `(x, y)`: `y` is `None` at an invalid reading (`NaN`) or other text.
    pub points: Vec<(f64, Option<f64>)>,
}

/// A recording or a buffer download read back.
#[derive(Clone, Debug, PartialEq)]
pub struct Read {
    /// The x column's header (`elapsed [s]`, or `index`).
    pub x_label: String,
    /// The value columns with a number in them.
    pub columns: Vec<Column>,
    /// The headers of the value columns without a number in them (text, or nothing read).
    pub left_out: Vec<String>,
}

/// Why a recording could not be read back.
#[derive(Debug)]
pub enum ReadRefused {
    /// The system could not read the file.
    Unreadable(String),
    /// The file is over [`RECORDING_LIMIT`].
    TooLarge(String),
    /// Not a CSV (or not text): the reader's reason.
    Unparsable(String),
    /// Columns neither of a recording nor of a buffer download.
    NotARecording,
    /// No column holds a number.
    NoNumbers,
}

impl std::fmt::Display for ReadRefused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Unreadable(why) | Self::TooLarge(why) | Self::Unparsable(why) => f.write_str(why),
            Self::NotARecording => {
                f.write_str("its columns are neither time, elapsed, values nor index, value")
            }
            Self::NoNumbers => f.write_str("it holds no numbers to plot"),
        }
    }
}

impl std::error::Error for ReadRefused {}

/// [`RECORDING_LIMIT`] for people (`256 MiB`).
pub fn limit_text() -> String {
    size_text(RECORDING_LIMIT)
}

/// Reads the recording at `path` (or a buffer download, `index,value`): the x axis label and
/// one column per value column with a number in it; a gap at each invalid reading (`NaN`) and
/// none where a recording's row did not read the column (an empty cell), which in a buffer
/// download (a value in every row) is a gap too.
pub fn read(path: &Path) -> Result<Read, ReadRefused> {
    // A file that cannot be read is the system's failure; one too large, or text that is no
    // CSV, input refused.
    let unreadable = |e: csv::Error| match e.kind() {
        csv::ErrorKind::Io(io) if io.kind() == std::io::ErrorKind::FileTooLarge => {
            ReadRefused::TooLarge(io.to_string())
        }
        csv::ErrorKind::Io(_) => ReadRefused::Unreadable(e.to_string()),
        _ => ReadRefused::Unparsable(e.to_string()),
    };
    let file = open_limited(path, RECORDING_LIMIT).map_err(|e| match e {
        ReadError::TooLarge { .. } => ReadRefused::TooLarge(e.to_string()),
        ReadError::Io(_) => ReadRefused::Unreadable(e.to_string()),
        _ => ReadRefused::Unparsable(e.to_string()),
    })?;
    let mut reader = csv::Reader::from_reader(file);
    let headers = reader.headers().map_err(unreadable)?.clone();
    // A recording: time, elapsed seconds, values; a buffer download: index, value.
    let x_column = match (headers.get(0), headers.get(1)) {
        (_, Some(elapsed)) if elapsed.starts_with("elapsed") => 1,
        (Some("index"), Some(_)) => 0,
        _ => return Err(ReadRefused::NotARecording),
    };
    let x_label = headers.get(x_column).unwrap_or_default().to_owned();
    let download = x_column == 0;
    let mut columns: Vec<Column> = headers
        .iter()
        .skip(x_column + 1)
        .map(|label| Column {
            label: label.to_owned(),
            points: Vec::new(),
        })
        .collect();
    for row in reader.records() {
        let row = row.map_err(unreadable)?;
        let Some(x) = row.get(x_column).and_then(|x| x.parse::<f64>().ok()) else {
            continue;
        };
        for (column, cell) in columns.iter_mut().zip(row.iter().skip(x_column + 1)) {
            column.points.extend(point(x, cell, download));
        }
    }
    let (columns, textual): (Vec<Column>, Vec<Column>) = columns
        .into_iter()
        .partition(|column| column.points.iter().any(|(_, y)| y.is_some()));
    if columns.is_empty() {
        return Err(ReadRefused::NoNumbers);
    }
    Ok(Read {
        x_label,
        columns,
        left_out: textual.into_iter().map(|column| column.label).collect(),
    })
}

/// The point of one cell at `x`: a gap for `NaN` (an invalid reading) or other text; in a
/// recording none for an empty cell (the row did not read that column: the line goes on past
/// it), in a buffer `download` a gap.
fn point(x: f64, cell: &str, download: bool) -> Option<(f64, Option<f64>)> {
    if cell.is_empty() && !download {
        return None;
    }
    Some((x, cell.parse::<f64>().ok().filter(|y| y.is_finite())))
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use optobus_driver::Scale;

    use super::*;

    fn millimetres(raw: i64) -> Option<Fixed> {
        Some(Fixed::new(raw, Scale::Decimal { exponent: -3 }))
    }

    #[test]
    fn a_buffer_download_is_index_and_value_an_invalid_value_an_empty_cell() {
        let values = [millimetres(1500), None, millimetres(-250)];
        assert_eq!(
            buffer_csv("mm", &values),
            "index,value_mm\n0,1.500\n1,\n2,-0.250\n"
        );
        assert_eq!(buffer_csv("", &[]), "index,value\n");
    }

    #[test]
    fn a_buffer_download_is_drawn_over_its_time_in_a_unit_that_suits_the_span() {
        let values = [millimetres(1000), None, millimetres(3000)];
        let (label, points) = buffer_points(None, &values);
        assert_eq!(label, "index");
        assert_eq!(points, [(0.0, Some(1.0)), (1.0, None), (2.0, Some(3.0))]);
        let timing = |micros, ratio| BufferTiming {
            interval: Duration::from_micros(micros),
            ratio,
        };
        let (label, points) = buffer_points(Some(timing(5_000, 2)), &values);
        assert_eq!(label, "time [ms]");
        assert_eq!(points[2], (20.0, Some(3.0)));
        let (label, points) = buffer_points(Some(timing(10, 1)), &values);
        assert_eq!(label, "time [µs]");
        assert_eq!(points[1], (10.0, None));
        let (label, _) = buffer_points(Some(timing(5_000_000, 1)), &values);
        assert_eq!(label, "time [s]");
    }
}
