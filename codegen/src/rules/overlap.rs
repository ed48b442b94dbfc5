//! `address-overlap`: no two registers of a table share an address unless one is declared
//! `alias_of` the other; reserved ranges do not cover registers.

use crate::diagnostic::Diagnostic;
use crate::model::{Model, Register};

/// Rule name.
pub const RULE: &str = "address-overlap";

fn span(model: &Model, r: &Register) -> (u32, u32) {
    (r.address.0, r.address.0.saturating_add(model.extent(r)))
}

fn aliased(a: &Register, b: &Register) -> bool {
    a.alias_of.as_deref() == Some(&b.name) || b.alias_of.as_deref() == Some(&a.name)
}

/// Checks overlaps.
pub fn check(model: &Model, out: &mut Vec<Diagnostic>) {
    let mut sorted: Vec<&Register> = model.registers.iter().collect();
    sorted.sort_by_key(|r| (r.table, r.address));
    for (i, a) in sorted.iter().enumerate() {
        let (_, a_end) = span(model, a);
        for b in &sorted[i + 1..] {
            if b.table != a.table || b.address.0 >= a_end {
                break;
            }
            // Copies of one repeat entry are the repeat rule's business.
            let same_entry = matches!((&a.repeat, &b.repeat), (Some(x), Some(y)) if x.repeat == y.repeat && x.base == y.base);
            if aliased(a, b) || same_entry {
                continue;
            }
            let (table, at, start) = (b.table.as_str(), b.address.0, a.address.0);
            let message = format!(
                "`{}` at {table} address {at} overlaps `{}` ({start}..{a_end})",
                b.name, a.name
            );
            out.push(
                Diagnostic::at(RULE, &b.path.key("address"), message)
                .label("overlapping register")
                .also(&a.path.key("address"), format!("`{}` starts here", a.name))
                .help(format!(
                    "fix the address, or declare `alias_of: {}` if both are views of the same words",
                    a.name
                )),
            );
        }
    }
    for reserved in &model.reserved {
        for register in model.registers.iter().filter(|r| r.table == reserved.table) {
            let (start, end) = span(model, register);
            if start <= reserved.to && reserved.from < end {
                out.push(
                    Diagnostic::at(
                        RULE,
                        &reserved.path.key("from"),
                        format!(
                            "reserved range {}..={} covers register `{}` at {}",
                            reserved.from, reserved.to, register.name, start
                        ),
                    )
                    .label("reserved range")
                    .also(&register.path.key("address"), "register defined here")
                    .help("shrink the reserved range (manuals get these wrong; note it)"),
                );
            }
        }
    }
}
