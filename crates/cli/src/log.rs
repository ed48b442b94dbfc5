//! Writing to stderr without panicking, and the simulator's exchange log, which never blocks
//! the runtime.
//!
//! `eprintln!` panics when stderr is closed, and any write to stderr blocks while nobody reads
//! a full pipe. Messages of the tool go through [`note!`] (errors ignored). The simulator logs
//! every exchange from inside its connection tasks, so those lines go to a [`Log`]: a bounded
//! channel to a writer thread of its own; when the channel is full, lines are dropped and
//! counted, and the writer says how many as soon as it can.
//!
//! `--verbose` installs a `tracing` subscriber on stderr ([`show_frames`]): the transport's
//! frame events and the driver's register events, one line each with the local time.

use std::fmt;
use std::io::Write;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::Duration;

/// Writes `args` to stderr, ignoring errors: a closed or broken stderr is no reason to stop.
pub(crate) fn stderr(args: fmt::Arguments<'_>) {
    let _ = std::io::stderr().lock().write_fmt(args);
}

/// `eprintln!` that never panics: a line on stderr, write errors ignored.
macro_rules! note {
    () => {
        $crate::log::stderr(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::log::stderr(format_args!("{}\n", format_args!($($arg)*)))
    };
}
pub(crate) use note;

/// `--verbose`: every frame the transport sends and receives (TRACE, `optobus_transport`) and
/// every register the driver reads or writes (DEBUG, `optobus_driver`), on stderr, as
/// `14:23:54.822 +01:00 -> 01 03 00 1F 00 07 B5 CE`.
pub(crate) fn show_frames() {
    use tracing::level_filters::LevelFilter;
    use tracing_subscriber::filter::Targets;
    use tracing_subscriber::layer::SubscriberExt;

    let targets = Targets::new()
        .with_target(
            optobus_driver::transport::frames::TARGET,
            LevelFilter::TRACE,
        )
        .with_target(optobus_driver::TRACE_TARGET, LevelFilter::DEBUG);
    // A closed stderr loses the lines; reporting that on stderr would panic.
    let lines = tracing_subscriber::fmt::layer()
        .event_format(EventLine)
        .log_internal_errors(false)
        .with_writer(std::io::stderr);
    let subscriber = tracing_subscriber::registry().with(lines).with(targets);
    // Only fails if a subscriber is already installed, which then shows the events.
    let _ = tracing::subscriber::set_global_default(subscriber);
}

/// An event as one line: the local time, the message, and a reply's delay.
struct EventLine;

/// The parts of an event a line shows.
#[derive(Default)]
struct LineFields {
    message: String,
    elapsed_us: Option<u64>,
}

impl tracing::field::Visit for LineFields {
    fn record_debug(&mut self, field: &tracing::field::Field, value: &dyn fmt::Debug) {
        if field.name() == "message" {
            self.message = format!("{value:?}");
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
        write!(
            writer,
            "{} {}",
            crate::render::time_of_day(),
            fields.message
        )?;
        if let Some(us) = fields.elapsed_us {
            write!(writer, " ({}.{:03} ms)", us / 1000, us % 1000)?;
        }
        writeln!(writer)
    }
}

/// Lines the writer thread may hold back before new ones are dropped.
const CAPACITY: usize = 1024;

enum Message {
    Line(String),
    /// Say how many lines were dropped, then stop.
    Finish(mpsc::Sender<()>),
}

/// A log whose lines a thread of its own writes to stderr.
#[derive(Clone)]
pub(crate) struct Log {
    sender: SyncSender<Message>,
    dropped: Arc<AtomicU64>,
}

impl fmt::Debug for Log {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Log")
            .field("dropped", &self.dropped.load(Ordering::Relaxed))
            .finish()
    }
}

impl Log {
    /// Starts the writer thread. If no thread can be started, lines are dropped and counted.
    pub(crate) fn start() -> Self {
        let (sender, receiver) = mpsc::sync_channel(CAPACITY);
        let dropped = Arc::new(AtomicU64::new(0));
        let count = Arc::clone(&dropped);
        let _ = std::thread::Builder::new()
            .name("optobus-log".into())
            .spawn(move || write_lines(&receiver, &count));
        Self { sender, dropped }
    }

    /// Hands `line` to the writer; never waits. A line that does not fit is dropped and
    /// counted.
    pub(crate) fn line(&self, line: impl Into<String>) {
        let mut line = line.into();
        line.push('\n');
        match self.sender.try_send(Message::Line(line)) {
            Ok(()) => {}
            Err(TrySendError::Full(_) | TrySendError::Disconnected(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Lines dropped so far.
    #[cfg_attr(not(test), allow(dead_code))]
    pub(crate) fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Lets the writer say how many lines were dropped, waiting for it at most `within` (it
    /// may be stuck on a stderr nobody reads).
    pub(crate) fn finish(&self, within: Duration) {
        let (done, finished) = mpsc::channel();
        if self.sender.try_send(Message::Finish(done)).is_ok() {
            let _ = finished.recv_timeout(within);
        }
    }
}

/// The writer thread: every line in order, a note of dropped lines before the next line
/// that gets through; write errors ignored.
fn write_lines(receiver: &Receiver<Message>, dropped: &AtomicU64) {
    let mut reported = 0u64;
    for message in receiver {
        let now = dropped.load(Ordering::Relaxed);
        if now > reported {
            stderr(format_args!(
                "optobus: {} log lines dropped: stderr is not keeping up\n",
                now - reported
            ));
            reported = now;
        }
        match message {
            Message::Line(line) => stderr(format_args!("{line}")),
            Message::Finish(done) => {
                let _ = done.send(());
                return;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_beyond_the_capacity_are_dropped_and_counted_never_waited_for() {
        // A channel nobody drains: the writer thread is not started.
        let (sender, _receiver) = mpsc::sync_channel(CAPACITY);
        let log = Log {
            sender,
            dropped: Arc::new(AtomicU64::new(0)),
        };
        for i in 0..CAPACITY + 10 {
            log.line(format!("line {i}"));
        }
        assert_eq!(log.dropped(), 10);
        // Finishing does not wait for a writer that cannot take the message.
        log.finish(Duration::from_secs(60));
    }
}
