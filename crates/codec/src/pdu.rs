//! Protocol data units shared by RTU and TCP framing, and the frame-shape description that
//! carries each device's framing quirks as data.

use core::fmt;

/// The largest number of registers one FC03/FC04 request may ask for (Modbus limit).
pub const MAX_READ_WORDS: u16 = 125;

/// Length of an FC03/FC04 request PDU: function code, address and count.
pub const READ_REQUEST_PDU_LEN: usize = 5;

/// Function code of "write single register".
pub const WRITE_SINGLE: u8 = 0x06;

/// The bit a device sets in the function code of an exception reply.
pub const EXCEPTION_BIT: u8 = 0x80;

/// The standard name of a Modbus function code (`read holding registers`), if it has one.
pub const fn function_name(code: u8) -> Option<&'static str> {
    Some(match code {
        0x01 => "read coils",
        0x02 => "read discrete inputs",
        0x03 => "read holding registers",
        0x04 => "read input registers",
        0x05 => "write single coil",
        0x06 => "write single register",
        0x07 => "read exception status",
        0x08 => "diagnostics",
        0x0F => "write multiple coils",
        0x10 => "write multiple registers",
        0x11 => "report server id",
        0x16 => "mask write register",
        0x17 => "read/write multiple registers",
        0x2B => "encapsulated interface transport",
        _ => return None,
    })
}

/// For the function code of an exception reply (one with [`EXCEPTION_BIT`] set), the function
/// that failed; `None` for other codes.
pub const fn exception_function(code: u8) -> Option<u8> {
    if code & EXCEPTION_BIT != 0 {
        Some(code & !EXCEPTION_BIT)
    } else {
        None
    }
}

/// Which register table a read addresses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ReadFunction {
    /// FC03, read holding registers.
    Holding,
    /// FC04, read input registers.
    Input,
}

impl ReadFunction {
    /// The function code on the wire.
    pub const fn code(self) -> u8 {
        match self {
            Self::Holding => 0x03,
            Self::Input => 0x04,
        }
    }

    /// The read function with this code, if it is one.
    pub const fn from_code(code: u8) -> Option<Self> {
        match code {
            0x03 => Some(Self::Holding),
            0x04 => Some(Self::Input),
            _ => None,
        }
    }
}

/// How many data bytes an FC06 frame carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PayloadWidth {
    /// The standard 16-bit register value.
    Two,
    /// A 32-bit value in one FC06 (the rangefinder's 10-byte frame).
    Four,
}

impl PayloadWidth {
    /// The number of data bytes.
    pub const fn bytes(self) -> usize {
        match self {
            Self::Two => 2,
            Self::Four => 4,
        }
    }

    /// The length of an FC06 PDU (request or echo) with this many data bytes: function code,
    /// address, data.
    pub const fn write_pdu_len(self) -> usize {
        3 + self.bytes()
    }
}

/// The value an FC06 request writes (and its reply echoes).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum WriteValue {
    /// A 16-bit value: two data bytes, high byte first.
    Word(u16),
    /// A 32-bit value: four data bytes, most significant first.
    DoubleWord(u32),
}

impl WriteValue {
    /// The payload width this value needs.
    pub const fn width(self) -> PayloadWidth {
        match self {
            Self::Word(_) => PayloadWidth::Two,
            Self::DoubleWord(_) => PayloadWidth::Four,
        }
    }

    /// The value widened to 32 bits.
    pub const fn as_u32(self) -> u32 {
        match self {
            Self::Word(value) => value as u32,
            Self::DoubleWord(value) => value,
        }
    }

    pub(crate) fn write_to(self, out: &mut [u8]) {
        match self {
            Self::Word(value) => out[..2].copy_from_slice(&value.to_be_bytes()),
            Self::DoubleWord(value) => out[..4].copy_from_slice(&value.to_be_bytes()),
        }
    }

    pub(crate) fn read_from(width: PayloadWidth, data: &[u8]) -> Self {
        match width {
            PayloadWidth::Two => Self::Word(u16::from_be_bytes([data[0], data[1]])),
            PayloadWidth::Four => {
                Self::DoubleWord(u32::from_be_bytes([data[0], data[1], data[2], data[3]]))
            }
        }
    }
}

