//! Issue 32, point 2: a measurement's inputs read together. The polls that feed one
//! measurement run back to back on their line, on ticks counted from the bus's start on every
//! line, and a device of theirs that is offline holds nobody up.
//!
//! Every test runs on tokio's paused clock: the emulated lines' byte timing and the schedule
//! are exact there, so the instants compared are the schedule's own, not the machine's.

use std::path::Path;
use std::time::{Duration, SystemTime};

use optobus_bus::{Bus, BusFile, Catalogue, Event, Health, Running};
use tokio::sync::broadcast::{error::RecvError, Receiver};

fn file(text: &str) -> BusFile {
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    BusFile::parse("bus.yaml", text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()))
}

const GAP: &str = "
measurements:
  - name: gap
    expr: 20mm - top.distance_1 - bottom.distance_1
    unit: mm
";

/// A sample as the tests look at it: the device and when it was asked.
#[derive(Clone, Debug)]
struct Asked {
    device: String,
    requested: SystemTime,
}

/// The samples (and health changes, as `device:offline`) of the bus until `virtual_time`
/// has passed on the paused clock.
async fn follow(events: &mut Receiver<Event>, virtual_time: Duration) -> Vec<Asked> {
    let until = tokio::time::Instant::now() + virtual_time;
    let mut seen = Vec::new();
    loop {
        let event = match tokio::time::timeout_at(until, events.recv()).await {
            Err(_) => return seen,
            Ok(Ok(event)) => event,
            Ok(Err(RecvError::Lagged(n))) => panic!("{n} events missed"),
            Ok(Err(RecvError::Closed)) => panic!("the bus stopped"),
        };
        match event {
            Event::Sample(sample) => seen.push(Asked {
                device: sample.source.device.to_string(),
                requested: sample.requested,
            }),
            Event::Health(health) if health.health == Health::Offline => seen.push(Asked {
                device: format!("{}:offline", health.source.device),
                requested: SystemTime::now(),
            }),
            _ => {}
        }
    }
}

fn requests_of<'a>(seen: &'a [Asked], device: &'a str) -> impl Iterator<Item = SystemTime> + 'a {
    seen.iter()
        .filter(move |a| a.device == device)
        .map(|a| a.requested)
}

/// The two heads of `gap` are asked one right after the other, every time: no poll of the
/// device listed between them in the file (and due on the same ticks) comes between.
#[tokio::test(start_paused = true)]
async fn a_measurements_two_inputs_are_requested_back_to_back_on_one_line() {
    let bus = Bus::new(file(&format!(
        "
lines: [{{ name: rs485, simulated: true, baud: 115200, any_format: true }}]
devices:
  - {{ name: top, model: p-series, slave: 1, timeout: 50ms, poll: [{{ read: distance_1, every: 20ms }}] }}
  - {{ name: other, model: p-series, slave: 3, timeout: 50ms, poll: [{{ read: distance_1, every: 20ms }}] }}
  - {{ name: bottom, model: p-series, slave: 2, timeout: 50ms, poll: [{{ read: distance_1, every: 20ms }}] }}
{GAP}"
    )));
    let mut events = bus.subscribe();
    let _running = bus.start().unwrap();
    let seen = follow(&mut events, Duration::from_secs(2)).await;
    let order: Vec<&str> = seen.iter().map(|a| a.device.as_str()).collect();
    let tops = order.iter().filter(|&&d| d == "top").count();
    assert!(tops >= 50, "top asked {tops} times in 2 s of 20 ms ticks");
    assert!(order.contains(&"other"), "{order:?}");
    for (index, _) in order.iter().enumerate().filter(|(_, &d)| d == "top") {
        if let Some(next) = order.get(index + 1) {
            assert_eq!(*next, "bottom", "at sample {index}: {order:?}");
        }
    }
}

