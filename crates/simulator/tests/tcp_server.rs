//! The simulator's Modbus TCP server reads each request with the codec's server framing
//! (issue 31, point 5): a request malformed for its function is answered 03 under its own
//! MBAP header and the connection goes on, as a device's would; real frames both ways.

use std::time::Duration;

use optobus_codec::{passthrough, tcp};
use optobus_p_series::DEVICE;
use optobus_simulator::Simulator;
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};
use tokio::time::timeout;

/// Sends one request PDU behind its MBAP header and reads the whole reply frame, both framed
/// by the codec.
async fn ask(stream: &mut DuplexStream, transaction: u16, unit: u8, pdu: &[u8]) -> Vec<u8> {
    let mut frame = [0u8; tcp::MAX_FRAME_LEN];
    let header = tcp::Header { transaction, unit };
    // An MBAP frame is the same both ways: the header, the unit id and the PDU.
    let len = passthrough::encode_tcp_reply(&mut frame, header, pdu).unwrap();
    stream.write_all(&frame[..len]).await.unwrap();
    let mut reply = vec![0u8; tcp::HEADER_LEN];
    let read = stream.read_exact(&mut reply);
    timeout(Duration::from_secs(5), read)
        .await
        .expect("a reply within 5 s")
        .expect("the connection stays open");
    let whole = tcp::Mbap::parse(&reply).unwrap().frame_len();
    reply.resize(whole, 0);
    stream
        .read_exact(&mut reply[tcp::HEADER_LEN..])
        .await
        .unwrap();
    reply
}

#[tokio::test]
async fn a_malformed_tcp_request_is_answered_03_and_the_connection_goes_on() {
    let sim = Simulator::new(&DEVICE);
    let (mut stream, server) = tokio::io::duplex(4096);
    let served = sim.clone();
    tokio::spawn(async move { served.serve_tcp_stream(server).await });
    let unit = sim.address();
    // A read with a sixth byte, a write without its data, a read of 0 registers.
    for (transaction, pdu) in [
        (1u16, &[0x04, 0x00, 0x00, 0x00, 0x01, 0x00][..]),
        (2, &[0x06, 0x00, 0x00][..]),
        (3, &[0x03, 0x00, 0x00, 0x00, 0x00][..]),
    ] {
        let [t0, t1] = transaction.to_be_bytes();
        let reply = ask(&mut stream, transaction, unit, pdu).await;
        assert_eq!(reply, [t0, t1, 0, 0, 0, 3, unit, pdu[0] | 0x80, 0x03]);
    }
    // FC16, which the device does not take: its own answer, 01, as before.
    let reply = ask(&mut stream, 4, unit, &[0x10, 0, 0, 0, 1, 2, 0, 1]).await;
    assert_eq!(reply, [0, 4, 0, 0, 0, 3, unit, 0x90, 0x01]);
    // And the connection goes on: a read is answered with its words.
    let reply = ask(&mut stream, 5, unit, &[0x03, 0x00, 0x00, 0x00, 0x02]).await;
    assert_eq!(&reply[..9], &[0, 5, 0, 0, 0, 7, unit, 0x03, 4]);
}
