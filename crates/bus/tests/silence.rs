//! The silences a line keeps: a device's own silence after its replies, and the turnaround
//! after a broadcast, measured on the client's end of the line (the bus only ever waits longer
//! than asked, so these are lower bounds, not timings of speed).

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use optobus_bus::{Bus, BusFile, Catalogue};
use optobus_simulator::Simulator;
use optobus_transport::{Flow, Tap};

/// Every chunk that crossed the client's end: when, which way, from which slave.
type Log = Arc<Mutex<Vec<(Instant, Flow, u8)>>>;

fn start(text: &str) -> (optobus_bus::Running, Log, Simulator) {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]);
    let file = BusFile::parse("bus.yaml", text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()));
    let members = [
        Simulator::new(&optobus_p_series::DEVICE).slave(1),
        Simulator::new(&optobus_ccs::DEVICE).slave(2),
    ];
    let head = members[0].clone();
    let (stream, _server) = optobus_simulator::Slaves::new(members).duplex();
    let log: Log = Arc::default();
    let record = Arc::clone(&log);
    let tap = Tap::new(stream, move |flow: Flow, bytes: &[u8]| {
        record
            .lock()
            .unwrap()
            .push((Instant::now(), flow, bytes.first().copied().unwrap_or(0)));
    });
    let running = Bus::new(file).with_stream("rs485", tap).start().unwrap();
    (running, log, head)
}

/// The shortest time from a reply of `slave` to the next request on the line.
fn shortest_gap_after(log: &Log, slave: u8) -> Option<Duration> {
    let log = log.lock().unwrap();
    let mut shortest: Option<Duration> = None;
    let mut last_reply: Option<Instant> = None;
    let mut replying = None;
    for &(at, flow, first) in log.iter() {
        match flow {
            Flow::Sent => {
                if let (Some(reply), Some(true)) = (last_reply, replying) {
                    let gap = at - reply;
                    shortest = Some(shortest.map_or(gap, |s: Duration| s.min(gap)));
                }
                replying = Some(first == slave);
                last_reply = None;
            }
            Flow::Received => last_reply = Some(at),
        }
    }
    shortest
}

#[tokio::test]
async fn a_devices_silence_after_its_replies_is_kept_before_the_next_request() {
    let (running, log, _) = start(
        "
lines: [{ name: rs485, serial: memory, baud: 115200, any_format: true }]
devices:
  - { name: head, model: p-series, slave: 1, silence_after: 15ms, poll: [{ read: measurements }] }
  - { name: confocal, model: ccs, slave: 2, poll: [{ read: measurements }] }
",
    );
    while log.lock().unwrap().len() < 40 {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    drop(running);
    let gap = shortest_gap_after(&log, 1).expect("the head answered and the line went on");
    assert!(gap >= Duration::from_millis(15), "{gap:?}");
}

#[tokio::test]
async fn a_broadcast_is_followed_by_the_lines_turnaround() {
    let (running, log, head) = start(
        "
lines: [{ name: rs485, serial: memory, baud: 115200, any_format: true, broadcast_turnaround: 40ms }]
devices:
  - { name: head, model: p-series, slave: 1, poll: [{ read: measurements }] }
  - { name: confocal, model: ccs, slave: 2, poll: [{ read: measurements }] }
",
    );
    let power = optobus_p_series::DEVICE.register("light_power").unwrap();
    let handle = running.handle();
    tokio::time::sleep(Duration::from_millis(20)).await;
    handle.write("head", power, vec![250], true).await.unwrap();
    let sent_at = Instant::now();
    while log
        .lock()
        .unwrap()
        .iter()
        .filter(|(at, ..)| *at > sent_at)
        .count()
        < 4
    {
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    drop(running);
    let log = log.lock().unwrap();
    let broadcast = log
        .iter()
        .position(|&(_, flow, slave)| flow == Flow::Sent && slave == 0)
        .expect("the broadcast went out");
    let (at, ..) = log[broadcast];
    let (next, ..) = log[broadcast + 1..]
        .iter()
        .find(|(_, flow, _)| *flow == Flow::Sent)
        .copied()
        .expect("a request after it");
    assert!(next - at >= Duration::from_millis(40), "{:?}", next - at);
    // The head carried the broadcast write out.
    assert_eq!(
        head.peek(optobus_device::Table::Holding, power.address),
        Some(vec![250])
    );
}
