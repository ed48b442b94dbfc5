//! Writing to stderr without panicking, and the simulator's exchange log, which never blocks
//! the runtime.
//!
//! `eprintln!` panics when stderr is closed, and any write to stderr blocks while nobody reads
//! a full pipe. Messages of the tool go through [`note!`] (errors ignored). The simulator logs
//! every exchange from inside its connection tasks, so those lines go to a [`Log`]: a bounded
//! channel to a writer thread of its own; when the channel is full, lines are dropped and
//! counted, and the writer says how many as soon as it can.

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
