//! `role`: what a register is to the device as a whole (its firmware version, its serial
//! number) is given to one register at most, outside repeat blocks (whose copies would all
//! claim it), and to one that can be read without changing the device, since tools read it
//! to name the device.

use crate::diagnostic::Diagnostic;
use crate::model::{Model, Register, RegisterNames, Role};

/// Rule name.
pub const RULE: &str = "role";

/// Checks roles.
pub fn check(model: &Model, _names: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    let mut first: Vec<(Role, &Register)> = Vec::new();
    for register in super::declared(model) {
        let Some(role) = register.role else {
            continue;
        };
        let at = register.path.key("role");
        if !register.readable() || register.read_side_effect.is_some() {
            out.push(
                Diagnostic::at(
                    RULE,
                    &at,
                    format!(
                        "`{}` has role `{}` but cannot be read as it is",
                        register.name,
                        role.name()
                    ),
                )
                .label("tools read it to name the device")
                .help("give the role to a register that is read without changing the device"),
            );
        }
        if register.repeat.is_some() {
            out.push(
                Diagnostic::at(
                    RULE,
                    &at,
                    format!("role `{}` in a repeat block", role.name()),
                )
                .label("every copy would claim it")
                .help("give the role to one register outside repeat blocks"),
            );
        }
        match first.iter().find(|(seen, _)| *seen == role) {
            Some((_, earlier)) => out.push(
                Diagnostic::at(RULE, &at, format!("role `{}` is given twice", role.name()))
                    .label("a second time")
                    .also(&earlier.path.key("role"), "first given here")
                    .help("a role names one register of the device"),
            ),
            None => first.push((role, register)),
        }
    }
}
