//! A Modbus TCP gateway onto an RTU line, as mbusd is, inside the bus: other masters (a PLC,
//! SCADA, a configuration tool) reach the line's devices while the bus keeps its schedule.
//!
//! Each connection has one request in flight; requests of all connections wait in one queue
//! that the line takes from between its own polls, so clients are served in turn and each
//! request waits for at most one poll. A reply goes back under its request's MBAP header; a
//! device that does not answer in time gives exception 0x0B, a line that cannot be used 0x0A,
//! a function whose reply cannot be framed on RTU 0x01. Writes pass only where the bus file
//! allows them, and a write to one of the bus's devices is checked against its spec first
//! (0x02 for an address that holds nothing writable, 0x03 for a value it refuses): nothing
//! invalid reaches the line.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use optobus_codec::passthrough::{encode_tcp_reply, MAX_PDU_LEN};
use optobus_codec::tcp::{Header, Mbap, HEADER_LEN};
use optobus_codec::EXCEPTION_BIT;
use optobus_device::{DeviceInfo, Table};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{mpsc, oneshot, Semaphore};

use crate::file::GatewayConfig;

/// Illegal function: not passed (unframable, or a write the bus file does not allow).
pub(crate) const ILLEGAL_FUNCTION: u8 = 0x01;
/// Illegal data address: a write to an address that holds nothing writable.
pub(crate) const ILLEGAL_ADDRESS: u8 = 0x02;
/// Illegal data value: a write of a value the register refuses.
pub(crate) const ILLEGAL_VALUE: u8 = 0x03;
/// Gateway path unavailable: the line cannot be used.
pub(crate) const PATH_UNAVAILABLE: u8 = 0x0A;
/// Gateway target device failed to respond.
pub(crate) const TARGET_FAILED: u8 = 0x0B;

/// A client's request, waiting for the line.
#[derive(Debug)]
pub(crate) struct GatewayRequest {
    pub(crate) unit: u8,
    pub(crate) pdu: Vec<u8>,
    /// The reply PDU, or `None` for a broadcast (nothing is sent back).
    pub(crate) reply: oneshot::Sender<Option<Vec<u8>>>,
}

/// The exception reply PDU to a request of `function`.
pub(crate) fn exception(function: u8, code: u8) -> Vec<u8> {
    vec![function | EXCEPTION_BIT, code]
}

/// Function codes that change a device.
pub(crate) fn is_write(function: u8) -> bool {
    matches!(function, 0x05 | 0x06 | 0x0F | 0x10 | 0x15 | 0x16 | 0x17)
}

/// Checks a write PDU to `device` against its spec: the exception code to refuse it with, if
/// it must be refused.
pub(crate) fn refuse_write(device: &DeviceInfo, pdu: &[u8]) -> Option<u8> {
    let function = pdu[0];
    if !device.functions.contains(&function) {
        return Some(ILLEGAL_FUNCTION);
    }
    let word = |at: usize| {
        pdu.get(at..at + 2)
            .map(|b| u16::from_be_bytes([b[0], b[1]]))
    };
    let words = |data: &[u8]| -> Vec<u16> {
        data.chunks(2)
            .map(|c| u16::from_be_bytes([c[0], c[1]]))
            .collect()
    };
    let written = match function {
        0x06 => word(1).zip(pdu.get(3..)).and_then(|(address, data)| {
            (!data.is_empty() && data.len() % 2 == 0).then(|| (address, words(data)))
        }),
        0x10 => match (word(1), word(3), pdu.get(5), pdu.get(6..)) {
            (Some(address), Some(count), Some(&bytes), Some(data))
                if data.len() == 2 * usize::from(count) && usize::from(bytes) == data.len() =>
            {
                Some((address, words(data)))
            }
            _ => None,
        },
        // Bits, files and masks: no register of our specs is written that way.
        _ => return Some(ILLEGAL_FUNCTION),
    };
    let Some((address, words)) = written else {
        return Some(ILLEGAL_VALUE);
    };
    check_words(device, address, &words)
}

