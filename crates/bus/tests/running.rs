//! A running bus on simulated lines: every device's samples are its own, a dead device goes
//! offline without stopping the others and comes back when it answers again.

use std::collections::HashMap;
use std::path::Path;
use std::time::Duration;

use optobus_bus::{Bus, BusFile, Catalogue, Event, Health};
use optobus_inspect::decode_value;
use tokio::sync::broadcast::error::RecvError;
use tokio::sync::broadcast::Receiver;

fn file(text: &str) -> BusFile {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE, &optobus_ccs::DEVICE]);
    BusFile::parse("bus.yaml", text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()))
}

async fn next(events: &mut Receiver<Event>) -> Event {
    match tokio::time::timeout(Duration::from_secs(10), events.recv()).await {
        Ok(Ok(event)) => event,
        Ok(Err(RecvError::Lagged(n))) => panic!("the test fell {n} events behind"),
        Ok(Err(RecvError::Closed)) => panic!("the bus stopped"),
        Err(_) => panic!("no event within 10 s"),
    }
}

const THREE_ON_ONE_LINE: &str = "
lines:
  - { name: rs485, simulated: true, baud: 115200, any_format: true }
devices:
  - name: top
    model: p-series
    slave: 1
    timeout: 200ms
    poll: [{ read: [light_power, measurements] }]
  - name: bottom
    model: p-series
    slave: 2
    timeout: 200ms
    poll: [{ read: [light_power, measurements] }]
  - name: confocal
    model: ccs
    slave: 3
    timeout: 200ms
    poll: [{ read: measurements, every: 20ms }]
";

#[tokio::test]
async fn each_device_on_a_shared_line_gives_its_own_values() {
    let bus = Bus::new(file(THREE_ON_ONE_LINE));
    let mut events = bus.subscribe();
    let running = bus.start().expect("starts");
    // Two heads of one model, told apart only by their slave address: different powers.
    let power = |percent: u16| [percent * 10];
    let top = running.simulator("top").expect("simulated");
    let bottom = running.simulator("bottom").expect("simulated");
    top.set("light_power", &power(42)).unwrap();
    bottom.set("light_power", &power(17)).unwrap();
    let mut powers: HashMap<String, Vec<String>> = HashMap::new();
    let mut devices_seen = HashMap::new();
    while powers.values().map(Vec::len).sum::<usize>() < 20 || devices_seen.len() < 3 {
        if let Event::Sample(sample) = next(&mut events).await {
            *devices_seen
                .entry(sample.source.device.to_string())
                .or_insert(0) += 1;
            if sample.register.name == "light_power" {
                powers
                    .entry(sample.source.device.to_string())
                    .or_default()
                    .push(sample.value.to_string());
            }
            assert!(sample.replied >= sample.requested);
        }
    }
    let expected = |sim: &optobus_simulator::Simulator| {
        let state = sim.register("light_power").unwrap();
        decode_value(state.info, &state.words).to_string()
    };
    assert_eq!(expected(top), "42.0 %");
    for (device, values) in &powers {
        let own = expected(running.simulator(device).unwrap());
        assert!(
            values.iter().all(|v| *v == own),
            "{device} read {values:?}, its simulator holds {own}"
        );
    }
    assert!(powers.contains_key("top") && powers.contains_key("bottom"));
    assert!(devices_seen["confocal"] > 0);
}

#[tokio::test]
async fn a_dead_device_goes_offline_and_comes_back_while_the_others_go_on() {
    let bus = Bus::new(file(THREE_ON_ONE_LINE));
    let mut events = bus.subscribe();
    let running = bus.start().expect("starts");
    let bottom = running.simulator("bottom").unwrap().clone();
    bottom.set_silent(true);
    // Offline after three failed polls; meanwhile the others keep answering.
    let mut others_while_offline = 0;
    let mut offline = false;
    while !offline || others_while_offline < 10 {
        match next(&mut events).await {
            Event::Health(health) if &*health.source.device == "bottom" => {
                assert_eq!(health.health, Health::Offline);
                assert!(health.errors.timeouts >= 3, "{:?}", health.errors);
                assert!(
                    health.reason.as_deref().unwrap_or("").contains("no reply"),
                    "{:?}",
                    health.reason
                );
                offline = true;
            }
            Event::Sample(sample) if &*sample.source.device == "bottom" => {
                assert!(!offline, "no sample from a silent device");
            }
            Event::Sample(_) if offline => others_while_offline += 1,
            _ => {}
        }
    }
    bottom.set_silent(false);
    loop {
        if let Event::Health(health) = next(&mut events).await {
            if &*health.source.device == "bottom" {
                assert_eq!(health.health, Health::Online);
                break;
            }
        }
    }
    drop(running);
}

