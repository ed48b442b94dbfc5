//! `type-width`: a register's value type fits the words it declares, and packed fields fit
//! inside the value.

use crate::diagnostic::Diagnostic;
use crate::model::{Kind, Model, RegisterNames, Scalar};

/// Rule name.
pub const RULE: &str = "type-width";

/// Checks widths.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for register in super::declared(model) {
        let words = register.words.0;
        let needed = match &register.kind {
            Kind::Bool => Some((1..=1, "one word")),
            Kind::Scalar(scalar) => Some(match scalar.words() {
                1 => (1..=1, "one word"),
                _ => (2..=2, "two words"),
            }),
            Kind::Enum(_) | Kind::Packed(_) => Some((1..=2, "one or two words")),
            Kind::Ipv4 => Some((4..=4, "four words, one octet each")),
            Kind::Version(_) => Some((2..=2, "two words (four bytes)")),
            Kind::Record(fields) => {
                let sum: u32 = fields
                    .iter()
                    .map(|f| f.scalar.map_or(1, Scalar::words))
                    .sum();
                if words != sum {
                    out.push(
                        Diagnostic::at(
                            RULE,
                            &register.path.key("words"),
                            format!(
                                "record `{}` declares {words} words but its fields take {sum}",
                                register.name
                            ),
                        )
                        .label("does not match the fields"),
                    );
                }
                None
            }
        };
        if let Some((allowed, what)) = needed {
            if !allowed.contains(&words) {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &register.path.key("words"),
                        format!(
                            "a `{}` value needs {what}; `{}` declares {words}",
                            register.kind.name(),
                            register.name
                        ),
                    )
                    .label("does not fit the type")
                    .help("fix `words:` or choose the type that matches the manual"),
                );
            }
        }
        if let Kind::Version(parts) = &register.kind {
            if parts.len() != 4 {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &register.path.key("parts"),
                        "a version names its four bytes: `parts: [ignore, major, minor, patch]`",
                    )
                    .label(format!("{} parts", parts.len())),
                );
            }
        }
        if let Kind::Packed(fields) = &register.kind {
            let bits = 16 * words.min(2);
            for field in fields {
                match (field.lsb, field.width) {
                    (Some(lsb), Some(width))
                        if width > 0 && u32::from(lsb) + u32::from(width) <= bits => {}
                    (Some(lsb), Some(width)) => out.push(
                        Diagnostic::at(
                            RULE,
                            &field.path.key("width"),
                            format!(
                                "field `{}` (bits {lsb}..{}) does not fit a {bits}-bit value",
                                field.name,
                                u32::from(lsb) + u32::from(width)
                            ),
                        )
                        .label("outside the register"),
                    ),
                    _ => out.push(
                        Diagnostic::at(
                            RULE,
                            &field.path.key("name"),
                            format!("packed field `{}` needs `lsb` and `width`", field.name),
                        )
                        .label("position missing"),
                    ),
                }
            }
        }
        if let Kind::Record(fields) = &register.kind {
            for field in fields.iter().filter(|f| f.scalar.is_none()) {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &field.path.key("name"),
                        format!(
                            "record member `{}` needs `type: u16|i16|u32|i32`",
                            field.name
                        ),
                    )
                    .label("type missing"),
                );
            }
        }
    }
}
