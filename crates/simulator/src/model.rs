//! The register model of one virtual device: stored words, measurements, reads, writes and
//! the replies they earn.

use optobus_codec::{
    rtu, tcp, EncodeError, ExceptionCode, ExceptionShape, ReadFunction, Request, Response, Words,
    WriteValue, MAX_READ_WORDS,
};
use optobus_device::{
    Addressing, DeviceInfo, LongWrites, RegisterInfo, Scalar, Table, ValueKind, WriteOrder,
};
use std::time::Duration;

use tokio::time::Instant;

use crate::buffer::{Buffer, BufferLayout, Role};
use crate::defaults::default_words;
use crate::faults::Injector;
use crate::layout::{stored_words, Cell, Layout};
use crate::names;
use crate::quirks::{BufferReadCount, Quirks, UnreadableReads};
use crate::signal::{raw_reading, raw_value, Signals, StatisticKind};

/// What the device answers to one request.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    /// The words of a read.
    Read {
        /// FC03 or FC04.
        function: ReadFunction,
        /// The words read.
        words: Vec<u16>,
    },
    /// The echo of a write.
    Write {
        /// Register address written.
        address: u16,
        /// The value written, two or four bytes.
        value: WriteValue,
    },
    /// An exception reply.
    Exception {
        /// The request's function code (without the exception bit).
        function: u8,
        /// The exception code, in the device's numbering.
        code: ExceptionCode,
    },
    /// No reply at all: another slave's request, a broadcast, a silent or busy device.
    Silent,
}

/// How a reply goes on the wire: an RTU frame from a slave address, or a Modbus TCP frame
/// under the request's MBAP header.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Envelope {
    Rtu { slave: u8 },
    Tcp(tcp::Header),
}

impl Envelope {
    /// Frames what `encode` writes into a buffer of the envelope's largest frame.
    fn frame(
        self,
        encode: impl FnOnce(&mut [u8], Self) -> Result<usize, EncodeError>,
    ) -> Option<Vec<u8>> {
        let mut out = [0u8; tcp::MAX_FRAME_LEN];
        let max = match self {
            Self::Rtu { .. } => rtu::MAX_FRAME_LEN,
            Self::Tcp(_) => tcp::MAX_FRAME_LEN,
        };
        let len = encode(&mut out[..max], self).ok()?;
        out.get(..len).map(<[u8]>::to_vec)
    }
}

impl Reply {
    /// The bytes of this reply in `envelope`, an exception in the device's `shape`; `None`
    /// for silence.
    pub(crate) fn encode(&self, envelope: Envelope, shape: ExceptionShape) -> Option<Vec<u8>> {
        let bytes: Vec<u8>;
        let response = match self {
            Self::Read { function, words } => {
                bytes = words.iter().flat_map(|w| w.to_be_bytes()).collect();
                Response::Read {
                    function: *function,
                    words: Words::from_bytes(&bytes)?,
                }
            }
            Self::Write { address, value } => Response::Write {
                address: *address,
                value: *value,
            },
            &Self::Exception { function, code } => {
                return envelope.frame(|out, envelope| match envelope {
                    Envelope::Rtu { slave } => {
                        rtu::encode_exception(out, slave, function, code, shape)
                    }
                    Envelope::Tcp(header) => {
                        tcp::encode_exception(out, header, function, code, shape)
                    }
                });
            }
            Self::Silent => return None,
        };
        envelope.frame(|out, envelope| match envelope {
            Envelope::Rtu { slave } => rtu::encode_response(out, slave, &response),
            Envelope::Tcp(header) => tcp::encode_response(out, header, &response),
        })
    }
}

/// Why a request is refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Fault {
    Function,
    Address,
    Value,
}

/// A request as the device received it: one the codec decodes, or just the function code of
/// one it does not.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Incoming<'a> {
    Request(&'a Request),
    Unsupported(u8),
}

