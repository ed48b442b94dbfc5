//! Requests and replies on an in-memory RTU line to the simulator, as the simulator suites
//! write them: frames from requests, and a client end that collects replies.

use std::time::Duration;

use optobus_codec::crc::crc16;
use optobus_codec::value::{join_i32, WordOrder};
use optobus_codec::{rtu, Decoded, ExceptionShape, ReadFunction, Request, Response, WriteValue};
use optobus_simulator::Simulator;
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};
use tokio::time::timeout;

/// Bytes written as spaced hex pairs (`01 03 00 00`).
pub fn hex(text: &str) -> Vec<u8> {
    text.split_whitespace()
        .map(|pair| u8::from_str_radix(pair, 16).unwrap())
        .collect()
}

/// `body` with its CRC appended (for frames the codec refuses to encode).
pub fn with_crc(body: &[u8]) -> Vec<u8> {
    let mut frame = body.to_vec();
    frame.extend_from_slice(&crc16(body).to_le_bytes());
    frame
}

/// The RTU frame of `request` to `slave`.
pub fn rtu_frame(slave: u8, request: &Request) -> Vec<u8> {
    let mut out = [0; rtu::MAX_FRAME_LEN];
    let len = rtu::encode_request(&mut out, slave, request).unwrap();
    out[..len].to_vec()
}

/// An FC03/FC04 read request.
pub fn read(function: ReadFunction, address: u16, count: u16) -> Request {
    Request::Read {
        function,
        address,
        count,
    }
}

/// An FC03 read of holding registers.
pub fn holding(address: u16, count: u16) -> Request {
    read(ReadFunction::Holding, address, count)
}

/// An FC04 read of input registers.
pub fn input(address: u16, count: u16) -> Request {
    read(ReadFunction::Input, address, count)
}

/// An FC06 write of one word.
pub fn write(address: u16, value: u16) -> Request {
    Request::Write {
        address,
        value: WriteValue::Word(value),
    }
}

/// The client's end of an in-memory RTU line.
pub struct Line {
    /// The client's end of the line, for bytes that are no frame.
    pub stream: DuplexStream,
    /// How the device frames its exception replies.
    pub shape: ExceptionShape,
}

impl Line {
    /// A new line to `sim`.
    pub fn new(sim: &Simulator) -> Self {
        let (stream, _server) = sim.duplex();
        Self {
            stream,
            shape: sim.device().frame_shape.exception,
        }
    }

    /// Sends `bytes` and collects what comes back until 30 ms of silence.
    pub async fn send(&mut self, bytes: &[u8]) -> Vec<u8> {
        self.stream.write_all(bytes).await.unwrap();
        let mut reply = Vec::new();
        let mut chunk = [0; 512];
        while let Ok(read) = timeout(Duration::from_millis(30), self.stream.read(&mut chunk)).await
        {
            let read = read.unwrap();
            assert!(read > 0, "the server closed the line");
            reply.extend_from_slice(&chunk[..read]);
        }
        reply
    }

    /// Sends `request` to `slave` as an RTU frame; the reply bytes.
    pub async fn ask(&mut self, slave: u8, request: &Request) -> Vec<u8> {
        self.send(&rtu_frame(slave, request)).await
    }

    /// The words a read returns (panics on anything else).
    pub async fn words(&mut self, slave: u8, request: &Request) -> Vec<u16> {
        let reply = self.ask(slave, request).await;
        match rtu::decode_response(&reply, slave, request, self.shape) {
            Ok(Decoded::Frame {
                frame: Response::Read { words, .. },
                consumed,
            }) if consumed == reply.len() => words.iter().collect(),
            other => panic!("{request:?} -> {reply:02X?}: {other:?}"),
        }
    }

    /// The exception code a request earns (panics on anything else).
    pub async fn exception(&mut self, slave: u8, request: &Request) -> u16 {
        let reply = self.ask(slave, request).await;
        match rtu::decode_response(&reply, slave, request, self.shape) {
            Err(optobus_codec::DecodeError::Exception { code, .. }) => code.0,
            other => panic!("{request:?} -> {reply:02X?}: expected an exception, {other:?}"),
        }
    }
}

/// The i32 of two words at `at`, high word first.
pub fn i32_at(words: &[u16], at: usize) -> i32 {
    join_i32([words[at], words[at + 1]], WordOrder::HighFirst)
}
