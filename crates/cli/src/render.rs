//! Output on stdout: text that ignores a closed pipe, pretty JSON, register values as aligned
//! lines, a JSON object or CSV cells, and blocks redrawn in place on a terminal.

use std::io::Write;

use crossterm::{cursor, terminal, QueueableCommand};
use optobus_device::{FieldInfo, RegisterInfo, ValueKind};
use serde_json::{Map, Value as Json};

use optobus_inspect::Value;

/// The local time of day with its offset, for people: `14:23:54.822 +01:00`.
pub(crate) fn time_of_day() -> String {
    jiff::ZonedDateTime::now()
        .strftime("%H:%M:%S%.3f %:z")
        .to_string()
}

/// Now for scripts and recordings, RFC 3339 with the date, microseconds and the local
/// offset: `2026-11-23T14:23:54.822153+01:00`.
pub(crate) fn timestamp() -> String {
    jiff::ZonedDateTime::now()
        .strftime("%Y-%m-%dT%H:%M:%S%.6f%:z")
        .to_string()
}

/// `1 line`, `2 lines`: a count and a noun whose plural takes an `s`.
pub(crate) fn counted(count: impl Into<Count>, noun: &str) -> String {
    let Count(count) = count.into();
    let plural = if count == 1 { "" } else { "s" };
    format!("{count} {noun}{plural}")
}

/// A count of things, from any unsigned integer.
pub(crate) struct Count(u128);

macro_rules! count_from {
    ($($int:ty),*) => {$(
        impl From<$int> for Count {
            fn from(count: $int) -> Self {
                Self(count as u128)
            }
        }
    )*};
}

count_from!(u8, u16, u32, u64, usize);

/// Prints `text` on stdout with a final newline, ignoring a closed stdout.
pub(crate) fn print(text: &str) {
    let mut out = std::io::stdout().lock();
    // A closed pipe (`| head`) is not an error worth a message.
    let _ = out.write_all(text.as_bytes());
    if !text.ends_with('\n') {
        let _ = out.write_all(b"\n");
    }
    let _ = out.flush();
}

pub(crate) fn pretty(json: &Json) -> String {
    serde_json::to_string_pretty(json).unwrap_or_default()
}

/// `name  value` lines, the values aligned.
pub(crate) fn values_text(values: &[(&'static RegisterInfo, Value)]) -> String {
    let width = values.iter().map(|(r, _)| r.name.len()).max().unwrap_or(0);
    values
        .iter()
        .map(|(r, v)| format!("{:<width$}  {v}\n", r.name))
        .collect()
}

/// A value for scripts ([`Value`]'s serialisation).
pub(crate) fn value_json(value: &Value) -> Json {
    serde_json::to_value(value).unwrap_or_default()
}

/// `{"name": value, …}`.
pub(crate) fn values_json(values: &[(&'static RegisterInfo, Value)]) -> Json {
    Json::Object(
        values
            .iter()
            .map(|(r, v)| (r.name.to_owned(), value_json(v)))
            .collect::<Map<_, _>>(),
    )
}

/// The terminal's `(columns, rows)`; where it reports none, or a zero (a serial console, some
/// CI terminals), the classic 80 × 24, so a drawing is cut to something that shows.
pub(crate) fn screen(reported: Option<(u16, u16)>) -> (u16, u16) {
    match reported {
        Some((columns, rows)) if columns > 0 && rows > 0 => (columns, rows),
        _ => (80, 24),
    }
}

/// Replaces the last drawing (`drawn` lines) with `block`, cut to a terminal of `(columns,
/// rows)` so that the cursor can always climb back over it (a taller block, or a line that
/// wraps, would scroll and smear the scrollback); gives the lines drawn. Each line is cleared as it is rewritten and only
/// what is left below the block is cleared after it: a clear of the whole screen from its
/// top corner is copied into the scrollback by some terminals (tmux's `scroll-on-clear`).
pub(crate) fn redraw(
    out: &mut impl Write,
    drawn: u16,
    block: &str,
    (columns, rows): (u16, u16),
) -> u16 {
    let lines: Vec<&str> = block.lines().take(usize::from(rows.max(2) - 1)).collect();
    if drawn > 0 {
        let _ = out.queue(cursor::MoveToPreviousLine(drawn));
    }
    for line in &lines {
        let _ = out.queue(terminal::Clear(terminal::ClearType::CurrentLine));
        let cut: String = line.chars().take(usize::from(columns.max(2) - 1)).collect();
        let _ = writeln!(out, "{cut}");
    }
    if usize::from(drawn) > lines.len() {
        let _ = out.queue(terminal::Clear(terminal::ClearType::FromCursorDown));
    }
    u16::try_from(lines.len()).unwrap_or(u16::MAX)
}

/// The cell of a reading the device marked invalid: `NaN`, which pandas, numpy, R and gnuplot
/// read as not-a-number in a numeric column; an empty cell is a column the row did not read
/// (another poll's, or a read that failed).
pub(crate) const INVALID_CELL: &str = "NaN";

/// The fields the spec splits a packed or record register into; none for other registers.
fn fields_of(register: &RegisterInfo) -> &'static [FieldInfo] {
    match register.kind {
        ValueKind::Packed(fields) | ValueKind::Record(fields) => fields,
        _ => &[],
    }
}

/// One column's header: a name and, in brackets, its unit (`distance_1 [mm]`).
fn header(name: &str, unit: Option<&str>) -> String {
    match unit {
        Some(unit) => format!("{name} [{unit}]"),
        None => name.to_owned(),
    }
}

/// A register's columns: its name and unit (`distance_1 [mm]`), or for a packed or record
/// register one column per field of its spec, named `register.field`
/// (`measurement_results.distance [mm]`).
pub(crate) fn csv_headers(register: &RegisterInfo) -> Vec<String> {
    match fields_of(register) {
        [] => vec![header(register.name, register.unit)],
        fields => fields
            .iter()
            .map(|field| header(&format!("{}.{}", register.name, field.name), field.unit))
            .collect(),
    }
}

/// A register's cells, one per column of [`csv_headers`]: a quantity's exact number in the
/// header's unit, a code's number, a flag as 0 or 1, [`INVALID_CELL`] for an invalid reading,
/// text (quoted) for anything else (an address, a version).
pub(crate) fn csv_cells(register: &RegisterInfo, value: &Value) -> Vec<String> {
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