/// A virtual device's whole state.
#[derive(Debug)]
pub(crate) struct Device {
    pub(crate) info: &'static DeviceInfo,
    pub(crate) layout: Layout,
    pub(crate) quirks: Quirks,
    epoch: Instant,
    /// Stored words of every register (settings; pinned measurements).
    pub(crate) words: Vec<Vec<u16>>,
    /// What `save` stored; a reboot or power cycle restores it.
    pub(crate) flash: Vec<Vec<u16>>,
    /// Factory values.
    pub(crate) factory: Vec<Vec<u16>>,
    /// Measurements a test fixed with `poke`.
    pub(crate) pinned: Vec<bool>,
    /// First halves of split 32-bit writes waiting for their second half.
    pub(crate) pending: Vec<Option<u16>>,
    pub(crate) signals: Signals,
    pub(crate) buffer: Option<Buffer>,
    /// The slave address the device answers to.
    pub(crate) address: u8,
    pub(crate) silent: bool,
    pub(crate) busy_until: Option<Instant>,
    /// Command registers still showing the value written: index, when the command finishes
    /// (`None`: never), and the words it shows then.
    pub(crate) finishing: Vec<(usize, Option<Instant>, Vec<u16>)>,
    /// How long a command with `done_when` takes to finish, instead of its busy time.
    pub(crate) finish_time: Option<Duration>,
    /// Faults injected into replies, shared by every server of the device.
    pub(crate) faults: Option<Injector>,
}

impl Device {
    pub(crate) fn new(info: &'static DeviceInfo) -> Self {
        let layout = Layout::new(info);
        let buffer_layout = BufferLayout::find(info);
        let signals = Signals::new(info, |index| {
            buffer_layout
                .as_ref()
                .is_some_and(|layout| layout.role(index).is_some())
        });
        let address = info.default_slave;
        let factory: Vec<Vec<u16>> = info
            .registers
            .iter()
            .map(|register| default_words(info, register, address))
            .collect();
        let count = info.registers.len();
        Self {
            info,
            layout,
            quirks: Quirks::of(info),
            epoch: Instant::now(),
            words: factory.clone(),
            flash: factory.clone(),
            factory,
            pinned: vec![false; count],
            pending: vec![None; count],
            signals,
            buffer: buffer_layout.map(|layout| Buffer::new(layout, 0.0)),
            address,
            silent: false,
            busy_until: None,
            finishing: Vec::new(),
            finish_time: None,
            faults: None,
        }
    }

    /// Seconds since the device was created.
    pub(crate) fn seconds(&self, now: Instant) -> f64 {
        now.saturating_duration_since(self.epoch).as_secs_f64()
    }