/// A request a client sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Request {
    /// FC03 or FC04: read `count` 16-bit words starting at `address`.
    Read {
        /// Which table.
        function: ReadFunction,
        /// First register address.
        address: u16,
        /// Number of 16-bit words.
        count: u16,
    },
    /// FC06: write one register.
    Write {
        /// Register address.
        address: u16,
        /// The value, two or four bytes.
        value: WriteValue,
    },
}

impl Request {
    /// The function code on the wire.
    pub const fn function_code(&self) -> u8 {
        match self {
            Self::Read { function, .. } => function.code(),
            Self::Write { .. } => WRITE_SINGLE,
        }
    }

    /// Length of the PDU (function code and data) in bytes.
    pub const fn pdu_len(&self) -> usize {
        match self {
            Self::Read { .. } => READ_REQUEST_PDU_LEN,
            Self::Write { value, .. } => value.width().write_pdu_len(),
        }
    }

    /// Length of the PDU of a successful reply to this request.
    pub const fn reply_pdu_len(&self) -> usize {
        match self {
            Self::Read { count, .. } => 2 + 2 * *count as usize,
            Self::Write { .. } => self.pdu_len(),
        }
    }
}

/// A PDU that an encoder frames: checked before the output buffer is touched (an error leaves
/// it as it was), then written in place.
pub(crate) trait OutgoingPdu {
    /// Refuses what cannot be put on the wire.
    fn check(&self) -> Result<(), EncodeError>;
    /// Length of the PDU (function code and data) in bytes.
    fn pdu_len(&self) -> usize;
    /// Writes the checked PDU into `out`, which holds `pdu_len()` bytes.
    fn write_pdu(&self, out: &mut [u8]);
}

impl OutgoingPdu for Request {
    fn check(&self) -> Result<(), EncodeError> {
        match *self {
            Self::Read { count, .. } if count == 0 || count > MAX_READ_WORDS => {
                Err(EncodeError::InvalidCount { count })
            }
            _ => Ok(()),
        }
    }

    fn write_pdu(&self, out: &mut [u8]) {
        out[0] = self.function_code();
        match *self {
            Self::Read { address, count, .. } => {
                out[1..3].copy_from_slice(&address.to_be_bytes());
                out[3..5].copy_from_slice(&count.to_be_bytes());
            }
            Self::Write { address, value } => {
                out[1..3].copy_from_slice(&address.to_be_bytes());
                value.write_to(&mut out[3..]);
            }
        }
    }

    fn pdu_len(&self) -> usize {
        Request::pdu_len(self)
    }
}

/// Big-endian 16-bit words borrowed from a reply's data bytes.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Words<'a> {
    bytes: &'a [u8],
}

impl<'a> Words<'a> {
    /// Wraps data bytes whose length is known to be even.
    pub(crate) const fn from_even(bytes: &'a [u8]) -> Self {
        Self { bytes }
    }

    /// Wraps data bytes; `None` when their number is odd.
    pub const fn from_bytes(bytes: &'a [u8]) -> Option<Self> {
        if bytes.len().is_multiple_of(2) {
            Some(Self { bytes })
        } else {
            None
        }
    }

    /// Number of words.
    pub const fn len(&self) -> usize {
        self.bytes.len() / 2
    }

    /// True when there are no words.
    pub const fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// The word at `index`, if there is one.
    pub fn get(&self, index: usize) -> Option<u16> {
        let start = index.checked_mul(2)?;
        let pair = self.bytes.get(start..start.checked_add(2)?)?;
        Some(u16::from_be_bytes([pair[0], pair[1]]))
    }

    /// The words in order.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = u16> + 'a {
        let (pairs, _) = self.bytes.as_chunks::<2>();
        pairs.iter().map(|pair| u16::from_be_bytes(*pair))
    }

    /// Copies the words into `out` and returns how many were copied (at most `out.len()`).
    pub fn copy_to(&self, out: &mut [u16]) -> usize {
        let mut copied = 0;
        for (slot, word) in out.iter_mut().zip(self.iter()) {
            *slot = word;
            copied += 1;
        }
        copied
    }

    /// The raw data bytes.
    pub const fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }
}

