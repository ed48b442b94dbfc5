//! `action`: an action register (writing acts, the manual does not say what a read returns)
//! can be written and is never named where registers are read: in groups or as the
//! continuous-send switch.

use crate::diagnostic::Diagnostic;
use crate::model::{Model, RegisterNames};

/// Rule name.
pub const RULE: &str = "action";

/// Checks action registers.
pub fn check(model: &Model, names: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for register in super::declared(model) {
        if register.action && !register.access.writable() {
            out.push(
                Diagnostic::at(
                    RULE,
                    &register.path.key("action"),
                    format!("action register `{}` is read-only", register.name),
                )
                .label("an action is written")
                .help("give it `access: w` or `rw`, or remove `action`"),
            );
        }
    }
    for group in &model.groups {
        for (name, path) in &group.registers {
            let Some(register) = names.resolve(name) else {
                continue;
            };
            if register.action {
                out.push(
                    Diagnostic::at(
                        RULE,
                        path,
                        format!(
                            "group `{}` names action register `{name}`, whose read is undefined",
                            group.name
                        ),
                    )
                    .label("never read")
                    .also(&register.path.key("action"), "declared an action here"),
                );
            }
        }
    }
}
