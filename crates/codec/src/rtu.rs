//! Modbus RTU framing: `slave pdu… crc_lo crc_hi`.
//!
//! Encoders write into the caller's buffer and return the frame length. Decoders are
//! incremental: give them the bytes received so far and they answer
//! [`Decoded::NeedMore`], [`Decoded::Frame`] (with how many bytes it used), or a typed
//! [`DecodeError`]. A decoded frame always has a valid CRC.

use crate::crc::{crc16, is_valid_frame};
use crate::pdu::{
    DecodeError, Decoded, EncodeError, ExceptionCode, ExceptionShape, FrameShape, OutgoingPdu,
    ReadFunction, Request, Response, Words, EXCEPTION_BIT, MAX_SLAVE, READ_REQUEST_PDU_LEN,
    WRITE_SINGLE,
};
use crate::server::ExceptionPdu;

/// The longest RTU frame Modbus allows.
pub const MAX_FRAME_LEN: usize = 256;

/// An RTU frame: the slave address and a PDU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<T> {
    /// Slave address (0 is broadcast).
    pub slave: u8,
    /// The protocol data unit.
    pub pdu: T,
}

/// Frames `pdu` with `slave` in front and the CRC behind; returns the frame length.
fn frame(out: &mut [u8], slave: u8, pdu: &impl OutgoingPdu) -> Result<usize, EncodeError> {
    pdu.check()?;
    let pdu_len = pdu.pdu_len();
    let len = pdu_len + OVERHEAD;
    let Some(out) = out.get_mut(..len) else {
        return Err(EncodeError::BufferTooSmall { needed: len });
    };
    out[0] = slave;
    pdu.write_pdu(&mut out[1..=pdu_len]);
    let crc = crc16(&out[..=pdu_len]);
    out[pdu_len + 1..].copy_from_slice(&crc.to_le_bytes());
    Ok(len)
}

/// Encodes a request to `slave` (0 broadcasts; 248 to 255 are refused); returns the frame
/// length.
///
/// ```
/// use optobus_codec::{rtu, ReadFunction, Request};
/// let mut buf = [0; rtu::MAX_FRAME_LEN];
/// let read = Request::Read { function: ReadFunction::Input, address: 0, count: 6 };
/// let len = rtu::encode_request(&mut buf, 1, &read).unwrap();
/// assert_eq!(&buf[..len], &[0x01, 0x04, 0x00, 0x00, 0x00, 0x06, 0x70, 0x08]);
/// ```
pub fn encode_request(out: &mut [u8], slave: u8, request: &Request) -> Result<usize, EncodeError> {
    if slave > MAX_SLAVE {
        return Err(EncodeError::ReservedSlave { slave });
    }
    frame(out, slave, request)
}

/// Encodes a device's successful reply; returns the frame length.
pub fn encode_response(
    out: &mut [u8],
    slave: u8,
    response: &Response<'_>,
) -> Result<usize, EncodeError> {
    frame(out, slave, response)
}

/// Encodes an exception reply to a request with function code `function`, in `shape`.
pub fn encode_exception(
    out: &mut [u8],
    slave: u8,
    function: u8,
    code: ExceptionCode,
    shape: ExceptionShape,
) -> Result<usize, EncodeError> {
    frame(out, slave, &ExceptionPdu::new(function, code, shape))
}

pub(crate) fn check_crc(frame: &[u8]) -> Result<(), DecodeError> {
    let (body, crc) = frame.split_at(frame.len() - 2);
    let computed = crc16(body);
    let received = u16::from_le_bytes([crc[0], crc[1]]);
    if computed == received {
        Ok(())
    } else {
        Err(DecodeError::BadCrc { computed, received })
    }
}

/// Bytes an RTU frame adds to its PDU: the slave address in front, the CRC behind.
pub const OVERHEAD: usize = 3;

/// The length of the RTU request frame starting at `buf`, from its first bytes: 8 for FC03
/// and FC04; for FC06 8, or 10 where `shape` says the address takes four data bytes (the
/// address must be in `buf`). `None` while too few bytes are there to tell, or for a function
/// this codec does not frame.
pub fn request_len(buf: &[u8], shape: &FrameShape<'_>) -> Option<usize> {
    let pdu_len = match *buf.get(1)? {
        0x03 | 0x04 => READ_REQUEST_PDU_LEN,
        WRITE_SINGLE => {
            let address = u16::from_be_bytes([*buf.get(2)?, *buf.get(3)?]);
            shape.write_width(address).write_pdu_len()
        }
        _ => return None,
    };
    Some(pdu_len + OVERHEAD)
}

