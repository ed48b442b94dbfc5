//! The exact request frames of a read or a write, from the driver's own read and write plans.

use optobus_codec::{rtu, tcp, EncodeError, Request, WriteValue};
use optobus_device::{DeviceInfo, RegisterInfo};
use optobus_driver::{plan_reads, plan_write, WritePart, WriteStep};
use serde::Serialize;

use crate::error::Error;
use crate::frame::{serialize_hex, Framing};
use crate::layout::span_text;
use crate::parse::parse_value;
use crate::resolve::{resolve_one, resolve_readable};
use crate::value::{decode_value, Value};

/// One request frame to send, and what it does in words.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct EncodedFrame {
    /// The frame's bytes (JSON: `hex`, `01 04 00 00 00 02 71 CB`).
    #[serde(rename = "hex", serialize_with = "serialize_hex")]
    pub bytes: Vec<u8>,
    /// `read input 0-1 (distance_1)`, `write holding 6 = 0x0014: sampling_interval = …`;
    /// over TCP with the transaction and unit.
    pub description: String,
    /// The request the frame carries.
    #[serde(skip)]
    pub request: Request,
}

/// A request of a plan and its description (without framing).
struct Planned {
    request: Request,
    description: String,
}

/// The frames that read `name` (a register, a repeat member or copy `copy` of it, or a
/// group) from `slave`, as [`encode_read`] gives them; refused when nothing is readable or
/// `slave` is the broadcast address, which no reply comes from.
pub fn encode_read_of(
    device: &'static DeviceInfo,
    name: &str,
    copy: Option<u8>,
    slave: u8,
    framing: Framing,
) -> Result<Vec<EncodedFrame>, Error> {
    if slave == optobus_codec::BROADCAST {
        return Err(
            Error::new("a read sent to slave 0, the broadcast address, gets no reply")
                .hint("give the device's address, 1 to 247"),
        );
    }
    let registers = resolve_readable(device, &[name], copy)?;
    encode_read(device, &registers, slave, framing).map_err(not_encoded)
}

/// The frames that write `value` (as people type it, see [`parse_value`]) to the one register
/// `name` (copy `copy` of a repeat member), validated as the drivers validate it.
pub fn encode_write_of(
    device: &'static DeviceInfo,
    name: &str,
    copy: Option<u8>,
    value: &str,
    slave: u8,
    framing: Framing,
) -> Result<Vec<EncodedFrame>, Error> {
    let register = resolve_one(device, name, copy)?;
    let words = parse_value(register, value)?;
    let frames = encode_write(device, register, &words, slave, framing).map_err(not_encoded)?;
    if frames.is_empty() {
        return Err(Error::new(format!(
            "`{value}` gives no words to write to `{}`",
            register.name
        )));
    }
    Ok(frames)
}

fn not_encoded(error: EncodeError) -> Error {
    Error::new(format!("cannot encode the request: {error}"))
}

/// The frames that read `registers` (readable ones; write-only and action registers are left
/// out) in the
/// fewest requests, as the driver plans them ([`optobus_driver::plan_reads`]). TCP frames
/// take transaction ids 1, 2, … and `slave` as unit id.
pub fn encode_read(
    device: &DeviceInfo,
    registers: &[&'static RegisterInfo],
    slave: u8,
    framing: Framing,
) -> Result<Vec<EncodedFrame>, EncodeError> {
    let readable: Vec<&RegisterInfo> = registers.iter().copied().filter(|r| r.readable()).collect();
    let planned: Vec<Planned> = plan_reads(device, &readable)
        .into_iter()
        .map(|span| Planned {
            request: Request::Read {
                function: span.table.read_function(),
                address: span.address,
                count: span.count,
            },
            description: format!(
                "read {}",
                span_text(device, span.table, span.address, usize::from(span.count))
            ),
        })
        .collect();
    frame(&planned, slave, framing)
}

/// The FC06 frames that store `words` (the register's words in address order, already
/// validated) in `register`, in send order, as the driver writes them
/// ([`optobus_driver::plan_write`]).
pub fn encode_write(
    device: &DeviceInfo,
    register: &'static RegisterInfo,
    words: &[u16],
    slave: u8,
    framing: Framing,
) -> Result<Vec<EncodedFrame>, EncodeError> {
    let value = decode_value(register, words);
    let steps = plan_write(device, register, words);
    let planned: Vec<Planned> = steps
        .iter()
        .enumerate()
        .map(|(i, step)| Planned {
            request: Request::Write {
                address: step.address,
                value: step.value,
            },
            description: write_text(register, step, i, words.len(), &value),
        })
        .collect();
    frame(&planned, slave, framing)
}

/// What one FC06 of a write plan does.
fn write_text(
    register: &RegisterInfo,
    step: &WriteStep,
    i: usize,
    words: usize,
    value: &Value,
) -> String {
    let table = register.table.as_str();
    let (name, address) = (register.name, step.address);
    let wire = match step.value {
        WriteValue::Word(word) => format!("0x{word:04X}"),
        WriteValue::DoubleWord(long) => format!("0x{long:08X}"),
    };
    match step.part {
        WritePart::Whole => format!("write {table} {address} = {wire}: {name} = {value}"),
        WritePart::Wide => format!(
            "write {table} {address} = {wire} (one FC06 with 4 data bytes): {name} = {value}"
        ),
        WritePart::High | WritePart::Low => {
            let half = if step.part == WritePart::High {
                "high"
            } else {
                "low"
            };
            format!(
                "write {table} {address} = {wire}: {half} word of {name} = {value} \
                 (frame {} of 2, {half} word {})",
                i + 1,
                if i == 0 { "first" } else { "last" }
            )
        }
        WritePart::Word(n) => format!(
            "write {table} {address} = {wire}: word {} of {words} of {name} = {value}",
            n + 1
        ),
    }
}

/// Bytes of each planned request in `framing`, with its description.
fn frame(
    planned: &[Planned],
    slave: u8,
    framing: Framing,
) -> Result<Vec<EncodedFrame>, EncodeError> {
    let mut frames = Vec::with_capacity(planned.len());
    for (i, plan) in planned.iter().enumerate() {
        let mut buf = [0u8; tcp::MAX_FRAME_LEN];
        let (len, description) = match framing {
            Framing::Rtu => (
                rtu::encode_request(&mut buf, slave, &plan.request)?,
                plan.description.clone(),
            ),
            Framing::Tcp => {
                let transaction = u16::try_from(i + 1).unwrap_or(u16::MAX);
                let header = tcp::Header {
                    transaction,
                    unit: slave,
                };
                (
                    tcp::encode_request(&mut buf, header, &plan.request)?,
                    format!(
                        "{}; transaction {transaction}, unit {slave}",
                        plan.description
                    ),
                )
            }
        };
        frames.push(EncodedFrame {
            bytes: buf.get(..len).unwrap_or_default().to_vec(),
            description,
            request: plan.request,
        });
    }
    Ok(frames)
}