/// `top` on one line, `bottom` on another with a busier neighbour on the first: every run of
/// the gap's polls asks both heads at the same instant, the bus's common tick.
#[tokio::test(start_paused = true)]
async fn two_lines_groups_start_on_the_same_tick() {
    let bus = Bus::new(file(&format!(
        "
lines:
  - {{ name: upper, simulated: true, baud: 115200, any_format: true }}
  - {{ name: lower, simulated: true, baud: 115200, any_format: true }}
devices:
  - {{ name: neighbour, line: upper, model: p-series, slave: 2, timeout: 50ms, poll: [{{ read: distance_1, every: 50ms }}] }}
  - {{ name: top, line: upper, model: p-series, slave: 1, timeout: 50ms, poll: [{{ read: distance_1, every: 20ms }}] }}
  - {{ name: bottom, line: lower, model: p-series, slave: 1, timeout: 50ms, poll: [{{ read: distance_1, every: 20ms }}] }}
{GAP}"
    )));
    let mut events = bus.subscribe();
    let _running = bus.start().unwrap();
    let seen = follow(&mut events, Duration::from_secs(2)).await;
    let top: Vec<SystemTime> = requests_of(&seen, "top").collect();
    let bottom: Vec<SystemTime> = requests_of(&seen, "bottom").collect();
    assert!(top.len() >= 50, "top asked {} times", top.len());
    assert!(requests_of(&seen, "neighbour").count() >= 20);
    // Each line's last run may not have been told yet when the test stopped looking.
    let both = top.len().min(bottom.len());
    assert!(top.len().abs_diff(bottom.len()) <= 1, "{top:?}\n{bottom:?}");
    assert_eq!(top[..both], bottom[..both]);
    // And the ticks are the bus's: a whole number of 20 ms from the first.
    for at in &top {
        let since = at.duration_since(top[0]).unwrap();
        assert_eq!(since.as_nanos() % 20_000_000, 0, "{since:?}");
    }
}

/// `top` goes silent: its failing polls cost their own timeout, then it is offline and the
/// gap's run goes on without it. `other`, in no measurement, is never held longer than its
/// period and top's timeout; `bottom` stays on the gap's ticks.
#[tokio::test(start_paused = true)]
async fn an_offline_input_holds_no_other_poll_beyond_its_own_timeout() {
    let bus = Bus::new(file(&format!(
        "
lines: [{{ name: rs485, simulated: true, baud: 115200, any_format: true }}]
devices:
  - {{ name: top, model: p-series, slave: 1, timeout: 50ms, retries: 0, poll: [{{ read: distance_1, every: 20ms }}] }}
  - {{ name: other, model: p-series, slave: 3, timeout: 50ms, poll: [{{ read: distance_1, every: 20ms }}] }}
  - {{ name: bottom, model: p-series, slave: 2, timeout: 50ms, poll: [{{ read: distance_1, every: 20ms }}] }}
{GAP}"
    )));
    let mut events = bus.subscribe();
    let running: Running = bus.start().unwrap();
    let before = follow(&mut events, Duration::from_millis(500)).await;
    let origin = requests_of(&before, "top")
        .next()
        .expect("top answered first");
    running.simulator("top").unwrap().set_silent(true);
    let seen = follow(&mut events, Duration::from_secs(5)).await;
    let offline = seen
        .iter()
        .position(|a| a.device == "top:offline")
        .expect("top goes offline");
    // A period, top's own timeout (no retry) and the quiet owed after it (as long as the
    // timeout), and the other polls' transactions at most.
    let longest = Duration::from_millis(20 + 50 + 50 + 5);
    let other: Vec<SystemTime> = requests_of(&seen, "other").collect();
    assert!(other.len() >= 100, "other asked {} times", other.len());
    for pair in other.windows(2) {
        let interval = pair[1].duration_since(pair[0]).unwrap();
        assert!(interval <= longest, "other waited {interval:?}");
    }
    // Once top is offline, the gap's run is bottom alone, on the bus's ticks but where a
    // probe of top (its timeout and quiet) came just before.
    let bottom: Vec<SystemTime> = requests_of(&seen[offline..], "bottom").collect();
    assert!(bottom.len() >= 100, "bottom asked {} times", bottom.len());
    let on_tick = bottom
        .iter()
        .filter(|at| at.duration_since(origin).unwrap().as_nanos() % 20_000_000 == 0)
        .count();
    assert!(
        on_tick * 10 >= bottom.len() * 9,
        "{on_tick} of {}",
        bottom.len()
    );
}
