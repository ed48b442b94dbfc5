//! Which registers the words of a read hold, and how a read is named.

use optobus_device::{Addressing, DeviceInfo, RegisterInfo, Table};

/// What a run of words at some address holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Held {
    /// A whole register.
    Whole(&'static RegisterInfo),
    /// Part of a register, from its word `usize` on (the read starts or stops inside it).
    Part(&'static RegisterInfo, usize),
    /// No register is defined there.
    Nothing,
}

/// A run of words of a read and what it holds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Slot {
    /// Index of the first word in the read.
    pub(crate) offset: usize,
    /// Words.
    pub(crate) len: usize,
    /// Register address of the first word.
    pub(crate) address: u32,
    pub(crate) held: Held,
}

/// What `count` words read from `start` of `table` hold. With one address per field (the
/// rangefinder) each address holds a whole field, whatever its width.
pub(crate) fn layout(device: &DeviceInfo, table: Table, start: u16, count: usize) -> Vec<Slot> {
    let mut slots = Vec::new();
    let mut offset = 0usize;
    let mut address = u32::from(start);
    while offset < count {
        let left = count - offset;
        let found = u16::try_from(address)
            .ok()
            .and_then(|at| device.register_at(table, at));
        let (len, held) = match found {
            Some((r, 0)) if usize::from(r.words) <= left => {
                (usize::from(r.words).max(1), Held::Whole(r))
            }
            Some((r, 0)) => (left, Held::Part(r, 0)),
            Some((r, inner)) => {
                let inner = usize::from(inner);
                (
                    (usize::from(r.words) - inner).min(left),
                    Held::Part(r, inner),
                )
            }
            None => (1, Held::Nothing),
        };
        slots.push(Slot {
            offset,
            len,
            address,
            held,
        });
        offset += len;
        address += match device.addressing {
            Addressing::Word => len as u32,
            Addressing::Field => 1,
        };
    }
    slots
}

/// `input 0-9` (one address per word) or `holding 2, 2 words` (one per field).
pub(crate) fn address_text(device: &DeviceInfo, table: Table, start: u32, count: usize) -> String {
    let table = table.as_str();
    match device.addressing {
        Addressing::Word if count > 1 => {
            format!("{table} {start}-{}", u64::from(start) + count as u64 - 1)
        }
        Addressing::Field if count > 1 => format!("{table} {start}, {count} words"),
        _ => format!("{table} {start}"),
    }
}

/// `input 0-9 (distance_1 .. statistic_2, 5 registers)`: a read's addresses and registers.
pub(crate) fn span_text(device: &DeviceInfo, table: Table, start: u16, count: usize) -> String {
    let mut names: Vec<&str> = Vec::new();
    for slot in layout(device, table, start, count) {
        if let Held::Whole(r) | Held::Part(r, _) = slot.held {
            if names.last() != Some(&r.name) {
                names.push(r.name);
            }
        }
    }
    let list = match names.as_slice() {
        [] => "no register defined there".to_owned(),
        [_] | [_, _] | [_, _, _] => names.join(", "),
        [first, .., last] => format!("{first} .. {last}, {} registers", names.len()),
    };
    format!(
        "{} ({list})",
        address_text(device, table, u32::from(start), count)
    )
}

/// The lowest start address from which `count` words of `table` are whole, readable
/// registers: where a lone reply most likely starts. With one address per field (the
/// rangefinder), where every read asks for one field, a field of that width comes first.
pub(crate) fn guess_start(device: &DeviceInfo, table: Table, count: usize) -> Option<u16> {
    let readable = || {
        device
            .registers
            .iter()
            .filter(move |r| r.table == table && r.readable())
    };
    if device.addressing == Addressing::Field {
        let field = readable()
            .filter(|r| usize::from(r.words) == count)
            .map(|r| r.address)
            .min();
        if field.is_some() {
            return field;
        }
    }
    let mut starts: Vec<u16> = readable().map(|r| r.address).collect();
    starts.sort_unstable();
    starts.dedup();
    let whole = |slot: &Slot| matches!(slot.held, Held::Whole(r) if r.readable());
    starts
        .into_iter()
        .find(|&start| count > 0 && layout(device, table, start, count).iter().all(whole))
}
