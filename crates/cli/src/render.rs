//! Output on stdout: text that ignores a closed pipe, pretty JSON, and register values as
//! aligned lines or a JSON object.

use std::io::Write;

use indicatif::{ProgressBar, ProgressStyle};
use optobus_device::RegisterInfo;
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

/// A progress bar on stderr drawn from `template` (indicatif's), hidden when stderr is not a
/// terminal.
pub(crate) fn progress_bar(length: u64, template: &str) -> ProgressBar {
    let style = ProgressStyle::with_template(template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("#-");
    ProgressBar::new(length).with_style(style)
}
