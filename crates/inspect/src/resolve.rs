//! Registers by the names people use: a register, a repeat member (every copy, or one), or a
//! group of them.

use std::fmt;

use optobus_device::{DeviceInfo, ModelName, RegisterInfo};

use crate::error::Error;

/// Why [`resolve`] found no register; `Display` gives one line for people.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ResolveError {
    /// No register, repeat member or group has the name.
    Unknown {
        /// The name given.
        name: String,
        /// The device's family.
        family: &'static str,
        /// Up to five register, member or group names near it, nearest first: a few edits
        /// away (`distanse_1`: `distance_1`), or containing it or contained in it.
        near: Vec<&'static str>,
    },
    /// A repeat member has no copy of that number.
    NoCopy {
        /// The member's name.
        name: String,
        /// The repeat block (`channel`).
        repeat: &'static str,
        /// The copy asked for.
        number: u8,
        /// How many copies there are (numbered from 1).
        copies: usize,
    },
    /// A copy number was given for a name that stands for no repeat member.
    NoRepeats {
        /// The name given.
        name: String,
        /// The device's family.
        family: &'static str,
        /// The copy asked for.
        number: u8,
    },
}

impl fmt::Display for ResolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Unknown { name, family, .. } => {
                write!(
                    f,
                    "`{name}` is no register or group of {}",
                    ModelName(family)
                )
            }
            Self::NoCopy {
                name,
                repeat,
                number,
                copies,
            } => write!(
                f,
                "`{name}` has no {repeat} {number}: {repeat}s are numbered 1 to {copies}"
            ),
            Self::NoRepeats {
                name,
                family,
                number,
            } => write!(
                f,
                "`{name}` of {} holds no repeated register, so copy {number} (a channel) names nothing",
                ModelName(family)
            ),
        }
    }
}

impl std::error::Error for ResolveError {}

/// The registers `name` stands for on `device`, in order: a register; a repeat member, every
/// copy or only copy `copy` (1-based); or a group, its members expanded the same way (its
/// registers named in full taken whole). A copy number for a name that holds no repeat member
/// is refused: it would name nothing.
pub fn resolve(
    device: &'static DeviceInfo,
    name: &str,
    copy: Option<u8>,
) -> Result<Vec<&'static RegisterInfo>, ResolveError> {
    let registers = match device.group(name) {
        None => members(device, name, copy)?,
        Some(group) => {
            let mut registers = Vec::new();
            for member in group.registers {
                registers.extend(members(device, member, copy)?);
            }
            registers
        }
    };
    match copy {
        Some(number) if registers.iter().all(|r| r.copy.is_none()) => {
            Err(ResolveError::NoRepeats {
                name: name.to_owned(),
                family: device.family,
                number,
            })
        }
        _ => Ok(registers),
    }
}

/// The readable registers behind `names` (see [`resolve`]), in order, without repeats; a name
/// that stands for a write-only register is refused.
pub fn resolve_readable(
    device: &'static DeviceInfo,
    names: &[impl AsRef<str>],
    copy: Option<u8>,
) -> Result<Vec<&'static RegisterInfo>, Error> {
    let mut registers: Vec<&'static RegisterInfo> = Vec::new();
    for name in names {
        for register in resolve(device, name.as_ref(), copy)? {
            if !register.readable() {
                let why = if register.action {
                    "is an action register: the manual does not say what a read returns"
                } else {
                    "is write-only: there is nothing to read"
                };
                return Err(Error::new(format!("`{}` {why}", register.name)));
            }
            if !registers.iter().any(|r| r.name == register.name) {
                registers.push(register);
            }
        }
    }
    Ok(registers)
}

/// The one register `name` stands for (with `copy` for a repeat member); a group or a member
/// without its copy is refused.
pub fn resolve_one(
    device: &'static DeviceInfo,
    name: &str,
    copy: Option<u8>,
) -> Result<&'static RegisterInfo, Error> {
    let registers = resolve(device, name, copy)?;
    match registers.as_slice() {
        [register] => Ok(register),
        many if device.group(name).is_some() => {
            let names: Vec<&str> = many.iter().map(|r| r.name).collect();
            Err(Error::new(format!(
                "`{name}` is a group: set its registers one at a time ({})",
                names.join(", ")
            )))
        }
        many => Err(Error::new(format!(
            "`{name}` has {} copies: choose one with --channel 1 to {}",
            many.len(),
            many.len()
        ))),
    }
}

impl From<ResolveError> for Error {
    fn from(error: ResolveError) -> Self {
        let hint = match &error {
            ResolveError::Unknown { family, near, .. } if near.is_empty() => {
                Some(format!("see `optobus registers {}`", ModelName(family)))
            }
            ResolveError::Unknown { near, .. } => {
                Some(format!("did you mean {}?", near.join(", ")))
            }
            ResolveError::NoCopy { .. } => None,
            ResolveError::NoRepeats { .. } => Some("leave the channel out".to_owned()),
        };
        Self {
            message: error.to_string(),
            hint,
        }
    }
}

/// The register `name`, or the copies (or copy `copy`) of the repeat member `name`.
fn members(
    device: &'static DeviceInfo,
    name: &str,
    copy: Option<u8>,
) -> Result<Vec<&'static RegisterInfo>, ResolveError> {
    let found: Vec<&'static RegisterInfo> = device.members(name).collect();
    let Some(first) = found.first() else {
        return Err(unknown(device, name));
    };
    match copy {
        Some(number) if first.name != name => found
            .iter()
            .find(|r| r.copy.is_some_and(|c| c.number == number))
            .map(|r| vec![*r])
            .ok_or_else(|| ResolveError::NoCopy {
                name: name.to_owned(),
                repeat: first.copy.map_or("copy", |c| c.repeat),
                number,
                copies: found.len(),
            }),
        _ => Ok(found),
    }
}

fn unknown(device: &DeviceInfo, name: &str) -> ResolveError {
    let known = device
        .registers
        .iter()
        .map(|r| r.member_name().unwrap_or(r.name))
        .chain(device.groups.iter().map(|g| g.name));
    ResolveError::Unknown {
        name: name.to_owned(),
        family: device.family,
        near: crate::near::near(name, known),
    }
}
