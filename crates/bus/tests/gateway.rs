//! The gateway's answers: Modbus TCP clients reach the line's devices between the bus's
//! polls, with real MBAP frames both ways; what the bus file lets them write, and every write
//! told. Its limits and timeouts are in `gateway_limits.rs`.

mod common;

use std::sync::Arc;
use std::time::Duration;

use common::gateway::{
    ask, connect, light_power_read, line_transactions, send, start, writes_without_polls, BUS,
};
use optobus_bus::{Event, Source, Writer, Written};
use optobus_device::Table;

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

    let no_polls = writes_without_polls();
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
