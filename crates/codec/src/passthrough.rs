//! PDUs passed on without being read, as a gateway between Modbus TCP and an RTU line does.
//!
//! RTU frames carry no length, so a reply can only be framed when its length follows from its
//! first bytes. [`PassPdu::new`] takes requests of the public function codes for which it
//! does (reads and writes of bits and registers, mask write, read/write multiple, FIFO,
//! exception status, event counter and log, server id, file records) and refuses the others
//! (a gateway answers those with exception 01 without touching the line). It refuses as well
//! a request whose length or counts do not fit its function as the Modbus application
//! protocol lays it out (a 2-byte FC03, a read of 0 or 126 registers, a byte count that
//! disagrees with the data): no device could parse it, and a gateway answers it with
//! exception 03 itself. The reply PDU is
//! handed back as it came, exceptions included, checked only for its slave, function code and
//! CRC; a device's own framing (four-byte FC06 data, LC-RS's counted-word exceptions) comes
//! from its [`FrameShape`].
//!
//! ```
//! use optobus_codec::passthrough::{self, PassPdu};
//! use optobus_codec::{Decoded, FrameShape};
//! // FC16: write 2 registers from 0x0010.
//! let request = PassPdu::new(&[0x10, 0x00, 0x10, 0x00, 0x02, 0x04, 0x00, 0x0A, 0x01, 0x02]).unwrap();
//! let mut frame = [0; 256];
//! let len = passthrough::encode_rtu(&mut frame, 1, &request).unwrap();
//! assert_eq!(len, 13);
//! let reply = [0x01, 0x10, 0x00, 0x10, 0x00, 0x02, 0x40, 0x0D];
//! let Ok(Decoded::Frame { frame: pdu, consumed: 8 }) =
//!     passthrough::decode_rtu_reply(&reply, 1, &request, &FrameShape::STANDARD)
//! else { panic!() };
//! assert_eq!(pdu, &reply[1..6]);
//! ```

use crate::crc::crc16;
use crate::pdu::{
    DecodeError, Decoded, EncodeError, ExceptionShape, FrameShape, EXCEPTION_BIT, MAX_READ_WORDS,
    MAX_SLAVE, WRITE_SINGLE,
};
use crate::rtu::{check_crc, OVERHEAD};
use crate::tcp::{Header, HEADER_LEN};

/// The longest PDU a frame carries (an RTU frame of 256 bytes less address and CRC).
pub const MAX_PDU_LEN: usize = 253;

/// The most bits one FC01 or FC02 request reads.
pub const MAX_READ_BITS: u16 = 2000;
/// The most bits one FC0F request writes.
pub const MAX_WRITE_BITS: u16 = 1968;
/// The most registers one FC16 request writes.
pub const MAX_WRITE_WORDS: u16 = 123;
/// The most registers one FC17 (read/write multiple) request writes.
pub const MAX_READ_WRITE_WORDS: u16 = 121;

