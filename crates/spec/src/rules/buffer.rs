//! `buffer`: the data buffer names what it needs: a writable unsigned count register whose
//! range holds `most` (not 0), lock and unlock commands, a page group holding the read count,
//! the valid count and a repeat member of values, an enum source register, an enum interval
//! register whose codes are durations and a writable unsigned ratio register that never
//! takes 0.

use optobus_device::parse_duration;

use crate::diagnostic::Diagnostic;
use crate::model::{Kind, Model, NameRef, Register, RegisterNames, Scalar};

/// Rule name.
pub const RULE: &str = "buffer";

/// The register `reference` names, or a diagnostic saying it names none (none when a reading
/// error already left it out).
fn register<'m>(
    model: &'m Model,
    reference: &NameRef,
    role: &str,
    out: &mut Vec<Diagnostic>,
) -> Option<&'m Register> {
    let found = model.register(&reference.name);
    if found.is_none() && !model.is_unread(&reference.name) {
        out.push(
            Diagnostic::at(
                RULE,
                &reference.path,
                format!(
                    "the buffer's {role} names unknown register `{}`",
                    reference.name
                ),
            )
            .label("no such register"),
        );
    }
    found
}

/// Whether `register` (named by `reference`) is a writable enum register; a diagnostic if not.
fn is_writable_enum(
    register: &Register,
    reference: &NameRef,
    role: &str,
    out: &mut Vec<Diagnostic>,
) -> bool {
    if matches!(register.kind, Kind::Enum(_)) && register.access.writable() {
        return true;
    }
    out.push(not_the_register_wanted(
        register,
        reference,
        format!(
            "the buffer's {role} `{}` is not a writable enum register",
            reference.name
        ),
        format!("a {} register", register.kind.name()),
    ));
    false
}

/// Whether `register` (named by `reference`) is a writable unsigned integer register without
/// a scale; a diagnostic if not.
fn is_writable_count(
    register: &Register,
    reference: &NameRef,
    role: &str,
    out: &mut Vec<Diagnostic>,
) -> bool {
    let unsigned = matches!(register.kind, Kind::Scalar(Scalar::U16 | Scalar::U32));
    if unsigned && register.scale.is_none() && register.access.writable() {
        return true;
    }
    out.push(not_the_register_wanted(
        register,
        reference,
        format!(
            "the buffer's {role} `{}` is not a writable unsigned integer register",
            register.name
        ),
        format!(
            "a {} {} register{}",
            access_name(register),
            register.kind.name(),
            if register.scale.is_some() {
                " with a scale"
            } else {
                ""
            }
        ),
    ));
    false
}

/// The diagnostic at `reference` for a buffer's register that is not of the kind its role
/// needs: `message`, the label `what_it_is`, and where `register` is defined.
fn not_the_register_wanted(
    register: &Register,
    reference: &NameRef,
    message: String,
    what_it_is: String,
) -> Diagnostic {
    Diagnostic::at(RULE, &reference.path, message)
        .label(what_it_is)
        .also(&register.path.key("name"), "register defined here")
}

