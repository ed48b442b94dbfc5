//! Read plans (which requests fetch a set of registers in the fewest transactions) and write
//! plans (which FC06 store a register's words, in send order).

use optobus_codec::value::{join_u32, u32_writes, WordOrder};
use optobus_codec::WriteValue;
use optobus_device::{Addressing, DeviceInfo, LongWrites, RegisterInfo, Table};

/// One read request of a plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadSpan {
    /// Table read.
    pub table: Table,
    /// First address.
    pub address: u16,
    /// Words asked for.
    pub count: u16,
}

impl ReadSpan {
    /// Whether a failed read of this span may be made again: false when it covers a register
    /// whose read changes the device.
    pub fn is_repeatable(&self, device: &DeviceInfo) -> bool {
        let (start, end) = (
            u32::from(self.address),
            u32::from(self.address) + u32::from(self.count),
        );
        !device.registers.iter().any(|r| {
            !r.read_is_repeatable()
                && r.table == self.table
                && u32::from(r.address) < end
                && start < u32::from(r.address) + u32::from(r.words)
        })
    }

    /// Whether this span passes over a reserved range (one the spec marks `readable`, the
    /// only kind a plan asks for).
    pub fn bridges_reserved(&self, device: &DeviceInfo) -> bool {
        let end = u32::from(self.address) + u32::from(self.count);
        device
            .reserved
            .iter()
            .any(|r| r.table == self.table && u32::from(r.from) < end && self.address <= r.to)
    }

    /// Where `register`'s words start in this span's reply, if it lies inside.
    pub fn offset_of(&self, register: &RegisterInfo, addressing: Addressing) -> Option<usize> {
        if register.table != self.table {
            return None;
        }
        match addressing {
            Addressing::Field => (register.address == self.address).then_some(0),
            Addressing::Word => {
                let offset = register.address.checked_sub(self.address)?;
                (offset + register.words <= self.count).then_some(usize::from(offset))
            }
        }
    }
}

/// What a read plan may pass over to join two reads into one.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Bridging {
    /// Readable registers whose read changes nothing, and reserved ranges the spec marks
    /// `readable` (the default).
    #[default]
    Reserved,
    /// Readable registers whose read changes nothing only: for a device that refuses reads
    /// of reserved addresses (see [`crate::DeviceMemory`]).
    RegistersOnly,
}

/// The requests that read `registers`: adjacent registers of one table merged, split at the
/// device's `max_read_words`. A gap between two registers is bridged only when readable
/// registers and reserved ranges the spec marks readable cover it, so a plan never asks
/// for an address the device may reject, nor reads a register whose read changes the device
/// or is undefined. With one address per field (the rangefinder) every register is its own
/// request.
pub fn plan_reads(device: &DeviceInfo, registers: &[&RegisterInfo]) -> Vec<ReadSpan> {
    plan_reads_bridging(device, registers, Bridging::Reserved)
}

/// [`plan_reads`], bridging gaps only as `bridging` allows.
pub fn plan_reads_bridging(
    device: &DeviceInfo,
    registers: &[&RegisterInfo],
    bridging: Bridging,
) -> Vec<ReadSpan> {
    let mut sorted: Vec<&RegisterInfo> = registers.to_vec();
    sorted.sort_by_key(|r| (r.table, r.address));
    sorted.dedup_by_key(|r| (r.table, r.address));
    if device.addressing == Addressing::Field {
        return sorted
            .iter()
            .map(|r| ReadSpan {
                table: r.table,
                address: r.address,
                count: r.words,
            })
            .collect();
    }
    let limit = u32::from(device.max_read_words.max(1));
    let mut spans: Vec<ReadSpan> = Vec::new();
    for register in sorted {
        let start = u32::from(register.address);
        let end = start + u32::from(register.words);
        if let Some(last) = spans.last_mut() {
            let last_start = u32::from(last.address);
            let last_end = last_start + u32::from(last.count);
            let joinable = last.table == register.table
                && (start <= last_end
                    || covered(device, bridging, register.table, last_end, start))
                && end.max(last_end) - last_start <= limit;
            if joinable {
                last.count = u16::try_from(end.max(last_end) - last_start).unwrap_or(u16::MAX);
                continue;
            }
        }
        spans.push(ReadSpan {
            table: register.table,
            address: register.address,
            count: register.words,
        });
    }
    spans
}

/// True when every address of `table` in `from..to` may be read in passing: it belongs to a
/// readable register whose read changes nothing (never a buffer page, never an action
/// register), or to a reserved range the spec marks readable (when `bridging` allows it),
/// and to no other register.
fn covered(device: &DeviceInfo, bridging: Bridging, table: Table, from: u32, to: u32) -> bool {
    (from..to).all(|at| {
        let Ok(address) = u16::try_from(at) else {
            return false;
        };
        let mut holders = device.registers.iter().filter(|r| {
            r.table == table
                && u32::from(r.address) <= at
                && at < u32::from(r.address) + u32::from(r.words)
        });
        let mut any = false;
        let harmless = holders.all(|r| {
            any = true;
            r.readable() && r.read_is_repeatable()
        });
        if any {
            harmless
        } else {
            bridging == Bridging::Reserved && device.reserved_readable(table, address)
        }
    })
}

/// What part of a register's value one FC06 of a write plan carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WritePart {
    /// The whole one-word value.
    Whole,
    /// The whole 32-bit value, in one FC06 with four data bytes (`long_writes: wide`).
    Wide,
    /// The high word of a 32-bit value written as two FC06.
    High,
    /// The low word of a 32-bit value written as two FC06.
    Low,
    /// Word `n` (from 0) of a register of more words, written one word at a time.
    Word(u16),
}

/// One FC06 of a write plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WriteStep {
    /// Holding register address written.
    pub address: u16,
    /// The value the FC06 carries.
    pub value: WriteValue,
    /// What part of the register's value it is.
    pub part: WritePart,
}

/// The FC06 requests that store `words` (a register's words in address order, already
/// validated) in `register`, in the order they must be sent: one word; a 32-bit value as two
/// words in the spec's `write_order`, or as one 4-byte FC06 on devices with `long_writes:
/// wide`; a longer register (IPv4) word by word.
pub fn plan_write(device: &DeviceInfo, register: &RegisterInfo, words: &[u16]) -> Vec<WriteStep> {
    match *words {
        [word] => vec![WriteStep {
            address: register.address,
            value: WriteValue::Word(word),
            part: WritePart::Whole,
        }],
        [first, second] if device.long_writes == LongWrites::Wide => vec![WriteStep {
            address: register.address,
            // The wire carries the words in address order, most significant byte first.
            value: WriteValue::DoubleWord(join_u32([first, second], WordOrder::HighFirst)),
            part: WritePart::Wide,
        }],
        [first, second] => {
            let value = join_u32([first, second], register.word_order);
            let high = register.word_order.high_offset();
            u32_writes(value, register.word_order, register.write_order)
                .iter()
                .map(|write| WriteStep {
                    address: register.address.wrapping_add(write.offset),
                    value: WriteValue::Word(write.value),
                    part: if write.offset == high {
                        WritePart::High
                    } else {
                        WritePart::Low
                    },
                })
                .collect()
        }
        _ => (register.address..)
            .zip(words)
            .zip(0u16..)
            .map(|((address, word), n)| WriteStep {
                address,
                value: WriteValue::Word(*word),
                part: WritePart::Word(n),
            })
            .collect(),
    }
}
