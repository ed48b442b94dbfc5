//! `sentinel`: an invalid-reading value fits the register's raw bits.

use crate::diagnostic::Diagnostic;
use crate::model::{Kind, Model, RegisterNames};

/// Rule name.
pub const RULE: &str = "sentinel";

/// Checks sentinels.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for register in super::declared(model) {
        if let Some(sentinel) = register.sentinel {
            let bits = 16 * register.words.0.min(2);
            let max = (1u64 << bits) - 1;
            if sentinel > max || !matches!(register.kind, Kind::Scalar(_)) {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &register.path.key("sentinel"),
                        format!(
                            "sentinel {sentinel:#X} does not fit `{}` ({}, at most {max:#X})",
                            register.name,
                            register.kind.name()
                        ),
                    )
                    .label("outside the type")
                    .help("a sentinel is the raw bits of an integer register, written unsigned"),
                );
            }
        }
        if let Kind::Record(fields) = &register.kind {
            for field in fields {
                let (Some(sentinel), Some(scalar)) = (field.sentinel, field.scalar) else {
                    continue;
                };
                let max = (1u64 << (16 * scalar.words())) - 1;
                if sentinel > max {
                    out.push(
                        Diagnostic::at(
                            RULE,
                            &field.path.key("sentinel"),
                            format!("sentinel {sentinel:#X} does not fit {}", scalar.as_str()),
                        )
                        .label("outside the type"),
                    );
                }
            }
        }
    }
}