/// Checks the buffer section.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    let Some(buffer) = &model.buffer else {
        return;
    };
    let count = register(model, &buffer.count, "count", out);
    if let Some(count) = count.filter(|found| is_writable_count(found, &buffer.count, "count", out))
    {
        let (most, most_path) = &buffer.most;
        let max = count
            .range
            .map_or_else(|| count.scalar().map_or(0, |s| s.bounds().1), |r| r.1);
        if *most == 0 || i64::from(*most) > max {
            let message = if *most == 0 {
                "the buffer's `most` is 0: no value could ever be read out".to_owned()
            } else {
                format!(
                    "the buffer hands out at most {most} values, but `{}` takes counts up to {max}",
                    count.name
                )
            };
            out.push(
                Diagnostic::at(RULE, most_path, message)
                    .label("not a count the register takes")
                    .help("`most` is the largest count that may be read out, 1 or more"),
            );
        }
    }
    for (reference, role) in [(&buffer.lock, "lock"), (&buffer.unlock, "unlock")] {
        if !model.commands.iter().any(|c| c.name == reference.name)
            && !model.is_unread(&reference.name)
        {
            let known: Vec<&str> = model.commands.iter().map(|c| c.name.as_str()).collect();
            out.push(
                Diagnostic::at(
                    RULE,
                    &reference.path,
                    format!("the buffer's {role} `{}` is not a command", reference.name),
                )
                .label("no such command")
                .help(format!("commands: {}", known.join(", "))),
            );
        }
    }
    let page = model.groups.iter().find(|g| g.name == buffer.page.name);
    match page {
        None if model.is_unread(&buffer.page.name) => {}
        None => out.push(
            Diagnostic::at(
                RULE,
                &buffer.page.path,
                format!("the buffer's page `{}` is not a group", buffer.page.name),
            )
            .label("no such group"),
        ),
        Some(page) => {
            let members = [
                (&buffer.read_count, "read count"),
                (&buffer.valid_count, "valid count"),
                (&buffer.values, "values"),
            ];
            for (reference, role) in members {
                if !page.registers.iter().any(|(n, _)| *n == reference.name) {
                    out.push(
                        Diagnostic::at(
                            RULE,
                            &reference.path,
                            format!(
                                "the buffer's {role} `{}` is not a member of its page `{}`",
                                reference.name, page.name
                            ),
                        )
                        .label("not in the page")
                        .also(&page.path.key("registers"), "the page's members"),
                    );
                }
            }
            let is_repeat_member = model.register(&buffer.values.name).is_none()
                && model.registers.iter().any(|r| {
                    r.repeat
                        .as_ref()
                        .is_some_and(|c| c.base == buffer.values.name)
                });
            if !is_repeat_member {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &buffer.values.path,
                        format!(
                            "the buffer's values `{}` are not a repeat block's register",
                            buffer.values.name
                        ),
                    )
                    .label("one value per page is no page")
                    .help("name a register of a `repeats:` block: one copy per value of a page"),
                );
            }
        }
    }
    if let Some(source) = &buffer.source {
        if let Some(found) = register(model, source, "source", out) {
            is_writable_enum(found, source, "source", out);
        }
    }
    if let Some(ratio) = &buffer.ratio {
        check_ratio(model, ratio, out);
    }
    if let Some(interval) = &buffer.interval {
        let register = register(model, interval, "interval", out)
            .filter(|found| is_writable_enum(found, interval, "interval", out));
        let def = register.and_then(|r| match &r.kind {
            Kind::Enum(reference) => model.enum_def(reference),
            _ => None,
        });
        for code in def.into_iter().flat_map(|def| &def.codes) {
            let meaning = code.meaning.as_deref().unwrap_or("");
            if parse_duration(meaning).is_none() {
                let at = match code.meaning {
                    Some(_) => code.path.key("meaning"),
                    None => code.path.clone(),
                };
                out.push(
                    Diagnostic::at(
                        RULE,
                        &at,
                        format!(
                            "the buffer's interval `{}` has code `{}` meaning `{meaning}`, not a duration",
                            interval.name, code.name
                        ),
                    )
                    .label("not a duration")
                    .also(&interval.path, "named as the interval here")
                    .help("write the interval as `100us`, `1ms` or `2s`"),
                );
            }
        }
    }
}

/// The ratio: a writable unsigned integer register that never takes 0 (one value in
/// `ratio` is buffered).
fn check_ratio(model: &Model, ratio: &NameRef, out: &mut Vec<Diagnostic>) {
    let Some(found) = register(model, ratio, "ratio", out) else {
        return;
    };
    if !is_writable_count(found, ratio, "ratio", out) {
        return;
    }
    if found.range.is_none_or(|(min, _)| min < 1) {
        let (at, what) = match found.range {
            Some(_) => (found.path.key("range"), "its range"),
            None => (found.path.key("name"), "defined here without a range"),
        };
        out.push(
            Diagnostic::at(
                RULE,
                &ratio.path,
                format!("the buffer's ratio `{}` may be 0", ratio.name),
            )
            .label("one value in 0 cannot be buffered")
            .also(&at, what)
            .help("give the register `range: [1, …]`, as the manual does"),
        );
    }
}

fn access_name(register: &Register) -> &'static str {
    if register.access.writable() {
        "writable"
    } else {
        "read-only"
    }
}