impl fmt::Debug for Words<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.iter().map(Hex)).finish()
    }
}

struct Hex(u16);

impl fmt::Debug for Hex {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:#06X}", self.0)
    }
}

/// A successful reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Response<'a> {
    /// Reply to FC03/FC04: the words read.
    Read {
        /// Which table was read.
        function: ReadFunction,
        /// The data.
        words: Words<'a>,
    },
    /// Reply to FC06: the echo of the request.
    Write {
        /// Register address.
        address: u16,
        /// The value written.
        value: WriteValue,
    },
}

impl Response<'_> {
    /// The function code on the wire.
    pub const fn function_code(&self) -> u8 {
        match self {
            Self::Read { function, .. } => function.code(),
            Self::Write { .. } => WRITE_SINGLE,
        }
    }

    /// Length of the PDU in bytes.
    pub const fn pdu_len(&self) -> usize {
        match self {
            Self::Read { words, .. } => 2 + words.as_bytes().len(),
            Self::Write { value, .. } => value.width().write_pdu_len(),
        }
    }
}

/// An exception code from a device's error reply.
///
/// Standard devices send one byte; LC-RS sends a 16-bit code, so the code is kept as `u16`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ExceptionCode(pub u16);

impl ExceptionCode {
    /// 01: the function code is not supported.
    pub const ILLEGAL_FUNCTION: Self = Self(0x01);
    /// 02: the address (or address range) is not defined.
    pub const ILLEGAL_DATA_ADDRESS: Self = Self(0x02);
    /// 03: the value is out of range for the register.
    pub const ILLEGAL_DATA_VALUE: Self = Self(0x03);
    /// 04: the device failed while handling the request.
    pub const SERVER_DEVICE_FAILURE: Self = Self(0x04);
    /// 06: the device is busy.
    pub const SERVER_DEVICE_BUSY: Self = Self(0x06);

    /// The standard Modbus name of the code, if it has one.
    pub const fn standard_name(self) -> Option<&'static str> {
        match self.0 {
            0x01 => Some("illegal function"),
            0x02 => Some("illegal data address"),
            0x03 => Some("illegal data value"),
            0x04 => Some("server device failure"),
            0x05 => Some("acknowledge"),
            0x06 => Some("server device busy"),
            0x08 => Some("memory parity error"),
            0x0A => Some("gateway path unavailable"),
            0x0B => Some("gateway target device failed to respond"),
            _ => None,
        }
    }
}

impl fmt::Display for ExceptionCode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.standard_name() {
            Some(name) => write!(f, "{:02X} ({name})", self.0),
            None => write!(f, "{:#06X}", self.0),
        }
    }
}

/// How a device frames an exception reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum ExceptionShape {
    /// `fc|0x80 code`: one code byte (the Modbus standard).
    #[default]
    Standard,
    /// `fc|0x80 02 code_hi code_lo`: a byte count of 2 and a 16-bit code (LC-RS).
    CountedWord,
}

impl ExceptionShape {
    /// Length of the exception PDU (function code and data).
    pub const fn pdu_len(self) -> usize {
        match self {
            Self::Standard => 2,
            Self::CountedWord => 4,
        }
    }

    /// Parses an exception PDU of `pdu_len()` bytes.
    pub(crate) fn parse_pdu(self, pdu: &[u8]) -> Result<ExceptionCode, DecodeError> {
        match self {
            Self::Standard => Ok(ExceptionCode(u16::from(pdu[1]))),
            Self::CountedWord if pdu[1] != 2 => Err(DecodeError::BadByteCount {
                expected: 2,
                received: pdu[1],
            }),
            Self::CountedWord => Ok(ExceptionCode(u16::from_be_bytes([pdu[2], pdu[3]]))),
        }
    }
}

/// Everything about a device's framing that departs from standard Modbus, as data.
///
/// A client needs only `exception` (it knows the width of what it writes); a device decoding
/// requests also needs to know which FC06 addresses carry four data bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct FrameShape<'a> {
    /// How exception replies are framed.
    pub exception: ExceptionShape,
    /// Holding-register addresses whose FC06 frames carry four data bytes.
    pub four_byte_writes: &'a [u16],
}

