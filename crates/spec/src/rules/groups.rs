//! `group`: a group names existing, readable registers of one table.

use crate::diagnostic::Diagnostic;
use crate::model::{Model, RegisterNames};

/// Rule name.
pub const RULE: &str = "group";

/// Checks groups.
pub fn check(model: &Model, names: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for group in &model.groups {
        if group.registers.is_empty() {
            out.push(
                Diagnostic::at(
                    RULE,
                    &group.path.key("registers"),
                    format!("group `{}` is empty", group.name),
                )
                .label("no registers"),
            );
        }
        let mut first: Option<(&str, crate::model::Table, &crate::source::Path)> = None;
        for (name, path) in &group.registers {
            let Some(register) = names.resolve(name) else {
                if model.is_unread(name) {
                    continue;
                }
                out.push(
                    Diagnostic::at(
                        RULE,
                        path,
                        format!("group `{}` names unknown register `{name}`", group.name),
                    )
                    .label("no such register")
                    .help(
                        "use a register name, or a repeat block's register name for all its copies",
                    ),
                );
                continue;
            };
            if !register.access.readable() {
                out.push(
                    Diagnostic::at(
                        RULE,
                        path,
                        format!("group `{}` names write-only `{name}`", group.name),
                    )
                    .label("cannot be read"),
                );
            }
            match first {
                None => first = Some((name, register.table, path)),
                Some((first_name, table, first_path)) if table != register.table => out.push(
                    Diagnostic::at(
                        RULE,
                        path,
                        format!(
                            "group `{}` mixes tables: `{name}` is {} but `{first_name}` is {}",
                            group.name,
                            register.table.as_str(),
                            table.as_str()
                        ),
                    )
                    .label(format!("{} register", register.table.as_str()))
                    .also(first_path, format!("{} register", table.as_str()))
                    .help("a group is read with one function code; split it in two"),
                ),
                Some(_) => {}
            }
        }
    }
}