/// Whether a request PDU's length, and the counts in it, fit its function as the Modbus
/// application protocol specification (V1.1b3, section 6) lays the request out; `Err` says
/// what the function asks for. FC06 takes two or four data bytes here (some devices write
/// four: their [`FrameShape`] says where, see [`PassPdu::check_shape`]). Functions this module
/// does not frame are left to [`reply_shape`].
fn check_request(pdu: &[u8]) -> Result<(), &'static str> {
    let word = |at: usize| u16::from_be_bytes([pdu[at], pdu[at + 1]]);
    let len_is = |len: usize, why: &'static str| if pdu.len() == len { Ok(()) } else { Err(why) };
    let at_least = |len: usize, why: &'static str| if pdu.len() >= len { Ok(()) } else { Err(why) };
    let count_in = |count: u16, max: u16, why: &'static str| {
        if (1..=max).contains(&count) {
            Ok(())
        } else {
            Err(why)
        }
    };
    match pdu[0] {
        0x01 | 0x02 => {
            len_is(5, "a read of bits is an address and a count (5 bytes)")?;
            count_in(word(3), MAX_READ_BITS, "a read of bits takes 1 to 2000")
        }
        0x03 | 0x04 => {
            len_is(5, "a read of registers is an address and a count (5 bytes)")?;
            count_in(
                word(3),
                MAX_READ_WORDS,
                "a read of registers takes 1 to 125",
            )
        }
        0x05 => {
            len_is(5, "a coil write is an address and a value (5 bytes)")?;
            match word(3) {
                0x0000 | 0xFF00 => Ok(()),
                _ => Err("a coil is written with FF00 (on) or 0000 (off)"),
            }
        }
        WRITE_SINGLE => match pdu.len() {
            5 | 7 => Ok(()),
            _ => Err("a register write is an address and 2 (or 4) data bytes"),
        },
        // Exception status, event counter and log, server id: the function code alone.
        0x07 | 0x0B | 0x0C | 0x11 => len_is(1, "the function takes no data"),
        0x0F => {
            let why = "a write of bits is an address, a count of 1 to 1968, a byte count of                        one byte per 8 bits and those bytes";
            at_least(6, why)?;
            count_in(word(3), MAX_WRITE_BITS, why)?;
            let bytes = usize::from(word(3).div_ceil(8));
            (usize::from(pdu[5]) == bytes && pdu.len() == 6 + bytes)
                .then_some(())
                .ok_or(why)
        }
        0x10 => {
            let why = "a write of registers is an address, a count of 1 to 123, a byte count                        of 2 per register and those bytes";
            at_least(6, why)?;
            count_in(word(3), MAX_WRITE_WORDS, why)?;
            let bytes = 2 * usize::from(word(3));
            (usize::from(pdu[5]) == bytes && pdu.len() == 6 + bytes)
                .then_some(())
                .ok_or(why)
        }
        0x14 => {
            let why = "a file record read is a byte count of 7 to 245 and that many bytes of                        7-byte sub-requests";
            at_least(2, why)?;
            let bytes = usize::from(pdu[1]);
            ((7..=0xF5).contains(&bytes) && bytes % 7 == 0 && pdu.len() == 2 + bytes)
                .then_some(())
                .ok_or(why)
        }
        0x15 => {
            let why = "a file record write is a byte count of 9 to 251 and that many bytes of                        sub-requests, each 7 bytes and its record length's registers";
            at_least(2, why)?;
            let bytes = usize::from(pdu[1]);
            if !(9..=0xFB).contains(&bytes) || pdu.len() != 2 + bytes {
                return Err(why);
            }
            let mut at = 2;
            while at < pdu.len() {
                if at + 7 > pdu.len() {
                    return Err(why);
                }
                at += 7 + 2 * usize::from(word(at + 5));
            }
            len_is(at, why)
        }
        0x16 => len_is(
            7,
            "a mask write is an address, an AND and an OR mask (7 bytes)",
        ),
        0x17 => {
            let why = "a read/write of registers is a read address and count (1 to 125), a                        write address and count (1 to 121), a byte count of 2 per register                        written and those bytes";
            at_least(10, why)?;
            count_in(word(3), MAX_READ_WORDS, why)?;
            count_in(word(7), MAX_READ_WRITE_WORDS, why)?;
            let bytes = 2 * usize::from(word(7));
            (usize::from(pdu[9]) == bytes && pdu.len() == 10 + bytes)
                .then_some(())
                .ok_or(why)
        }
        0x18 => len_is(3, "a FIFO read is a pointer address (3 bytes)"),
        _ => Ok(()),
    }
}

/// How the length of a reply follows from its first bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ReplyShape {
    /// A fixed number of PDU bytes.
    Fixed(usize),
    /// The function code, a one-byte byte count, and that many bytes.
    ByteCounted,
    /// The function code, a two-byte byte count, and that many bytes (FC24, read FIFO).
    WordCounted,
}

