//! Which register, if any, each address of each table belongs to, and the words a register
//! stores for a raw value.

use std::collections::HashMap;

use optobus_device::{CommandInfo, DeviceInfo, RegisterInfo, Table};

/// What one address holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Cell {
    /// Inside the table, but neither a register nor reserved.
    Undefined,
    /// A reserved address; `readable` when the spec marks it readable.
    Reserved { readable: bool },
    /// Word `offset` of register `index` (always 0 with field addressing: the whole field).
    Register { index: usize, offset: u16 },
}

/// The address map of a device.
#[derive(Debug)]
pub(crate) struct Layout {
    holding: Vec<Cell>,
    input: Vec<Cell>,
    by_name: HashMap<&'static str, usize>,
}

impl Layout {
    pub(crate) fn new(device: &'static DeviceInfo) -> Self {
        let mut layout = Self {
            holding: vec![Cell::Undefined; usize::from(device.holding_registers)],
            input: vec![Cell::Undefined; usize::from(device.input_registers)],
            by_name: HashMap::new(),
        };
        for reserved in device.reserved {
            let cells = layout.cells_mut(reserved.table);
            for address in reserved.from..=reserved.to {
                if let Some(cell) = cells.get_mut(usize::from(address)) {
                    *cell = Cell::Reserved {
                        readable: reserved.readable,
                    };
                }
            }
        }
        for (index, register) in device.registers.iter().enumerate() {
            layout.by_name.insert(register.name, index);
            // With one address per field a register takes one address whatever its width.
            let span = register.span(device.addressing);
            let cells = layout.cells_mut(register.table);
            for offset in 0..span {
                let address = usize::from(register.address) + usize::from(offset);
                if let Some(cell) = cells.get_mut(address) {
                    *cell = Cell::Register { index, offset };
                }
            }
        }
        layout
    }

    fn cells_mut(&mut self, table: Table) -> &mut Vec<Cell> {
        match table {
            Table::Holding => &mut self.holding,
            Table::Input => &mut self.input,
        }
    }

    /// The cell at `address`, `None` past the end of the table.
    pub(crate) fn cell(&self, table: Table, address: u16) -> Option<Cell> {
        let cells = match table {
            Table::Holding => &self.holding,
            Table::Input => &self.input,
        };
        cells.get(usize::from(address)).copied()
    }

    /// The index of the register called `name`.
    pub(crate) fn find(&self, name: &str) -> Option<usize> {
        self.by_name.get(name).copied()
    }
}

/// Whether `command` is written through `register`, and for which repeat copy: `Some(None)`
/// for a plain register, `Some(Some(prefix))` for a copy (`channel_2_`), whose targets are the
/// same copy's registers.
pub(crate) fn command_copy(
    command: &CommandInfo,
    register: &RegisterInfo,
) -> Option<Option<String>> {
    if register.name == command.register {
        return Some(None);
    }
    let copy = register.copy?;
    (copy.member == command.register).then(|| Some(format!("{}_{}_", copy.repeat, copy.number)))
}

/// The stored words of `register` holding `raw`: its raw value in the register's words,
/// padded with zeros to the register's width.
pub(crate) fn stored_words(register: &RegisterInfo, raw: u32) -> Vec<u16> {
    let mut words = register.raw_words(raw).to_vec();
    words.resize(usize::from(register.words).max(words.len()), 0);
    words
}
