//! Writing to stderr without panicking and without ever blocking the runtime.
//!
//! `eprintln!` panics when stderr is closed, and any write to stderr blocks while nobody reads
//! a full pipe: on `optobus run`'s runtime that would freeze the gateway and every output.
//! Every message of the tool ([`note!`]), every exchange the simulator logs and every
//! `--verbose` line goes to one [`Outlet`]: a writer thread of its own, fed through a bounded
//! queue. When stderr does not keep up, the oldest lines are dropped and counted, and the
//! writer says how many before the next line that gets through.
//!
//! `--verbose` installs the service's `tracing` lines ([`show_frames`]): the transport's frame
//! events and the driver's register events, one line each with the local time. `optobus run`
//! and `optobus ui` install them for the operator ([`show_operations`]): changes of state and
//! the audit trail of writes from the network.

use std::fmt;
use std::sync::OnceLock;
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

use optobus_service::journal::{self, Lines};
use optobus_service::outlet::{LineInto, Outlet, TextLines};

/// Lines stderr's writer may hold back; beyond, the oldest are dropped.
const CAPACITY: usize = 1024;

/// The outlet of stderr, started with the first line.
static STDERR: OnceLock<Outlet<String, StderrLines>> = OnceLock::new();

/// What stderr's outlet writes to: stderr, telling the lines it dropped.
type StderrLines = TextLines<std::io::Stderr>;

fn outlet() -> &'static Outlet<String, StderrLines> {
    let lines = || TextLines::new(std::io::stderr(), "stderr");
    STDERR.get_or_init(|| Outlet::start("optobus-stderr", CAPACITY, lines()))
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

/// `--verbose`: every frame the transport sends and receives and every register the driver
/// reads or writes, on stderr (the service's [`journal`] lines).
pub(crate) fn show_frames() {
    journal::install(
        Lines {
            frames: true,
            operations: false,
        },
        || LineInto::new(outlet()),
    );
}

/// What a bus that runs unattended tells its operator, on stderr (the service's
/// [`journal`] lines: changes of state and the audit trail).
pub(crate) fn show_operations() {
    journal::install(
        Lines {
            frames: false,
            operations: true,
        },
        || LineInto::new(outlet()),
    );
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
