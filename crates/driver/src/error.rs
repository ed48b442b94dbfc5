//! What a driver call can fail with.

use std::fmt;
use std::time::Duration;

use optobus_codec::value::{Fixed, Scale};
use optobus_device::{Invalid, RegisterInfo};

/// Why a driver call failed. Validation errors are raised before anything is sent.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The transaction failed on the wire (timeout, exception, malformed reply, I/O).
    Transport(optobus_transport::Error),
    /// The value lies outside the register's range.
    OutOfRange {
        /// Register name.
        register: &'static str,
        /// The value, in raw steps.
        raw: i64,
        /// Smallest allowed raw value.
        min: i64,
        /// Largest allowed raw value.
        max: i64,
        /// One raw step, for showing the values in units.
        scale: Option<Scale>,
        /// The register's unit, if it has one.
        unit: Option<&'static str>,
    },
    /// The value lies within the range but is not one of the values the manual lists for the
    /// register (LC-RS baud rates).
    NotListed {
        /// Register name.
        register: &'static str,
        /// The value, in raw steps.
        raw: i64,
        /// The values the register accepts, in raw steps.
        allowed: &'static [i64],
        /// One raw step, for showing the values in units.
        scale: Option<Scale>,
        /// The register's unit, if it has one.
        unit: Option<&'static str>,
    },
    /// The value is not a whole number of the register's steps, or has too many of them.
    NotRepresentable {
        /// Register name.
        register: &'static str,
        /// The value given.
        value: Fixed,
        /// The register's step.
        scale: Scale,
        /// The register's unit, if it has one.
        unit: Option<&'static str>,
    },
    /// The code is not one the manual defines for the register or field.
    UndefinedCode {
        /// Register name (`register.field` for a packed field).
        register: &'static str,
        /// Field name, for packed registers.
        field: Option<&'static str>,
        /// The code.
        code: u32,
    },
    /// A packed field's value does not fit its bits.
    FieldTooWide {
        /// Register name.
        register: &'static str,
    },
    /// The register cannot be read or written this way (for example reading a write-only
    /// register through a generic tool).
    NotAllowed {
        /// Register name.
        register: &'static str,
        /// What was refused.
        what: &'static str,
    },
    /// The slave address cannot be used for this: 248 to 255 are reserved, and broadcast
    /// (0) only writes, as nothing answers it. Nothing was sent.
    Slave {
        /// The address.
        slave: u8,
        /// Why it cannot be used.
        reason: &'static str,
    },
    /// A multi-request read came back out of step with the device: the device's own count
    /// shows data that never reached us (a buffer page lost to a failed read).
    OutOfStep {
        /// What was being read.
        what: &'static str,
        /// Values received.
        received: u64,
        /// Values the device reports as handed out.
        reported: u64,
    },
    /// The device did not answer within the time the manual gives for starting up.
    NotReady {
        /// How long we polled.
        waited: Duration,
        /// The last failure.
        last: Box<optobus_transport::Error>,
    },
    /// A command was written and acknowledged, but its register did not read back the value
    /// that shows the device finished (its spec's `done_when`) within the time the spec
    /// allows: the command may not have taken effect (a flash write still going on, or lost).
    CommandNotFinished {
        /// The command.
        command: &'static str,
        /// The register polled.
        register: &'static str,
        /// The raw value that means finished.
        expected: u32,
        /// What the register read last, if a read was answered.
        last_read: Option<u32>,
        /// How long after the write we gave up.
        waited: Duration,
        /// The last poll's failure, if it failed.
        last_error: Option<Box<optobus_transport::Error>>,
    },
}

/// `raw` steps of `scale` in `unit`: `5000.1 us`.
fn show(raw: i64, scale: Option<Scale>, unit: Option<&str>) -> String {
    let number = match scale {
        Some(scale) => Fixed::new(raw, scale).to_string(),
        None => raw.to_string(),
    };
    with_unit(number, unit)
}

/// `number unit`, or the number alone.
fn with_unit(number: impl fmt::Display, unit: Option<&str>) -> String {
    match unit {
        Some(unit) => format!("{number} {unit}"),
        None => number.to_string(),
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Transport(error) => error.fmt(f),
            Self::OutOfRange {
                register,
                raw,
                min,
                max,
                scale,
                unit,
            } => write!(
                f,
                "{} is out of range for `{register}` ({} ..= {})",
                show(*raw, *scale, *unit),
                show(*min, *scale, *unit),
                show(*max, *scale, *unit)
            ),
            Self::NotListed {
                register,
                raw,
                allowed,
                scale,
                unit,
            } => {
                let allowed: Vec<String> =
                    allowed.iter().map(|v| show(*v, *scale, *unit)).collect();
                write!(
                    f,
                    "{} is not a value `{register}` accepts (only {})",
                    show(*raw, *scale, *unit),
                    allowed.join(", ")
                )
            }
            Self::NotRepresentable {
                register,
                value,
                scale,
                unit,
            } => write!(
                f,
                "{} cannot be written to `{register}` exactly: it holds whole steps of {} within its width",
                with_unit(value, *unit),
                with_unit(scale.step(), *unit)
            ),
            Self::UndefinedCode {
                register,
                field: Some(field),
                code,
            } => write!(f, "code {code} is not defined for `{register}.{field}`"),
            Self::UndefinedCode {
                register, code, ..
            } => write!(f, "code {code} is not defined for `{register}`"),
            Self::FieldTooWide { register } => {
                write!(f, "a field of `{register}` does not fit its bits")
            }
            Self::NotAllowed { register, what } => write!(f, "`{register}` cannot be {what}"),
            Self::Slave { slave, reason } => write!(f, "slave address {slave}: {reason}"),
            Self::OutOfStep {
                what,
                received,
                reported,
            } => write!(
                f,
                "{what} lost data: {received} values received, the device handed out {reported}"
            ),
            Self::NotReady { waited, last } => write!(
                f,
                "the device did not answer within {} ms (last error: {last})",
                waited.as_millis()
            ),
            Self::CommandNotFinished {
                command,
                register,
                expected,
                last_read,
                waited,
                last_error,
            } => {
                write!(
                    f,
                    "`{command}` did not finish within {} ms: `{register}` ",
                    waited.as_millis()
                )?;
                match (last_error, last_read) {
                    (Some(error), _) => write!(f, "could not be read ({error})"),
                    (None, Some(raw)) => write!(f, "still reads {raw}"),
                    (None, None) => f.write_str("was not read"),
                }?;
                write!(f, ", not {expected}")
            }
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Transport(error) => Some(error),
            Self::NotReady { last, .. } => Some(last.as_ref()),
            Self::CommandNotFinished {
                last_error: Some(last),
                ..
            } => Some(last.as_ref()),
            _ => None,
        }
    }
}