impl FrameShape<'static> {
    /// Plain Modbus: one-byte exception codes, two-byte FC06 values.
    pub const STANDARD: Self = Self {
        exception: ExceptionShape::Standard,
        four_byte_writes: &[],
    };
}

impl FrameShape<'_> {
    /// The payload width of an FC06 frame addressed to `address`.
    pub fn write_width(&self, address: u16) -> PayloadWidth {
        if self.four_byte_writes.contains(&address) {
            PayloadWidth::Four
        } else {
            PayloadWidth::Two
        }
    }
}

/// The outcome of feeding bytes to an incremental decoder that did not fail.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Decoded<T> {
    /// The bytes so far are a valid prefix; at least `at_least` more are needed.
    NeedMore {
        /// Lower bound on the number of missing bytes.
        at_least: usize,
    },
    /// A whole, checked frame, made of the first `consumed` bytes of the input.
    Frame {
        /// The frame.
        frame: T,
        /// How many bytes of the input it used.
        consumed: usize,
    },
}

impl<T> Decoded<T> {
    /// The frame, if one is complete.
    pub fn frame(self) -> Option<T> {
        match self {
            Self::Frame { frame, .. } => Some(frame),
            Self::NeedMore { .. } => None,
        }
    }

    /// Transforms the frame, keeping `consumed`.
    pub fn map<U>(self, f: impl FnOnce(T) -> U) -> Decoded<U> {
        match self {
            Self::Frame { frame, consumed } => Decoded::Frame {
                frame: f(frame),
                consumed,
            },
            Self::NeedMore { at_least } => Decoded::NeedMore { at_least },
        }
    }
}

/// Why bytes could not be decoded as the expected frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum DecodeError {
    /// The CRC at the end of the frame does not match its contents.
    BadCrc {
        /// The CRC of the received bytes.
        computed: u16,
        /// The CRC the frame carried.
        received: u16,
    },
    /// The frame is from (or for) another slave address or unit.
    UnexpectedSlave {
        /// The address of the request in flight.
        expected: u8,
        /// The address in the frame.
        received: u8,
    },
    /// The function code is neither the request's nor its exception form.
    UnexpectedFunction {
        /// The function code of the request in flight.
        expected: u8,
        /// The function code in the frame.
        received: u8,
    },
    /// A byte count that disagrees with the request or the frame shape.
    BadByteCount {
        /// The byte count the request implies.
        expected: u8,
        /// The byte count in the frame.
        received: u8,
    },
    /// An FC06 reply that does not echo the request.
    EchoMismatch {
        /// The address written.
        address: u16,
        /// The value written.
        value: u32,
        /// The address echoed.
        received_address: u16,
        /// The value echoed.
        received_value: u32,
    },
    /// The device answered with an exception reply.
    Exception {
        /// The function code of the request (without the exception bit).
        function: u8,
        /// The exception code.
        code: ExceptionCode,
    },
    /// A CRC-valid request with a function code this codec does not implement.
    UnsupportedFunction {
        /// The function code.
        function: u8,
    },
    /// A Modbus TCP reply with another transaction id than the request's.
    UnexpectedTransaction {
        /// The request's transaction id.
        expected: u16,
        /// The reply's transaction id.
        received: u16,
    },
    /// A Modbus TCP header whose protocol id is not 0.
    BadProtocolId {
        /// The protocol id received.
        received: u16,
    },
    /// A Modbus TCP length field that disagrees with the PDU it announces.
    BadLength {
        /// The length the PDU needs (unit id included), or the largest allowed.
        expected: u16,
        /// The length field received.
        received: u16,
    },
    /// Another reply to the same request came behind a complete one: another master on the
    /// line, or the reply to an earlier request still under way. RTU frames carry no
    /// transaction id, so which one answers this request cannot be told; neither is taken.
    SecondReply,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::BadCrc { computed, received } => write!(
                f,
                "bad CRC: frame carries {received:#06X}, its bytes give {computed:#06X}"
            ),
            Self::UnexpectedSlave { expected, received } => {
                write!(f, "reply from slave {received}, expected slave {expected}")
            }
            Self::UnexpectedFunction { expected, received } => write!(
                f,
                "unexpected function code {received:#04X}, expected {expected:#04X}"
            ),
            Self::BadByteCount { expected, received } => {
                write!(f, "byte count {received}, expected {expected}")
            }
            Self::EchoMismatch {
                address,
                value,
                received_address,
                received_value,
            } => write!(
                f,
                "wrote {value:#X} to register {address:#06X}, \
                 echo says {received_value:#X} to {received_address:#06X}"
            ),
            Self::Exception { function, code } => {
                write!(f, "exception {code} in reply to function {function:#04X}")
            }
            Self::UnsupportedFunction { function } => {
                write!(f, "unsupported function code {function:#04X}")
            }
            Self::UnexpectedTransaction { expected, received } => write!(
                f,
                "reply to transaction {received}, expected transaction {expected}"
            ),
            Self::BadProtocolId { received } => {
                write!(f, "protocol id {received}, Modbus TCP requires 0")
            }
            Self::BadLength { expected, received } => {
                write!(f, "MBAP length {received}, expected {expected}")
            }
            Self::SecondReply => f.write_str(
                "a second reply came behind the first, so which one answers the request cannot be told",
            ),
        }
    }
}

