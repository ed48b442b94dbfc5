//! What a run tells people on stderr through `tracing`, one line per event: the operator's
//! news of a bus that runs unattended ([`Lines::operations`]) and, for `--verbose`, the
//! transport's frames and the driver's register events ([`Lines::frames`]). The front end
//! gives the writer (its own non-blocking outlet); this module decides which events and how
//! each is written.

use std::fmt;

use tracing_subscriber::fmt::MakeWriter;

/// Which events become lines.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Lines {
    /// Every frame the transport sends and receives (TRACE, the transport's frame target) and
    /// every register the driver reads or writes (DEBUG, the driver's target), as
    /// `14:23:54.822 +01:00 -> 01 03 00 1F 00 07 B5 CE`.
    pub frames: bool,
    /// What a bus that runs unattended tells its operator, one line per change, never per
    /// retry: a line opened, closed or opened again; a device offline (why) or online again;
    /// the MQTT broker connected, unreachable or connected again; a listener that cannot
    /// accept; and the audit trail (`optobus_audit`): every write, command and buffer read-out
    /// a network source asked for, who asked, and whether it was done or why not. Under
    /// systemd (stderr handed to the journal, `JOURNAL_STREAM` set) each line starts with its
    /// syslog priority (`<4>` a warning, `<6>` news) so that journald keeps it at that level,
    /// and without a time (journald adds its own); elsewhere with the local time.
    pub operations: bool,
}

/// The targets whose INFO and WARN events are the operator's news.
pub const OPERATIONS: [&str; 5] = [
    "optobus_bus",
    "optobus_audit",
    "optobus_mqtt",
    "optobus_http",
    "optobus_console",
];

/// The local time of day with its offset, for people: `14:23:54.822 +01:00`.
pub fn time_of_day() -> String {
    jiff::ZonedDateTime::now()
        .strftime("%H:%M:%S%.3f %:z")
        .to_string()
}

/// Installs the one `tracing` subscriber of the process, writing `lines` through `writer`
/// (a line per writer made). A subscriber already installed is left as it is (it then shows
/// the events).
pub fn install<W>(lines: Lines, writer: W)
where
    W: for<'writer> MakeWriter<'writer> + Clone + Send + Sync + 'static,
{
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
    let frame_lines = lines.frames.then(|| {
        tracing_subscriber::fmt::layer()
            .event_format(EventLine::Frame)
            .log_internal_errors(false)
            .with_writer(writer.clone())
            .with_filter(frame_targets)
    });
    let operation_targets = OPERATIONS.iter().fold(Targets::new(), |targets, target| {
        targets.with_target(*target, LevelFilter::INFO)
    });
    let operation_lines = lines.operations.then(|| {
        tracing_subscriber::fmt::layer()
            .event_format(EventLine::Operation {
                journald: std::env::var_os("JOURNAL_STREAM").is_some(),
            })
            .log_internal_errors(false)
            .with_writer(writer)
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
        let time = time_of_day();
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