/// The reply shape of a request PDU, or `None` for a function this module cannot frame.
fn reply_shape(pdu: &[u8], shape: &FrameShape<'_>) -> Option<ReplyShape> {
    Some(match pdu[0] {
        // Read coils, discrete inputs, holding and input registers; get comm event log;
        // report server id; read and write file records; read/write multiple registers.
        0x01..=0x04 | 0x0C | 0x11 | 0x14 | 0x15 | 0x17 => ReplyShape::ByteCounted,
        WRITE_SINGLE if pdu.len() >= 3 => {
            let address = u16::from_be_bytes([pdu[1], pdu[2]]);
            ReplyShape::Fixed(shape.write_width(address).write_pdu_len())
        }
        // Write single coil, write multiple coils and registers.
        0x05 | 0x0F | 0x10 => ReplyShape::Fixed(5),
        // Read exception status.
        0x07 => ReplyShape::Fixed(2),
        // Get comm event counter.
        0x0B => ReplyShape::Fixed(5),
        // Mask write register.
        0x16 => ReplyShape::Fixed(7),
        // Read FIFO queue.
        0x18 => ReplyShape::WordCounted,
        _ => return None,
    })
}

/// What a request PDU asks of the registers it names, as [`PassPdu::access`] reads it: what a
/// gateway checks before the request may go to a device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Access<'a> {
    /// Reads `count` registers from `address` (FC03 holding, FC04 input).
    ReadRegisters {
        /// Input registers (FC04) rather than holding ones (FC03).
        input: bool,
        /// The first register.
        address: u16,
        /// How many.
        count: u16,
    },
    /// Writes holding registers from `address` (FC06, FC16).
    WriteRegisters {
        /// The first register.
        address: u16,
        /// The data written: two bytes per register, high byte first ([`words`]).
        data: &'a [u8],
    },
    /// Any other function: bits, files, masks, FIFOs, diagnostics, read/write multiple.
    Other {
        /// Whether it changes the device (coil, file, mask and read/write multiple writes).
        writes: bool,
    },
}

/// The registers' words in `data` of an [`Access::WriteRegisters`], in order.
pub fn words(data: &[u8]) -> impl Iterator<Item = u16> + '_ {
    data.chunks_exact(2)
        .map(|pair| u16::from_be_bytes([pair[0], pair[1]]))
}

/// A request PDU (function code and data) to pass on unread.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PassPdu<'a> {
    pdu: &'a [u8],
}

impl<'a> PassPdu<'a> {
    /// `pdu`, if it is 1 to [`MAX_PDU_LEN`] bytes of a function whose reply can be framed
    /// ([`EncodeError::UnframedFunction`] else) and its length and counts fit its function
    /// ([`EncodeError::MalformedRequest`] else; see the module docs).
    pub fn new(pdu: &'a [u8]) -> Result<Self, EncodeError> {
        let Some(&function) = pdu.first() else {
            return Err(EncodeError::PduLength { len: 0 });
        };
        if pdu.len() > MAX_PDU_LEN {
            return Err(EncodeError::PduLength { len: pdu.len() });
        }
        if function & EXCEPTION_BIT != 0 || reply_shape(pdu, &FrameShape::STANDARD).is_none() {
            return Err(EncodeError::UnframedFunction { function });
        }
        check_request(pdu).map_err(|why| EncodeError::MalformedRequest {
            function,
            len: pdu.len(),
            why,
        })?;
        Ok(Self { pdu })
    }

    /// Checks the request against the framing of the device it goes to: an FC06 carries the
    /// data width `shape` gives its address (two bytes, or four where the device writes four).
    pub fn check_shape(&self, shape: &FrameShape<'_>) -> Result<(), EncodeError> {
        if self.function() != WRITE_SINGLE {
            return Ok(());
        }
        let address = u16::from_be_bytes([self.pdu[1], self.pdu[2]]);
        let expected = shape.write_width(address).write_pdu_len();
        if self.pdu.len() == expected {
            return Ok(());
        }
        Err(EncodeError::MalformedRequest {
            function: WRITE_SINGLE,
            len: self.pdu.len(),
            why: if expected == 5 {
                "the device takes 2 data bytes at this address"
            } else {
                "the device takes 4 data bytes at this address"
            },
        })
    }

