//! The gateway's limits and timeouts: a client limit where the one idle the longest makes room,
//! idle and stalled clients closed, malformed requests answered without the line, a full
//! queue answered busy. Its answers are in `gateway.rs`.

mod common;

use std::time::Duration;

use common::gateway::{
    ask, connect, light_power_read, line_transactions, send, start, writes_without_polls, BUS,
};
use optobus_bus::{GatewayCounts, Running};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// Whether the gateway closed `stream` (within a generous deadline).
async fn closed(stream: &mut TcpStream) -> bool {
    let mut byte = [0u8; 1];
    let read = tokio::time::timeout(Duration::from_secs(30), stream.read(&mut byte)).await;
    matches!(read, Ok(Ok(0)) | Ok(Err(_)))
}

/// The gateway's counts once `done` holds for them (within a generous deadline).
async fn counts_when(running: &Running, done: impl Fn(&GatewayCounts) -> bool) -> GatewayCounts {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    loop {
        let counts = running.gateway_counts("rs485").unwrap();
        if done(&counts) || tokio::time::Instant::now() > deadline {
            return counts;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
}

#[tokio::test]
async fn eight_silent_gateway_clients_lock_out_no_new_one() {
    // The default client limit (8).
    let running = start(
        "
lines:
  - { name: rs485, simulated: true, baud: 115200, any_format: true, gateway: 127.0.0.1:0 }
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: measurements }] }
",
    );
    running
        .simulator("head")
        .unwrap()
        .set("light_power", &[425])
        .unwrap();
    let address = running.gateway_address("rs485").unwrap();
    let mut silent = Vec::new();
    for _ in 0..8 {
        silent.push(TcpStream::connect(address).await.unwrap());
    }
    // A ninth client is served: the client idle the longest (the first) made room; and a
    // tenth, for which the second silent one makes room.
    let (read, value) = light_power_read();
    // Kept connected, so that each newcomer finds the limit reached.
    let mut newcomers = Vec::new();
    for (evicted, transaction) in [(1u64, 9u8), (2, 10)] {
        let mut newcomer = TcpStream::connect(address).await.unwrap();
        let reply = ask(&mut newcomer, u16::from(transaction), 1, &read).await;
        newcomers.push(newcomer);
        assert_eq!(
            reply,
            [&[0, transaction, 0, 0, 0, 5, 1][..], &value].concat()
        );
        let oldest = &mut silent[evicted as usize - 1];
        assert!(closed(oldest).await, "silent client {evicted} is closed");
        let counts = running.gateway_counts("rs485").unwrap();
        assert_eq!((counts.evicted, counts.refused), (evicted, 0), "{counts:?}");
    }
}

#[tokio::test]
async fn an_idle_gateway_client_is_closed_after_its_idle_timeout() {
    let running = start(&BUS.replace("clients: 2", "clients: 2, idle: 2s"));
    let address = running.gateway_address("rs485").unwrap();
    let mut silent = TcpStream::connect(address).await.unwrap();
    let mut asked_once = TcpStream::connect(address).await.unwrap();
    let reply = ask(&mut asked_once, 1, 1, &[0x04, 0x00, 0x00, 0x00, 0x01]).await;
    assert_eq!(&reply[6..9], &[1, 0x04, 0x02]);
    // Half a request is no request: the idle time runs on.
    asked_once.write_all(&[0, 2, 0, 0]).await.unwrap();
    assert!(closed(&mut silent).await, "the silent client is closed");
    assert!(
        closed(&mut asked_once).await,
        "the client idle since its reply is closed"
    );
    let counts = counts_when(&running, |c| c.idle_closed == 2).await;
    assert_eq!(
        counts,
        GatewayCounts {
            requests: 1,
            idle_closed: 2,
            ..GatewayCounts::default()
        }
    );
}

