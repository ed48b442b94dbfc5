//! Which line of a bus file a tool serves or uses when the user names none, and which
//! line's gateway a tool moves to another address.

use std::net::SocketAddr;

use super::{BusFile, GatewayConfig, LineConfig, Port};

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

/// Why a gateway could not be moved to another address: which gateway is meant must be plain.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum GatewayMoveError {
    /// No line has a gateway, and no RTU line could get one (a Modbus TCP line needs none).
    NoRtuLine,
    /// No line has a gateway, and several RTU lines could get one.
    SeveralRtuLines {
        /// Their names, in order.
        lines: Vec<String>,
    },
    /// Several lines have gateways.
    SeveralGateways {
        /// Their names, in order.
        lines: Vec<String>,
    },
}

impl std::fmt::Display for GatewayMoveError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let names = |lines: &[String]| {
            let names: Vec<String> = lines.iter().map(|l| format!("`{l}`")).collect();
            names.join(", ")
        };
        match self {
            Self::NoRtuLine => write!(f, "the bus file has no RTU line for a gateway to serve"),
            Self::SeveralRtuLines { lines } => write!(
                f,
                "which line should it serve? The bus file has RTU lines {}",
                names(lines)
            ),
            Self::SeveralGateways { lines } => write!(
                f,
                "lines {} of the bus file have gateways, and it moves one",
                names(lines)
            ),
        }
    }
}

impl std::error::Error for GatewayMoveError {}

impl BusFile {
    /// Makes the file's one gateway listen at `address` instead; a file without one gets a
    /// read-only gateway there on its one RTU line. Several gateways, or several RTU lines
    /// and no gateway, are refused: which one is meant must be plain.
    pub fn move_gateway(&mut self, address: SocketAddr) -> Result<(), GatewayMoveError> {
        let names = |lines: &[&LineConfig]| lines.iter().map(|l| l.name.clone()).collect();
        let with_gateway: Vec<&LineConfig> =
            self.lines.iter().filter(|l| l.gateway.is_some()).collect();
        let rtu: Vec<&LineConfig> = self.lines.iter().filter(|l| l.port.is_rtu()).collect();
        let line = match (with_gateway.as_slice(), rtu.as_slice()) {
            ([one], _) | ([], [one]) => one.name.clone(),
            ([], []) => return Err(GatewayMoveError::NoRtuLine),
            ([], several) => {
                return Err(GatewayMoveError::SeveralRtuLines {
                    lines: names(several),
                })
            }
            (several, _) => {
                return Err(GatewayMoveError::SeveralGateways {
                    lines: names(several),
                })
            }
        };
        if let Some(line) = self.lines.iter_mut().find(|l| l.name == line) {
            match line.gateway.as_mut() {
                Some(gateway) => gateway.listen = address,
                None => line.gateway = Some(GatewayConfig::new(address)),
            }
        }
        Ok(())
    }
}