    /// Whether the request may be broadcast (to slave 0): the writes may; nobody answers a
    /// broadcast, so a read broadcast would be asked for nothing.
    pub fn may_broadcast(&self) -> bool {
        matches!(self.function(), 0x05 | 0x06 | 0x0F | 0x10 | 0x15 | 0x16)
    }

    /// What the request reads or writes.
    pub fn access(&self) -> Access<'a> {
        let pdu = self.pdu;
        let word = |at: usize| u16::from_be_bytes([pdu[at], pdu[at + 1]]);
        // `new` checked each function's length and counts.
        match self.function() {
            function @ (0x03 | 0x04) => Access::ReadRegisters {
                input: function == 0x04,
                address: word(1),
                count: word(3),
            },
            WRITE_SINGLE => Access::WriteRegisters {
                address: word(1),
                data: &pdu[3..],
            },
            0x10 => Access::WriteRegisters {
                address: word(1),
                data: &pdu[6..],
            },
            function => Access::Other {
                writes: matches!(function, 0x05 | 0x0F | 0x15 | 0x16 | 0x17),
            },
        }
    }

    /// Whether the request changes the device: a write of bits, registers, file records or a
    /// mask.
    pub fn writes(&self) -> bool {
        match self.access() {
            Access::ReadRegisters { .. } => false,
            Access::WriteRegisters { .. } => true,
            Access::Other { writes } => writes,
        }
    }

    /// The function code.
    pub fn function(&self) -> u8 {
        self.pdu[0]
    }

    /// The PDU's bytes.
    pub fn bytes(&self) -> &'a [u8] {
        self.pdu
    }
}

/// Frames `pdu` for `slave` (0 broadcasts) as RTU; gives the frame's length.
pub fn encode_rtu(out: &mut [u8], slave: u8, pdu: &PassPdu<'_>) -> Result<usize, EncodeError> {
    if slave > MAX_SLAVE {
        return Err(EncodeError::ReservedSlave { slave });
    }
    let len = pdu.pdu.len() + OVERHEAD;
    let Some(out) = out.get_mut(..len) else {
        return Err(EncodeError::BufferTooSmall { needed: len });
    };
    out[0] = slave;
    out[1..=pdu.pdu.len()].copy_from_slice(pdu.pdu);
    let crc = crc16(&out[..len - 2]);
    out[len - 2..].copy_from_slice(&crc.to_le_bytes());
    Ok(len)
}

/// Frames a reply PDU passed back unread (a gateway's answer to a Modbus TCP client) behind
/// the MBAP header of the request it answers; gives the frame's length.
pub fn encode_tcp_reply(out: &mut [u8], header: Header, pdu: &[u8]) -> Result<usize, EncodeError> {
    if pdu.is_empty() || pdu.len() > MAX_PDU_LEN {
        return Err(EncodeError::PduLength { len: pdu.len() });
    }
    let len = HEADER_LEN + pdu.len();
    let Some(out) = out.get_mut(..len) else {
        return Err(EncodeError::BufferTooSmall { needed: len });
    };
    // A PDU is at most 253 bytes, so the length field (unit id and PDU) fits.
    let length = (pdu.len() + 1) as u16;
    out[0..2].copy_from_slice(&header.transaction.to_be_bytes());
    out[2..4].copy_from_slice(&[0, 0]);
    out[4..6].copy_from_slice(&length.to_be_bytes());
    out[6] = header.unit;
    out[HEADER_LEN..].copy_from_slice(pdu);
    Ok(len)
}

