//! One error type for the tool: a line saying what failed and what to try, and the exit code
//! that tells a script which kind of failure it was.

use std::fmt;
use std::process::ExitCode;

use optobus_driver::transport::Error as WireError;

/// The exit codes of `optobus`, documented in its `--help` and the README.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Exit {
    /// The device, the line, the network or the system failed: a timeout, an exception, a
    /// malformed reply, a port that does not open, no device found.
    Failed = 1,
    /// The command line is malformed (clap's own code for usage errors).
    Usage = 2,
    /// Refused before anything was sent: an unknown name, a value out of range, a missing
    /// `--yes`, no model named for a real device.
    Refused = 3,
}

impl Exit {
    pub(crate) fn code(self) -> ExitCode {
        ExitCode::from(self as u8)
    }
}

/// The exit codes, for `--help`.
pub(crate) const EXIT_CODES: &str =
    "Exit codes: 0 done; 1 the device, the line or the system failed \
(timeout, exception, bad reply, port or address unreachable); 2 usage error; 3 refused before \
anything was sent (unknown name, value out of range, missing --yes, no model for a device).";

/// A failure the user sees as one line on stderr (with a hint in parentheses where one helps)
/// and the exit code of its kind.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct CliError {
    error: optobus_inspect::Error,
    exit: Exit,
}

impl CliError {
    /// Input refused before anything was sent.
    pub(crate) fn new(message: impl Into<String>) -> Self {
        Self {
            error: optobus_inspect::Error::new(message),
            exit: Exit::Refused,
        }
    }

    /// The command line itself is malformed (a usage error, as clap reports them).
    pub(crate) fn usage(message: impl Into<String>) -> Self {
        Self {
            error: optobus_inspect::Error::new(message),
            exit: Exit::Usage,
        }
    }

    /// The device, the line or the system failed.
    pub(crate) fn failed(message: impl Into<String>) -> Self {
        Self {
            error: optobus_inspect::Error::new(message),
            exit: Exit::Failed,
        }
    }

    /// A bus file at `path` that could not be used: one that cannot be read is the system's
    /// failure, one that does not pass is refused with every problem.
    pub(crate) fn bus_file(path: &std::path::Path, error: optobus_bus::LoadError) -> Self {
        match error {
            optobus_bus::LoadError::Read { .. } => Self::failed(error.to_string()),
            optobus_bus::LoadError::Rejected(rejected) => Self::new(format!(
                "{} does not pass the bus file checks:\n{}",
                path.display(),
                rejected.render().trim_end()
            )),
        }
    }

    /// Input refused as `refusal` says, with its `hint` if it has one (a list of addresses or
    /// rates).
    pub(crate) fn listed(refusal: &impl fmt::Display, hint: Option<String>) -> Self {
        let refused = Self::new(refusal.to_string());
        match hint {
            Some(hint) => refused.hint(hint),
            None => refused,
        }
    }

    /// The error with what to try instead.
    pub(crate) fn hint(mut self, hint: impl Into<String>) -> Self {
        self.error = self.error.hint(hint);
        self
    }

    /// The error with `prefix` before its message (where the input came from).
    pub(crate) fn prefixed(mut self, prefix: &str) -> Self {
        self.error.message.insert_str(0, prefix);
        self
    }

    pub(crate) fn exit(&self) -> Exit {
        self.exit
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.error.fmt(f)
    }
}

impl std::error::Error for CliError {}

/// The inspector refuses names, values and bytes; it never sends anything.
impl From<optobus_inspect::Error> for CliError {
    fn from(error: optobus_inspect::Error) -> Self {
        Self {
            error,
            exit: Exit::Refused,
        }
    }
}

impl From<optobus_inspect::ParseError> for CliError {
    fn from(error: optobus_inspect::ParseError) -> Self {
        optobus_inspect::Error::from(error).into()
    }
}

impl From<optobus_driver::Error> for CliError {
    fn from(error: optobus_driver::Error) -> Self {
        driver_error(error, None)
    }
}

/// A list of slave addresses refused before anything was sent.
impl From<optobus_driver::scan::SlaveListError> for CliError {
    fn from(error: optobus_driver::scan::SlaveListError) -> Self {
        Self::listed(&error, error.hint())
    }
}

/// Whether the driver refused before sending (a value, a request no device takes) or the
/// exchange failed.
fn exit_of(error: &optobus_driver::Error) -> Exit {
    match error {
        optobus_driver::Error::Transport(WireError::Request(_) | WireError::Unsupported(_)) => {
            Exit::Refused
        }
        optobus_driver::Error::Transport(_) => Exit::Failed,
        // Sent, and the device did not show it had finished (or did not answer): its failure.
        optobus_driver::Error::CommandNotFinished { .. }
        | optobus_driver::Error::NotReady { .. } => Exit::Failed,
        _ => Exit::Refused,
    }
}

/// Explains a driver error; `register` names the register involved, if any.
pub(crate) fn driver_error(error: optobus_driver::Error, register: Option<&str>) -> CliError {
    let subject = register.map(|r| format!(" for `{r}`")).unwrap_or_default();
    let timed_out = matches!(
        error,
        optobus_driver::Error::Transport(WireError::Timeout { .. })
    );
    // A reply of another shape than the model's (length, byte count, exception frame) is
    // most often another model's reply.
    let misfit = matches!(
        error,
        optobus_driver::Error::Transport(WireError::Frame(_) | WireError::WordCount { .. })
    );
    let explained = CliError {
        error: optobus_inspect::Error::new(format!("{error}{subject}")),
        exit: exit_of(&error),
    };
    if timed_out {
        explained.hint(
            "check the connection and --slave (on a serial line also --baud and --parity), or \
             raise --timeout",
        )
    } else if misfit {
        explained.hint(
            "check --model: the reply does not fit this model's framing, `optobus identify` \
             names the model that answers; then the connection (on a serial line --baud and \
             --parity)",
        )
    } else {
        explained
    }
}

/// Explains a transport error of a raw exchange; `subject` says what was read or written.
pub(crate) fn transport_error(error: WireError, subject: &str) -> CliError {
    driver_error(optobus_driver::Error::Transport(error), Some(subject))
}

/// A chart's file name is refused before anything is read or sent; drawing it is the system's
/// failure.
impl From<optobus_chart::ChartError> for CliError {
    fn from(error: optobus_chart::ChartError) -> Self {
        match error {
            optobus_chart::ChartError::NotSvgOrPng { .. } => {
                Self::new(error.to_string()).hint("name the output file `….svg` or `….png`")
            }
            optobus_chart::ChartError::Draw { .. } => Self::failed(error.to_string()),
        }
    }
}
