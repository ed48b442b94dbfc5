//! The server side of Modbus: what a device, a simulator or a gateway answering requests
//! needs. A request PDU is parsed into a typed [`ServerRequest`] (FC03/FC04 reads, FC06, FC16),
//! or refused with the exception code a server answers it with: 01 for a function it does not
//! serve, 03 for a request whose length, byte count or quantity does not fit its function (a
//! short PDU, a byte count that disagrees with the count, a read of 0 or 126 registers, a
//! write of 124), before anything reaches a register. Reply and exception PDUs are encoded
//! here too; [`crate::tcp`] and [`crate::rtu`] frame them.
//!
//! ```
//! use optobus_codec::server::{self, ServerRequest};
//! use optobus_codec::{ExceptionCode, FrameShape, ReadFunction};
//! let request = server::parse_request(&[0x04, 0x00, 0x10, 0x00, 0x02], &FrameShape::STANDARD);
//! assert_eq!(
//!     request,
//!     Ok(ServerRequest::Read { function: ReadFunction::Input, address: 0x10, count: 2 })
//! );
//! let refused = server::parse_request(&[0x04, 0x00, 0x10, 0x00, 0x00], &FrameShape::STANDARD);
//! assert_eq!(refused.unwrap_err().exception(), ExceptionCode::ILLEGAL_DATA_VALUE);
//! let mut reply = [0; 256];
//! let len = server::encode_read_reply(&mut reply, ReadFunction::Input, [425, 1]).unwrap();
//! assert_eq!(&reply[..len], &[0x04, 4, 0x01, 0xA9, 0x00, 0x01]);
//! ```

use core::fmt;

use crate::pdu::{
    EncodeError, ExceptionCode, ExceptionShape, FrameShape, OutgoingPdu, PayloadWidth,
    ReadFunction, Request, Response, Words, WriteValue, EXCEPTION_BIT, MAX_READ_WORDS,
    READ_REQUEST_PDU_LEN, WRITE_SINGLE,
};

/// Function code of "write multiple registers".
pub const WRITE_MULTIPLE: u8 = 0x10;

/// The most registers one FC16 request writes.
pub const MAX_WRITE_WORDS: u16 = 123;

/// A request as a server reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ServerRequest<'a> {
    /// FC03 or FC04: read `count` (1 to 125) registers from `address`.
    Read {
        /// Which table.
        function: ReadFunction,
        /// The first register.
        address: u16,
        /// How many.
        count: u16,
    },
    /// FC06: write one register (two data bytes, or four where the device's
    /// [`FrameShape`] says so).
    WriteSingle {
        /// The register.
        address: u16,
        /// The value.
        value: WriteValue,
    },
    /// FC16: write 1 to 123 registers from `address`.
    WriteMultiple {
        /// The first register.
        address: u16,
        /// The words written, in order.
        words: Words<'a>,
    },
}

impl ServerRequest<'_> {
    /// The function code on the wire.
    pub const fn function_code(&self) -> u8 {
        match self {
            Self::Read { function, .. } => function.code(),
            Self::WriteSingle { .. } => WRITE_SINGLE,
            Self::WriteMultiple { .. } => WRITE_MULTIPLE,
        }
    }

    /// Length of the request's PDU.
    pub const fn pdu_len(&self) -> usize {
        match self {
            Self::Read { .. } => READ_REQUEST_PDU_LEN,
            Self::WriteSingle { value, .. } => value.width().write_pdu_len(),
            Self::WriteMultiple { words, .. } => 6 + words.as_bytes().len(),
        }
    }

    /// Writes the request's PDU (as a client sends it) into `out`; gives its length. A read
    /// of 0 or more than 125 registers, or a write of 0 or more than 123, is refused.
    pub fn encode(&self, out: &mut [u8]) -> Result<usize, EncodeError> {
        match *self {
            Self::Read { count, .. } if !(1..=MAX_READ_WORDS).contains(&count) => {
                return Err(EncodeError::InvalidCount { count })
            }
            Self::WriteMultiple { words, .. }
                if !(1..=usize::from(MAX_WRITE_WORDS)).contains(&words.len()) =>
            {
                return Err(EncodeError::MalformedRequest {
                    function: WRITE_MULTIPLE,
                    len: self.pdu_len(),
                    why: "a write of registers takes 1 to 123",
                })
            }
            _ => {}
        }
        let len = self.pdu_len();
        let Some(out) = out.get_mut(..len) else {
            return Err(EncodeError::BufferTooSmall { needed: len });
        };
        out[0] = self.function_code();
        match *self {
            Self::Read { address, count, .. } => {
                out[1..3].copy_from_slice(&address.to_be_bytes());
                out[3..5].copy_from_slice(&count.to_be_bytes());
            }
            Self::WriteSingle { address, value } => {
                out[1..3].copy_from_slice(&address.to_be_bytes());
                value.write_to(&mut out[3..]);
            }
            Self::WriteMultiple { address, words } => {
                let data = words.as_bytes();
                out[1..3].copy_from_slice(&address.to_be_bytes());
                // At most 123 words, checked above.
                out[3..5].copy_from_slice(&(words.len() as u16).to_be_bytes());
                out[5] = data.len() as u8;
                out[6..].copy_from_slice(data);
            }
        }
        Ok(len)
    }
}

