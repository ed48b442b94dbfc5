//! The bus file's measurements as the input registers of a virtual unit of each gateway, so
//! that a PLC reading the sensors through the gateway reads the measurements too.
//!
//! Each measurement has a block of [`BLOCK`] registers, in the bus file's order (the first at
//! address 0, the second at 20, …); the map is in the crate's README. A block is rewritten
//! whole from each [`Event::Measurement`] of its measurement, so a read of one block is the
//! value, judgement, counts and skew of one and the same value. Nothing here reaches a line.

use std::collections::HashSet;
use std::sync::{Arc, PoisonError, RwLock};
use std::time::Duration;

use optobus_codec::server::{self, ServerRequest};
use optobus_codec::value::{Fixed, Scale};
use optobus_codec::{ExceptionCode, FrameShape, ReadFunction, MAX_READ_WORDS};
use optobus_measure::Judgement;
use tokio::sync::broadcast::{self, error::RecvError};

use crate::event::Event;
use crate::file::Measurements;
use crate::measurement::MeasurementEvent;
use crate::schedule::Health;

/// Registers per measurement.
pub(crate) const BLOCK: usize = 20;

/// Offsets in a block.
mod at {
    /// The value, a signed 32-bit integer in steps of `10^EXPONENT` of the unit (two words,
    /// high word first).
    pub(super) const VALUE: usize = 0;
    /// The decimal exponent of the value's step, a signed 16-bit integer (−6: µm of mm).
    pub(super) const EXPONENT: usize = 2;
    /// The value's [`Status`](super::Status).
    pub(super) const STATUS: usize = 3;
    /// The judgement: 0 none, 1 ll, 2 lo, 3 go, 4 hi, 5 hh.
    pub(super) const JUDGEMENT: usize = 4;
    /// The judgement counts ll, lo, go, hi, hh, unsigned 32-bit each (high word first).
    pub(super) const COUNTS: usize = 5;
    /// Between the first and last input's request in µs, unsigned 32-bit (high word first).
    pub(super) const SKEW: usize = 15;
}

/// Whether a block's value is valid, or why it is not.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u16)]
pub(crate) enum Status {
    /// The value is valid.
    Valid = 0,
    /// An input has no valid value (the device's sentinel: out of range, no target).
    InvalidInput = 1,
    /// An input's device is offline.
    Offline = 2,
    /// The inputs were read further apart than `max_skew`.
    Skew = 3,
    /// No value has been computed yet.
    NoValueYet = 4,
    /// The value does not fit a signed 32-bit integer at its resolution (never wrapped).
    OutOfRange = 5,
    /// No exact result (a division by zero, an overflow), or a measurement it uses has none
    /// for another reason.
    NoResult = 6,
}

/// The judgement's code in a block (0 is none).
fn judgement_code(judgement: Option<Judgement>) -> u16 {
    match judgement {
        None => 0,
        Some(Judgement::LowLow) => 1,
        Some(Judgement::Low) => 2,
        Some(Judgement::Go) => 3,
        Some(Judgement::High) => 4,
        Some(Judgement::HighHigh) => 5,
    }
}

/// How one measurement is written into its block.
#[derive(Clone, Debug)]
struct Layout {
    name: Arc<str>,
    /// The decimal exponent of the value's step in its unit.
    exponent: i32,
    max_skew: Duration,
}

/// The virtual unit's registers: a block per measurement, in the bus file's order.
#[derive(Debug)]
pub(crate) struct MeasurementUnit {
    layouts: Vec<Layout>,
    registers: RwLock<Vec<u16>>,
}

impl MeasurementUnit {
    /// The registers of `measurements`, each block without a value yet.
    pub(crate) fn new(measurements: &Measurements) -> Self {
        let plan = &measurements.plan;
        // The plan orders formulas so that each comes after those it uses; blocks follow the
        // file's order, which the plan's `order` gives.
        let mut layouts: Vec<(usize, Layout)> = plan
            .formulas
            .iter()
            .zip(&measurements.settings)
            .zip(&plan.order)
            .map(|((formula, settings), &definition)| {
                let layout = Layout {
                    name: Arc::from(formula.name.as_str()),
                    exponent: formula.resolution,
                    max_skew: settings.max_skew,
                };
                (definition, layout)
            })
            .collect();
        layouts.sort_by_key(|(definition, _)| *definition);
        let layouts: Vec<Layout> = layouts.into_iter().map(|(_, layout)| layout).collect();
        let mut registers = vec![0; layouts.len() * BLOCK];
        for (block, layout) in registers.chunks_exact_mut(BLOCK).zip(&layouts) {
            block[at::EXPONENT] = exponent_word(layout.exponent);
            block[at::STATUS] = Status::NoValueYet as u16;
        }
        Self {
            layouts,
            registers: RwLock::new(registers),
        }
    }