#[tokio::test]
async fn line_statistics_count_transactions_and_busy_time() {
    let bus = Bus::new(file(THREE_ON_ONE_LINE));
    let mut events = bus.subscribe();
    let _running = bus.start().expect("starts");
    loop {
        if let Event::Line(stats) = next(&mut events).await {
            if stats.transactions == 0 {
                continue;
            }
            assert_eq!(&*stats.line, "rs485");
            assert!(stats.open);
            assert_eq!(stats.errors.total(), 0);
            let utilisation = stats.utilisation();
            assert!(utilisation > 0.0 && utilisation <= 1.0, "{utilisation}");
            break;
        }
    }
}

#[tokio::test]
async fn a_garbling_a_slow_and_a_dead_device_never_yield_a_wrong_sample() {
    let text = "
lines:
  - { name: rs485, simulated: true, baud: 115200, any_format: true }
devices:
  - { name: good, model: p-series, slave: 1, timeout: 100ms, poll: [{ read: light_power }] }
  - { name: garbling, model: p-series, slave: 2, timeout: 100ms, faults: 'corrupt=0.1,truncate=0.05,wrong_slave=0.05,garbage=0.05,seed=3', poll: [{ read: light_power }] }
  - { name: slow, model: p-series, slave: 3, timeout: 100ms, faults: 'delay=0.2,seed=5', poll: [{ read: light_power }] }
  - { name: dead, model: p-series, slave: 4, timeout: 100ms, faults: 'drop=1', poll: [{ read: light_power }] }
";
    let bus = Bus::new(file(text));
    let mut events = bus.subscribe();
    let running = bus.start().expect("starts");
    for (index, name) in ["good", "garbling", "slow", "dead"].iter().enumerate() {
        let words = [100 + 10 * index as u16];
        running
            .simulator(name)
            .unwrap()
            .set("light_power", &words)
            .unwrap();
    }
    let mut samples: HashMap<String, usize> = HashMap::new();
    let mut dead_offline = false;
    let enough = |samples: &HashMap<String, usize>| {
        ["good", "garbling", "slow"]
            .iter()
            .all(|d| samples.get(*d).copied().unwrap_or(0) >= 20)
    };
    while !dead_offline || !enough(&samples) {
        match next(&mut events).await {
            Event::Sample(sample) => {
                let device = sample.source.device.to_string();
                let state = running
                    .simulator(&device)
                    .unwrap()
                    .register("light_power")
                    .unwrap();
                assert_eq!(
                    sample.value,
                    decode_value(state.info, &state.words),
                    "{device}: a sample that is not the device's value"
                );
                *samples.entry(device).or_default() += 1;
            }
            Event::Health(health) if &*health.source.device == "dead" => {
                dead_offline = health.health == Health::Offline;
            }
            _ => {}
        }
    }
    assert_eq!(samples.get("dead"), None);
    for device in ["good", "garbling", "slow"] {
        assert!(
            samples.get(device).copied().unwrap_or(0) > 0,
            "{device}: {samples:?}"
        );
    }
}

#[tokio::test]
async fn a_late_reply_within_the_timeout_is_a_sample_when_the_faults_say_how_late() {
    // Every reply 20 ms late: within the device's 200 ms timeout, as the file's `late=` says
    // (the bus's own default would put a late reply past the timeout).
    let running = Bus::new(file(
        "
lines: [{ name: rs485, simulated: true, baud: 115200, any_format: true }]
devices:
  - { name: slow, model: p-series, slave: 1, timeout: 200ms, faults: 'delay=1,late=20ms', poll: [{ read: light_power }] }
",
    ));
    let mut events = running.subscribe();
    let running = running.start().unwrap();
    let mut samples = 0;
    while samples < 3 {
        match next(&mut events).await {
            Event::Sample(sample) => {
                assert!(
                    sample.replied.duration_since(sample.requested).unwrap()
                        >= Duration::from_millis(20),
                    "a delayed reply"
                );
                samples += 1;
            }
            Event::Health(health) => panic!("{health:?}: every reply came within the timeout"),
            Event::Line(_) | Event::Measurement(_) | Event::Written(_) => {}
        }
    }
    running.stop();
}