/// The reply PDU's length from its first bytes (`pdu` holds at least the function code).
fn reply_pdu_len(
    pdu: &[u8],
    request: &PassPdu<'_>,
    shape: &FrameShape<'_>,
) -> Result<Result<usize, usize>, DecodeError> {
    let expected = request.function();
    let received = pdu[0];
    if received == expected | EXCEPTION_BIT {
        if shape.exception == ExceptionShape::CountedWord {
            match pdu.get(1) {
                None => return Ok(Err(1)),
                Some(&2) => {}
                Some(&other) => {
                    return Err(DecodeError::BadByteCount {
                        expected: 2,
                        received: other,
                    })
                }
            }
        }
        return Ok(Ok(shape.exception.pdu_len()));
    }
    if received != expected {
        return Err(DecodeError::UnexpectedFunction { expected, received });
    }
    // `PassPdu::new` admitted only framable functions.
    let reply = reply_shape(request.pdu, shape).unwrap_or(ReplyShape::Fixed(1));
    Ok(match reply {
        ReplyShape::Fixed(len) => Ok(len),
        ReplyShape::ByteCounted => match pdu.get(1) {
            Some(&count) => Ok(2 + usize::from(count)),
            None => Err(1),
        },
        ReplyShape::WordCounted => match pdu.get(1..3) {
            Some(&[high, low]) => {
                let count = usize::from(u16::from_be_bytes([high, low]));
                if 3 + count > MAX_PDU_LEN {
                    return Err(DecodeError::BadByteCount {
                        expected: (MAX_PDU_LEN - 3) as u8,
                        received: u8::try_from(count).unwrap_or(u8::MAX),
                    });
                }
                Ok(3 + count)
            }
            _ => Err(3 - pdu.len().min(3)),
        },
    })
}

