//! Pure Modbus encoding for optobus: CRC-16/MODBUS, RTU and TCP frames in both directions,
//! and register value codecs.
//!
//! No I/O, no async, no allocator: the crate is `no_std`, so firmware talking to these
//! sensors from a microcontroller can use it as well as the async drivers.
//!
//! Device framing quirks are data: a [`FrameShape`] says how exceptions are framed and which
//! FC06 writes carry four data bytes, and the same decoder serves every device.
#![no_std]
#![forbid(unsafe_code)]

pub mod crc;
mod fixed;
mod hex;
mod line;
pub mod passthrough;
mod pdu;
pub mod rtu;
pub mod server;
pub mod tcp;
pub mod value;

pub use hex::Hex;
pub use line::{LineFormat, LineFormatError, Parity};
pub use pdu::{
    exception_function, function_name, DecodeError, Decoded, EncodeError, ExceptionCode,
    ExceptionShape, FrameShape, PayloadWidth, ReadFunction, Request, Response, Words, WriteValue,
    BROADCAST, EXCEPTION_BIT, MAX_READ_WORDS, MAX_SLAVE, READ_REQUEST_PDU_LEN, WRITE_SINGLE,
};
