//! The recent frames of each device, as its line sent and received them: whole frames with
//! their direction and timing, kept per device, bounded.

mod common;

use std::time::Duration;

use common::file;
use optobus_bus::{Bus, Direction, FRAMES_KEPT};
use optobus_inspect::parse_value;

const TWO: &str = "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, timeout: 50ms, poll: [{ read: measurements, every: 20ms }] }
  - { name: confocal, model: ccs, slave: 2, timeout: 50ms, poll: [{ read: measurements, every: 20ms }] }
";

#[tokio::test(start_paused = true)]
async fn a_write_shows_as_its_request_and_reply_in_its_devices_frames_only() {
    let running = Bus::new(file(TWO)).start().unwrap();
    let handle = running.handle();
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let words = parse_value(power, "12.5").unwrap();
    handle.write("head", power, words, false).await.unwrap();
    let frames = handle.frames("head").unwrap();
    let [address_high, address_low] = power.address.to_be_bytes();
    let request = frames
        .iter()
        .rposition(|f| f.direction == Direction::Sent && f.bytes[1] == 6)
        .expect("the write's request is kept");
    let sent = &frames[request];
    assert_eq!(sent.bytes[..6], [1, 6, address_high, address_low, 0, 125]);
    assert_eq!(sent.bytes.len(), 8, "with its CRC");
    let reply = &frames[request + 1];
    assert_eq!(reply.direction, Direction::Received);
    assert_eq!(reply.bytes, sent.bytes, "FC06 echoes its request whole");
    assert!(reply
        .after_request
        .is_some_and(|after| after > Duration::ZERO));
    assert!(reply.at >= sent.at);
    tokio::time::sleep(Duration::from_millis(100)).await;
    let confocal = handle.frames("confocal").unwrap();
    assert!(!confocal.is_empty());
    assert!(confocal.iter().all(|f| f.bytes[0] == 2), "{confocal:?}");
    assert!(handle.frames("tail").is_err());
}

#[tokio::test(start_paused = true)]
async fn a_device_keeps_its_latest_frames_and_drops_the_oldest() {
    let running = Bus::new(file(TWO)).start().unwrap();
    let handle = running.handle();
    let mut first = None;
    for _ in 0..1000 {
        tokio::time::sleep(Duration::from_millis(100)).await;
        let frames = handle.frames("head").unwrap();
        first.get_or_insert_with(|| frames[0].clone());
        if frames.len() == FRAMES_KEPT && Some(&frames[0]) != first.as_ref() {
            // Requests and replies alternate, each reply after its request.
            for pair in frames.windows(2) {
                assert_ne!(pair[0].direction, pair[1].direction);
            }
            return;
        }
        assert!(frames.len() <= FRAMES_KEPT);
    }
    panic!("the ring never filled");
}
