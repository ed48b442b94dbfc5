//! `allowed-values`: a list of allowed values belongs to an integer register, is not empty,
//! and holds distinct values that the register's type and range can hold.

use foldhash::{HashMap, HashMapExt};

use crate::diagnostic::Diagnostic;
use crate::model::{Kind, Model, RegisterNames};

/// Rule name.
pub const RULE: &str = "allowed-values";

/// Checks allowed-value lists.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for register in super::declared(model) {
        let Some((values, path)) = &register.allowed_values else {
            continue;
        };
        let Kind::Scalar(scalar) = register.kind else {
            out.push(
                Diagnostic::at(
                    RULE,
                    path,
                    format!(
                        "`{}` lists allowed values, but it is {} register",
                        register.name,
                        article(register.kind.name())
                    ),
                )
                .label("only for integer registers")
                .help("an enum register lists its values as `codes`"),
            );
            continue;
        };
        if values.is_empty() {
            out.push(
                Diagnostic::at(
                    RULE,
                    path,
                    format!("`{}` allows no value at all", register.name),
                )
                .label("empty list")
                .help("list the values the manual gives, or remove `allowed_values`"),
            );
            continue;
        }
        let (min, max) = register.range.unwrap_or_else(|| scalar.bounds());
        let limit = if register.range.is_some() {
            "range"
        } else {
            "type"
        };
        let mut first_of = HashMap::new();
        for (i, &value) in values.iter().enumerate() {
            if !scalar.holds(value) || value < min || value > max {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &path.index(i),
                        format!(
                            "allowed value {value} of `{}` is outside its {limit} ({min}..={max})",
                            register.name
                        ),
                    )
                    .label(format!("outside the {limit}"))
                    .help("allowed values are raw register values, like `range`"),
                );
            }
            if let Some(&first) = first_of.get(&value) {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &path.index(i),
                        format!("`{}` allows {value} twice", register.name),
                    )
                    .label("repeated")
                    .also(&path.index(first), "first listed here"),
                );
            } else {
                first_of.insert(value, i);
            }
        }
    }
}

/// `a u16`, `an enum`.
fn article(kind: &str) -> String {
    match kind.chars().next() {
        Some('a' | 'e' | 'i' | 'o' | 'u') => format!("an {kind}"),
        _ => format!("a {kind}"),
    }
}
