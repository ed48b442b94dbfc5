//! A lenient decode of captured bytes: the frames in them, RTU or Modbus TCP, however broken.

use optobus_codec::crc::{crc16, is_valid_frame};
use optobus_codec::tcp::{Mbap, HEADER_LEN};
use optobus_codec::{
    exception_function, rtu, ExceptionShape, FrameShape, ReadFunction, Request,
    READ_REQUEST_PDU_LEN, WRITE_SINGLE,
};
use optobus_device::DeviceInfo;

use crate::error::Error;
use crate::explain::{explain_pdu, function_list, Context, ExplainAs, Sent};
use crate::frame::{CrcCheck, ExplainedFrame, Field, FrameKind, Framing};
use crate::hex::hex;

/// Every frame in `bytes`, explained field by field: request, reply or exception, CRC
/// checked, registers named and values decoded, with notes on anything a device would
/// refuse. A reply right after its request is paired with it (so its registers are named);
/// a lone read reply is placed at `address` if given, else at the first address where its
/// words are whole registers (with a note). Frames after the first that cannot be decoded are
/// kept as one [`FrameKind::Undecoded`] entry saying why; if the first cannot be, that is the
/// error. Never panics.
pub fn decode(
    device: &DeviceInfo,
    bytes: &[u8],
    framing: Framing,
    address: Option<u16>,
) -> Result<Vec<ExplainedFrame>, Error> {
    let mut context = Context {
        previous: None,
        address,
    };
    let mut frames: Vec<ExplainedFrame> = Vec::new();
    let mut at = 0usize;
    while let Some(rest) = bytes.get(at..).filter(|rest| !rest.is_empty()) {
        let decoded = match framing {
            Framing::Rtu => rtu_frame(device, rest, &context),
            Framing::Tcp => tcp_frame(device, rest, &context),
        };
        match decoded {
            Ok((explained, sent)) => {
                at += explained.bytes.len().max(1);
                context.previous = sent;
                frames.push(explained);
            }
            Err(error) if frames.is_empty() => return Err(error),
            Err(error) => {
                frames.push(ExplainedFrame {
                    bytes: rest.to_vec(),
                    kind: FrameKind::Undecoded,
                    summary: format!("left over: {error}"),
                    fields: Vec::new(),
                    crc: None,
                    registers: Vec::new(),
                    notes: Vec::new(),
                });
                break;
            }
        }
    }
    Ok(frames)
}

/// A way to read the bytes at the start of an RTU frame, and its length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Candidate {
    kind: ExplainAs,
    len: usize,
}

impl Candidate {
    /// `a read request (8 bytes)`, for "too short" messages.
    fn describe(self, rest: &[u8]) -> String {
        let len = self.len;
        match self.kind {
            ExplainAs::ReadRequest => format!("a read request ({len} bytes)"),
            ExplainAs::ReadReply => format!(
                "a read reply with byte count {} ({len} bytes)",
                rest.get(2).copied().unwrap_or(0)
            ),
            ExplainAs::Write if len == 10 => format!("a 4-byte write or its echo ({len} bytes)"),
            ExplainAs::Write => format!("a write or its echo ({len} bytes)"),
            ExplainAs::Exception(_) => format!("an exception reply ({len} bytes)"),
            ExplainAs::Other => format!("a frame ({len} bytes)"),
        }
    }
}

/// The other exception shape than `shape`.
fn other_shape(shape: ExceptionShape) -> ExceptionShape {
    match shape {
        ExceptionShape::Standard => ExceptionShape::CountedWord,
        ExceptionShape::CountedWord => ExceptionShape::Standard,
    }
}

/// The ways to read an RTU frame starting at `rest`, most likely first; lengths from the
/// codec, for the device's frame shape and for the other shapes a capture may hold.
fn rtu_candidates(device: &DeviceInfo, rest: &[u8], context: &Context) -> Vec<Candidate> {
    let function = rest.get(1).copied().unwrap_or(0);
    let shape = device.frame_shape;
    let candidate = |kind, len: Option<usize>| len.map(|len| Candidate { kind, len });
    let wide: &[u16] = &[u16::from_be_bytes([
        rest.get(2).copied().unwrap_or(0),
        rest.get(3).copied().unwrap_or(0),
    ])];
    let shapes = |exception| FrameShape {
        exception,
        ..FrameShape::STANDARD
    };
    let found: Vec<Option<Candidate>> = if let Some(read) = ReadFunction::from_code(function) {
        let request = candidate(ExplainAs::ReadRequest, rtu::request_len(rest, &shape));
        let reply = candidate(ExplainAs::ReadReply, rtu::response_len(rest, &shape));
        let answers_previous = matches!(
            context.previous,
            Some(Sent { request: Request::Read { function: f, .. }, .. }) if f == read
        );
        if answers_previous {
            vec![reply, request]
        } else {
            vec![request, reply]
        }
    } else if exception_function(function).is_some() {
        [shape.exception, other_shape(shape.exception)]
            .into_iter()
            .map(|exception| {
                candidate(
                    ExplainAs::Exception(exception),
                    rtu::response_len(rest, &shapes(exception)),
                )
            })
            .collect()
    } else if function == WRITE_SINGLE {
        // Two or four data bytes: the device's width for the address first.
        let two = rtu::request_len(rest, &FrameShape::STANDARD);
        let four = rtu::request_len(
            rest,
            &FrameShape {
                four_byte_writes: wide,
                ..FrameShape::STANDARD
            },
        );
        let lens = if rtu::request_len(rest, &shape) == four {
            [four, two]
        } else {
            [two, four]
        };
        lens.into_iter()
            .map(|len| candidate(ExplainAs::Write, len))
            .collect()
    } else {
        Vec::new()
    };
    let found: Vec<Candidate> = found.into_iter().flatten().collect();
    if found.is_empty() {
        return vec![Candidate {
            kind: ExplainAs::Other,
            len: rest.len(),
        }];
    }
    found
}

