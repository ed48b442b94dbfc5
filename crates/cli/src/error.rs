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
    use optobus_driver::transport::Error as Wire;
    use optobus_driver::Error;
    let subject = register.map(|r| format!(" for `{r}`")).unwrap_or_default();
    match error {
        Error::Transport(Wire::Timeout { after }) => {
            CliError::new(format!("no reply within {} ms{subject}", after.as_millis()))
                .hint("check wiring, --slave, --baud and --parity, or raise --timeout")
        }
        Error::Transport(Wire::Exception { function, code }) => {
            let name = match code.0 {
                1 => " \"illegal function\"",
                2 => " \"illegal data address\"",
                3 => " \"illegal data value\"",
                4 => " \"slave device failure\"",
                _ => "",
            };
            CliError::new(format!(
                "the device answered exception {:02X}{name} to function {function:02X}{subject}",
                code.0
            ))
        }
        Error::Transport(Wire::Io(io)) => CliError::new(format!("I/O error{subject}: {io}")),
        other => CliError::new(format!("{other}")),
    }
}

impl From<optobus_driver::Error> for CliError {
    fn from(error: optobus_driver::Error) -> Self {
        driver_error(error, None)
    }
}

impl From<optobus_inspect::ResolveError> for CliError {
    fn from(error: optobus_inspect::ResolveError) -> Self {
        let hint = match &error {
            optobus_inspect::ResolveError::Unknown { family, near, .. } if near.is_empty() => {
                Some(format!("see `optobus registers {family}`"))
            }
            optobus_inspect::ResolveError::Unknown { near, .. } => {
                Some(format!("did you mean {}?", near.join(", ")))
            }
            optobus_inspect::ResolveError::NoCopy { .. } => None,
        };
        Self {
            message: error.to_string(),
            hint,
        }
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