/// The length of the RTU reply frame starting at `buf`, from its first bytes: FC03 and FC04
/// by their byte count, an FC06 echo like its request, an exception reply (function code
/// with [`EXCEPTION_BIT`]) in `shape`'s exception shape. `None` while too few bytes are
/// there to tell, or for a function this codec does not frame.
pub fn response_len(buf: &[u8], shape: &FrameShape<'_>) -> Option<usize> {
    let function = *buf.get(1)?;
    if function & EXCEPTION_BIT != 0 {
        return Some(shape.exception.pdu_len() + OVERHEAD);
    }
    match function {
        0x03 | 0x04 => Some(2 + usize::from(*buf.get(2)?) + OVERHEAD),
        _ => request_len(buf, shape),
    }
}

/// Whether `after`, bytes that came behind the complete reply `reply`, begin another reply to
/// the same request: the same slave address and the same function code, or its exception form.
/// A lone byte behind a reply (a transceiver's glitch as it lets go of the line) does not.
/// The transport then takes neither reply ([`DecodeError::SecondReply`]).
pub fn another_reply_follows(reply: &[u8], after: &[u8]) -> bool {
    match (reply, after) {
        ([slave, function, ..], [next_slave, next_function, ..]) => {
            next_slave == slave && next_function & !EXCEPTION_BIT == function & !EXCEPTION_BIT
        }
        _ => false,
    }
}

/// Returns `NeedMore` from the enclosing decoder when `$buf` is shorter than `$len`.
macro_rules! need {
    ($buf:expr, $len:expr) => {{
        let (have, want) = ($buf.len(), $len);
        if have < want {
            return Ok(Decoded::NeedMore {
                at_least: want - have,
            });
        }
    }};
}
pub(crate) use need;

/// Decodes a request as a device sees it. `shape` says which FC06 addresses carry four bytes.
///
/// RTU frames are delimited by line silence, so a request with a function code this codec does
/// not know is recognised only when the whole of `buf` is one CRC-valid frame; it is then
/// reported as [`DecodeError::UnsupportedFunction`] (a device answers exception 01).
pub fn decode_request(
    buf: &[u8],
    shape: &FrameShape<'_>,
) -> Result<Decoded<Frame<Request>>, DecodeError> {
    need!(buf, 2);
    let function = buf[1];
    let pdu_len = match function {
        0x03 | 0x04 => READ_REQUEST_PDU_LEN,
        WRITE_SINGLE => {
            need!(buf, 4);
            3 + shape
                .write_width(u16::from_be_bytes([buf[2], buf[3]]))
                .bytes()
        }
        _ if buf.len() >= 4 && is_valid_frame(buf) => {
            return Err(DecodeError::UnsupportedFunction { function });
        }
        _ => {
            return Ok(Decoded::NeedMore {
                at_least: 4usize.saturating_sub(buf.len()).max(1),
            })
        }
    };
    let len = pdu_len + 3;
    need!(buf, len);
    check_crc(&buf[..len])?;
    let width = shape.write_width(u16::from_be_bytes([buf[2], buf[3]]));
    Ok(Decoded::Frame {
        frame: Frame {
            slave: buf[0],
            pdu: Request::parse_pdu(&buf[1..=pdu_len], width),
        },
        consumed: len,
    })
}

/// What a reply to `request` may look like, from its function code on.
pub(crate) enum ReplyKind {
    Normal,
    Exception,
}

/// What the first bytes of a reply PDU tell about its length.
pub(crate) enum ReplyLength {
    /// The kind of reply and its PDU length.
    Known(ReplyKind, usize),
    /// This many more PDU bytes are needed to tell.
    NeedMore(usize),
}