impl core::error::Error for DecodeError {}

/// The highest slave address; 248 to 255 are reserved (Modbus over serial line V1.02, 2.2).
pub const MAX_SLAVE: u8 = 247;

/// The broadcast address: every slave carries out the request and none answers.
pub const BROADCAST: u8 = 0;

/// Why a frame could not be encoded. Nothing is written to the caller's buffer on error.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum EncodeError {
    /// The output buffer is too small for the frame.
    BufferTooSmall {
        /// Bytes the frame needs.
        needed: usize,
    },
    /// A read of zero or more than 125 words.
    InvalidCount {
        /// The count asked for.
        count: u16,
    },
    /// A read reply with more than 125 words.
    TooManyWords {
        /// The number of words.
        words: usize,
    },
    /// A code above 0xFF for a standard, one-byte exception reply.
    CodeTooWide {
        /// The code.
        code: ExceptionCode,
    },
    /// A request to a reserved slave address (248 to 255).
    ReservedSlave {
        /// The address.
        slave: u8,
    },
    /// A PDU passed on unread that is empty or longer than a frame carries (253 bytes).
    PduLength {
        /// Its length.
        len: usize,
    },
    /// A PDU passed on unread whose function's reply cannot be framed on an RTU line (its
    /// length does not follow from its first bytes), or an exception function code.
    UnframedFunction {
        /// The function code.
        function: u8,
    },
    /// A request PDU passed on unread whose length or counts do not fit its function (a
    /// 2-byte FC03, a read of 0 registers, a byte count that disagrees with the data): no
    /// device could parse it, so it is not sent (a server answers it with exception 03).
    MalformedRequest {
        /// The function code.
        function: u8,
        /// The PDU's length.
        len: usize,
        /// What its function asks for.
        why: &'static str,
    },
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            Self::BufferTooSmall { needed } => {
                write!(f, "output buffer too small: the frame needs {needed} bytes")
            }
            Self::InvalidCount { count } => write!(
                f,
                "cannot read {count} registers: a read takes 1 to {MAX_READ_WORDS}"
            ),
            Self::TooManyWords { words } => write!(
                f,
                "cannot reply with {words} words: a read reply holds at most {MAX_READ_WORDS}"
            ),
            Self::CodeTooWide { code } => write!(
                f,
                "exception code {code} does not fit the standard one-byte exception frame"
            ),
            Self::ReservedSlave { slave } => write!(
                f,
                "slave address {slave} is reserved: slaves are 1 to {MAX_SLAVE}, 0 broadcasts"
            ),
            Self::PduLength { len } => {
                write!(f, "a PDU of {len} bytes: a frame carries 1 to 253")
            }
            Self::UnframedFunction { function } => write!(
                f,
                "function {function:#04X} cannot be passed to an RTU line: its reply's length is unknown"
            ),
            Self::MalformedRequest { function, len, why } => write!(
                f,
                "a request of function {function:#04X} of {len} bytes is malformed: {why}"
            ),
        }
    }
}

impl core::error::Error for EncodeError {}