    /// Rewrites the block of `event`'s measurement; `offline` tells whether a device is.
    fn update(&self, event: &MeasurementEvent, offline: impl Fn(&str) -> bool) {
        let Some(index) = self
            .layouts
            .iter()
            .position(|layout| layout.name == event.measurement)
        else {
            return;
        };
        let block = block(event, &self.layouts[index], offline);
        let mut registers = self
            .registers
            .write()
            .unwrap_or_else(PoisonError::into_inner);
        registers[index * BLOCK..(index + 1) * BLOCK].copy_from_slice(&block);
    }

    /// `count` registers from `address`, or exception 02 when any is outside the map.
    fn read(&self, address: u16, count: u16) -> Result<Vec<u16>, ExceptionCode> {
        let registers = self
            .registers
            .read()
            .unwrap_or_else(PoisonError::into_inner);
        let start = usize::from(address);
        registers
            .get(start..start + usize::from(count))
            .map(<[u16]>::to_vec)
            .ok_or(ExceptionCode::ILLEGAL_DATA_ADDRESS)
    }

    /// The reply PDU to a request PDU, read with the codec's server framing: FC04 reads of
    /// the map; exception 02 for a read outside it, 03 for a request malformed for its
    /// function, 01 for anything else (a write, FC03, another function).
    pub(crate) fn answer(&self, pdu: &[u8]) -> Vec<u8> {
        let request = match server::parse_request(pdu, &FrameShape::STANDARD) {
            Ok(request) => request,
            Err(refused) => return exception(refused.function(), refused.exception()),
        };
        let function = request.function_code();
        match request {
            ServerRequest::Read {
                function: ReadFunction::Input,
                address,
                count,
            } => match self.read(address, count) {
                Ok(words) => {
                    let mut reply = [0u8; 2 + 2 * MAX_READ_WORDS as usize];
                    match server::encode_read_reply(&mut reply, ReadFunction::Input, words) {
                        Ok(len) => reply[..len].to_vec(),
                        Err(_) => exception(function, ExceptionCode::ILLEGAL_DATA_VALUE),
                    }
                }
                Err(code) => exception(function, code),
            },
            _ => exception(function, ExceptionCode::ILLEGAL_FUNCTION),
        }
    }
}

/// The exception reply PDU to a request of `function` (every code here is one byte).
fn exception(function: u8, code: ExceptionCode) -> Vec<u8> {
    server::exception_pdu(function, code.0 as u8).to_vec()
}

/// The exponent as its register holds it (a signed 16-bit integer).
fn exponent_word(exponent: i32) -> u16 {
    let exponent =
        i16::try_from(exponent).unwrap_or(if exponent < 0 { i16::MIN } else { i16::MAX });
    exponent as u16
}

/// Two words of a 32-bit value, high word first.
fn words32(value: u32) -> [u16; 2] {
    [(value >> 16) as u16, value as u16]
}

/// The block of one value of a measurement laid out as `layout`.
fn block(
    event: &MeasurementEvent,
    layout: &Layout,
    offline: impl Fn(&str) -> bool,
) -> [u16; BLOCK] {
    let mut block = [0; BLOCK];
    let (value, status) = match &event.value {
        Ok(value) => match steps(*value, layout.exponent) {
            Some(steps) => (steps, Status::Valid),
            None => (0, Status::OutOfRange),
        },
        Err(_) => (0, why_invalid(event, layout, offline)),
    };
    block[at::VALUE..at::VALUE + 2].copy_from_slice(&words32(value as u32));
    block[at::EXPONENT] = exponent_word(layout.exponent);
    block[at::STATUS] = status as u16;
    // A value out of range is not judged here: its judgement would describe a value the PLC
    // cannot see.
    if status == Status::Valid {
        block[at::JUDGEMENT] = judgement_code(event.judgement);
    }
    for (slot, count) in block[at::COUNTS..at::COUNTS + 10]
        .chunks_exact_mut(2)
        .zip(event.counts.unwrap_or_default())
    {
        // Counters wrap at 2^32 as a PLC's counters do; the difference of two reads holds.
        slot.copy_from_slice(&words32(count as u32));
    }
    let skew = u32::try_from(event.skew.as_micros()).unwrap_or(u32::MAX);
    block[at::SKEW..at::SKEW + 2].copy_from_slice(&words32(skew));
    block
}