/// Every register the words cover must be writable and written whole, with a value its spec
/// accepts.
fn check_words(device: &DeviceInfo, address: u16, words: &[u16]) -> Option<u8> {
    let mut at = Some(address);
    let mut offset = 0usize;
    while offset < words.len() {
        let Some((register, 0)) = at.and_then(|at| device.register_at(Table::Holding, at)) else {
            return Some(ILLEGAL_ADDRESS);
        };
        if !register.access.writable() {
            return Some(ILLEGAL_ADDRESS);
        }
        let width = usize::from(register.words);
        let Some(own) = words.get(offset..offset + width) else {
            return Some(ILLEGAL_ADDRESS);
        };
        if register.check(register.raw(own)).is_err() {
            return Some(ILLEGAL_VALUE);
        }
        offset += width;
        at = at.and_then(|a| a.checked_add(register.span(device.addressing)));
    }
    None
}

/// What a gateway has done.
#[derive(Debug, Default)]
pub(crate) struct GatewayCounters {
    /// Connections closed at once because the client limit was reached.
    pub(crate) refused: AtomicU64,
    /// Requests passed to the line.
    pub(crate) requests: AtomicU64,
}

/// Accepts clients on `listener` until the task is aborted.
pub(crate) async fn serve(
    listener: TcpListener,
    config: GatewayConfig,
    queue: mpsc::Sender<GatewayRequest>,
    counters: Arc<GatewayCounters>,
) {
    let permits = Arc::new(Semaphore::new(config.clients));
    loop {
        let Ok((socket, _peer)) = listener.accept().await else {
            // Out of file descriptors or similar: try again shortly rather than spin.
            tokio::time::sleep(std::time::Duration::from_millis(100)).await;
            continue;
        };
        match Arc::clone(&permits).try_acquire_owned() {
            Ok(permit) => {
                let queue = queue.clone();
                let counters = Arc::clone(&counters);
                tokio::spawn(async move {
                    connection(socket, queue, &counters).await;
                    drop(permit);
                });
            }
            Err(_) => {
                counters.refused.fetch_add(1, Ordering::Relaxed);
                drop(socket);
            }
        }
    }
}

/// Serves one client, one request at a time, until it closes or sends what is not Modbus TCP.
async fn connection(
    mut socket: TcpStream,
    queue: mpsc::Sender<GatewayRequest>,
    counters: &GatewayCounters,
) {
    let _ = socket.set_nodelay(true);
    let mut header = [0u8; HEADER_LEN];
    let mut pdu = [0u8; MAX_PDU_LEN];
    let mut out = [0u8; HEADER_LEN + MAX_PDU_LEN];
    loop {
        if socket.read_exact(&mut header).await.is_err() {
            return;
        }
        let Some(mbap) = Mbap::parse(&header) else {
            return;
        };
        let Some(len) = mbap.pdu_len().filter(|_| mbap.check().is_ok()) else {
            // Not Modbus TCP: nothing else on this connection can be trusted to be framed.
            return;
        };
        if socket.read_exact(&mut pdu[..len]).await.is_err() {
            return;
        }
        let (reply, answer) = oneshot::channel();
        let request = GatewayRequest {
            unit: mbap.unit,
            pdu: pdu[..len].to_vec(),
            reply,
        };
        counters.requests.fetch_add(1, Ordering::Relaxed);
        if queue.send(request).await.is_err() {
            return;
        }
        let Ok(reply) = answer.await else { return };
        let Some(reply) = reply else { continue };
        let header = Header {
            transaction: mbap.transaction,
            unit: mbap.unit,
        };
        let Ok(n) = encode_tcp_reply(&mut out, header, &reply) else {
            return;
        };
        if socket.write_all(&out[..n]).await.is_err() {
            return;
        }
    }
}
