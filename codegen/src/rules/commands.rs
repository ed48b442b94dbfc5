//! `command`: a command writes an existing, writable register with a value it accepts, and its
//! targets exist; the continuous-send code is a value its register accepts.

use foldhash::HashSet;

use crate::diagnostic::Diagnostic;
use crate::model::{Kind, Model, Register, RegisterNames};

/// Rule name.
pub const RULE: &str = "command";

/// The codes of every enum of a model, by enum index, as sets: a command's value is looked up
/// in one rather than compared with every code.
fn code_sets(model: &Model) -> Vec<HashSet<i64>> {
    model
        .enums
        .iter()
        .map(|def| def.codes.iter().map(|c| c.code).collect())
        .collect()
}

/// True when `value` is a value `register` accepts (range, enum codes, type bounds).
fn accepts(codes: &[HashSet<i64>], register: &Register, value: i64) -> bool {
    if let Some((min, max)) = register.range {
        if value < min || value > max {
            return false;
        }
    }
    match &register.kind {
        Kind::Enum(reference) => reference
            .index
            .and_then(|i| codes.get(i))
            .is_none_or(|codes| codes.contains(&value)),
        Kind::Bool => value == 0 || value == 1,
        _ => register.scalar().is_none_or(|s| {
            let (min, max) = s.bounds();
            (min..=max).contains(&value)
        }),
    }
}

/// Checks commands.
pub fn check(model: &Model, names: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    let codes = code_sets(model);
    if let Some((name, code, path)) = &model.protocol.continuous_send {
        let code_path = path.parent().key("code");
        match model.register(name) {
            Some(register)
                if u32::try_from(*code).is_err() || !accepts(&codes, register, *code) =>
            {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &code_path,
                        format!("continuous send writes {code} to `{name}`, which refuses it"),
                    )
                    .label("outside the register's range or codes")
                    .also(&register.path.key("name"), "register defined here"),
                )
            }
            _ => {}
        }
    }
    for command in &model.commands {
        let register_path = command.path.key("register");
        match names.resolve(&command.register) {
            None if model.is_unread(&command.register) => {}
            None => out.push(
                Diagnostic::at(
                    RULE,
                    &register_path,
                    format!(
                        "command `{}` writes unknown register `{}`",
                        command.name, command.register
                    ),
                )
                .label("no such register"),
            ),
            Some(register) if !register.access.writable() => out.push(
                Diagnostic::at(
                    RULE,
                    &register_path,
                    format!(
                        "command `{}` writes `{}`, which is read-only",
                        command.name, command.register
                    ),
                )
                .label("read-only register")
                .also(&register.path.key("access"), "declared read-only here")
                .help("a command acts through a writable register (access `w` or `rw`)"),
            ),
            Some(_) if u32::try_from(command.value).is_err() => out.push(
                Diagnostic::at(
                    RULE,
                    &command.path.key("value"),
                    format!(
                        "command `{}` writes {}; a command value is 0 to 4294967295",
                        command.name, command.value
                    ),
                )
                .label("outside 0..=4294967295"),
            ),
            Some(register) if !accepts(&codes, register, command.value) => out.push(
                Diagnostic::at(
                    RULE,
                    &command.path.key("value"),
                    format!(
                        "command `{}` writes {} to `{}`, which refuses it",
                        command.name, command.value, command.register
                    ),
                )
                .label("outside the register's range or codes")
                .also(&register.path.key("name"), "register defined here"),
            ),
            Some(_) => {}
        }
        for (i, target) in command.targets.iter().enumerate() {
            if names.resolve(target).is_none() && !model.is_unread(target) {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &command.path.key("targets").index(i),
                        format!(
                            "command `{}` targets unknown register `{target}`",
                            command.name
                        ),
                    )
                    .label("no such register"),
                );
            }
        }
    }
}
