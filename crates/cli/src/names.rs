//! The registers the names on a command line stand for ([`optobus_inspect::resolve`]), as the
//! commands need them: readable ones, or exactly one.

use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_inspect::resolve;

use crate::error::CliError;

/// The readable registers behind `names`, in order, without repeats.
pub(crate) fn readable(
    device: &'static DeviceInfo,
    names: &[String],
    copy: Option<u8>,
) -> Result<Vec<&'static RegisterInfo>, CliError> {
    let mut registers: Vec<&'static RegisterInfo> = Vec::new();
    for name in names {
        for register in resolve(device, name, copy)? {
            if register.action {
                return Err(CliError::new(format!(
                    "`{}` is an action register: the manual defines no read",
                    register.name
                )));
            }
            if !register.readable() {
                return Err(CliError::new(format!("`{}` is write-only", register.name)));
            }
            if !registers.iter().any(|r| r.name == register.name) {
                registers.push(register);
            }
        }
    }
    Ok(registers)
}

/// The one register `name` (with `copy` for per-channel registers) names.
pub(crate) fn single(
    device: &'static DeviceInfo,
    name: &str,
    copy: Option<u8>,
) -> Result<&'static RegisterInfo, CliError> {
    let registers = resolve(device, name, copy)?;
    match registers.as_slice() {
        [register] => Ok(register),
        [first, ..] => Err(CliError::new(format!(
            "`{name}` stands for {} registers",
            registers.len()
        ))
        .hint(match first.copy {
            Some(copy) => format!("choose one with --{} N… try --channel N", copy.repeat),
            None => "name one register".into(),
        })),
        [] => Err(CliError::new(format!("`{name}` names no register"))),
    }
}
