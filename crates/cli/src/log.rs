//! Writing to stderr without panicking and without ever blocking the runtime.
//!
//! `eprintln!` panics when stderr is closed, and any write to stderr blocks while nobody reads
//! a full pipe: on `optobus run`'s runtime that would freeze the gateway and every output.
//! Every message of the tool ([`note!`]), every exchange the simulator logs and every
//! `--verbose` line goes to one [`Outlet`]: a writer thread of its own, fed through a bounded
//! queue. When stderr does not keep up, the oldest lines are dropped and counted, and the
//! writer says how many before the next line that gets through.
//!
//! `--verbose` installs a `tracing` subscriber ([`show_frames`]): the transport's frame events
//! and the driver's register events, one line each with the local time. `optobus run` and
//! `optobus ui` install one for the operator ([`show_operations`]): changes of state and the
//! audit trail of writes from the network.

use std::fmt;
use std::io::Write;
use std::sync::OnceLock;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

use optobus_service::outlet::{Outlet, Sink};

/// Lines stderr's writer may hold back; beyond, the oldest are dropped.
const CAPACITY: usize = 1024;

/// Writes the lines of the tool to stderr, each batch at once; write errors ignored (a closed
/// or broken stderr is no reason to stop).
#[derive(Default)]
struct Stderr {
    /// Dropped lines already told about.
    told: u64,
}

impl Sink<String> for Stderr {
    fn write(&mut self, lines: Vec<String>, dropped: u64) {
        let mut text = String::new();
        if dropped > self.told {
            text += &format!(
                "optobus: stderr is not being read: {} of its oldest lines dropped\n",
                dropped - self.told
            );
            self.told = dropped;
        }
        text.extend(lines);
        let mut out = std::io::stderr().lock();
        let _ = out.write_all(text.as_bytes());
        let _ = out.flush();
    }
}

/// The outlet of stderr, started with the first line.
static STDERR: OnceLock<Outlet<String, Stderr>> = OnceLock::new();

fn outlet() -> &'static Outlet<String, Stderr> {
    STDERR.get_or_init(|| Outlet::start("optobus-stderr", CAPACITY, Stderr::default()))
}

/// Hands `args` to stderr's writer; never waits.
pub(crate) fn stderr(args: fmt::Arguments<'_>) {
    outlet().push(args.to_string());
}

/// Waits, at most `within`, until what was said so far is on stderr (before the process
/// ends; stderr may be a pipe nobody reads).
pub(crate) fn flush(within: Duration) {
    if let Some(outlet) = STDERR.get() {
        outlet.flush(within);
    }
}

