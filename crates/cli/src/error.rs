//! One error type for the tool: a line saying what failed and what to try.

use std::fmt;

/// A failure the user sees as one line on stderr, with a non-zero exit code.
#[derive(Debug)]
pub(crate) struct CliError {
    /// What failed.
    pub(crate) message: String,
    /// What to try, if there is something.
    pub(crate) hint: Option<String>,
}

impl CliError {
    pub(crate) fn new(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            hint: None,
        }
    }

    pub(crate) fn hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }
}

impl fmt::Display for CliError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)?;
        if let Some(hint) = &self.hint {
            write!(f, " ({hint})")?;
        }
        Ok(())
    }
}

impl std::error::Error for CliError {}

/// Explains a driver error; `register` names the register involved, if any.
pub(crate) fn driver_error(error: optobus_driver::Error, register: Option<&str>) -> CliError {
    let subject = register.map(|r| format!(" for `{r}`")).unwrap_or_default();
    let timed_out = matches!(
        error,
        optobus_driver::Error::Transport(optobus_driver::transport::Error::Timeout { .. })
    );
    let error = CliError::new(format!("{error}{subject}"));
    if timed_out {
        error.hint("check wiring, --slave, --baud and --parity, or raise --timeout")
    } else {
        error
    }
}

impl From<optobus_driver::Error> for CliError {
    fn from(error: optobus_driver::Error) -> Self {
        driver_error(error, None)
    }
}

impl From<optobus_inspect::ResolveError> for CliError {
    fn from(error: optobus_inspect::ResolveError) -> Self {
        optobus_inspect::Error::from(error).into()
    }
}

impl From<optobus_inspect::ParseError> for CliError {
    fn from(error: optobus_inspect::ParseError) -> Self {
        Self::new(error.to_string())
    }
}

impl From<optobus_inspect::Error> for CliError {
    fn from(error: optobus_inspect::Error) -> Self {
        Self {
            message: error.message,
            hint: error.hint,
        }
    }
}