/// Why a value without one has none, from what the event carries: an input without a value
/// (its device offline, or the device's sentinel), else inputs too far apart, else the
/// arithmetic.
fn why_invalid(
    event: &MeasurementEvent,
    layout: &Layout,
    offline: impl Fn(&str) -> bool,
) -> Status {
    let mut missing = event.inputs.iter().filter(|input| input.value.is_none());
    if let Some(first) = missing.next() {
        let device_of = |name: &str| {
            name.split_once('.')
                .map_or("", |(device, _)| device)
                .to_owned()
        };
        let is_offline = |name: &str| offline(&device_of(name));
        if is_offline(&first.name) || missing.any(|input| is_offline(&input.name)) {
            return Status::Offline;
        }
        return Status::InvalidInput;
    }
    if event.skew > layout.max_skew {
        return Status::Skew;
    }
    Status::NoResult
}

/// `value` in steps of `10^exponent`, rounded half away from zero where it is finer; `None`
/// when that does not fit an `i32`.
fn steps(value: Fixed, exponent: i32) -> Option<i32> {
    let ten = |power: u32| 10i128.checked_pow(power);
    let raw = i128::from(value.raw());
    // value = numerator / denominator steps.
    let (mut numerator, mut denominator) = match value.scale() {
        Scale::Decimal { .. } => (raw, 1i128),
        Scale::Ratio {
            numerator,
            denominator,
        } => (
            raw.checked_mul(i128::from(numerator))?,
            i128::from(denominator.get()),
        ),
    };
    let shift = match value.scale() {
        Scale::Decimal { exponent: own } => i32::from(own) - exponent,
        Scale::Ratio { .. } => -exponent,
    };
    if shift >= 0 {
        numerator = numerator.checked_mul(ten(shift.unsigned_abs())?)?;
    } else {
        denominator = denominator.checked_mul(ten(shift.unsigned_abs())?)?;
    }
    let (quotient, remainder) = (numerator / denominator, numerator % denominator);
    let rounded = if 2 * remainder.abs() >= denominator {
        quotient + numerator.signum()
    } else {
        quotient
    };
    i32::try_from(rounded).ok()
}

