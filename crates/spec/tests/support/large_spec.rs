//! A generated spec of any size, for the test and the benchmark of the checker's complexity:
//! half holding, half input registers, a free (reserved) address after every hundred, shared
//! and inline enums, aliases, one command per thousand registers and one group per hundred.

use std::fmt::Write as _;

/// The address of the `index`th register of a table: one address left free after every 100.
fn address(index: usize) -> usize {
    index + index / 100
}

/// A spec of `registers` registers (an even number) that passes every check.
pub(crate) fn large_spec(registers: usize) -> String {
    let per_table = registers / 2;
    let size = address(per_table) + 1;
    let mut spec = format!(
        "family: large\n\
         title: Generated large spec\n\
         manual: {{file: none.txt, version: \"1\"}}\n\
         device:\n  \
           transports:\n    \
             rtu: {{default_baud: 9600, bauds: [9600], parity: none, data_bits: 8, stop_bits: 1}}\n  \
           slave: {{default: 1, min: 1, max: 247}}\n  \
           functions: [3, 4, 6]\n  \
           max_read_words: 100\n  \
           power_up_ms: 100\n  \
           tables: {{holding: {size}, input: {size}}}\n\
         protocol: {{addressing: word, long_writes: split, exception: standard, apply: immediately}}\n\
         enums:\n  \
           mode:\n    \
             doc: A mode.\n    \
             codes:\n      \
               - {{code: 0, name: off, meaning: off, doc: Off.}}\n      \
               - {{code: 1, name: on, meaning: on, doc: On.}}\n\
         registers:\n"
    );
    for table in ["holding", "input"] {
        let access = if table == "holding" { "rw" } else { "r" };
        for i in 0..per_table {
            let kind = match i % 5 {
                0 if table == "holding" => "type: u16, scale: 1e-1, unit: mm, range: [0, 1000]",
                0 => "type: u16, scale: 1e-1, unit: mm",
                1 => "type: enum, enum: mode",
                2 => "type: enum, codes: [{code: 0, name: low, doc: Low.}, {code: 1, name: high, doc: High.}]",
                3 => "type: i16",
                _ => "type: u16, allowed_values: [1, 2, 4, 8]",
            };
            // Every fiftieth register is a second view of the one before it.
            let (address, kind) = if i % 50 == 4 {
                (
                    address(i - 1),
                    format!("type: u16, alias_of: {table}_{}", i - 1),
                )
            } else {
                (address(i), kind.to_owned())
            };
            let _ = writeln!(
                spec,
                "  - {{name: {table}_{i}, table: {table}, address: {address}, access: {access}, \
                 {kind}, doc: Register {i}., zh: 寄存器, section: \"1\"}}"
            );
        }
    }
    spec.push_str("reserved:\n");
    for table in ["holding", "input"] {
        for block in (0..per_table / 100).step_by(10) {
            let free = address(block * 100 + 99) + 1;
            let _ = writeln!(spec, "  - {{table: {table}, from: {free}, to: {free}}}");
        }
    }
    spec.push_str("commands:\n");
    for i in (0..per_table).step_by(1000) {
        let _ = writeln!(
            spec,
            "  - {{name: set_{i}, register: holding_{i}, value: 1, doc: Sets register {i}.}}"
        );
    }
    spec.push_str("groups:\n");
    for table in ["holding", "input"] {
        for first in (0..per_table.saturating_sub(8)).step_by(100) {
            let members: Vec<String> = (first..first + 8).map(|i| format!("{table}_{i}")).collect();
            let _ = writeln!(
                spec,
                "  - {{name: {table}_group_{first}, doc: Registers from {first}., registers: [{}]}}",
                members.join(", ")
            );
        }
    }
    spec
}
