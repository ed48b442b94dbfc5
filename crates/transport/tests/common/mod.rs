//! What the RTU client's tests share: the device's side of an in-memory duplex, which decodes
//! the client's requests with the codec, and the words a device answers reads with.

#![allow(dead_code, unreachable_pub)]

use optobus_codec::rtu::{self, Frame};
use optobus_codec::{Decoded, ExceptionShape, FrameShape, Request};
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};

/// The device's end of the duplex: the client's requests as they decode, and the replies sent
/// back.
pub struct DeviceSide {
    stream: DuplexStream,
    received: Vec<u8>,
    four_byte_writes: Vec<u16>,
}

impl DeviceSide {
    /// The device's end `stream`, whose registers at `four_byte_writes` take FC06 writes of
    /// four bytes.
    pub fn new(stream: DuplexStream, four_byte_writes: Vec<u16>) -> Self {
        Self {
            stream,
            received: Vec::new(),
            four_byte_writes,
        }
    }

    /// The next whole request and how many bytes it took on the line; `None` once the
    /// client's end is closed.
    pub async fn next_request(&mut self) -> Option<(Frame<Request>, usize)> {
        let mut chunk = [0u8; 256];
        loop {
            let shape = FrameShape {
                exception: ExceptionShape::Standard,
                four_byte_writes: &self.four_byte_writes,
            };
            if let Ok(Decoded::Frame { frame, consumed }) =
                rtu::decode_request(&self.received, &shape)
            {
                self.received.drain(..consumed);
                return Some((frame, consumed));
            }
            match self.stream.read(&mut chunk).await {
                Ok(0) | Err(_) => return None,
                Ok(n) => self.received.extend_from_slice(&chunk[..n]),
            }
        }
    }

    /// Sends `bytes` to the client; whether its end is still open.
    pub async fn send(&mut self, bytes: &[u8]) -> bool {
        self.stream.write_all(bytes).await.is_ok()
    }
}

/// The data of a read of `count` registers from `address`: each word `address + i`, as
/// the device sends it.
pub fn counting_words(address: u16, count: u16) -> Vec<u8> {
    (0..count)
        .flat_map(|i| address.wrapping_add(i).to_be_bytes())
        .collect()
}
