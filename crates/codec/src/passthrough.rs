//! PDUs passed on without being read, as a gateway between Modbus TCP and an RTU line does.
//!
//! RTU frames carry no length, so a reply can only be framed when its length follows from its
//! first bytes. [`PassPdu::new`] takes requests of the public function codes for which it
//! does (reads and writes of bits and registers, mask write, read/write multiple, FIFO,
//! exception status, event counter and log, server id, file records) and refuses the others
//! (a gateway answers those with exception 01 without touching the line). The reply PDU is
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
    DecodeError, Decoded, EncodeError, ExceptionShape, FrameShape, EXCEPTION_BIT, MAX_SLAVE,
    WRITE_SINGLE,
};
use crate::rtu::{check_crc, OVERHEAD};
use crate::tcp::{Header, HEADER_LEN};

/// The longest PDU a frame carries (an RTU frame of 256 bytes less address and CRC).
pub const MAX_PDU_LEN: usize = 253;

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

/// A request PDU (function code and data) to pass on unread.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PassPdu<'a> {
    pdu: &'a [u8],
}

impl<'a> PassPdu<'a> {
    /// `pdu`, if it is 1 to [`MAX_PDU_LEN`] bytes of a function whose reply can be framed
    /// (see the module docs).
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
        Ok(Self { pdu })
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
    use super::*;
    use crate::{rtu, ExceptionCode, ReadFunction, Request};

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
