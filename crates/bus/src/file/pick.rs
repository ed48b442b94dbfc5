//! Which line of a bus file a tool serves or uses when the user names none.

use super::{BusFile, Port};

/// Why no line of a bus file was picked.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LinePickError {
    /// The file has no line of the name given.
    NoSuchLine {
        /// The name given.
        name: String,
        /// The file's lines, in order.
        lines: Vec<String>,
    },
    /// No name was given, and the file has several lines of which not exactly one is
    /// simulated.
    Several {
        /// The file's lines, in order.
        lines: Vec<String>,
    },
}

impl std::fmt::Display for LinePickError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::NoSuchLine { name, lines } => {
                write!(f, "no line `{name}` (its lines: {})", lines.join(", "))
            }
            Self::Several { lines } => write!(f, "several lines ({})", lines.join(", ")),
        }
    }
}

impl std::error::Error for LinePickError {}

impl BusFile {
    /// The index of the line named `named`; without a name, the file's only line, or else
    /// its only `simulated: true` line.
    pub fn pick_line(&self, named: Option<&str>) -> Result<usize, LinePickError> {
        let lines = || self.lines.iter().map(|line| line.name.clone()).collect();
        if let Some(name) = named {
            return self
                .lines
                .iter()
                .position(|line| line.name == name)
                .ok_or_else(|| LinePickError::NoSuchLine {
                    name: name.to_owned(),
                    lines: lines(),
                });
        }
        let mut simulated = (0..self.lines.len()).filter(|&index| {
            self.lines
                .get(index)
                .is_some_and(|line| line.port == Port::Simulated)
        });
        match (self.lines.len(), simulated.next(), simulated.next()) {
            (1, _, _) => Ok(0),
            (_, Some(only), None) => Ok(only),
            _ => Err(LinePickError::Several { lines: lines() }),
        }
    }
}
