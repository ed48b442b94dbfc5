//! `address-overlap`: no two registers of a table share an address unless one is declared
//! `alias_of` the other; reserved ranges do not cover registers.

use std::cmp::Reverse;
use std::collections::{BTreeSet, BinaryHeap};

use crate::diagnostic::Diagnostic;
use crate::model::{Model, Register, RegisterNames, Reserved, Table};

/// Rule name.
pub const RULE: &str = "address-overlap";

fn span(model: &Model, r: &Register) -> (u32, u32) {
    (r.address.0, r.address.0.saturating_add(model.extent(r)))
}

fn aliased(a: &Register, b: &Register) -> bool {
    a.alias_of.as_deref() == Some(&b.name) || b.alias_of.as_deref() == Some(&a.name)
}

/// Checks overlaps: each register against the nearest earlier one that covers its address,
/// each register against the reserved ranges. Sorting and a sweep: n log n, and one report per
/// overlapping register, however many others it overlaps.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    let mut sorted: Vec<&Register> = model.registers.iter().collect();
    sorted.sort_by_key(|r| (r.table, r.address));
    // Registers whose words reach the address being looked at: by start (nearest last, the
    // first declared first among equals), and by end to drop them once passed.
    let mut open: BTreeSet<(u32, Reverse<usize>)> = BTreeSet::new();
    let mut ends: BinaryHeap<Reverse<(u32, usize)>> = BinaryHeap::new();
    for (i, b) in sorted.iter().enumerate() {
        if i > 0 && sorted[i - 1].table != b.table {
            open.clear();
            ends.clear();
        }
        let (start, end) = span(model, b);
        while let Some(Reverse((end, j))) = ends.peek().copied() {
            if end > start {
                break;
            }
            ends.pop();
            open.remove(&(span(model, sorted[j]).0, Reverse(j)));
        }
        // Only aliases of `b`, copies of its repeat entry, or registers sharing the name of
        // its target (already an error) are passed over; the bound keeps that last case linear.
        let covering = open
            .iter()
            .rev()
            .take(MOST_PASSED_OVER)
            .map(|&(_, Reverse(j))| sorted[j])
            .find(|a| !aliased(a, b) && !same_entry(a, b));
        if let Some(a) = covering {
            let (a_start, a_end) = span(model, a);
            let table = b.table.as_str();
            let message = format!(
                "`{}` at {table} address {start} overlaps `{}` ({a_start}..{a_end})",
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
        open.insert((start, Reverse(i)));
        ends.push(Reverse((end, i)));
    }
    reserved(model, out);
}

/// How many registers that may overlap a register without an error (its aliases, copies of
/// its repeat entry) are passed over before looking no further.
const MOST_PASSED_OVER: usize = 1024;

/// True for two copies of one repeat entry: the repeat rule's business.
fn same_entry(a: &Register, b: &Register) -> bool {
    matches!((&a.repeat, &b.repeat), (Some(x), Some(y)) if x.repeat == y.repeat && x.base == y.base)
}

/// Reserved ranges cover no register: each register is looked up among the ranges of its table
/// sorted by start (the widest reach of those starting before its end), and reported once.
fn reserved(model: &Model, out: &mut Vec<Diagnostic>) {
    let mut found: Vec<(usize, usize)> = Vec::new();
    for table in [Table::Holding, Table::Input] {
        let mut ranges: Vec<(usize, &Reserved)> = model
            .reserved
            .iter()
            .enumerate()
            .filter(|(_, r)| r.table == table)
            .collect();
        ranges.sort_by_key(|(_, r)| r.from);
        // For the first k ranges: the one reaching furthest.
        let mut furthest: Vec<(u32, usize)> = Vec::with_capacity(ranges.len());
        for &(index, range) in &ranges {
            let best = furthest.last().copied().filter(|(to, _)| *to >= range.to);
            furthest.push(best.unwrap_or((range.to, index)));
        }
        for (r, register) in model.registers.iter().enumerate() {
            if register.table != table {
                continue;
            }
            let (start, end) = span(model, register);
            let starting_before_end = ranges.partition_point(|(_, range)| range.from < end);
            if let Some(&(to, index)) = starting_before_end
                .checked_sub(1)
                .and_then(|k| furthest.get(k))
            {
                if to >= start {
                    found.push((index, r));
                }
            }
        }
    }
    found.sort_unstable();
    for (index, r) in found {
        let (reserved, register) = (&model.reserved[index], &model.registers[r]);
        out.push(
            Diagnostic::at(
                RULE,
                &reserved.path.key("from"),
                format!(
                    "reserved range {}..={} covers register `{}` at {}",
                    reserved.from, reserved.to, register.name, register.address.0
                ),
            )
            .label("reserved range")
            .also(&register.path.key("address"), "register defined here")
            .help("shrink the reserved range (manuals get these wrong; note it)"),
        );
    }
}
