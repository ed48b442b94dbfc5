//! `command`: a command writes an existing, writable register with a value it accepts, and its
//! targets exist; the continuous-send code is a value its register accepts; a command that
//! waits for its register to show it finished (`done_when`) reads a readable register for a
//! value it can hold, other than the one written, within a bound (`within_ms`, longer than
//! `busy_ms`).

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
    shows(codes, register, value)
}

/// True when `register` can hold `value` (enum codes, type bounds; the range bounds writes
/// only: a device may show a code nobody may write, as a save flag clearing itself).
fn shows(codes: &[HashSet<i64>], register: &Register, value: i64) -> bool {
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
        if let Some(register) = names.resolve(&command.register) {
            check_completion(&codes, command, register, out);
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

/// The longest `within_ms`: a day, as for every other duration.
const MAX_WITHIN_MS: u32 = 24 * 60 * 60 * 1000;

/// Checks `done_when` and `within_ms` of `command`, which writes `register`.
fn check_completion(
    codes: &[HashSet<i64>],
    command: &crate::model::Command,
    register: &Register,
    out: &mut Vec<Diagnostic>,
) {
    let done_path = command.path.key("done_when");
    let within_path = command.path.key("within_ms");
    let (value, within) = match (command.done_when, command.within_ms) {
        (None, None) => return,
        (Some(_), None) => {
            out.push(
                Diagnostic::at(
                    RULE,
                    &done_path,
                    format!(
                        "command `{}` waits for `done_when` without a bound",
                        command.name
                    ),
                )
                .label("for how long?")
                .help("give `within_ms`: the longest time from the write until the register reads this value"),
            );
            return;
        }
        (None, Some(_)) => {
            out.push(
                Diagnostic::at(
                    RULE,
                    &within_path,
                    format!(
                        "`within_ms` bounds `done_when`, which command `{}` does not give",
                        command.name
                    ),
                )
                .label("bounds nothing"),
            );
            return;
        }
        (Some(value), Some(within)) => (value, within),
    };
    let busy = command.busy_ms.unwrap_or(0);
    if within == 0 || within > MAX_WITHIN_MS || within <= busy {
        out.push(
            Diagnostic::at(
                RULE,
                &within_path,
                format!(
                    "command `{}` waits {within} ms for `done_when`; a bound is longer than its busy time ({busy} ms) and at most {MAX_WITHIN_MS} ms (24 h)",
                    command.name
                ),
            )
            .label(format!("outside {}..={MAX_WITHIN_MS}", busy + 1)),
        );
    }
    if !register.readable() {
        out.push(
            Diagnostic::at(
                RULE,
                &done_path,
                format!(
                    "command `{}` waits for `{}` to read {value}, which cannot be read",
                    command.name, command.register
                ),
            )
            .label("cannot be read back")
            .also(
                &register.path.key("access"),
                "write-only or an action register",
            ),
        );
    } else if u32::try_from(value).is_err() || !shows(codes, register, value) {
        out.push(
            Diagnostic::at(
                RULE,
                &done_path,
                format!(
                    "command `{}` waits for `{}` to read {value}, which it cannot hold",
                    command.name, command.register
                ),
            )
            .label("outside the register's codes or type")
            .also(&register.path.key("name"), "register defined here"),
        );
    } else if value == command.value {
        out.push(
            Diagnostic::at(
                RULE,
                &done_path,
                format!(
                    "command `{}` writes {value} and waits for `{}` to read {value}: done at once",
                    command.name, command.register
                ),
            )
            .label("the value written")
            .help("`done_when` is what the device shows once it has finished, e.g. a flag cleared to 0"),
        );
    }
}
