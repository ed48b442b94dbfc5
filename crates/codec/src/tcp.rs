//! Modbus TCP framing: the MBAP header (transaction id, protocol id 0, length, unit id) and a
//! PDU, with no CRC.
//!
//! Same conventions as [`crate::rtu`]: encoders write into the caller's buffer, decoders are
//! incremental and shape-driven, and errors are typed.

use crate::pdu::{
    DecodeError, Decoded, EncodeError, ExceptionCode, ExceptionShape, FrameShape, OutgoingPdu,
    Request, Response, READ_REQUEST_PDU_LEN, WRITE_SINGLE,
};
use crate::rtu::{need, parse_reply, reply_pdu_len, ReplyLength};
use crate::server::ExceptionPdu;

/// Bytes of the MBAP header, unit id included.
pub const HEADER_LEN: usize = 7;

/// The longest Modbus TCP frame (7-byte header and a 253-byte PDU).
pub const MAX_FRAME_LEN: usize = 260;

/// The largest value of the MBAP length field (unit id and a 253-byte PDU).
const MAX_LENGTH_FIELD: u16 = 254;

/// The MBAP fields a client chooses and a server copies into its reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Header {
    /// Transaction id, echoed by the server.
    pub transaction: u16,
    /// Unit identifier (the slave address behind a gateway).
    pub unit: u8,
}

/// A Modbus TCP frame: header and PDU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Frame<T> {
    /// The MBAP header fields.
    pub header: Header,
    /// The protocol data unit.
    pub pdu: T,
}

/// Frames `pdu` behind the MBAP header; returns the frame length.
fn frame(out: &mut [u8], header: Header, pdu: &impl OutgoingPdu) -> Result<usize, EncodeError> {
    pdu.check()?;
    let pdu_len = pdu.pdu_len();
    let len = HEADER_LEN + pdu_len;
    let Some(out) = out.get_mut(..len) else {
        return Err(EncodeError::BufferTooSmall { needed: len });
    };
    pdu.write_pdu(&mut out[HEADER_LEN..]);
    // PDUs are at most 253 bytes, so the length field fits.
    let length = (pdu_len + 1) as u16;
    out[0..2].copy_from_slice(&header.transaction.to_be_bytes());
    out[2..4].copy_from_slice(&[0, 0]);
    out[4..6].copy_from_slice(&length.to_be_bytes());
    out[6] = header.unit;
    Ok(len)
}

/// Encodes a request; returns the frame length.
///
/// ```
/// use optobus_codec::{tcp, ReadFunction, Request};
/// let mut buf = [0; tcp::MAX_FRAME_LEN];
/// let read = Request::Read { function: ReadFunction::Holding, address: 0, count: 3 };
/// let len = tcp::encode_request(&mut buf, tcp::Header { transaction: 0, unit: 1 }, &read).unwrap();
/// assert_eq!(&buf[..len], &[0, 0, 0, 0, 0, 6, 1, 3, 0, 0, 0, 3]);
/// ```
pub fn encode_request(
    out: &mut [u8],
    header: Header,
    request: &Request,
) -> Result<usize, EncodeError> {
    frame(out, header, request)
}

/// Encodes a successful reply; returns the frame length.
pub fn encode_response(
    out: &mut [u8],
    header: Header,
    response: &Response<'_>,
) -> Result<usize, EncodeError> {
    frame(out, header, response)
}

/// Encodes an exception reply to a request with function code `function`.
pub fn encode_exception(
    out: &mut [u8],
    header: Header,
    function: u8,
    code: ExceptionCode,
    shape: ExceptionShape,
) -> Result<usize, EncodeError> {
    frame(out, header, &ExceptionPdu::new(function, code, shape))
}

/// An MBAP header as it is on the wire, unchecked: what a sniffer shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Mbap {
    /// Transaction id.
    pub transaction: u16,
    /// Protocol id (0 for Modbus).
    pub protocol: u16,
    /// Bytes that follow the length field: the unit id and the PDU.
    pub length: u16,
    /// Unit identifier.
    pub unit: u8,
}

impl Mbap {
    /// The header at the start of `buf`, if `buf` holds its [`HEADER_LEN`] bytes.
    pub fn parse(buf: &[u8]) -> Option<Self> {
        let [t0, t1, p0, p1, l0, l1, unit, ..] = *buf else {
            return None;
        };
        Some(Self {
            transaction: u16::from_be_bytes([t0, t1]),
            protocol: u16::from_be_bytes([p0, p1]),
            length: u16::from_be_bytes([l0, l1]),
            unit,
        })
    }

