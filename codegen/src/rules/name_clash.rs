//! `name-clash`: tools look a name up among registers and groups alike (`optobus read
//! <name>`), so a group, a register, a repeat block's member and its copies never share a
//! name.

use std::collections::HashMap;

use crate::diagnostic::Diagnostic;
use crate::model::Model;
use crate::source::Path;

/// Rule name.
pub const RULE: &str = "name-clash";

/// Checks the names tools resolve.
pub fn check(model: &Model, out: &mut Vec<Diagnostic>) {
    let mut registers: HashMap<&str, (&str, &Path)> = HashMap::new();
    for register in &model.registers {
        registers
            .entry(register.name.as_str())
            .or_insert(("register", &register.path));
        if let Some(copy) = &register.repeat {
            registers
                .entry(copy.base.as_str())
                .or_insert(("repeat member", &register.path));
        }
    }
    for group in &model.groups {
        if let Some((what, path)) = registers.get(group.name.as_str()) {
            out.push(
                Diagnostic::at(
                    RULE,
                    &group.path.key("name"),
                    format!("group `{}` has the name of a {what}", group.name),
                )
                .label("also a register name")
                .also(&path.key("name"), format!("{what} named here"))
                .help("tools resolve a name to a register or a group: rename the group"),
            );
        }
    }
}