impl From<optobus_transport::Error> for Error {
    fn from(error: optobus_transport::Error) -> Self {
        Self::Transport(error)
    }
}

impl Error {
    /// The typed error for a value [`RegisterInfo::check`] refuses for `register`.
    pub(crate) fn invalid(register: &'static RegisterInfo, why: Invalid) -> Self {
        match why {
            Invalid::OutOfRange {
                field,
                value,
                min,
                max,
            } => Self::OutOfRange {
                register: field.map_or(register.name, |field| field.name),
                raw: value,
                min,
                max,
                scale: field.map_or(register.scale, |field| field.scale),
                unit: field.map_or(register.unit, |field| field.unit),
            },
            Invalid::UndefinedCode { field, code } => Self::UndefinedCode {
                register: register.name,
                field: field.map(|field| field.name),
                code,
            },
            Invalid::Unlisted { value, allowed } => Self::NotListed {
                register: register.name,
                raw: value,
                allowed,
                scale: register.scale,
                unit: register.unit,
            },
            Invalid::StrayBits { .. } => Self::FieldTooWide {
                register: register.name,
            },
        }
    }

    /// The refusal to read `register`: write-only, or an action register whose read the
    /// manual leaves undefined. Nothing is sent.
    pub(crate) fn unreadable(register: &'static RegisterInfo) -> Self {
        Self::NotAllowed {
            register: register.name,
            what: if register.action {
                "read (it is an action register: the manual does not say what a read returns)"
            } else {
                "read (it is write-only)"
            },
        }
    }

    /// The device's exception code, when it answered with one.
    pub fn exception(&self) -> Option<optobus_transport::ExceptionCode> {
        match self {
            Self::Transport(optobus_transport::Error::Exception { code, .. }) => Some(*code),
            _ => None,
        }
    }
}

/// The kind of a failure ([`Error::kind`]): two failures of one kind compare equal whatever
/// their counts, durations and messages, so `cannot connect (1 attempt)` and `(2 attempts)`
/// are one kind, while a refused connection and an unreachable host, or exceptions 02 and 04,
/// are two.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ErrorKind {
    variant: std::mem::Discriminant<Error>,
    wire: Option<std::mem::Discriminant<optobus_transport::Error>>,
    detail: Detail,
}

/// What tells failures of one variant apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Detail {
    None,
    Exception(optobus_transport::ExceptionCode),
    Io(std::io::ErrorKind),
}

impl Error {
    /// The kind of this failure: a tool that reports a lasting failure once says it again only
    /// when its kind changes (or it recovers).
    pub fn kind(&self) -> ErrorKind {
        use optobus_transport::Error as Wire;
        let wire = match self {
            Self::Transport(wire) => Some(wire),
            Self::NotReady { last, .. } => Some(last.as_ref()),
            Self::CommandNotFinished {
                last_error: Some(last),
                ..
            } => Some(last.as_ref()),
            _ => None,
        };
        let detail = match wire {
            Some(Wire::Exception { code, .. }) => Detail::Exception(*code),
            Some(Wire::Connect { source, .. } | Wire::Io(source)) => Detail::Io(source.kind()),
            _ => Detail::None,
        };
        ErrorKind {
            variant: std::mem::discriminant(self),
            wire: wire.map(std::mem::discriminant),
            detail,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Error;
    use optobus_transport::{Error as Wire, ExceptionCode};
    use std::io;

    fn cannot_connect(attempts: u32, kind: io::ErrorKind) -> Error {
        Error::Transport(Wire::Connect {
            attempts,
            source: io::Error::new(kind, format!("attempt {attempts}")),
        })
    }

    fn exception(code: u16) -> Error {
        Error::Transport(Wire::Exception {
            function: 3,
            code: ExceptionCode(code),
        })
    }

    #[test]
    fn point_9_failures_of_one_kind_compare_equal_whatever_their_text() {
        let refused = io::ErrorKind::ConnectionRefused;
        let first = cannot_connect(1, refused);
        let second = cannot_connect(2, refused);
        assert_ne!(first.to_string(), second.to_string());
        assert_eq!(first.kind(), second.kind());
        // Another cause, another wire failure, another exception: another kind.
        assert_ne!(
            first.kind(),
            cannot_connect(3, io::ErrorKind::TimedOut).kind()
        );
        let timeout = |ms| {
            Error::Transport(Wire::Timeout {
                after: std::time::Duration::from_millis(ms),
            })
        };
        assert_eq!(timeout(100).kind(), timeout(200).kind());
        assert_ne!(first.kind(), timeout(100).kind());
        assert_eq!(exception(2).kind(), exception(2).kind());
        assert_ne!(exception(2).kind(), exception(4).kind());
    }
}