/// Follows `events` until the bus stops, rewriting each measurement's block from its values.
/// Devices' health is followed too, to tell an offline input from an invalid one (a device's
/// health event comes before the measurement it makes invalid).
pub(crate) async fn follow(unit: Arc<MeasurementUnit>, mut events: broadcast::Receiver<Event>) {
    let mut offline: HashSet<Arc<str>> = HashSet::new();
    loop {
        match events.recv().await {
            Ok(Event::Measurement(event)) => {
                unit.update(&event, |device| offline.contains(device));
            }
            Ok(Event::Health(health)) => {
                let device = Arc::clone(&health.source.device);
                match health.health {
                    Health::Offline => offline.insert(device),
                    Health::Online => offline.remove(&device),
                };
            }
            Ok(_) => {}
            // Missed values: the next ones rewrite the blocks.
            Err(RecvError::Lagged(_)) => {}
            Err(RecvError::Closed) => return,
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::SystemTime;

    use super::*;
    use crate::measurement::InputValue;

    const MM: Scale = Scale::Decimal { exponent: -6 };

    fn gap(value: Result<Fixed, String>, inputs: [Option<i64>; 2]) -> MeasurementEvent {
        MeasurementEvent {
            measurement: Arc::from("gap"),
            unit: Arc::from("mm"),
            value,
            inputs: ["top.distance_1", "bottom.distance_1"]
                .into_iter()
                .zip(inputs)
                .map(|(name, value)| InputValue {
                    name: Arc::from(name),
                    value: value.map(|raw| Fixed::new(raw, MM)),
                    unit: Arc::from("mm"),
                    requested: SystemTime::UNIX_EPOCH,
                    reason: value.is_none().then(|| "no value".to_owned()),
                })
                .collect(),
            skew: Duration::from_micros(2150),
            judgement: Some(Judgement::Go),
            stats: None,
            counts: Some([0, 1, 70_000, 3, (1 << 32) + 4]),
            time: SystemTime::UNIX_EPOCH,
        }
    }

    fn unit() -> MeasurementUnit {
        let layout = |name: &str| Layout {
            name: Arc::from(name),
            exponent: -6,
            max_skew: Duration::from_millis(1),
        };
        let layouts = vec![layout("gap"), layout("step")];
        let registers = vec![0; layouts.len() * BLOCK];
        MeasurementUnit {
            layouts,
            registers: RwLock::new(registers),
        }
    }

    #[test]
    fn a_valid_value_fills_its_block_high_word_first() {
        let unit = unit();
        let value = Fixed::new(-10_061_630, MM);
        unit.update(&gap(Ok(value), [Some(1), Some(2)]), |_| false);
        let block = unit.read(0, BLOCK as u16).unwrap();
        // -10061630 = 0xFF66_78C2.
        assert_eq!(&block[..5], &[0xFF66, 0x78C2, (-6i16) as u16, 0, 3]);
        assert_eq!(
            &block[5..15],
            &[0, 0, 0, 1, 0x0001, 0x1170, 0, 3, 0, 4],
            "counts wrap at 2^32"
        );
        assert_eq!(&block[15..17], &[0, 2150]);
    }

    #[test]
    fn an_invalid_value_says_why_and_has_no_judgement() {
        let unit = unit();
        let invalid = gap(Err("top.distance_1: no value".into()), [None, Some(2)]);
        unit.update(&invalid, |_| false);
        let block = unit.read(0, 5).unwrap();
        assert_eq!(
            block,
            [0, 0, (-6i16) as u16, Status::InvalidInput as u16, 0]
        );
        unit.update(&invalid, |device| device == "top");
        assert_eq!(unit.read(3, 1).unwrap(), [Status::Offline as u16]);
        let late = gap(Err("read 2 ms apart".into()), [Some(1), Some(2)]);
        unit.update(&late, |_| false);
        assert_eq!(unit.read(3, 1).unwrap(), [Status::Skew as u16]);
    }

    #[test]
    fn a_value_too_large_for_32_bits_is_out_of_range_never_wrapped() {
        let unit = unit();
        // 2^31 µm: one step beyond i32.
        let large = Fixed::new(1 << 31, MM);
        unit.update(&gap(Ok(large), [Some(1), Some(2)]), |_| false);
        let block = unit.read(0, 5).unwrap();
        assert_eq!(block, [0, 0, (-6i16) as u16, Status::OutOfRange as u16, 0]);
        assert_eq!(
            steps(Fixed::new(i64::from(i32::MAX), MM), -6),
            Some(i32::MAX)
        );
        assert_eq!(
            steps(Fixed::new(i64::from(i32::MIN), MM), -6),
            Some(i32::MIN)
        );
        assert_eq!(steps(Fixed::new(i64::from(i32::MIN) - 1, MM), -6), None);
        // Finer than the resolution: rounded half away from zero.
        let nm = Scale::Decimal { exponent: -9 };
        assert_eq!(steps(Fixed::new(-1_500, nm), -6), Some(-2));
        assert_eq!(steps(Fixed::new(1_499, nm), -6), Some(1));
        assert_eq!(
            steps(Fixed::new(i64::MAX, Scale::Decimal { exponent: 3 }), -6),
            None
        );
    }

    #[test]
    fn reads_outside_the_map_and_writes_get_their_exceptions() {
        let unit = unit();
        // Two blocks: 40 registers.
        assert_eq!(unit.answer(&[0x04, 0, 39, 0, 1]), [0x04, 2, 0, 0]);
        assert_eq!(unit.answer(&[0x04, 0, 40, 0, 1]), [0x84, 0x02]);
        assert_eq!(unit.answer(&[0x04, 0, 30, 0, 11]), [0x84, 0x02]);
        assert_eq!(unit.answer(&[0x04, 0xFF, 0xFF, 0, 125]), [0x84, 0x02]);
        // Input registers only, never written.
        assert_eq!(unit.answer(&[0x03, 0, 0, 0, 1]), [0x83, 0x01]);
        assert_eq!(unit.answer(&[0x06, 0, 0, 0, 1]), [0x86, 0x01]);
        assert_eq!(unit.answer(&[0x10, 0, 0, 0, 1, 2, 0, 1]), [0x90, 0x01]);
        // Malformed: a read of 0 registers, a short PDU.
        assert_eq!(unit.answer(&[0x04, 0, 0, 0, 0]), [0x84, 0x03]);
        assert_eq!(unit.answer(&[0x04, 0, 0]), [0x84, 0x03]);
    }
}
