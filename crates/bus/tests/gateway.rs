//! The gateway: Modbus TCP clients reach the line's devices between the bus's polls, with
//! real MBAP frames both ways.

use std::path::Path;
use std::time::Duration;

use optobus_bus::{Bus, BusFile, Catalogue, Running};
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

/// Sends one request and reads its whole reply frame.
async fn ask(stream: &mut TcpStream, transaction: u16, unit: u8, pdu: &[u8]) -> Vec<u8> {
    let mut frame = transaction.to_be_bytes().to_vec();
    frame.extend_from_slice(&[0, 0]);
    frame.extend_from_slice(&(pdu.len() as u16 + 1).to_be_bytes());
    frame.push(unit);
    frame.extend_from_slice(pdu);
    stream.write_all(&frame).await.unwrap();
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
    let mut client = TcpStream::connect(running.gateway_address("rs485").unwrap())
        .await
        .unwrap();
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
    let mut client = TcpStream::connect(running.gateway_address("rs485").unwrap())
        .await
        .unwrap();
    let reply = ask(&mut client, 7, 1, &[0x06, high, low, 0x00, 0x64]).await;
    assert_eq!(&reply[7..], &[0x86, 0x01]);
    assert_eq!(head.peek(Table::Holding, power.address), before);
    drop(running);

    let no_polls = BUS
        .replace("clients: 2", "clients: 2, writes: true")
        .replace(", poll: [{ read: measurements }]", "");
    let running = start(&no_polls);
    let head = running.simulator("head").unwrap();
    let mut client = TcpStream::connect(running.gateway_address("rs485").unwrap())
        .await
        .unwrap();
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
    let mut client = TcpStream::connect(running.gateway_address("rs485").unwrap())
        .await
        .unwrap();
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
    let mut client = TcpStream::connect(running.gateway_address("rs485").unwrap())
        .await
        .unwrap();
    // An undefined address: LC-RS answers with a byte count of 2 and its own 16-bit code
    // 0001 (register address error, table 2), `83 02 00 01`, where others send `83 02`.
    let reply = ask(&mut client, 4, 1, &[0x03, 0x7F, 0x00, 0x00, 0x01]).await;
    assert_eq!(&reply[7..], &[0x83, 0x02, 0x00, 0x01]);
}

#[tokio::test]
async fn clients_beyond_the_limit_are_closed_and_a_broken_client_harms_no_other() {
    let running = start(BUS);
    let address = running.gateway_address("rs485").unwrap();
    let mut first = TcpStream::connect(address).await.unwrap();
    let mut second = TcpStream::connect(address).await.unwrap();
    ask(&mut first, 1, 1, &[0x04, 0x00, 0x00, 0x00, 0x01]).await;
    ask(&mut second, 1, 1, &[0x04, 0x00, 0x00, 0x00, 0x01]).await;
    let mut third = TcpStream::connect(address).await.unwrap();
    let mut byte = [0u8; 1];
    let closed = tokio::time::timeout(Duration::from_secs(5), third.read(&mut byte)).await;
    assert!(matches!(closed, Ok(Ok(0)) | Ok(Err(_))), "{closed:?}");
    // The refused client is counted, beside the two requests passed.
    assert_eq!(running.gateway_counts("rs485"), Some((2, 1)));
    // Protocol id 1 is not Modbus: that connection is closed, the other goes on.
    second
        .write_all(&[0, 1, 0, 1, 0, 6, 1, 4, 0, 0, 0, 1])
        .await
        .unwrap();
    let closed = tokio::time::timeout(Duration::from_secs(5), second.read(&mut byte)).await;
    assert!(matches!(closed, Ok(Ok(0)) | Ok(Err(_))), "{closed:?}");
    let reply = ask(&mut first, 2, 2, &[0x04, 0x00, 0x00, 0x00, 0x01]).await;
    assert_eq!(&reply[6..9], &[2, 0x04, 0x02]);
}