#[tokio::test]
async fn malformed_gateway_requests_are_answered_without_the_line() {
    let no_polls = writes_without_polls();
    let running = start(&no_polls);
    let mut client = connect(&running).await;
    // (unit, request PDU, reply PDU)
    let refused: &[(u8, &[u8], &[u8])] = &[
        // The 2-byte FC03 of issue 28, and an FC03 a byte too long.
        (1, &[0x03, 0x00], &[0x83, 0x03]),
        (1, &[0x03, 0x00, 0x00, 0x00, 0x01, 0x00], &[0x83, 0x03]),
        // Reads of 0 and 126 registers, of 2001 coils.
        (1, &[0x03, 0x00, 0x00, 0x00, 0x00], &[0x83, 0x03]),
        (2, &[0x04, 0x00, 0x00, 0x00, 0x7E], &[0x84, 0x03]),
        (1, &[0x01, 0x00, 0x00, 0x07, 0xD1], &[0x81, 0x03]),
        // A register write of 1 data byte; a coil written 1234; an FC16 a data byte short.
        (1, &[0x06, 0x00, 0x01, 0x00], &[0x86, 0x03]),
        (1, &[0x05, 0x00, 0x01, 0x12, 0x34], &[0x85, 0x03]),
        (
            1,
            &[0x10, 0x00, 0x10, 0x00, 0x02, 0x04, 0x00, 0x0A, 0x01],
            &[0x90, 0x03],
        ),
        // A mask write and a FIFO read of the wrong length; an exception status with data.
        (1, &[0x16, 0x00, 0x04, 0x00, 0xF2, 0x00], &[0x96, 0x03]),
        (1, &[0x18, 0x04, 0xDE, 0x00, 0x00], &[0x98, 0x03]),
        (1, &[0x07, 0x00], &[0x87, 0x03]),
        // Diagnostics: their reply's length cannot be told on RTU.
        (1, &[0x08, 0x00, 0x00, 0x12, 0x34], &[0x88, 0x01]),
        // A read broadcast: nobody would answer it.
        (0, &[0x03, 0x00, 0x00, 0x00, 0x01], &[0x83, 0x01]),
        // A unit id RTU reserves.
        (250, &[0x03, 0x00, 0x00, 0x00, 0x01], &[0x83, 0x0A]),
    ];
    for (transaction, &(unit, request, expected)) in (1u16..).zip(refused) {
        let reply = ask(&mut client, transaction, unit, request).await;
        let header = [&transaction.to_be_bytes()[..], &[0, 0, 0, 3, unit]].concat();
        assert_eq!(reply, [&header[..], expected].concat(), "{request:02X?}");
    }
    // The same connection goes on: a good read is passed, and answered.
    running
        .simulator("head")
        .unwrap()
        .set("light_power", &[425])
        .unwrap();
    let (read, value) = light_power_read();
    let reply = ask(&mut client, 100, 1, &read).await;
    assert_eq!(reply, [&[0, 100, 0, 0, 0, 5, 1][..], &value].concat());
    // Only that read reached the line: its frames are the device's only ones.
    assert_eq!(line_transactions(&running).await, 1);
    let frames = running.handle().frames("head").unwrap();
    assert_eq!(frames.len(), 2, "{frames:?}");
    assert_eq!(&frames[0].bytes[1..6], &read);
    assert!(running.handle().frames("confocal").unwrap().is_empty());
    let counts = running.gateway_counts("rs485").unwrap();
    assert_eq!(
        (counts.malformed, counts.not_carried, counts.requests),
        (11, 3, 1),
        "{counts:?}"
    );
}

/// A line whose confocal sensor (slave 2) is silent and waited for an hour: a request to it
/// holds the line, deterministically.
const HELD: &str = "
lines:
  - name: rs485
    simulated: true
    baud: 115200
    any_format: true
    gateway: { listen: 127.0.0.1:0, clients: 3, queue: 1 }
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms }
  - { name: confocal, model: ccs, slave: 2, timeout: 1h, retries: 0 }
";

