//! The gateway: Modbus TCP clients reach the line's devices between the bus's polls, with
//! real MBAP frames both ways.

use std::path::Path;
use std::time::Duration;

use std::sync::Arc;

use optobus_bus::{
    Bus, BusFile, Catalogue, Event, GatewayCounts, Running, Source, Writer, Written,
};
use optobus_device::Table;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

fn start(text: &str) -> Running {
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
async fn connect(running: &Running) -> TcpStream {
    TcpStream::connect(running.gateway_address("rs485").unwrap())
        .await
        .unwrap()
}

/// Sends one request and reads its whole reply frame.
async fn ask(stream: &mut TcpStream, transaction: u16, unit: u8, pdu: &[u8]) -> Vec<u8> {
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

const BUS: &str = "
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

#[tokio::test]
async fn a_client_reads_the_devices_through_the_gateway_while_the_bus_polls() {
    let running = start(BUS);
    let head = running.simulator("head").unwrap();
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    head.set("light_power", &[425]).unwrap();
    let mut client = connect(&running).await;
    let [high, low] = power.address.to_be_bytes();
    for transaction in 0..20u16 {
        let reply = ask(&mut client, transaction, 1, &[0x03, high, low, 0x00, 0x01]).await;
        // The request's MBAP header comes back with the device's reply PDU: 42.5 % is 425.
        assert_eq!(
            reply,
            [
                &transaction.to_be_bytes()[..],
                &[0, 0, 0, 5, 1, 0x03, 0x02, 0x01, 0xA9]
            ]
            .concat()
        );
    }
    assert_eq!(head.peek(Table::Holding, power.address), Some(vec![425]));
}

#[tokio::test]
async fn writes_are_refused_unless_the_file_allows_them_and_then_checked_against_the_spec() {
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let [high, low] = power.address.to_be_bytes();
    // Not allowed: exception 01, the device untouched.
    let running = start(BUS);
    let head = running.simulator("head").unwrap();
    let before = head.peek(Table::Holding, power.address);
    let mut client = connect(&running).await;
    let reply = ask(&mut client, 7, 1, &[0x06, high, low, 0x00, 0x64]).await;
    assert_eq!(&reply[7..], &[0x86, 0x01]);
    assert_eq!(head.peek(Table::Holding, power.address), before);
    drop(running);

    let no_polls = BUS
        .replace("clients: 2", "clients: 2, writes: true")
        .replace(", poll: [{ read: measurements }]", "")
        .replace("slave: 1,", "slave: 1, writable: [light_power],");
    let running = start(&no_polls);
    let head = running.simulator("head").unwrap();
    let mut client = connect(&running).await;
    // 100.1 % is beyond the light power's range: exception 03, and it never reached the line.
    let before = head.peek(Table::Holding, power.address);
    let reply = ask(&mut client, 8, 1, &[0x06, high, low, 0x03, 0xE9]).await;
    assert_eq!(&reply[7..], &[0x86, 0x03]);
    assert_eq!(head.peek(Table::Holding, power.address), before);
    // 10.0 % is written, and echoed.
    let reply = ask(&mut client, 9, 1, &[0x06, high, low, 0x00, 0x64]).await;
    assert_eq!(&reply[7..], &[0x06, high, low, 0x00, 0x64]);
    assert_eq!(head.peek(Table::Holding, power.address), Some(vec![100]));
    // An address that holds no register: exception 02.
    let reply = ask(&mut client, 10, 1, &[0x06, 0x7F, 0xF0, 0x00, 0x01]).await;
    assert_eq!(&reply[7..], &[0x86, 0x02]);
    // Of the three writes only the valid one went onto the line (the bus polls nothing).
    let mut events = running.subscribe();
    loop {
        if let optobus_bus::Event::Line(stats) = events.recv().await.unwrap() {
            assert_eq!(stats.transactions, 1, "only the valid write was sent");
            break;
        }
    }
}

#[tokio::test]
async fn a_silent_device_gives_exception_0b_and_an_unframable_function_01() {
    let running = start(BUS);
    running.simulator("confocal").unwrap().set_silent(true);
    let mut client = connect(&running).await;
    let reply = ask(&mut client, 1, 2, &[0x04, 0x00, 0x00, 0x00, 0x01]).await;
    assert_eq!(&reply[6..], &[2, 0x84, 0x0B]);
    // FC08 (diagnostics): its reply's length cannot be told on an RTU line.
    let reply = ask(&mut client, 2, 1, &[0x08, 0x00, 0x00, 0x12, 0x34]).await;
    assert_eq!(&reply[6..], &[1, 0x88, 0x01]);
    // A slave nobody answers to: 0x0B too.
    let reply = ask(&mut client, 3, 99, &[0x03, 0x00, 0x00, 0x00, 0x01]).await;
    assert_eq!(&reply[6..], &[99, 0x83, 0x0B]);
}

#[tokio::test]
async fn a_vendor_exception_comes_back_as_the_device_framed_it() {
    let running = start(
        "
lines:
  - { name: rs485, simulated: true, gateway: 0 }
devices:
  - { name: range, model: lc-rs, slave: 1, timeout: 100ms }
",
    );
    let mut client = connect(&running).await;
    // An undefined address: LC-RS answers with a byte count of 2 and its own 16-bit code
    // 0001 (register address error, table 2), `83 02 00 01`, where others send `83 02`.
    let reply = ask(&mut client, 4, 1, &[0x03, 0x7F, 0x00, 0x00, 0x01]).await;
    assert_eq!(&reply[7..], &[0x83, 0x02, 0x00, 0x01]);
}

/// Sends one request without waiting for its reply.
async fn send(stream: &mut TcpStream, transaction: u16, unit: u8, pdu: &[u8]) {
    let mut frame = transaction.to_be_bytes().to_vec();
    frame.extend_from_slice(&[0, 0]);
    frame.extend_from_slice(&(pdu.len() as u16 + 1).to_be_bytes());
    frame.push(unit);
    frame.extend_from_slice(pdu);
    stream.write_all(&frame).await.unwrap();
}

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

/// The line's transactions so far, from its next statistics event.
async fn line_transactions(running: &Running) -> u64 {
    let mut events = running.subscribe();
    loop {
        if let Event::Line(stats) = events.recv().await.unwrap() {
            return stats.transactions;
        }
    }
}

/// The light power read of the P series at slave 1, and its reply when it holds 42.5 %.
fn light_power_read() -> ([u8; 5], [u8; 4]) {
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let [high, low] = power.address.to_be_bytes();
    ([0x03, high, low, 0x00, 0x01], [0x03, 0x02, 0x01, 0xA9])
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
    let no_polls = BUS
        .replace("clients: 2", "clients: 2, writes: true")
        .replace(", poll: [{ read: measurements }]", "")
        .replace("slave: 1,", "slave: 1, writable: [light_power],");
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

/// The FC06 request PDU writing `value` to holding register `name` of the P series.
fn write_p_series(name: &str, value: u16) -> Vec<u8> {
    let register = optobus_p_series::DEVICE.register(name).unwrap();
    [
        &[0x06][..],
        &register.address.to_be_bytes(),
        &value.to_be_bytes(),
    ]
    .concat()
}

/// The words of register `name` of the P series in `simulator`.
fn p_series_words(simulator: &optobus_simulator::Simulator, name: &str) -> Option<Vec<u16>> {
    let register = optobus_p_series::DEVICE.register(name).unwrap();
    simulator.peek(Table::Holding, register.address)
}

/// A simulated line behind a gateway that writes; its devices follow.
macro_rules! writable_line {
    () => {
        "
lines:
  - name: rs485
    simulated: true
    baud: 115200
    any_format: true
    gateway: { listen: 127.0.0.1:0, clients: 2, writes: true }
devices:
"
    };
}

/// A head that lists the light power as writable and a confocal, behind a gateway that
/// writes.
const WRITABLE_GATEWAY: &str = concat!(
    writable_line!(),
    "  - { name: head, model: p-series, slave: 1, timeout: 50ms, writable: [light_power] }
  - { name: confocal, model: ccs, slave: 2, timeout: 50ms }
"
);

/// Two heads that both list the light power as writable, behind a gateway that writes.
const TWO_HEADS: &str = concat!(
    writable_line!(),
    "  - { name: top, model: p-series, slave: 1, timeout: 50ms, writable: [light_power] }
  - { name: bottom, model: p-series, slave: 2, timeout: 50ms, writable: [light_power] }
"
);

#[tokio::test]
async fn the_gateway_with_writes_writes_only_what_the_bus_file_lists() {
    let running = start(WRITABLE_GATEWAY);
    let head = running.simulator("head").unwrap();
    let mut client = connect(&running).await;
    let names = [
        "slave_address",
        "save_parameters",
        "network_reset_or_reboot",
        "laser_enabled",
    ];
    let before: Vec<_> = names.iter().map(|n| p_series_words(head, n)).collect();
    // Issue 29: slave address 31 (the head would be lost to the bus), a save, a reboot and a
    // register nothing lists: each "not allowed", exception 01.
    for (transaction, (name, value)) in [
        ("slave_address", 31),
        ("save_parameters", 1),
        ("network_reset_or_reboot", 170),
        ("laser_enabled", 0),
    ]
    .into_iter()
    .enumerate()
    {
        let request = write_p_series(name, value);
        let reply = ask(&mut client, transaction as u16, 1, &request).await;
        assert_eq!(&reply[7..], &[0x86, 0x01], "{name} = {value}");
    }
    let after: Vec<_> = names.iter().map(|n| p_series_words(head, n)).collect();
    assert_eq!(after, before, "nothing reached the device");
    let counts = running.gateway_counts("rs485").unwrap();
    assert_eq!(counts.policy_refused, 4);
    // FC16, which the P series' manual does not list, even of a listed register: 01.
    let [high, low] = optobus_p_series::DEVICE
        .register("light_power")
        .unwrap()
        .address
        .to_be_bytes();
    let reply = ask(&mut client, 8, 1, &[0x10, high, low, 0, 1, 2, 0x02, 0x58]).await;
    assert_eq!(&reply[7..], &[0x90, 0x01]);
    // What is listed is written.
    let reply = ask(&mut client, 9, 1, &write_p_series("light_power", 600)).await;
    assert_eq!(reply[7..], write_p_series("light_power", 600)[..]);
    assert_eq!(p_series_words(head, "light_power"), Some(vec![600]));
    drop(running);

    // A drastic command runs where the file names it, with its own value only.
    let running =
        start(&WRITABLE_GATEWAY.replace("[light_power]", "[light_power, reset_sampled_data]"));
    let head = running.simulator("head").unwrap();
    let mut client = connect(&running).await;
    let reply = ask(&mut client, 1, 1, &write_p_series("sampled_data_reset", 1)).await;
    assert_eq!(reply[7..], write_p_series("sampled_data_reset", 1)[..]);
    let reply = ask(&mut client, 2, 1, &write_p_series("save_parameters", 1)).await;
    assert_eq!(&reply[7..], &[0x86, 0x01]);
    assert_eq!(p_series_words(head, "save_parameters"), Some(vec![0]));
}

/// Waits until `done` holds (within a generous deadline); whether it did.
async fn eventually(done: impl Fn() -> bool) -> bool {
    let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
    while tokio::time::Instant::now() < deadline {
        if done() {
            return true;
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    done()
}

#[tokio::test]
async fn a_broadcast_write_goes_out_only_where_every_device_lists_it_and_takes_the_value() {
    // Issue 29: unit 0, holding 2 = 600 set the head's light power and the confocal's
    // exposure time although the confocal lists nothing.
    let running = start(WRITABLE_GATEWAY);
    let head = running.simulator("head").unwrap();
    let confocal = running.simulator("confocal").unwrap();
    let before = (
        head.peek(Table::Holding, 2),
        confocal.peek(Table::Holding, 2),
    );
    let mut client = connect(&running).await;
    let reply = ask(&mut client, 1, 0, &[0x06, 0x00, 0x02, 0x02, 0x58]).await;
    assert_eq!(&reply[6..], &[0x00, 0x86, 0x01], "the confocal refuses it");
    let after = (
        head.peek(Table::Holding, 2),
        confocal.peek(Table::Holding, 2),
    );
    assert_eq!(after, before, "nothing was broadcast");
    drop(running);

    // Two heads that both list the light power: one broadcast, both set, no reply.
    let running = start(TWO_HEADS);
    let top = running.simulator("top").unwrap();
    let bottom = running.simulator("bottom").unwrap();
    let mut client = connect(&running).await;
    // Out of range for both (100.1 %): exception 03, nothing sent.
    let reply = ask(&mut client, 2, 0, &write_p_series("light_power", 1001)).await;
    assert_eq!(&reply[7..], &[0x86, 0x03]);
    send(&mut client, 3, 0, &write_p_series("light_power", 600)).await;
    let both = || {
        p_series_words(top, "light_power") == Some(vec![600])
            && p_series_words(bottom, "light_power") == Some(vec![600])
    };
    assert!(eventually(both).await, "the broadcast reached both heads");
    // Nothing comes back for a broadcast: the next reply is the next request's.
    let (read, answer) = light_power_read();
    let reply = ask(&mut client, 4, 1, &read).await;
    assert_eq!(&reply[..2], &4u16.to_be_bytes());
    assert_eq!(&reply[7..9], &answer[..2]);
}

#[tokio::test]
async fn a_read_only_gateway_refuses_reads_that_change_the_device() {
    let buffered = optobus_p_series::DEVICE
        .register("buffer_sample_1_buffered_value")
        .unwrap();
    let [high, low] = buffered.address.to_be_bytes();
    let page_read = [0x04, high, low, 0x00, 0x02];
    let distance = optobus_p_series::DEVICE.register("distance_1").unwrap();
    let [d_high, d_low] = distance.address.to_be_bytes();
    let running = start(&WRITABLE_GATEWAY.replace(", writes: true", ""));
    let mut client = connect(&running).await;
    // Issue 29: FC04 of the buffer page (input 0x12) turns the page: not allowed, 01; a read
    // that covers it from below too.
    let reply = ask(&mut client, 1, 1, &page_read).await;
    assert_eq!(&reply[7..], &[0x84, 0x01]);
    let [below_high, below_low] = (buffered.address - 2).to_be_bytes();
    let covering = [0x04, below_high, below_low, 0x00, 0x04];
    let reply = ask(&mut client, 2, 1, &covering).await;
    assert_eq!(&reply[7..], &[0x84, 0x01]);
    // Other input registers read as ever.
    let reply = ask(&mut client, 3, 1, &[0x04, d_high, d_low, 0x00, 0x02]).await;
    assert_eq!(&reply[7..9], &[0x04, 0x04]);
    assert_eq!(running.gateway_counts("rs485").unwrap().policy_refused, 2);
    drop(running);

    // Where writes pass and the buffer's lock and unlock are listed, the page may be read.
    let running = start(&WRITABLE_GATEWAY.replace("[light_power]", "[lock_buffer, unlock_buffer]"));
    let mut client = connect(&running).await;
    let reply = ask(&mut client, 1, 1, &page_read).await;
    assert_eq!(&reply[7..9], &[0x04, 0x04]);
}

#[tokio::test]
async fn a_read_of_unit_0_is_answered_at_once_with_exception_01() {
    let running = start(WRITABLE_GATEWAY);
    let mut client = connect(&running).await;
    let (read, _) = light_power_read();
    let reply = ask(&mut client, 1, 0, &read).await;
    assert_eq!(&reply[6..], &[0x00, 0x83, 0x01]);
}

#[tokio::test]
async fn a_unit_id_no_device_has_is_answered_0b_without_the_line() {
    // Issue 30: slave 99 waited out a timeout on the line (1 s, mbpoll's own timeout, so
    // mbpoll said "Connection timed out"); the bus file says who is on the line.
    let no_polls = BUS.replace(", poll: [{ read: measurements }]", "");
    let running = start(&no_polls);
    let mut client = connect(&running).await;
    for (transaction, unit) in [(1u16, 99u8), (2, 3), (3, 247)] {
        let reply = ask(
            &mut client,
            transaction,
            unit,
            &[0x03, 0x00, 0x00, 0x00, 0x01],
        )
        .await;
        assert_eq!(&reply[6..], &[unit, 0x83, 0x0B]);
    }
    let reply = ask(&mut client, 4, 99, &write_p_series("light_power", 600)).await;
    assert_eq!(&reply[6..], &[99, 0x86, 0x0B]);
    let counts = running.gateway_counts("rs485").unwrap();
    assert_eq!((counts.not_carried, counts.requests), (4, 0), "{counts:?}");
    assert_eq!(
        line_transactions(&running).await,
        0,
        "nothing went onto the line"
    );
}

/// The next `Written` event, the others skipped.
async fn next_written(events: &mut tokio::sync::broadcast::Receiver<Event>) -> Arc<Written> {
    tokio::time::timeout(Duration::from_secs(10), async {
        loop {
            match events.recv().await {
                Ok(Event::Written(written)) => return written,
                Ok(_) => {}
                Err(error) => panic!("{error}"),
            }
        }
    })
    .await
    .expect("a write told within 10 s")
}

#[tokio::test]
async fn every_write_a_device_took_is_told_as_written_with_its_registers_and_who_wrote() {
    let running = start(WRITABLE_GATEWAY);
    let mut events = running.subscribe();
    let head = running.simulator("head").unwrap();
    let mut client = connect(&running).await;
    let told = |written: &Written| {
        let names: Vec<&str> = written.registers.iter().map(|r| r.name).collect();
        (written.source.device.to_string(), names, written.by)
    };
    // A gateway write the device took: its register, by the gateway.
    let reply = ask(&mut client, 1, 1, &write_p_series("light_power", 600)).await;
    assert_eq!(&reply[7..], &write_p_series("light_power", 600)[..]);
    let written = next_written(&mut events).await;
    assert_eq!(
        told(&written),
        ("head".to_owned(), vec!["light_power"], Writer::Gateway)
    );
    // Refused (100.1 % is out of range, exception 03): nothing written, nothing told; the
    // next write told is the console's.
    let reply = ask(&mut client, 2, 1, &write_p_series("light_power", 1001)).await;
    assert_eq!(&reply[7..], &[0x86, 0x03]);
    let console = running.handle().for_source(Source::Console);
    console
        .set_listed("head", "light_power", "30")
        .await
        .unwrap();
    assert_eq!(p_series_words(head, "light_power"), Some(vec![300]));
    let written = next_written(&mut events).await;
    assert_eq!(
        told(&written),
        (
            "head".to_owned(),
            vec!["light_power"],
            Writer::Job(Source::Console)
        )
    );
    // In the JSON a script reads.
    let json = serde_json::to_value(&*written).unwrap();
    assert_eq!(json["registers"], serde_json::json!(["light_power"]));
    assert_eq!(json["by"], "console");
}

#[tokio::test]
async fn a_broadcast_write_is_told_as_written_for_every_device_of_the_line() {
    let running = start(TWO_HEADS);
    let mut events = running.subscribe();
    let told = |written: &Written| {
        let names: Vec<&str> = written.registers.iter().map(|r| r.name).collect();
        (written.source.device.to_string(), names, written.by)
    };
    // Through the gateway, unit 0: nothing comes back, both devices are told.
    let mut client = connect(&running).await;
    send(&mut client, 1, 0, &write_p_series("light_power", 600)).await;
    for device in ["top", "bottom"] {
        let written = next_written(&mut events).await;
        assert_eq!(
            told(&written),
            (device.to_owned(), vec!["light_power"], Writer::Gateway)
        );
    }
    // The program's handle, broadcasting through `top`.
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    running
        .handle()
        .write("top", power, vec![700], true)
        .await
        .unwrap();
    for device in ["top", "bottom"] {
        let written = next_written(&mut events).await;
        assert_eq!(
            told(&written),
            (
                device.to_owned(),
                vec!["light_power"],
                Writer::Job(Source::Api)
            )
        );
    }
    let bottom = running.simulator("bottom").unwrap();
    assert!(eventually(|| p_series_words(bottom, "light_power") == Some(vec![700])).await);
    drop(running);

    // Devices of other models on the line are told the register they have at that address.
    let running = start(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: top, model: p-series, slave: 1, timeout: 50ms }
  - { name: confocal, model: ccs, slave: 2, timeout: 50ms }
",
    );
    let mut events = running.subscribe();
    let (theirs, _) = optobus_ccs::DEVICE
        .register_at(Table::Holding, power.address)
        .unwrap();
    running
        .handle()
        .write("top", power, vec![600], true)
        .await
        .unwrap();
    let expected = [("top", power.name), ("confocal", theirs.name)];
    for (device, register) in expected {
        let written = next_written(&mut events).await;
        assert_eq!(
            told(&written),
            (device.to_owned(), vec![register], Writer::Job(Source::Api))
        );
    }
}
