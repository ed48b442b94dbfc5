//! `enum-codes`: an enum has codes, no duplicate codes or names, and codes that fit the value
//! they are stored in: 0 to 2^32 - 1 for any enum, and the bits of each register, field or
//! exception reply that uses it.

use std::fmt;

use foldhash::{HashMap, HashMapExt, HashSet, HashSetExt};

use crate::diagnostic::Diagnostic;
use crate::model::{ExceptionStyle, Kind, Model, RegisterNames};
use crate::source::Path;

/// Rule name.
pub const RULE: &str = "enum-codes";

/// What stores an enum's codes, written out only in a report.
enum User<'m> {
    Exceptions,
    Register(&'m str),
    Field(&'m str, &'m str),
}

impl fmt::Display for User<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Exceptions => f.write_str("exception replies"),
            Self::Register(name) => write!(f, "`{name}`"),
            Self::Field(name, field) => write!(f, "`{name}.{field}`"),
        }
    }
}

/// Checks enums.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for def in &model.enums {
        if def.codes.is_empty() {
            out.push(
                Diagnostic::at(RULE, &def.path, format!("enum `{}` has no codes", def.name))
                    .label("empty"),
            );
        }
        for code in def.codes.iter().filter(|c| u32::try_from(c.code).is_err()) {
            out.push(
                Diagnostic::at(
                    RULE,
                    &code.path.key("code"),
                    format!(
                        "code {} of `{}` is not a raw register value",
                        code.code, def.name
                    ),
                )
                .label("outside 0..=4294967295")
                .help("codes are the unsigned bits the device sends"),
            );
        }
        let mut codes = HashMap::new();
        let mut names = HashMap::new();
        for code in &def.codes {
            // The same `key` a second time: marked here, with the first use labelled.
            let twice = |key: &'static str, first: &Path, what: String| {
                Diagnostic::at(
                    RULE,
                    &code.path.key(key),
                    format!("enum `{}` has {what}", def.name),
                )
                .label(format!("duplicate {key}"))
                .also(&first.key(key), "first used here")
            };
            if let Some(first) = codes.insert(code.code, &code.path) {
                out.push(twice("code", first, format!("code {} twice", code.code)));
            }
            if let Some(first) = names.insert(code.name.as_str(), &code.path) {
                out.push(twice(
                    "name",
                    first,
                    format!("two codes named `{}`", code.name),
                ));
            }
        }
    }
    // Codes fit the storage of every user of the enum.
    let mut users = Vec::new();
    if let Some(reference) = &model.protocol.exception_codes {
        let bits = match model.protocol.exception {
            ExceptionStyle::Standard => 8,
            ExceptionStyle::CountedWord => 16,
        };
        users.push((reference, bits, User::Exceptions));
    }
    for register in super::declared(model) {
        let name = &register.name;
        match &register.kind {
            Kind::Enum(reference) => {
                let bits = 16 * register.words.0.min(2);
                users.push((reference, bits, User::Register(name)));
            }
            Kind::Packed(fields) => {
                for field in fields {
                    if let (Some(reference), Some(width)) = (&field.enum_ref, field.width) {
                        users.push((reference, u32::from(width), User::Field(name, &field.name)));
                    }
                }
            }
            Kind::Record(fields) => {
                for field in fields {
                    if let Some(reference) = &field.enum_ref {
                        let bits = 16 * field.scalar.map_or(1, |s| s.words());
                        users.push((reference, bits, User::Field(name, &field.name)));
                    }
                }
            }
            _ => {}
        }
    }
    {
        // A code too wide for one user is too wide for all users of that width: reported with
        // the first, so that many users of a large enum cost one pass over its codes each width.
        let mut judged = HashSet::new();
        for (reference, bits, user) in users {
            let Some(def) = model.enum_def(reference) else {
                continue;
            };
            if !judged.insert((reference.index, bits)) {
                continue;
            }
            let max = if bits >= 63 {
                i64::MAX
            } else {
                (1i64 << bits) - 1
            };
            for code in def
                .codes
                .iter()
                .filter(|c| c.code > max && u32::try_from(c.code).is_ok())
            {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &code.path.key("code"),
                        format!(
                            "code {} of `{}` does not fit the {bits} bits of {user}",
                            code.code, def.name
                        ),
                    )
                    .label(format!("outside 0..={max}"))
                    .also(&reference.path, "used here"),
                );
            }
        }
    }
}