    /// The length of the whole frame the header announces (header and PDU).
    pub const fn frame_len(&self) -> usize {
        6 + self.length as usize
    }

    /// The length of the PDU the header announces (`None` when the length field leaves no
    /// room for the unit id).
    pub const fn pdu_len(&self) -> Option<usize> {
        (self.length as usize).checked_sub(1)
    }

    /// Checks the header as a decoder does: protocol id 0, a length that holds a unit id, a
    /// function code and at most a 253-byte PDU.
    pub fn check(&self) -> Result<(), DecodeError> {
        if self.protocol != 0 {
            return Err(DecodeError::BadProtocolId {
                received: self.protocol,
            });
        }
        if !(2..=MAX_LENGTH_FIELD).contains(&self.length) {
            return Err(DecodeError::BadLength {
                expected: self.length.clamp(2, MAX_LENGTH_FIELD),
                received: self.length,
            });
        }
        Ok(())
    }
}

/// The checked header at the start of `buf`, which holds at least [`HEADER_LEN`] bytes.
fn parse_mbap(buf: &[u8]) -> Result<Mbap, DecodeError> {
    let mbap = Mbap::parse(buf).ok_or(DecodeError::BadLength {
        expected: 2,
        received: 0,
    })?;
    mbap.check()?;
    Ok(mbap)
}

/// The length of the whole frame starting at `buf`, once its header says so: lets a server
/// skip a frame it could not decode.
pub fn frame_len(buf: &[u8]) -> Option<usize> {
    let length = u16::from_be_bytes([*buf.get(4)?, *buf.get(5)?]);
    Some(6 + usize::from(length))
}

fn check_length(expected_pdu_len: usize, mbap: &Mbap) -> Result<(), DecodeError> {
    let expected = (expected_pdu_len + 1) as u16;
    if mbap.length == expected {
        Ok(())
    } else {
        Err(DecodeError::BadLength {
            expected,
            received: mbap.length,
        })
    }
}

/// Decodes a request as a server sees it. `shape` says which FC06 addresses carry four bytes.
pub fn decode_request(
    buf: &[u8],
    shape: &FrameShape<'_>,
) -> Result<Decoded<Frame<Request>>, DecodeError> {
    need!(buf, HEADER_LEN + 1);
    let mbap = parse_mbap(buf)?;
    let function = buf[HEADER_LEN];
    let pdu_len = match function {
        0x03 | 0x04 => READ_REQUEST_PDU_LEN,
        WRITE_SINGLE => {
            need!(buf, HEADER_LEN + 3);
            let address = u16::from_be_bytes([buf[HEADER_LEN + 1], buf[HEADER_LEN + 2]]);
            shape.write_width(address).write_pdu_len()
        }
        _ => return Err(DecodeError::UnsupportedFunction { function }),
    };
    check_length(pdu_len, &mbap)?;
    let len = HEADER_LEN + pdu_len;
    need!(buf, len);
    let pdu = &buf[HEADER_LEN..len];
    let width = shape.write_width(u16::from_be_bytes([pdu[1], pdu[2]]));
    Ok(Decoded::Frame {
        frame: Frame {
            header: Header {
                transaction: mbap.transaction,
                unit: mbap.unit,
            },
            pdu: Request::parse_pdu(pdu, width),
        },
        consumed: len,
    })
}

/// Decodes the reply to `request`, sent with `header`. An exception reply becomes
/// [`DecodeError::Exception`].
pub fn decode_response<'b>(
    buf: &'b [u8],
    header: Header,
    request: &Request,
    exception: ExceptionShape,
) -> Result<Decoded<Response<'b>>, DecodeError> {
    need!(buf, HEADER_LEN + 1);
    let mbap = parse_mbap(buf)?;
    if mbap.transaction != header.transaction {
        return Err(DecodeError::UnexpectedTransaction {
            expected: header.transaction,
            received: mbap.transaction,
        });
    }
    if mbap.unit != header.unit {
        return Err(DecodeError::UnexpectedSlave {
            expected: header.unit,
            received: mbap.unit,
        });
    }
    let (kind, pdu_len) = match reply_pdu_len(&buf[HEADER_LEN..], request, exception)? {
        ReplyLength::Known(kind, pdu_len) => (kind, pdu_len),
        ReplyLength::NeedMore(more) => return Ok(Decoded::NeedMore { at_least: more }),
    };
    check_length(pdu_len, &mbap)?;
    let len = HEADER_LEN + pdu_len;
    need!(buf, len);
    let response = parse_reply(&buf[HEADER_LEN..len], kind, request, exception)?;
    Ok(Decoded::Frame {
        frame: response,
        consumed: len,
    })
}
