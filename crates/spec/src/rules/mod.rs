//! Validation: a list of small, named rules over the lowered model. Each reports every
//! problem it finds; `check` runs them all.

use crate::diagnostic::Diagnostic;
use crate::model::{Model, RegisterNames};

pub mod action;
pub mod allowed_values;
pub mod buffer;
pub mod commands;
pub mod device;
pub mod docs;
pub mod enum_codes;
pub mod groups;
pub mod name_clash;
pub mod names;
pub mod overlap;
pub mod range;
pub mod references;
pub mod repeats;
pub mod role;
pub mod scale;
pub mod sentinel;
pub mod table_bounds;
pub mod text;
pub mod type_width;
pub mod write_order;

/// A rule: its name (shown as `error[name]`) and its check.
pub struct Rule {
    /// The rule's name.
    pub name: &'static str,
    /// Appends a diagnostic for each problem found; the registers by name are built once for
    /// every rule.
    pub check: fn(&Model, &RegisterNames<'_>, &mut Vec<Diagnostic>),
}

/// Every rule, in the order their diagnostics are reported.
pub const RULES: &[Rule] = &[
    Rule {
        name: names::RULE,
        check: names::check,
    },
    Rule {
        name: names::FORMAT_RULE,
        check: names::check_format,
    },
    Rule {
        name: name_clash::RULE,
        check: name_clash::check,
    },
    Rule {
        name: references::RULE,
        check: references::check,
    },
    Rule {
        name: device::RULE,
        check: device::check,
    },
    Rule {
        name: type_width::RULE,
        check: type_width::check,
    },
    Rule {
        name: table_bounds::RULE,
        check: table_bounds::check,
    },
    Rule {
        name: overlap::RULE,
        check: overlap::check,
    },
    Rule {
        name: repeats::RULE,
        check: repeats::check,
    },
    Rule {
        name: enum_codes::RULE,
        check: enum_codes::check,
    },
    Rule {
        name: range::RULE,
        check: range::check,
    },
    Rule {
        name: allowed_values::RULE,
        check: allowed_values::check,
    },
    Rule {
        name: action::RULE,
        check: action::check,
    },
    Rule {
        name: role::RULE,
        check: role::check,
    },
    Rule {
        name: sentinel::RULE,
        check: sentinel::check,
    },
    Rule {
        name: scale::RULE,
        check: scale::check,
    },
    Rule {
        name: write_order::RULE,
        check: write_order::check,
    },
    Rule {
        name: commands::RULE,
        check: commands::check,
    },
    Rule {
        name: groups::RULE,
        check: groups::check,
    },
    Rule {
        name: buffer::RULE,
        check: buffer::check,
    },
    Rule {
        name: docs::RULE,
        check: docs::check,
    },
];

/// Runs every rule.
pub fn check(model: &Model) -> Vec<Diagnostic> {
    let mut diagnostics = Vec::new();
    let names = model.register_names();
    for rule in RULES {
        (rule.check)(model, &names, &mut diagnostics);
    }
    diagnostics
}

/// Registers as declared: repeat copies other than the first are skipped, so that a problem
/// in a block entry is reported once.
pub(crate) fn declared(model: &Model) -> impl Iterator<Item = &crate::model::Register> {
    model
        .registers
        .iter()
        .filter(|r| r.repeat.as_ref().is_none_or(|copy| copy.number == 1))
}