/// True when `bytes` start like a Modbus TCP frame (protocol id 0, a length that fits).
fn looks_like_mbap(bytes: &[u8]) -> bool {
    Mbap::parse(bytes).is_some_and(|mbap| {
        mbap.protocol == 0 && mbap.length >= 2 && mbap.frame_len() <= bytes.len()
    })
}

/// `error`, with a hint when the bytes look like the other framing.
fn hinted(error: Error, other_framing: bool, hint: &str) -> Error {
    if other_framing {
        error.hint(hint)
    } else {
        error
    }
}

/// The RTU frame at the start of `rest`, and the request it is (for pairing its reply).
fn rtu_frame(
    device: &DeviceInfo,
    rest: &[u8],
    context: &Context,
) -> Result<(ExplainedFrame, Option<Sent>), Error> {
    let tcp_hint = |error: Error| {
        hinted(
            error,
            looks_like_mbap(rest),
            "these bytes look like Modbus TCP: add --mbap",
        )
    };
    if rest.len() < 4 {
        let count = rest.len();
        return Err(tcp_hint(Error::new(format!(
            "{count} byte{} too short for a Modbus RTU frame (slave, function, data and a \
             2-byte CRC: at least 4 bytes)",
            if count == 1 { " is" } else { "s are" }
        ))));
    }
    let candidates = rtu_candidates(device, rest, context);
    let fitting: Vec<Candidate> = candidates
        .iter()
        .copied()
        .filter(|c| c.len <= rest.len())
        .collect();
    // A good CRC decides; else the reading that uses every byte; else the likeliest one,
    // which must fit (rather than a shorter reading that happens to).
    let chosen = fitting
        .iter()
        .find(|c| rest.get(..c.len).is_some_and(is_valid_frame))
        .or_else(|| fitting.iter().find(|c| c.len == rest.len()))
        .or_else(|| candidates.first().filter(|c| c.len <= rest.len()))
        .copied();
    let Some(chosen) = chosen else {
        let options: Vec<String> = candidates
            .iter()
            .filter(|c| c.len > rest.len())
            // Other widths of a write or an exception are fallbacks, not worth naming.
            .filter(|c| {
                matches!(c.kind, ExplainAs::ReadRequest | ExplainAs::ReadReply)
                    || Some(*c) == candidates.first()
            })
            .map(|c| c.describe(rest))
            .collect();
        return Err(tcp_hint(Error::new(format!(
            "{} bytes are too short for {}",
            rest.len(),
            options.join(" or ")
        ))));
    };
    let frame = rest.get(..chosen.len).unwrap_or(rest);
    let (Some((&slave, _)), Some((body, crc))) =
        (frame.split_first(), frame.split_last_chunk::<2>())
    else {
        return Err(Error::new("too short for a Modbus RTU frame"));
    };
    let check = CrcCheck {
        received: u16::from_le_bytes(*crc),
        computed: crc16(body),
    };
    if chosen.kind == ExplainAs::Other && !check.ok() {
        let function = body.get(1).copied().unwrap_or(0);
        return Err(tcp_hint(
            Error::new(format!(
                "not a Modbus RTU frame of {}: function {function:02X} is not one it answers \
                 ({}) and the last two bytes are no CRC of the others",
                device.family,
                function_list(device)
            ))
            .hint("the first byte must be the slave address, the second the function code"),
        ));
    }
    let pdu_bytes = body.get(1..).unwrap_or_default();
    let pdu = explain_pdu(device, chosen.kind, pdu_bytes, context);
    let mut fields = vec![Field::new(&[slave], slave_text(slave))];
    fields.extend(pdu.fields);
    let crc_bytes = check.received.to_le_bytes();
    let right = check.computed.to_le_bytes();
    let mut notes = pdu.notes;
    if check.ok() {
        fields.push(Field::new(
            &crc_bytes,
            format!("CRC 0x{:04X} (low byte first): correct", check.computed),
        ));
    } else {
        fields.push(Field::new(
            &crc_bytes,
            format!("CRC wrong: these bytes give {}", hex(&right)),
        ));
        notes.insert(
            0,
            format!(
                "wrong CRC: the frame carries {}, the right CRC is {} (0x{:04X}, low byte \
                 first); a device ignores a frame with a wrong CRC",
                hex(&crc_bytes),
                hex(&right),
                check.computed
            ),
        );
    }
    if let (Some(previous), None) = (context.previous, pdu.request) {
        if previous.slave != slave && previous.slave != 0 {
            notes.push(format!(
                "the request above went to slave {}, this reply is from slave {slave}",
                previous.slave
            ));
        }
    }
    let sent = pdu.request.map(|request| Sent {
        slave,
        transaction: None,
        request,
    });
    Ok((
        ExplainedFrame {
            bytes: frame.to_vec(),
            kind: pdu.kind,
            summary: pdu.summary,
            fields,
            crc: Some(check),
            registers: pdu.registers,
            notes,
        },
        sent,
    ))
}

