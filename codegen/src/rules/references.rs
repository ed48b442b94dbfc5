//! `unknown-reference`: every name a spec refers to exists (shared enums, `alias_of`, the
//! continuous-send register).

use crate::diagnostic::Diagnostic;
use crate::model::{EnumRef, Kind, Model};

/// Rule name.
pub const RULE: &str = "unknown-reference";

fn check_enum(model: &Model, reference: &EnumRef, out: &mut Vec<Diagnostic>) {
    if reference.index.is_none() && !model.is_unread(&reference.name) {
        let known: Vec<&str> = model
            .enums
            .iter()
            .filter(|e| e.shared)
            .map(|e| e.name.as_str())
            .collect();
        out.push(
            Diagnostic::at(
                RULE,
                &reference.path,
                format!("no enum named `{}`", reference.name),
            )
            .label("unknown enum")
            .help(format!("declared enums: {}", known.join(", "))),
        );
    }
}

/// Checks references.
pub fn check(model: &Model, out: &mut Vec<Diagnostic>) {
    for register in super::declared(model) {
        match &register.kind {
            Kind::Enum(reference) => check_enum(model, reference, out),
            Kind::Packed(fields) | Kind::Record(fields) => {
                for reference in fields.iter().filter_map(|f| f.enum_ref.as_ref()) {
                    check_enum(model, reference, out);
                }
            }
            _ => {}
        }
        if let Some(target) = &register.alias_of {
            if model.register(target).is_none() && !model.is_unread(target) {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &register.path.key("alias_of"),
                        format!(
                            "`{}` is an alias of unknown register `{target}`",
                            register.name
                        ),
                    )
                    .label("no such register"),
                );
            }
        }
    }
    if let Some(reference) = &model.protocol.exception_codes {
        if reference.index.is_none() && !model.is_unread(&reference.name) {
            out.push(
                Diagnostic::at(
                    RULE,
                    &reference.path,
                    format!("exception codes name unknown enum `{}`", reference.name),
                )
                .label("unknown enum"),
            );
        }
    }
    if let Some((name, _, path)) = &model.protocol.continuous_send {
        if model.register(name).is_none() && !model.is_unread(name) {
            out.push(
                Diagnostic::at(
                    RULE,
                    path,
                    format!("continuous send names unknown register `{name}`"),
                )
                .label("no such register"),
            );
        }
    }
}
