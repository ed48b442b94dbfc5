//! What the gateway's tests share: a bus started from text with the models they name, a
//! client of its gateway, and Modbus TCP requests and replies as real MBAP frames.

use std::path::Path;
use std::time::Duration;

use optobus_bus::{Bus, BusFile, Catalogue, Event, Running};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// `text` read as a bus file naming the P series, the CCS and the LC-RS, and started.
pub fn start(text: &str) -> Running {
    let catalogue = Catalogue::new([
        &optobus_p_series::DEVICE,
        &optobus_ccs::DEVICE,
        &optobus_lc_rs::DEVICE,
    ]);
    let file = BusFile::parse("bus.yaml", text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    Bus::new(file).start().expect("the gateway listens")
}

/// A new client of the gateway of line `rs485`.
pub async fn connect(running: &Running) -> TcpStream {
    TcpStream::connect(running.gateway_address("rs485").unwrap())
        .await
        .unwrap()
}

/// Sends one request and reads its whole reply frame.
pub async fn ask(stream: &mut TcpStream, transaction: u16, unit: u8, pdu: &[u8]) -> Vec<u8> {
    send(stream, transaction, unit, pdu).await;
    let mut header = [0u8; 7];
    tokio::time::timeout(Duration::from_secs(5), stream.read_exact(&mut header))
        .await
        .expect("a reply within 5 s")
        .unwrap();
    let len = usize::from(u16::from_be_bytes([header[4], header[5]])) - 1;
    let mut reply = header.to_vec();
    reply.resize(7 + len, 0);
    stream.read_exact(&mut reply[7..]).await.unwrap();
    reply
}

/// Sends one request without waiting for its reply.
pub async fn send(stream: &mut TcpStream, transaction: u16, unit: u8, pdu: &[u8]) {
    let mut frame = transaction.to_be_bytes().to_vec();
    frame.extend_from_slice(&[0, 0]);
    frame.extend_from_slice(&(pdu.len() as u16 + 1).to_be_bytes());
    frame.push(unit);
    frame.extend_from_slice(pdu);
    stream.write_all(&frame).await.unwrap();
}

/// A line of a P series head (slave 1) and a CCS (slave 2) polling their measurements, behind
/// a gateway of two clients that does not write.
pub const BUS: &str = "
lines:
  - name: rs485
    simulated: true
    baud: 115200
    any_format: true
    gateway: { listen: 127.0.0.1:0, clients: 2 }
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: measurements }] }
  - { name: confocal, model: ccs, slave: 2, timeout: 50ms, poll: [{ read: measurements }] }
";

/// [`BUS`] with a gateway that writes, the head's light power writable, nothing polled.
pub fn writes_without_polls() -> String {
    BUS.replace("clients: 2", "clients: 2, writes: true")
        .replace(", poll: [{ read: measurements }]", "")
        .replace("slave: 1,", "slave: 1, writable: [light_power],")
}

/// The line's transactions so far, from its next statistics event.
pub async fn line_transactions(running: &Running) -> u64 {
    let mut events = running.subscribe();
    loop {
        if let Event::Line(stats) = events.recv().await.unwrap() {
            return stats.transactions;
        }
    }
}

/// The light power read of the P series at slave 1, and its reply when it holds 42.5 %.
pub fn light_power_read() -> ([u8; 5], [u8; 4]) {
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let [high, low] = power.address.to_be_bytes();
    ([0x03, high, low, 0x00, 0x01], [0x03, 0x02, 0x01, 0xA9])
}
