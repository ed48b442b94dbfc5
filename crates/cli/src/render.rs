//! Output on stdout: text that ignores a closed pipe, pretty JSON, register values as aligned
//! lines or a JSON object, and blocks redrawn in place on a terminal.

use std::io::Write;

use crossterm::{cursor, terminal, QueueableCommand};
use optobus_device::RegisterInfo;
use serde_json::{Map, Value as Json};

use optobus_inspect::Value;

/// The local time of day with its offset, for people: `14:23:54.822 +01:00`.
pub(crate) use optobus_service::journal::time_of_day;

/// Now for scripts, in the recording's RFC 3339 form (the date, microseconds and the local
/// offset): `2026-11-23T14:23:54.822153+01:00`.
pub(crate) fn timestamp() -> String {
    optobus_service::recording::local_time(std::time::SystemTime::now())
}

/// `1 line`, `2 lines`: a count and a noun whose plural takes an `s`.
pub(crate) use optobus_service::counted;

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
pub(crate) use optobus_inspect::values_text;

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