/// Decodes the RTU reply of `slave` to `request` from the bytes received so far: the reply's
/// PDU as it came (an exception reply too), once its CRC checks.
pub fn decode_rtu_reply<'b>(
    buf: &'b [u8],
    slave: u8,
    request: &PassPdu<'_>,
    shape: &FrameShape<'_>,
) -> Result<Decoded<&'b [u8]>, DecodeError> {
    crate::rtu::need!(buf, 2);
    let pdu_len = match reply_pdu_len(&buf[1..], request, shape)? {
        Ok(len) => len,
        Err(more) => return Ok(Decoded::NeedMore { at_least: more }),
    };
    let len = pdu_len + OVERHEAD;
    crate::rtu::need!(buf, len);
    check_crc(&buf[..len])?;
    if buf[0] != slave {
        return Err(DecodeError::UnexpectedSlave {
            expected: slave,
            received: buf[0],
        });
    }
    Ok(Decoded::Frame {
        frame: &buf[1..=pdu_len],
        consumed: len,
    })
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::{rtu, ExceptionCode, ReadFunction, Request};
    use std::string::ToString;
    use std::vec;

    #[test]
    fn access_names_the_registers_a_request_reads_or_writes() {
        let read = PassPdu::new(&[0x04, 0x00, 0x12, 0x00, 0x02]).unwrap();
        assert_eq!(
            read.access(),
            Access::ReadRegisters {
                input: true,
                address: 0x12,
                count: 2
            }
        );
        assert!(!read.writes());
        let single = PassPdu::new(&[0x06, 0x00, 0x1F, 0x00, 0x05]).unwrap();
        assert_eq!(
            single.access(),
            Access::WriteRegisters {
                address: 0x1F,
                data: &[0x00, 0x05]
            }
        );
        let multiple =
            PassPdu::new(&[0x10, 0x00, 0x10, 0x00, 0x02, 0x04, 0x00, 0x0A, 0x01, 0x02]).unwrap();
        let Access::WriteRegisters { address, data } = multiple.access() else {
            panic!("FC16 writes registers");
        };
        assert_eq!(address, 0x10);
        assert!(words(data).eq([0x000A, 0x0102]));
        let coil = PassPdu::new(&[0x05, 0x00, 0x01, 0xFF, 0x00]).unwrap();
        assert_eq!(coil.access(), Access::Other { writes: true });
        assert!(coil.writes() && multiple.writes());
        let server_id = PassPdu::new(&[0x11]).unwrap();
        assert!(!server_id.writes());
    }

    #[test]
    fn a_read_passed_through_frames_like_the_typed_read() {
        let typed = Request::Read {
            function: ReadFunction::Holding,
            address: 0x1F,
            count: 7,
        };
        let mut expected = [0; 256];
        let expected_len = rtu::encode_request(&mut expected, 1, &typed).unwrap();
        let pdu = PassPdu::new(&expected[1..expected_len - 2]).unwrap();
        let mut out = [0; 256];
        let len = encode_rtu(&mut out, 1, &pdu).unwrap();
        assert_eq!(&out[..len], &expected[..expected_len]);
    }

    #[test]
    fn counted_word_exceptions_are_framed_by_the_shape() {
        let pdu = PassPdu::new(&[0x03, 0x00, 0x83, 0x00, 0x05]).unwrap();
        let mut reply = [0; 256];
        let len = rtu::encode_exception(
            &mut reply,
            1,
            0x03,
            ExceptionCode(2),
            ExceptionShape::CountedWord,
        )
        .unwrap();
        assert_eq!(len, 7);
        let shape = FrameShape {
            exception: ExceptionShape::CountedWord,
            four_byte_writes: &[],
        };
        let decoded = decode_rtu_reply(&reply[..len], 1, &pdu, &shape).unwrap();
        assert_eq!(
            decoded,
            Decoded::Frame {
                frame: &reply[1..5],
                consumed: 7
            }
        );
        // The same bytes read as a standard exception end two bytes early: the CRC fails.
        assert!(decode_rtu_reply(&reply[..len], 1, &pdu, &FrameShape::STANDARD).is_err());
    }

    #[test]
    fn a_four_byte_write_echo_is_framed_by_the_shape() {
        let shape = FrameShape {
            exception: ExceptionShape::Standard,
            four_byte_writes: &[0x0040],
        };
        let request = [0x06, 0x00, 0x40, 0x00, 0x01, 0x86, 0xA0];
        let pdu = PassPdu::new(&request).unwrap();
        let mut frame = [0; 256];
        let len = encode_rtu(&mut frame, 7, &pdu).unwrap();
        assert_eq!(len, 10);
        // The echo is the request itself.
        let decoded = decode_rtu_reply(&frame[..len], 7, &pdu, &shape).unwrap();
        assert_eq!(
            decoded,
            Decoded::Frame {
                frame: &request[..],
                consumed: 10
            }
        );
    }

    #[test]
    fn functions_whose_reply_cannot_be_framed_are_refused() {
        assert_eq!(
            PassPdu::new(&[0x08, 0x00, 0x00, 0x12, 0x34]),
            Err(EncodeError::UnframedFunction { function: 0x08 })
        );
        assert_eq!(
            PassPdu::new(&[0x83, 0x02]),
            Err(EncodeError::UnframedFunction { function: 0x83 })
        );
        assert_eq!(PassPdu::new(&[]), Err(EncodeError::PduLength { len: 0 }));
        assert_eq!(
            PassPdu::new(&[0x03; 254]),
            Err(EncodeError::PduLength { len: 254 })
        );
    }

    /// The request examples of the Modbus application protocol specification (V1.1b3,
    /// section 6), one per function this module frames.
    const SPEC_REQUESTS: &[&[u8]] = &[
        &[0x01, 0x00, 0x13, 0x00, 0x13],
        &[0x02, 0x00, 0xC4, 0x00, 0x16],
        &[0x03, 0x00, 0x6B, 0x00, 0x03],
        &[0x04, 0x00, 0x08, 0x00, 0x01],
        &[0x05, 0x00, 0xAC, 0xFF, 0x00],
        &[0x06, 0x00, 0x01, 0x00, 0x03],
        &[0x07],
        &[0x0B],
        &[0x0C],
        &[0x0F, 0x00, 0x13, 0x00, 0x0A, 0x02, 0xCD, 0x01],
        &[0x10, 0x00, 0x01, 0x00, 0x02, 0x04, 0x00, 0x0A, 0x01, 0x02],
        &[0x11],
        &[
            0x14, 0x0E, 0x06, 0x00, 0x04, 0x00, 0x01, 0x00, 0x02, 0x06, 0x00, 0x03, 0x00, 0x09,
            0x00, 0x02,
        ],
        &[
            0x15, 0x0D, 0x06, 0x00, 0x04, 0x00, 0x07, 0x00, 0x03, 0x06, 0xAF, 0x04, 0xBE, 0x10,
            0x0D,
        ],
        &[0x16, 0x00, 0x04, 0x00, 0xF2, 0x00, 0x25],
        &[
            0x17, 0x00, 0x03, 0x00, 0x06, 0x00, 0x0E, 0x00, 0x03, 0x06, 0x00, 0xFF, 0x00, 0xFF,
            0x00, 0xFF,
        ],
        &[0x18, 0x04, 0xDE],
    ];

    fn malformed(pdu: &[u8]) -> bool {
        matches!(
            PassPdu::new(pdu),
            Err(EncodeError::MalformedRequest { function, len, .. })
                if function == pdu[0] && len == pdu.len()
        )
    }

    #[test]
    fn the_specifications_requests_pass_and_a_byte_more_or_less_is_malformed() {
        for &request in SPEC_REQUESTS {
            assert_eq!(PassPdu::new(request).map(|p| p.bytes()), Ok(request));
            if request.len() > 1 {
                assert!(
                    malformed(&request[..request.len() - 1]),
                    "{request:02X?} cut"
                );
            }
            let longer = [request, &[0x00]].concat();
            assert!(malformed(&longer), "{request:02X?} and a byte");
        }
    }

    #[test]
    fn counts_outside_their_functions_range_are_malformed() {
        // Reads of 0 and 126 registers, of 2001 coils; the 2-byte FC03 of issue 28.
        assert!(malformed(&[0x03, 0x00, 0x00, 0x00, 0x00]));
        assert!(malformed(&[0x04, 0x00, 0x00, 0x00, 0x7E]));
        assert!(PassPdu::new(&[0x04, 0x00, 0x00, 0x00, 0x7D]).is_ok());
        assert!(malformed(&[0x01, 0x00, 0x00, 0x07, 0xD1]));
        assert!(PassPdu::new(&[0x01, 0x00, 0x00, 0x07, 0xD0]).is_ok());
        assert!(malformed(&[0x03, 0x00]));
        // A coil is written FF00 or 0000, nothing else.
        assert!(malformed(&[0x05, 0x00, 0xAC, 0x12, 0x34]));
        assert!(PassPdu::new(&[0x05, 0x00, 0xAC, 0x00, 0x00]).is_ok());
        // FC0F: 10 coils take 2 bytes, not 1; FC16: 2 registers take 4 bytes, not 3.
        assert!(malformed(&[0x0F, 0x00, 0x13, 0x00, 0x0A, 0x01, 0xCD]));
        assert!(malformed(&[
            0x10, 0x00, 0x01, 0x00, 0x02, 0x03, 0x00, 0x0A, 0x01
        ]));
        // FC16 of 124 registers: one more than a request may write.
        let mut long = vec![0x10, 0x00, 0x00, 0x00, 124, 248];
        long.resize(6 + 248, 0);
        assert_eq!(long.len(), MAX_PDU_LEN + 1);
        assert_eq!(
            PassPdu::new(&long),
            Err(EncodeError::PduLength { len: 254 })
        );
        let mut long = vec![0x10, 0x00, 0x00, 0x00, 124, 248];
        long.resize(6 + 246, 0);
        assert!(malformed(&long));
        // FC17 writing 0 registers; FC15 whose record length runs past its byte count.
        assert!(malformed(&[
            0x17, 0x00, 0x03, 0x00, 0x06, 0x00, 0x0E, 0x00, 0x00, 0x00
        ]));
        assert!(malformed(&[
            0x15, 0x0D, 0x06, 0x00, 0x04, 0x00, 0x07, 0x00, 0x04, 0x06, 0xAF, 0x04, 0xBE, 0x10,
            0x0D,
        ]));
        // FC14 with a byte count that is not a whole number of sub-requests.
        assert!(malformed(&[
            0x14, 0x08, 0x06, 0x00, 0x04, 0x00, 0x01, 0x00, 0x02, 0x06
        ]));
        assert_eq!(
            PassPdu::new(&[0x03, 0x00]).unwrap_err().to_string(),
            "a request of function 0x03 of 2 bytes is malformed: a read of registers is an \
             address and a count (5 bytes)"
        );
    }

    #[test]
    fn a_register_write_carries_the_width_its_device_takes_at_its_address() {
        let wide = FrameShape {
            exception: ExceptionShape::Standard,
            four_byte_writes: &[0x0040],
        };
        let two = PassPdu::new(&[0x06, 0x00, 0x40, 0x00, 0x01]).unwrap();
        let four = PassPdu::new(&[0x06, 0x00, 0x40, 0x00, 0x01, 0x86, 0xA0]).unwrap();
        assert_eq!(two.check_shape(&FrameShape::STANDARD), Ok(()));
        assert_eq!(four.check_shape(&wide), Ok(()));
        assert!(matches!(
            two.check_shape(&wide),
            Err(EncodeError::MalformedRequest { len: 5, .. })
        ));
        assert!(matches!(
            four.check_shape(&FrameShape::STANDARD),
            Err(EncodeError::MalformedRequest { len: 7, .. })
        ));
        let read = PassPdu::new(&[0x03, 0x00, 0x40, 0x00, 0x02]).unwrap();
        assert_eq!(read.check_shape(&wide), Ok(()));
    }

    #[test]
    fn only_writes_may_be_broadcast() {
        assert!(PassPdu::new(&[0x06, 0x00, 0x01, 0x00, 0x03])
            .unwrap()
            .may_broadcast());
        assert!(!PassPdu::new(&[0x03, 0x00, 0x6B, 0x00, 0x03])
            .unwrap()
            .may_broadcast());
        assert!(!PassPdu::new(SPEC_REQUESTS[15]).unwrap().may_broadcast());
    }

    #[test]
    fn a_reply_from_another_slave_or_function_is_an_error() {
        let pdu = PassPdu::new(&[0x04, 0x00, 0x00, 0x00, 0x01]).unwrap();
        let mut reply = [0x02, 0x04, 0x02, 0x00, 0x2A, 0, 0];
        let crc = crc16(&reply[..5]);
        reply[5..].copy_from_slice(&crc.to_le_bytes());
        assert!(matches!(
            decode_rtu_reply(&reply, 1, &pdu, &FrameShape::STANDARD),
            Err(DecodeError::UnexpectedSlave {
                expected: 1,
                received: 2
            })
        ));
        let other = PassPdu::new(&[0x03, 0x00, 0x00, 0x00, 0x01]).unwrap();
        assert!(matches!(
            decode_rtu_reply(&reply, 2, &other, &FrameShape::STANDARD),
            Err(DecodeError::UnexpectedFunction {
                expected: 3,
                received: 4
            })
        ));
    }

    #[test]
    fn a_reply_pdu_goes_back_behind_the_requests_mbap_header() {
        let mut out = [0; 260];
        let header = Header {
            transaction: 0x1234,
            unit: 7,
        };
        let len = encode_tcp_reply(&mut out, header, &[0x83, 0x0B]).unwrap();
        assert_eq!(&out[..len], &[0x12, 0x34, 0, 0, 0, 3, 7, 0x83, 0x0B]);
        assert_eq!(
            encode_tcp_reply(&mut out, header, &[]),
            Err(EncodeError::PduLength { len: 0 })
        );
    }

    #[test]
    fn a_fifo_reply_is_framed_by_its_two_byte_count() {
        let pdu = PassPdu::new(&[0x18, 0x04, 0xDE]).unwrap();
        // Byte count 6: the FIFO count (2) and two registers.
        let mut reply = [
            0x01, 0x18, 0x00, 0x06, 0x00, 0x02, 0x01, 0xB8, 0x12, 0x34, 0, 0,
        ];
        let crc = crc16(&reply[..10]);
        reply[10..].copy_from_slice(&crc.to_le_bytes());
        assert_eq!(
            decode_rtu_reply(&reply[..10], 1, &pdu, &FrameShape::STANDARD),
            Ok(Decoded::NeedMore { at_least: 2 })
        );
        let decoded = decode_rtu_reply(&reply, 1, &pdu, &FrameShape::STANDARD).unwrap();
        assert_eq!(
            decoded,
            Decoded::Frame {
                frame: &reply[1..10],
                consumed: 12
            }
        );
    }
}