/// `eprintln!` that never panics and never waits: a line for stderr, written by a thread of
/// its own.
macro_rules! note {
    () => {
        $crate::log::stderr(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::log::stderr(format_args!("{}\n", format_args!($($arg)*)))
    };
}
pub(crate) use note;

/// A `--verbose` line being formatted, handed to stderr's writer whole when done.
#[derive(Default)]
struct TracedLine(Vec<u8>);

impl Write for TracedLine {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.0.extend_from_slice(bytes);
        Ok(bytes.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Drop for TracedLine {
    fn drop(&mut self) {
        if !self.0.is_empty() {
            outlet().push(String::from_utf8_lossy(&self.0).into_owned());
        }
    }
}

/// `--verbose`: every frame the transport sends and receives (TRACE, `optobus_transport`) and
/// every register the driver reads or writes (DEBUG, `optobus_driver`), on stderr, as
/// `14:23:54.822 +01:00 -> 01 03 00 1F 00 07 B5 CE`.
pub(crate) fn show_frames() {
    install(true, false);
}

/// What a bus that runs unattended tells its operator on stderr, one line per change, never
/// per retry: a line opened, closed or opened again; a device offline (why) or online again;
/// the MQTT broker connected, unreachable or connected again; a listener that cannot accept;
/// and the audit trail (`optobus_audit`): every write, command and buffer read-out a network
/// source asked for, who asked, and whether it was done or why not. Under systemd (stderr
/// handed to the journal, `JOURNAL_STREAM` set) each line starts with its syslog priority
/// (`<4>` a warning, `<6>` news) so that journald keeps it at that level, and without a time
/// (journald adds its own); elsewhere with the local time.
pub(crate) fn show_operations() {
    install(false, true);
}

/// The targets whose INFO and WARN events are the operator's news.
const OPERATIONS: [&str; 5] = [
    "optobus_bus",
    "optobus_audit",
    "optobus_mqtt",
    "optobus_http",
    "optobus_console",
];

/// Installs the one `tracing` subscriber of the process: the frames, the operations, or both.
fn install(frames: bool, operations: bool) {
    use tracing::level_filters::LevelFilter;
    use tracing_subscriber::filter::Targets;
    use tracing_subscriber::layer::SubscriberExt;
    use tracing_subscriber::Layer;

    let frame_targets = Targets::new()
        .with_target(
            optobus_driver::transport::frames::TARGET,
            LevelFilter::TRACE,
        )
        .with_target(optobus_driver::TRACE_TARGET, LevelFilter::DEBUG);
    // A closed stderr loses the lines; reporting that on stderr would panic.
    let frame_lines = frames.then(|| {
        tracing_subscriber::fmt::layer()
            .event_format(EventLine::Frame)
            .log_internal_errors(false)
            .with_writer(TracedLine::default)
            .with_filter(frame_targets)
    });
    let operation_targets = OPERATIONS.iter().fold(Targets::new(), |targets, target| {
        targets.with_target(*target, LevelFilter::INFO)
    });
    let operation_lines = operations.then(|| {
        tracing_subscriber::fmt::layer()
            .event_format(EventLine::Operation {
                journald: std::env::var_os("JOURNAL_STREAM").is_some(),
            })
            .log_internal_errors(false)
            .with_writer(TracedLine::default)
            .with_filter(operation_targets)
    });
    let subscriber = tracing_subscriber::registry()
        .with(frame_lines)
        .with(operation_lines);
    // Only fails if a subscriber is already installed, which then shows the events.
    let _ = tracing::subscriber::set_global_default(subscriber);
}

/// How an event is written as one line.
enum EventLine {
    /// A frame or register event of `--verbose`: the local time, the message, and a reply's
    /// delay: `14:23:54.822 +01:00 -> 01 03 00 1F 00 07 B5 CE`.
    Frame,
    /// An operator's line: `optobus: 14:23:54.822 +01:00 warning: line `rs485` closed …`, or
    /// for journald `<4>optobus: line `rs485` closed …`.
    Operation { journald: bool },
}

/// The parts of an event a line shows.
#[derive(Default)]
struct LineFields {
    message: String,
    elapsed_us: Option<u64>,
    /// The other fields, as ` name=value`.
    others: String,
}

impl tracing::field::Visit for LineFields {
    fn record_debug(&mut self, field: &tracing::field::Field, value: &dyn fmt::Debug) {
        if field.name() == "message" {
            self.message = format!("{value:?}");
        } else {
            self.others += &format!(" {}={value:?}", field.name());
        }
    }

    fn record_u64(&mut self, field: &tracing::field::Field, value: u64) {
        if field.name() == "elapsed_us" {
            self.elapsed_us = Some(value);
        }
    }
}

impl<S, N> tracing_subscriber::fmt::FormatEvent<S, N> for EventLine
where
    S: tracing::Subscriber + for<'a> tracing_subscriber::registry::LookupSpan<'a>,
    N: for<'a> tracing_subscriber::fmt::FormatFields<'a> + 'static,
{
    fn format_event(
        &self,
        _: &tracing_subscriber::fmt::FmtContext<'_, S, N>,
        mut writer: tracing_subscriber::fmt::format::Writer<'_>,
        event: &tracing::Event<'_>,
    ) -> fmt::Result {
        let mut fields = LineFields::default();
        event.record(&mut fields);
        let time = crate::render::time_of_day();
        match self {
            Self::Frame => {
                write!(writer, "{time} {}", fields.message)?;
                if let Some(us) = fields.elapsed_us {
                    write!(writer, " ({}.{:03} ms)", us / 1000, us % 1000)?;
                }
                writeln!(writer)
            }
            Self::Operation { journald } => {
                let (priority, word) = match *event.metadata().level() {
                    tracing::Level::ERROR => (3, "error"),
                    tracing::Level::WARN => (4, "warning"),
                    _ => (6, "info"),
                };
                if *journald {
                    write!(writer, "<{priority}>optobus: ")?;
                } else {
                    write!(writer, "optobus: {time} {word}: ")?;
                }
                // One event, one line: journald and grep take a line as a record.
                let line = fields.message + &fields.others;
                writeln!(writer, "{}", line.replace('\n', " "))
            }
        }
    }
}

/// A progress bar on stderr drawn from `template` (indicatif's), hidden when stderr is not a
/// terminal. The notes said before it are written first (they have a thread of their own).
pub(crate) fn progress_bar(length: u64, template: &str) -> ProgressBar {
    flush(Duration::from_secs(1));
    let style = ProgressStyle::with_template(template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("#-");
    ProgressBar::new(length).with_style(style)
}
