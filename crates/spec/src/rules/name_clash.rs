//! `name-clash`: tools look a name up among registers and groups alike (`optobus read
//! <name>`), so a group, a register, a repeat block's member and its copies never share a
//! name.

use crate::diagnostic::Diagnostic;
use crate::model::{Model, RegisterNames};

/// Rule name.
pub const RULE: &str = "name-clash";

/// Checks the names tools resolve.
pub fn check(model: &Model, names: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for group in &model.groups {
        let named = names.register(&group.name).map(|r| ("register", r));
        let named = named.or_else(|| names.resolve(&group.name).map(|r| ("repeat member", r)));
        if let Some((what, register)) = named {
            out.push(
                Diagnostic::at(
                    RULE,
                    &group.path.key("name"),
                    format!("group `{}` has the name of a {what}", group.name),
                )
                .label("also a register name")
                .also(&register.path.key("name"), format!("{what} named here"))
                .help("tools resolve a name to a register or a group: rename the group"),
            );
        }
    }
}
