//! The one-line error of the inspector (and of the tools built on it), with a hint where one
//! helps.

use std::fmt;

use crate::parse::ParseError;

/// Why bytes could not be decoded, or a name or value not encoded, in a line for people;
/// `Display` gives the message and, in parentheses, the hint.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Error {
    /// What is wrong.
    pub message: String,
    /// What to try instead, if anything.
    pub hint: Option<String>,
}

impl Error {
    /// An error saying `message`.
    pub fn new(message: impl Into<String>) -> Self {
        Self {
            message: message.into(),
            hint: None,
        }
    }

    /// The error with what to try instead.
    pub fn hint(mut self, hint: impl Into<String>) -> Self {
        self.hint = Some(hint.into());
        self
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)?;
        if let Some(hint) = &self.hint {
            write!(f, " ({hint})")?;
        }
        Ok(())
    }
}

impl std::error::Error for Error {}

impl From<ParseError> for Error {
    fn from(error: ParseError) -> Self {
        Self::new(error.to_string())
    }
}

impl From<optobus_driver::Error> for Error {
    fn from(error: optobus_driver::Error) -> Self {
        Self::new(error.to_string())
    }
}
