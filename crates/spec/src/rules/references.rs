//! `unknown-reference`: every name a spec refers to exists (shared enums, `alias_of`, the
//! continuous-send register).

use crate::diagnostic::Diagnostic;
use crate::model::{EnumRef, Kind, Model, RegisterNames};

/// Rule name.
pub const RULE: &str = "unknown-reference";

/// How many declared enums the help of an unknown enum lists.
const KNOWN_SHOWN: usize = 20;

/// The declared enums, as the help of an unknown enum lists them.
fn known_enums(model: &Model) -> String {
    let shared: Vec<&str> = model
        .enums
        .iter()
        .filter(|e| e.shared)
        .map(|e| e.name.as_str())
        .collect();
    let mut known = shared[..shared.len().min(KNOWN_SHOWN)].join(", ");
    if shared.len() > KNOWN_SHOWN {
        known.push_str(&format!(" and {} more", shared.len() - KNOWN_SHOWN));
    }
    known
}

fn check_enum(model: &Model, reference: &EnumRef, known: &str, out: &mut Vec<Diagnostic>) {
    if reference.index.is_none() && !model.is_unread(&reference.name) {
        out.push(
            Diagnostic::at(
                RULE,
                &reference.path,
                format!("no enum named `{}`", reference.name),
            )
            .label("unknown enum")
            .help(format!("declared enums: {known}")),
        );
    }
}

/// Checks references.
pub fn check(model: &Model, names: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    let known = known_enums(model);
    for register in super::declared(model) {
        match &register.kind {
            Kind::Enum(reference) => check_enum(model, reference, &known, out),
            Kind::Packed(fields) | Kind::Record(fields) => {
                for reference in fields.iter().filter_map(|f| f.enum_ref.as_ref()) {
                    check_enum(model, reference, &known, out);
                }
            }
            _ => {}
        }
        if let Some(target) = &register.alias_of {
            if names.register(target).is_none() && !model.is_unread(target) {
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