/// The Modbus TCP frame at the start of `rest`, and the request it is.
fn tcp_frame(
    device: &DeviceInfo,
    rest: &[u8],
    context: &Context,
) -> Result<(ExplainedFrame, Option<Sent>), Error> {
    let rtu_hint = |error: Error| {
        hinted(
            error,
            is_valid_frame(rest),
            "these bytes look like Modbus RTU: leave out --mbap",
        )
    };
    let Some(mbap) = Mbap::parse(rest) else {
        return Err(rtu_hint(Error::new(format!(
            "{} bytes are too short for a Modbus TCP frame (a 7-byte MBAP header and a PDU)",
            rest.len()
        ))));
    };
    let Mbap {
        transaction,
        protocol,
        length,
        unit,
    } = mbap;
    if protocol != 0 {
        return Err(rtu_hint(Error::new(format!(
            "not a Modbus TCP frame: the protocol id is 0x{protocol:04X}, Modbus requires 0"
        ))));
    }
    if length < 2 {
        return Err(Error::new(format!(
            "MBAP length {length} is too short for a unit id and a function code (at least 2)"
        )));
    }
    let total = mbap.frame_len();
    let (Some(frame), Some(pdu_bytes)) = (rest.get(..total), rest.get(HEADER_LEN..total)) else {
        return Err(rtu_hint(Error::new(format!(
            "{} bytes are too short for the {total} bytes the MBAP header announces \
             (length {length}: unit id and {} PDU bytes)",
            rest.len(),
            length - 1
        ))));
    };
    let function = pdu_bytes.first().copied().unwrap_or(0);
    // The MBAP length delimits the PDU: its length tells the shapes apart.
    let counted = ExceptionShape::CountedWord.pdu_len();
    let read = ReadFunction::from_code(function).is_some();
    let kind = match function {
        _ if read && pdu_bytes.len() == READ_REQUEST_PDU_LEN => ExplainAs::ReadRequest,
        _ if read => ExplainAs::ReadReply,
        WRITE_SINGLE => ExplainAs::Write,
        _ if exception_function(function).is_some() && pdu_bytes.len() == counted => {
            ExplainAs::Exception(ExceptionShape::CountedWord)
        }
        _ if exception_function(function).is_some() => {
            ExplainAs::Exception(ExceptionShape::Standard)
        }
        _ => ExplainAs::Other,
    };
    let pdu = explain_pdu(device, kind, pdu_bytes, context);
    let header = frame.get(..HEADER_LEN).unwrap_or_default();
    let bytes = |range: std::ops::Range<usize>| header.get(range).unwrap_or_default();
    let mut fields = vec![
        Field::new(bytes(0..2), format!("transaction {transaction}")),
        Field::new(bytes(2..4), "protocol id 0 (Modbus)"),
        Field::new(
            bytes(4..6),
            format!("length {length} (unit id and {} PDU bytes)", length - 1),
        ),
        Field::new(bytes(6..7), format!("unit {unit}")),
    ];
    fields.extend(pdu.fields);
    let mut notes = pdu.notes;
    if let (Some(previous), None) = (context.previous, pdu.request) {
        if previous.transaction.is_some_and(|t| t != transaction) {
            notes.push(format!(
                "the request above has transaction {}, this reply {transaction}",
                previous.transaction.unwrap_or(0)
            ));
        }
    }
    let sent = pdu.request.map(|request| Sent {
        slave: unit,
        transaction: Some(transaction),
        request,
    });
    Ok((
        ExplainedFrame {
            bytes: frame.to_vec(),
            kind: pdu.kind,
            summary: format!("{}; transaction {transaction}, unit {unit}", pdu.summary),
            fields,
            crc: None,
            registers: pdu.registers,
            notes,
        },
        sent,
    ))
}

/// `slave 1`, `slave 0 (broadcast)`.
fn slave_text(slave: u8) -> String {
    if slave == 0 {
        "slave 0 (broadcast)".to_owned()
    } else {
        format!("slave {slave}")
    }
}