    pub(crate) fn register(&self, index: usize) -> Option<&'static RegisterInfo> {
        self.info.registers.get(index)
    }

    /// The slave-address register, if the device has one.
    pub(crate) fn slave_register(&self) -> Option<usize> {
        self.layout
            .find(names::SLAVE_ADDRESS)
            .filter(|&i| matches!(self.info.registers[i].kind, ValueKind::Scalar(_)))
    }

    /// Makes `slave` the address the device answers to, as configured (live and saved).
    pub(crate) fn set_slave(&mut self, slave: u8) {
        self.address = slave;
        if let Some(index) = self.slave_register() {
            let words = stored_words(&self.info.registers[index], u32::from(slave));
            self.words[index] = words.clone();
            self.flash[index] = words;
        }
    }

    /// The address the slave-address register of `words` names, if valid.
    pub(crate) fn configured_slave(&self, words: &[Vec<u16>]) -> Option<u8> {
        let index = self.slave_register()?;
        let raw = self.info.registers[index].raw(words.get(index)?);
        u8::try_from(raw).ok().filter(|a| (1..=247).contains(a))
    }

    // ------------------------------------------------------------------ requests

    /// Answers `incoming`, sent to `slave` (`None`: over TCP, where the device is addressed by its
    /// IP and answers every unit id).
    pub(crate) fn respond(
        &mut self,
        slave: Option<u8>,
        incoming: Incoming<'_>,
        now: Instant,
    ) -> Reply {
        self.settle(now);
        if self.silent || self.busy_until.is_some_and(|until| now < until) {
            return Reply::Silent;
        }
        let broadcast = slave == Some(0);
        if slave.is_some_and(|s| s != 0 && s != self.address) {
            return Reply::Silent;
        }
        let function = match incoming {
            Incoming::Request(request) => request.function_code(),
            Incoming::Unsupported(function) => function,
        };
        let request = match incoming {
            Incoming::Request(request) if self.info.functions.contains(&function) => Some(request),
            _ => None,
        };
        let outcome = match request {
            None => Err(Fault::Function),
            Some(Request::Read {
                function,
                address,
                count,
            }) => {
                // A broadcast read is answered only by devices that do (rangefinder 3.5).
                if broadcast && !self.quirks.answer_broadcast_reads {
                    return Reply::Silent;
                }
                self.read(Table::from(*function), *address, *count, now)
                    .map(|words| Reply::Read {
                        function: *function,
                        words,
                    })
            }
            Some(Request::Write { address, value }) => {
                self.write(*address, *value, now).map(|()| Reply::Write {
                    address: *address,
                    value: *value,
                })
            }
        };
        match outcome {
            // A broadcast write is carried out but never answered.
            Ok(Reply::Write { .. }) | Err(_) if broadcast => Reply::Silent,
            Ok(reply) => reply,
            Err(fault) => Reply::Exception {
                function,
                code: match fault {
                    Fault::Function => self.quirks.illegal_function,
                    Fault::Address => self.quirks.illegal_address,
                    Fault::Value => self.quirks.illegal_value,
                },
            },
        }
    }

    // ------------------------------------------------------------------ reads

    fn readable(&self, index: usize) -> bool {
        self.register(index)
            .is_some_and(|register| register.readable())
    }

    /// Reads `count` words (or one field) from `address`.
    pub(crate) fn read(
        &mut self,
        table: Table,
        address: u16,
        count: u16,
        now: Instant,
    ) -> Result<Vec<u16>, Fault> {
        let limit = self.info.max_read_words.min(MAX_READ_WORDS);
        if count == 0 || count > limit {
            return Err(Fault::Address);
        }
        let refuse_unreadable = self.quirks.unreadable == UnreadableReads::Refused;
        let refuse_readable_reserved = self.quirks.readable_reserved == UnreadableReads::Refused;
        let t = self.seconds(now);
        match self.info.addressing {
            Addressing::Field => {
                // One field per request, asked for with its own width (rangefinder 1.2).
                match self.layout.cell(table, address) {
                    Some(Cell::Register { index, .. }) => {
                        let register = &self.info.registers[index];
                        if count != register.words {
                            return Err(Fault::Address);
                        }
                        if !self.readable(index) {
                            return if refuse_unreadable {
                                Err(Fault::Address)
                            } else {
                                Ok(vec![0; usize::from(count)])
                            };
                        }
                        self.turn_page_if_reading(&[index]);
                        Ok(self.live_words(index, t))
                    }
                    Some(Cell::Reserved { readable }) if count == 1 => {
                        let refused = if readable {
                            refuse_readable_reserved
                        } else {
                            refuse_unreadable
                        };
                        if !refused {
                            Ok(vec![0])
                        } else {
                            Err(Fault::Address)
                        }
                    }
                    _ => Err(Fault::Address),
                }
            }
            Addressing::Word => {
                let end = u32::from(address) + u32::from(count);
                let mut cells = Vec::with_capacity(usize::from(count));
                for at in u32::from(address)..end {
                    let at = u16::try_from(at).map_err(|_| Fault::Address)?;
                    let cell = self.layout.cell(table, at).ok_or(Fault::Address)?;
                    match cell {
                        Cell::Undefined => return Err(Fault::Address),
                        // A range the spec marks readable answers zeros, unless told to refuse.
                        Cell::Reserved { readable: false } if refuse_unreadable => {
                            return Err(Fault::Address)
                        }
                        Cell::Reserved { readable: true } if refuse_readable_reserved => {
                            return Err(Fault::Address)
                        }
                        Cell::Register { index, .. }
                            if refuse_unreadable && !self.readable(index) =>
                        {
                            return Err(Fault::Address)
                        }
                        _ => cells.push(cell),
                    }
                }
                let indices: Vec<usize> = cells
                    .iter()
                    .filter_map(|cell| match cell {
                        Cell::Register { index, .. } => Some(*index),
                        _ => None,
                    })
                    .collect();
                self.turn_page_if_reading(&indices);
                // Each register is evaluated once, so both halves of a reading agree.
                let mut cache: Vec<(usize, Vec<u16>)> = Vec::new();
                let mut words = Vec::with_capacity(cells.len());
                for cell in cells {
                    let word = match cell {
                        Cell::Register { index, offset } if self.readable(index) => {
                            let position = match cache.iter().position(|(i, _)| *i == index) {
                                Some(position) => position,
                                None => {
                                    cache.push((index, self.live_words(index, t)));
                                    cache.len() - 1
                                }
                            };
                            cache
                                .get(position)
                                .and_then(|(_, w)| w.get(usize::from(offset)))
                                .copied()
                                .unwrap_or(0)
                        }
                        _ => 0,
                    };
                    words.push(word);
                }
                Ok(words)
            }
        }
    }

    /// A read covering a buffered value turns the buffer's page first.
    fn turn_page_if_reading(&mut self, indices: &[usize]) {
        if let Some(buffer) = &mut self.buffer {
            let turns = indices.iter().any(|&index| {
                !self.pinned.get(index).copied().unwrap_or(false)
                    && matches!(buffer.layout.role(index), Some(Role::Value(_)))
            });
            if turns {
                buffer.turn_page();
            }
        }
    }

    /// The words register `index` shows now.
    pub(crate) fn live_words(&self, index: usize, t: f64) -> Vec<u16> {
        let stored = || self.words.get(index).cloned().unwrap_or_default();
        let Some(register) = self.register(index) else {
            return Vec::new();
        };
        if self.pinned.get(index).copied().unwrap_or(false) {
            return stored();
        }
        if let Some(buffer) = &self.buffer {
            if let Some(role) = buffer.layout.role(index) {
                return self.buffer_words(buffer, register, role);
            }
        }
        let Some(ids) = self.signals.of_register(index) else {
            return stored();
        };
        match register.kind {
            ValueKind::Record(fields) => {
                let mut words = Vec::with_capacity(usize::from(register.words));
                for (field, &id) in fields.iter().zip(ids) {
                    let raw = self.signal_raw(id, t);
                    match field.scalar {
                        Scalar::U16 | Scalar::I16 => words.push(raw as u16),
                        Scalar::U32 | Scalar::I32 => {
                            words.extend(optobus_codec::value::split_u32(raw, register.word_order))
                        }
                    }
                }
                words.resize(usize::from(register.words), 0);
                words
            }
            _ => ids
                .first()
                .map(|&id| stored_words(register, self.signal_raw(id, t)))
                .unwrap_or_else(stored),
        }
    }

    fn signal_raw(&self, id: usize, t: f64) -> u32 {
        let Some(signal) = self.signals.get(id) else {
            return 0;
        };
        raw_reading(signal, self.signal_value(id, t))
    }

    /// The reading of signal `id` at `t` (`None`: a sentinel sample).
    pub(crate) fn signal_value(&self, id: usize, t: f64) -> Option<i64> {
        self.signals.reading(id, t, |statistic| {
            let config = self.register(statistic.config)?;
            let raw = config.raw(self.words.get(statistic.config)?);
            let field_value = |field: &optobus_device::FieldInfo| {
                let value = optobus_codec::value::BitField {
                    shift: field.lsb,
                    width: field.width,
                }
                .get(raw);
                field.codes.iter().find(|c| c.code == value)
            };
            let source = field_value(statistic.source_field)?;
            let kind = field_value(statistic.kind_field)?;
            let source = self.layout.find(source.name)?;
            let source = *self.signals.of_register(source)?.first()?;
            Some((source, StatisticKind::from_code_name(kind.name)?))
        })
    }

    fn buffer_words(&self, buffer: &Buffer, register: &RegisterInfo, role: Role) -> Vec<u16> {
        let (read, valid) = buffer.counts();
        let raw = match role {
            Role::ReadCount => match self.quirks.buffer_read_count {
                BufferReadCount::IncludingPage => read,
                BufferReadCount::BeforePage => read - valid,
            },
            Role::ValidCount => valid,
            Role::Value(slot) => {
                let value = buffer.sample(slot).and_then(|(source, at)| {
                    let source = source?;
                    let id = *self.signals.of_register(source)?.first()?;
                    self.signal_value(id, at)
                });
                raw_value(register.scalar(), register.sentinel, value)
            }
        };
        stored_words(register, raw)
    }

    // ------------------------------------------------------------------ writes

    /// Writes `value` to holding register `address`.
    pub(crate) fn write(
        &mut self,
        address: u16,
        value: WriteValue,
        now: Instant,
    ) -> Result<(), Fault> {
        let Some(Cell::Register { index, offset }) = self.layout.cell(Table::Holding, address)
        else {
            return Err(Fault::Address);
        };
        let register = &self.info.registers[index];
        if !register.access.writable() {
            return Err(Fault::Address);
        }
        let raw = match (value, register.words) {
            (WriteValue::DoubleWord(raw), 2) if offset == 0 => raw,
            (WriteValue::DoubleWord(_), _) => return Err(Fault::Value),
            (WriteValue::Word(word), 1) => u32::from(word),
            (WriteValue::Word(word), 2) => {
                if self.info.addressing == Addressing::Field
                    || self.info.long_writes == LongWrites::Wide
                {
                    // A 32-bit field takes its whole value in one 4-byte write.
                    return Err(Fault::Value);
                }
                match self.split_write(index, offset, word) {
                    Some(raw) => raw,
                    None => return Ok(()),
                }
            }
            (WriteValue::Word(word), _) => {
                // Multi-word registers other than 32-bit ones (IPv4): one word at a time.
                if register.check(u32::from(word)).is_err() {
                    return Err(Fault::Value);
                }
                if let Some(slot) = self
                    .words
                    .get_mut(index)
                    .and_then(|words| words.get_mut(usize::from(offset)))
                {
                    *slot = word;
                }
                return Ok(());
            }
        };
        if register.check(raw).is_err() {
            return Err(Fault::Value);
        }
        self.words[index] = stored_words(register, raw);
        self.after_write(index, raw, now);
        Ok(())
    }

    /// One half of a split 32-bit write (P series 4.1.2 note 4: low word first, latched when
    /// the high word arrives). The half that comes first in the register's `write_order` is
    /// held; the second completes the value, which is validated whole. A second half without
    /// a first pairs with the stored first half. `None` while waiting for the second half.
    fn split_write(&mut self, index: usize, offset: u16, word: u16) -> Option<u32> {
        let register = &self.info.registers[index];
        let high = register.word_order.high_offset();
        let first = match register.write_order {
            WriteOrder::HighWordFirst => high,
            WriteOrder::LowWordFirst => 1 - high,
        };
        if offset == first {
            if let Some(pending) = self.pending.get_mut(index) {
                *pending = Some(word);
            }
            return None;
        }
        let stored = self.words.get(index)?;
        let first_word = self
            .pending
            .get_mut(index)
            .and_then(Option::take)
            .or_else(|| stored.get(usize::from(first)).copied())
            .unwrap_or(0);
        let mut words = [0u16; 2];
        words[usize::from(first)] = first_word;
        words[usize::from(offset)] = word;
        Some(register.raw(&words))
    }

    // ------------------------------------------------------------------ inspection

    /// The words a read of `address` alone shows now (one word, or one field).
    pub(crate) fn peek(&self, table: Table, address: u16, now: Instant) -> Option<Vec<u16>> {
        let t = self.seconds(now);
        match self.layout.cell(table, address)? {
            Cell::Register { index, offset } => {
                let words = self.live_words(index, t);
                match self.info.addressing {
                    Addressing::Field => Some(words),
                    Addressing::Word => words.get(usize::from(offset)).map(|&w| vec![w]),
                }
            }
            Cell::Reserved { .. } => Some(vec![0]),
            Cell::Undefined => None,
        }
    }

    /// Stores `words` from `address` on, pinning measurements; `Err(address)` names the
    /// first address without a register.
    pub(crate) fn poke(
        &mut self,
        table: Table,
        address: u16,
        words: &[u16],
        now: Instant,
    ) -> Result<(), u16> {
        let t = self.seconds(now);
        match self.info.addressing {
            Addressing::Field => {
                let Some(Cell::Register { index, .. }) = self.layout.cell(table, address) else {
                    return Err(address);
                };
                let mut stored = words.to_vec();
                stored.resize(usize::from(self.info.registers[index].words), 0);
                self.words[index] = stored;
                self.pinned[index] =
                    self.signals.of_register(index).is_some() || self.buffer_role(index).is_some();
                Ok(())
            }
            Addressing::Word => {
                for (at, &word) in (u32::from(address)..).zip(words) {
                    let at = u16::try_from(at).map_err(|_| u16::MAX)?;
                    let Some(Cell::Register { index, offset }) = self.layout.cell(table, at) else {
                        return Err(at);
                    };
                    let dynamic = self.signals.of_register(index).is_some()
                        || self.buffer_role(index).is_some();
                    if dynamic && !self.pinned[index] {
                        // Pin the current reading, then overwrite the poked word.
                        self.words[index] = self.live_words(index, t);
                        self.pinned[index] = true;
                    }
                    if let Some(slot) = self.words[index].get_mut(usize::from(offset)) {
                        *slot = word;
                    }
                }
                Ok(())
            }
        }
    }

    fn buffer_role(&self, index: usize) -> Option<Role> {
        self.buffer.as_ref()?.layout.role(index)
    }
}
