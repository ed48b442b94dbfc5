//! `range`: a valid range has min <= max and lies within the value's type.

use crate::diagnostic::Diagnostic;
use crate::model::{Kind, Model, RegisterNames, Scalar};
use crate::source::Path;

/// Rule name.
pub const RULE: &str = "range";

fn check_one(
    owner: &str,
    range: (i64, i64),
    bounds: (i64, i64),
    type_name: &str,
    path: &Path,
    out: &mut Vec<Diagnostic>,
) {
    let (min, max) = range;
    if min > max {
        out.push(
            Diagnostic::at(
                RULE,
                path,
                format!("range of `{owner}` has min {min} > max {max}"),
            )
            .label("empty range")
            .help("write `[min, max]`"),
        );
    } else if min < bounds.0 || max > bounds.1 {
        out.push(
            Diagnostic::at(
                RULE,
                path,
                format!(
                    "range [{min}, {max}] of `{owner}` is outside its type {type_name} ({}..={})",
                    bounds.0, bounds.1
                ),
            )
            .label("outside the type")
            .help("ranges are raw register values"),
        );
    }
}

/// Checks ranges.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for register in super::declared(model) {
        if let (Some(range), Some(scalar)) = (register.range, register.scalar()) {
            check_one(
                &register.name,
                range,
                scalar.bounds(),
                scalar.as_str(),
                &register.path.key("range"),
                out,
            );
        }
        if let Kind::Packed(fields) | Kind::Record(fields) = &register.kind {
            for field in fields {
                let Some(range) = field.range else { continue };
                let (bounds, name) = match (field.scalar, field.width) {
                    (Some(scalar), _) => (scalar.bounds(), scalar.as_str().to_owned()),
                    (None, Some(width)) if width < 63 => {
                        ((0, (1i64 << width) - 1), format!("{width}-bit field"))
                    }
                    _ => ((0, i64::from(u32::MAX)), Scalar::U32.as_str().to_owned()),
                };
                check_one(
                    &format!("{}.{}", register.name, field.name),
                    range,
                    bounds,
                    &name,
                    &field.path.key("range"),
                    out,
                );
            }
        }
    }
}