/// Classifies a reply PDU from its first bytes (`pdu` holds at least the function code).
pub(crate) fn reply_pdu_len(
    pdu: &[u8],
    request: &Request,
    exception: ExceptionShape,
) -> Result<ReplyLength, DecodeError> {
    let expected = request.function_code();
    let received = pdu[0];
    if received == expected {
        match *request {
            Request::Read { count, .. } => {
                let Some(&byte_count) = pdu.get(1) else {
                    return Ok(ReplyLength::NeedMore(1));
                };
                let expected_count = 2 * usize::from(count);
                if usize::from(byte_count) != expected_count {
                    return Err(DecodeError::BadByteCount {
                        expected: u8::try_from(expected_count).unwrap_or(u8::MAX),
                        received: byte_count,
                    });
                }
                let pdu_len = 2 + expected_count;
                Ok(ReplyLength::Known(ReplyKind::Normal, pdu_len))
            }
            Request::Write { .. } => {
                let pdu_len = request.pdu_len();
                Ok(ReplyLength::Known(ReplyKind::Normal, pdu_len))
            }
        }
    } else if received == expected | EXCEPTION_BIT {
        if exception == ExceptionShape::CountedWord {
            match pdu.get(1) {
                None => return Ok(ReplyLength::NeedMore(1)),
                Some(&2) => {}
                Some(&other) => {
                    return Err(DecodeError::BadByteCount {
                        expected: 2,
                        received: other,
                    })
                }
            }
        }
        Ok(ReplyLength::Known(
            ReplyKind::Exception,
            exception.pdu_len(),
        ))
    } else {
        Err(DecodeError::UnexpectedFunction { expected, received })
    }
}

/// Interprets a whole, integrity-checked reply PDU.
pub(crate) fn parse_reply<'b>(
    pdu: &'b [u8],
    kind: ReplyKind,
    request: &Request,
    exception: ExceptionShape,
) -> Result<Response<'b>, DecodeError> {
    match (kind, *request) {
        (ReplyKind::Exception, _) => Err(DecodeError::Exception {
            function: request.function_code(),
            code: exception.parse_pdu(pdu)?,
        }),
        (ReplyKind::Normal, Request::Read { function, .. }) => Ok(Response::Read {
            function: ReadFunction::from_code(pdu[0]).unwrap_or(function),
            words: Words::from_even(&pdu[2..]),
        }),
        (ReplyKind::Normal, Request::Write { address, value }) => {
            let (received_address, received_value) = Request::parse_write(pdu, value.width());
            if (received_address, received_value) != (address, value) {
                return Err(DecodeError::EchoMismatch {
                    address,
                    value: value.as_u32(),
                    received_address,
                    received_value: received_value.as_u32(),
                });
            }
            Ok(Response::Write { address, value })
        }
    }
}

/// Decodes the reply to `request`, sent to `slave`, from a device framing exceptions in
/// `exception` shape. An exception reply becomes [`DecodeError::Exception`].
///
/// ```
/// use optobus_codec::{rtu, Decoded, ExceptionShape, ReadFunction, Request, Response};
/// let read = Request::Read { function: ReadFunction::Input, address: 0, count: 2 };
/// let reply = [0x01, 0x04, 0x04, 0x00, 0x36, 0xB0, 0xBE, 0xEE, 0x3A];
/// let Ok(Decoded::Frame { frame: Response::Read { words, .. }, consumed: 9 }) =
///     rtu::decode_response(&reply, 1, &read, ExceptionShape::Standard)
/// else { panic!() };
/// assert_eq!(words.get(1), Some(0xB0BE));
/// ```
pub fn decode_response<'b>(
    buf: &'b [u8],
    slave: u8,
    request: &Request,
    exception: ExceptionShape,
) -> Result<Decoded<Response<'b>>, DecodeError> {
    need!(buf, 2);
    let (kind, pdu_len) = match reply_pdu_len(&buf[1..], request, exception)? {
        ReplyLength::Known(kind, pdu_len) => (kind, pdu_len),
        ReplyLength::NeedMore(more) => return Ok(Decoded::NeedMore { at_least: more }),
    };
    let len = pdu_len + 3;
    need!(buf, len);
    check_crc(&buf[..len])?;
    if buf[0] != slave {
        return Err(DecodeError::UnexpectedSlave {
            expected: slave,
            received: buf[0],
        });
    }
    let response = parse_reply(&buf[1..=pdu_len], kind, request, exception)?;
    Ok(Decoded::Frame {
        frame: response,
        consumed: len,
    })
}