/// Why a server does not serve a request PDU, and the exception it answers with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RequestError {
    /// A function this server does not serve (or an exception function code): exception 01.
    Unsupported {
        /// The function code.
        function: u8,
    },
    /// The PDU's length, byte count or quantity does not fit its function: exception 03.
    Malformed {
        /// The function code (0 for an empty PDU).
        function: u8,
        /// What the function asks for.
        why: &'static str,
    },
}

impl RequestError {
    /// The exception code a server answers with.
    pub const fn exception(&self) -> ExceptionCode {
        match self {
            Self::Unsupported { .. } => ExceptionCode::ILLEGAL_FUNCTION,
            Self::Malformed { .. } => ExceptionCode::ILLEGAL_DATA_VALUE,
        }
    }

    /// The function code of the request, for the exception reply.
    pub const fn function(&self) -> u8 {
        match self {
            Self::Unsupported { function } | Self::Malformed { function, .. } => *function,
        }
    }
}

impl fmt::Display for RequestError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::Unsupported { function } => write!(f, "function {function:#04X} is not served"),
            Self::Malformed { function, why } => {
                write!(
                    f,
                    "a request of function {function:#04X} is malformed: {why}"
                )
            }
        }
    }
}

impl core::error::Error for RequestError {}

/// Parses a request PDU (function code and data, as an MBAP header or an RTU frame carries
/// it) as a server: FC03/FC04, FC06 (its width at its address from `shape`) and FC16;
/// another function is [`RequestError::Unsupported`], a PDU whose length or counts do not fit
/// its function [`RequestError::Malformed`]. Never panics, whatever the bytes.
pub fn parse_request<'a>(
    pdu: &'a [u8],
    shape: &FrameShape<'_>,
) -> Result<ServerRequest<'a>, RequestError> {
    let Some(&function) = pdu.first() else {
        return Err(RequestError::Malformed {
            function: 0,
            why: "a request holds at least its function code",
        });
    };
    let malformed = |why| Err(RequestError::Malformed { function, why });
    let word = |at: usize| match pdu.get(at..at + 2) {
        Some(&[high, low]) => Some(u16::from_be_bytes([high, low])),
        _ => None,
    };
    match function {
        0x03 | 0x04 => {
            let (Some(address), Some(count), READ_REQUEST_PDU_LEN) = (word(1), word(3), pdu.len())
            else {
                return malformed("a read of registers is an address and a count (5 bytes)");
            };
            if !(1..=MAX_READ_WORDS).contains(&count) {
                return malformed("a read of registers takes 1 to 125");
            }
            let function = ReadFunction::from_code(function).unwrap_or(ReadFunction::Holding);
            Ok(ServerRequest::Read {
                function,
                address,
                count,
            })
        }
        WRITE_SINGLE => {
            let Some(address) = word(1) else {
                return malformed("a register write is an address and its data bytes");
            };
            let width = shape.write_width(address);
            if pdu.len() != width.write_pdu_len() {
                return malformed(match width {
                    PayloadWidth::Two => "a register write here is an address and 2 data bytes",
                    PayloadWidth::Four => "a register write here is an address and 4 data bytes",
                });
            }
            Ok(ServerRequest::WriteSingle {
                address,
                value: WriteValue::read_from(width, &pdu[3..]),
            })
        }
        WRITE_MULTIPLE => {
            let why = "a write of registers is an address, a count of 1 to 123, a byte count \
                       of 2 per register and those bytes";
            let (Some(address), Some(count), Some(&bytes)) = (word(1), word(3), pdu.get(5)) else {
                return malformed(why);
            };
            let data = &pdu[6..];
            if !(1..=MAX_WRITE_WORDS).contains(&count)
                || usize::from(bytes) != 2 * usize::from(count)
                || data.len() != usize::from(bytes)
            {
                return malformed(why);
            }
            Ok(ServerRequest::WriteMultiple {
                address,
                words: Words::from_even(data),
            })
        }
        _ => Err(RequestError::Unsupported { function }),
    }
}

/// Writes the PDU of a successful reply into `out`; gives its length.
pub fn encode_reply(out: &mut [u8], response: &Response<'_>) -> Result<usize, EncodeError> {
    encode_pdu(out, response)
}