#[tokio::test]
async fn a_full_gateway_queue_answers_busy() {
    let running = start(HELD);
    running.simulator("confocal").unwrap().set_silent(true);
    let address = running.gateway_address("rs485").unwrap();
    let read = [0x04, 0x00, 0x00, 0x00, 0x01];
    // The first request holds the line once its frame is out.
    let mut first = TcpStream::connect(address).await.unwrap();
    send(&mut first, 1, 2, &read).await;
    let deadline = tokio::time::Instant::now() + Duration::from_secs(30);
    while running.handle().frames("confocal").unwrap().is_empty() {
        assert!(
            tokio::time::Instant::now() < deadline,
            "the line took the request"
        );
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    // The second waits in the queue (of 1) ...
    let mut second = TcpStream::connect(address).await.unwrap();
    send(&mut second, 1, 1, &read).await;
    let counts = counts_when(&running, |c| c.requests == 2).await;
    assert_eq!(counts.requests, 2, "{counts:?}");
    // ... so the third is answered busy at once, and its connection goes on.
    let mut third = TcpStream::connect(address).await.unwrap();
    let reply = ask(&mut third, 7, 1, &read).await;
    assert_eq!(reply, [0, 7, 0, 0, 0, 3, 1, 0x84, 0x06]);
    let reply = ask(&mut third, 8, 1, &[0x03, 0x00]).await;
    assert_eq!(reply, [0, 8, 0, 0, 0, 3, 1, 0x83, 0x03]);
    let counts = running.gateway_counts("rs485").unwrap();
    assert_eq!((counts.busy, counts.requests), (1, 2), "{counts:?}");
}

#[tokio::test]
async fn a_client_beyond_the_limit_is_refused_only_when_every_client_has_a_request_in_flight() {
    let running = start(&HELD.replace("clients: 3, queue: 1", "clients: 2"));
    running.simulator("confocal").unwrap().set_silent(true);
    let address = running.gateway_address("rs485").unwrap();
    let read = [0x04, 0x00, 0x00, 0x00, 0x01];
    let mut first = TcpStream::connect(address).await.unwrap();
    let mut second = TcpStream::connect(address).await.unwrap();
    send(&mut first, 1, 2, &read).await;
    send(&mut second, 1, 2, &read).await;
    let counts = counts_when(&running, |c| c.requests == 2).await;
    assert_eq!(counts.requests, 2, "{counts:?}");
    let mut third = TcpStream::connect(address).await.unwrap();
    assert!(closed(&mut third).await, "the third client is refused");
    let counts = running.gateway_counts("rs485").unwrap();
    assert_eq!((counts.refused, counts.evicted), (1, 0), "{counts:?}");
}

#[tokio::test]
async fn the_client_idle_the_longest_makes_room_and_a_broken_client_harms_no_other() {
    let running = start(BUS);
    let address = running.gateway_address("rs485").unwrap();
    let mut first = TcpStream::connect(address).await.unwrap();
    let mut second = TcpStream::connect(address).await.unwrap();
    ask(&mut first, 1, 1, &[0x04, 0x00, 0x00, 0x00, 0x01]).await;
    ask(&mut second, 1, 1, &[0x04, 0x00, 0x00, 0x00, 0x01]).await;
    // At the limit of 2, a third client closes the one idle the longest: the first.
    let mut third = TcpStream::connect(address).await.unwrap();
    let reply = ask(&mut third, 1, 2, &[0x04, 0x00, 0x00, 0x00, 0x01]).await;
    assert_eq!(&reply[6..9], &[2, 0x04, 0x02]);
    assert!(closed(&mut first).await, "the first client is closed");
    assert_eq!(
        running.gateway_counts("rs485"),
        Some(GatewayCounts {
            requests: 3,
            evicted: 1,
            ..GatewayCounts::default()
        })
    );
    // Protocol id 1 is not Modbus: that connection is closed, the other goes on.
    second
        .write_all(&[0, 1, 0, 1, 0, 6, 1, 4, 0, 0, 0, 1])
        .await
        .unwrap();
    assert!(
        closed(&mut second).await,
        "the client that is not Modbus is closed"
    );
    let reply = ask(&mut third, 2, 2, &[0x04, 0x00, 0x00, 0x00, 0x01]).await;
    assert_eq!(&reply[6..9], &[2, 0x04, 0x02]);
    let counts = counts_when(&running, |c| c.not_modbus == 1).await;
    assert_eq!(counts.not_modbus, 1, "{counts:?}");
}

#[tokio::test]
async fn a_client_that_takes_no_replies_is_closed_after_its_idle_timeout() {
    let running = start(&BUS.replace("clients: 2", "clients: 2, idle: 1s"));
    let address = running.gateway_address("rs485").unwrap();
    // A small receive window, and requests the gateway answers itself (a 2-byte FC03), sent
    // without end and never read: the gateway's replies fill the socket until they block.
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let stream = socket.connect(address).await.unwrap();
    let (mut reader, mut writer) = stream.into_split();
    let flood = tokio::spawn(async move {
        let request = [0, 1, 0, 0, 0, 3, 1, 0x03, 0x00].repeat(1000);
        while writer.write_all(&request).await.is_ok() {}
    });
    // The first reply is a whole exception reply; no other is read.
    let mut first = [0u8; 9];
    reader.read_exact(&mut first).await.unwrap();
    assert_eq!(first, [0, 1, 0, 0, 0, 3, 1, 0x83, 0x03]);
    let counts = counts_when(&running, |c| c.stalled == 1).await;
    assert_eq!(counts.stalled, 1, "{counts:?}");
    assert!(counts.malformed > 0, "{counts:?}");
    assert_eq!(counts.requests, 0, "{counts:?}");
    // The flood ends once the gateway has closed the connection.
    tokio::time::timeout(Duration::from_secs(30), flood)
        .await
        .expect("the writes fail once the connection is closed")
        .unwrap();
}