/// Writes the PDU of a read's reply of `words` (at most 125) into `out`; gives its length.
pub fn encode_read_reply(
    out: &mut [u8],
    function: ReadFunction,
    words: impl IntoIterator<Item = u16>,
) -> Result<usize, EncodeError> {
    let mut count = 0usize;
    for word in words {
        let at = 2 + 2 * count;
        count += 1;
        if count > usize::from(MAX_READ_WORDS) {
            return Err(EncodeError::TooManyWords { words: count });
        }
        let Some(slot) = out.get_mut(at..at + 2) else {
            return Err(EncodeError::BufferTooSmall { needed: at + 2 });
        };
        slot.copy_from_slice(&word.to_be_bytes());
    }
    let Some(head) = out.get_mut(..2) else {
        return Err(EncodeError::BufferTooSmall { needed: 2 });
    };
    // At most 125 words: 250 bytes.
    head.copy_from_slice(&[function.code(), (2 * count) as u8]);
    Ok(2 + 2 * count)
}

/// Writes the PDU of an exception reply to a request of `function` into `out`, in `shape`;
/// gives its length.
pub fn encode_exception(
    out: &mut [u8],
    function: u8,
    code: ExceptionCode,
    shape: ExceptionShape,
) -> Result<usize, EncodeError> {
    encode_pdu(out, &ExceptionPdu::new(function, code, shape))
}

/// The standard two-byte exception PDU to a request of `function`.
pub const fn exception_pdu(function: u8, code: u8) -> [u8; 2] {
    [function | EXCEPTION_BIT, code]
}

fn encode_pdu(out: &mut [u8], pdu: &impl OutgoingPdu) -> Result<usize, EncodeError> {
    pdu.check()?;
    let len = pdu.pdu_len();
    let Some(out) = out.get_mut(..len) else {
        return Err(EncodeError::BufferTooSmall { needed: len });
    };
    pdu.write_pdu(out);
    Ok(len)
}

/// Request PDUs as a device decoding its own frames parses them (FC03/04/06, their length
/// known right).
impl Request {
    /// Parses a request PDU whose length is already known to be right for its function.
    pub(crate) fn parse_pdu(pdu: &[u8], width: PayloadWidth) -> Self {
        match ReadFunction::from_code(pdu[0]) {
            Some(function) => Self::Read {
                function,
                address: u16::from_be_bytes([pdu[1], pdu[2]]),
                count: u16::from_be_bytes([pdu[3], pdu[4]]),
            },
            None => {
                let (address, value) = Self::parse_write(pdu, width);
                Self::Write { address, value }
            }
        }
    }

    /// Parses the address and value of an FC06 PDU of the right length.
    pub(crate) fn parse_write(pdu: &[u8], width: PayloadWidth) -> (u16, WriteValue) {
        (
            u16::from_be_bytes([pdu[1], pdu[2]]),
            WriteValue::read_from(width, &pdu[3..]),
        )
    }
}

impl OutgoingPdu for Response<'_> {
    fn check(&self) -> Result<(), EncodeError> {
        match self {
            Self::Read { words, .. } if words.len() > usize::from(MAX_READ_WORDS) => {
                Err(EncodeError::TooManyWords { words: words.len() })
            }
            _ => Ok(()),
        }
    }

    fn write_pdu(&self, out: &mut [u8]) {
        out[0] = self.function_code();
        match *self {
            Self::Read { words, .. } => {
                let data = words.as_bytes();
                // `check` bounds the data to 250 bytes.
                out[1] = data.len() as u8;
                out[2..2 + data.len()].copy_from_slice(data);
            }
            Self::Write { address, value } => {
                out[1..3].copy_from_slice(&address.to_be_bytes());
                value.write_to(&mut out[3..]);
            }
        }
    }

    fn pdu_len(&self) -> usize {
        Response::pdu_len(self)
    }
}

/// An exception reply's PDU: the request's function code with the exception bit, and the
/// device's code in the device's shape.
pub(crate) struct ExceptionPdu {
    pub(crate) function: u8,
    pub(crate) code: ExceptionCode,
    pub(crate) shape: ExceptionShape,
}

impl ExceptionPdu {
    pub(crate) const fn new(function: u8, code: ExceptionCode, shape: ExceptionShape) -> Self {
        Self {
            function,
            code,
            shape,
        }
    }
}

impl OutgoingPdu for ExceptionPdu {
    fn check(&self) -> Result<(), EncodeError> {
        match self.shape {
            ExceptionShape::Standard if self.code.0 > 0xFF => {
                Err(EncodeError::CodeTooWide { code: self.code })
            }
            _ => Ok(()),
        }
    }

    fn pdu_len(&self) -> usize {
        self.shape.pdu_len()
    }

    fn write_pdu(&self, out: &mut [u8]) {
        let fc = self.function | EXCEPTION_BIT;
        let [high, low] = self.code.0.to_be_bytes();
        match self.shape {
            // `check` bounds the code to one byte.
            ExceptionShape::Standard => out[..2].copy_from_slice(&[fc, low]),
            ExceptionShape::CountedWord => out[..4].copy_from_slice(&[fc, 2, high, low]),
        }
    }
}
