//! Floods from the broker on a real mosquitto (issue 28, points 2, 3 and 5; issue 29 point 4):
//! a write's payload over the limit is refused with a short message and publishing goes on;
//! a flood of writes is refused beyond a bounded queue while the polls go on; a flood of Home
//! Assistant births keeps the control queue bounded; a retained write is not carried out.

mod common;

use std::time::{Duration, SystemTime};

use common::{Broker, Heard, Watcher};
use optobus_bus::{Bus, Event, Running};
use optobus_mqtt::{Counts, Publisher, MAX_WRITE_PAYLOAD, WRITE_QUEUE};
use rumqttc::QoS;

const P: &optobus_device::DeviceInfo = &optobus_p_series::DEVICE;
/// Where refusals of writes to `light_power` are answered.
const POWER_ERROR: &str = "plant/top/light_power/error";
/// The answer to a retained write.
const RETAINED_REFUSAL: &str = "a retained write is not carried out (the broker would hand it \
                                over again at every connection); nothing was sent: publish it \
                                without the retain flag, and clear the retained one with an \
                                empty retained message on this topic";

fn file(port: u16, homeassistant: bool) -> common::File {
    common::parse(&common::top_alone(
        "poll: [{ read: distance_1, every: 50ms }], writable: [light_power, zero_position_1]",
        &format!(
            "broker: 127.0.0.1:{port}, prefix: plant, client_id: hall-2, \
             homeassistant: {homeassistant}"
        ),
    ))
}

/// A running bus of `file` with a publisher taking writes.
fn start(file: &common::File) -> (Running, Publisher) {
    common::start_taking_writes(Bus::new(file.bus.clone()), file)
}

async fn wait_counts(publisher: &Publisher, what: &str, done: impl Fn(&Counts) -> bool) {
    for _ in 0..3000 {
        if done(&publisher.counts()) {
            return;
        }
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    panic!("{what}: {:?}", publisher.counts());
}

/// Waits until the publisher is connected and has subscribed (a write sent earlier would
/// not reach it).
async fn subscribed(publisher: &Publisher) {
    wait_counts(publisher, "connected", |c| c.connected).await;
    tokio::time::sleep(Duration::from_millis(500)).await;
}

/// How many of `heard` came on `topic` after `since`.
fn heard_since(heard: &[Heard], topic: &str, since: SystemTime) -> usize {
    heard
        .iter()
        .filter(|h| h.topic == topic && h.arrived > since)
        .count()
}

/// Publishing goes on: the watcher hears `at_least` samples of the head's distance after
/// `since` within `within`, else the test fails with the publisher's counts.
async fn samples_go_on(
    watcher: &Watcher,
    publisher: &Publisher,
    since: SystemTime,
    at_least: usize,
    within: Duration,
) {
    let heard = watcher
        .wait_for(within, |heard| {
            heard_since(heard, "plant/top/distance_1", since) >= at_least
        })
        .await;
    assert!(
        heard,
        "fewer than {at_least} samples heard: {:?}",
        publisher.counts()
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn a_262_kb_set_payload_is_refused_and_publishing_goes_on() {
    let broker = Broker::start("large-set").await;
    let watcher = Watcher::start(broker.port, "watcher-large", "plant/top/#").await;
    let file = file(broker.port, false);
    let (running, publisher) = start(&file);
    let simulator = running.simulator("top").unwrap();
    let power = P.register("light_power").unwrap();
    let power_before = simulator.peek(power.table, power.address).unwrap();
    subscribed(&publisher).await;
    let (client, _controller) = common::controller(broker.port, "controller");

    // As the author sent it, then a 1 MB one (over the client's former packet limit).
    for size in [262_060, 1_000_000] {
        client
            .publish(
                "plant/top/light_power/set",
                QoS::AtLeastOnce,
                false,
                "9".repeat(size),
            )
            .await
            .unwrap();
        let expected = format!(
            "the payload is {size} bytes, over the {MAX_WRITE_PAYLOAD} bytes a write takes; \
             nothing was sent"
        );
        assert!(
            watcher
                .hears(Duration::from_secs(20), POWER_ERROR, |h| h.payload
                    == expected)
                .await,
            "no refusal `{expected}`: {:?}",
            watcher
                .on(POWER_ERROR)
                .iter()
                .map(|h| h.payload.len())
                .collect::<Vec<_>>()
        );
    }
    // Under the limit, the value goes to the bus's checks; their message quotes an excerpt.
    client
        .publish(
            "plant/top/light_power/set",
            QoS::AtLeastOnce,
            false,
            "9".repeat(3000),
        )
        .await
        .unwrap();
    assert!(
        watcher
            .wait_for(Duration::from_secs(20), |heard| heard
                .iter()
                .filter(|h| h.topic == POWER_ERROR)
                .count()
                == 3)
            .await
    );
    let errors = watcher.on(POWER_ERROR);
    println!(
        "{:?}",
        errors.iter().map(|h| &h.payload).collect::<Vec<_>>()
    );
    for error in &errors {
        assert!(error.payload.len() <= 400, "{}", error.payload);
        assert!(
            !error.payload.contains(&"9".repeat(41)),
            "{}",
            error.payload
        );
    }

    // Publishing goes on, on the one connection.
    let since = SystemTime::now();
    samples_go_on(&watcher, &publisher, since, 20, Duration::from_secs(20)).await;
    let counts = publisher.counts();
    assert_eq!(counts.connections, 1, "{counts:?}");
    assert_eq!(counts.writes_too_large, 2, "{counts:?}");
    assert_eq!(counts.writes_taken, 1, "{counts:?}");
    assert_eq!(
        (counts.oversize_dropped, counts.incoming_too_large),
        (0, 0),
        "{counts:?}"
    );
    assert_eq!(
        simulator.peek(power.table, power.address).unwrap(),
        power_before,
        "nothing was written"
    );
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn ten_thousand_writes_are_refused_beyond_the_queue_and_the_polls_go_on() {
    const WRITES: usize = 10_000;
    let broker = Broker::start("write-flood").await;
    let watcher = Watcher::start(broker.port, "watcher-flood", "plant/top/#").await;
    let file = file(broker.port, false);
    let (running, publisher) = start(&file);
    let simulator = running.simulator("top").unwrap();
    let power = P.register("light_power").unwrap();
    subscribed(&publisher).await;
    let (client, _controller) = common::controller(broker.port, "controller");

    // Values 1.0 % to 99.9 %, every one a valid light power.
    let value = |n: usize| {
        let tenths = 10 + n % 990;
        format!("{}.{} %", tenths / 10, tenths % 10)
    };
    let flood_start = SystemTime::now();
    for n in 0..WRITES {
        client
            .publish(
                "plant/top/light_power/set",
                QoS::AtLeastOnce,
                false,
                value(n),
            )
            .await
            .unwrap();
    }
    // The polls go on during the flood (on 9e415f3, none for minutes).
    samples_go_on(
        &watcher,
        &publisher,
        flood_start,
        10,
        Duration::from_secs(30),
    )
    .await;
    wait_counts(&publisher, "every write taken in", |c| {
        c.writes_taken + c.writes_busy == WRITES as u64
    })
    .await;
    let counts = publisher.counts();
    println!("{counts:?}");
    assert!(counts.writes_busy > 0, "{counts:?}");
    assert!(counts.writes_taken >= WRITE_QUEUE as u64, "{counts:?}");
    assert_eq!(counts.connections, 1, "{counts:?}");

    // Every value read back is one that was sent, and the device holds one of them.
    let sent: std::collections::HashSet<String> = (10..1000)
        .map(|tenths| format!("{}.{}", tenths / 10, tenths % 10))
        .collect();
    let read_back = watcher.on("plant/top/light_power");
    assert!(!read_back.is_empty());
    for heard in &read_back {
        let json: serde_json::Value = serde_json::from_str(&heard.payload).unwrap();
        let text = json["text"].as_str().unwrap_or_default();
        assert!(sent.contains(text), "{}", heard.payload);
    }
    let busy: Vec<_> = watcher
        .on(POWER_ERROR)
        .into_iter()
        .map(|h| h.payload)
        .collect();
    assert!(!busy.is_empty());
    for refusal in &busy {
        assert_eq!(
            *refusal,
            format!(
                "{WRITE_QUEUE} writes from MQTT already wait for their turn; nothing was sent, \
                 try again later"
            )
        );
    }
    let words = simulator.peek(power.table, power.address).unwrap();
    assert!(
        words.len() == 1 && (10..1000).contains(&words[0]),
        "a value that was sent: {words:?}"
    );

    // Once the flood is over, a write is done with its value (one the flood did not send).
    client
        .publish(
            "plant/top/light_power/set",
            QoS::AtLeastOnce,
            false,
            "0.7 %",
        )
        .await
        .unwrap();
    assert!(
        watcher
            .hears(Duration::from_secs(20), "plant/top/light_power", |h| h
                .payload
                .contains("\"0.7\""))
            .await
    );
    assert_eq!(simulator.peek(power.table, power.address).unwrap(), [7]);
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn twenty_thousand_homeassistant_status_messages_keep_the_control_queue_bounded() {
    const BIRTHS: u64 = 20_000;
    let broker = Broker::start("births").await;
    let watcher = Watcher::start(broker.port, "watcher-births", "#").await;
    let file = file(broker.port, true);
    let (running, publisher, mut events) = common::start_publishing(&file);
    subscribed(&publisher).await;
    let configs = |heard: &[Heard]| {
        heard
            .iter()
            .filter(|h| h.topic.starts_with("homeassistant/") && h.topic.ends_with("/config"))
            .count()
    };
    assert!(
        watcher
            .wait_for(Duration::from_secs(10), |heard| configs(heard) > 0)
            .await
    );
    let per_announcement = configs(&watcher.heard.lock().unwrap());
    let (client, _controller) = common::controller(broker.port, "controller");

    for _ in 0..BIRTHS {
        client
            .publish("homeassistant/status", QoS::AtLeastOnce, false, "online")
            .await
            .unwrap();
    }
    wait_counts(&publisher, "every birth heard", |c| {
        c.homeassistant_births == BIRTHS
    })
    .await;
    wait_counts(&publisher, "everything sent", |c| {
        c.control_queued == 0 && c.queued == 0
    })
    .await;
    let counts = publisher.counts();
    println!("{per_announcement} configurations; {counts:?}");
    // At connection: status, availability and the configurations; then at most one
    // re-announcement waiting beside them.
    assert!(
        counts.control_peak <= 2 + 2 * per_announcement,
        "{per_announcement} configurations, {counts:?}"
    );
    let announced_again = BIRTHS - counts.rediscoveries_coalesced;
    assert!(announced_again >= 1, "{counts:?}");
    assert_eq!(counts.connections, 1, "{counts:?}");
    // What was announced again reached the broker: as many configurations as re-announcements
    // made, besides the first.
    assert!(
        watcher
            .wait_for(Duration::from_secs(20), |heard| configs(heard)
                >= per_announcement * (1 + announced_again as usize))
            .await,
        "{} heard, {counts:?}",
        configs(&watcher.heard.lock().unwrap())
    );
    // The bus polls on and its samples are published.
    let since = SystemTime::now();
    while events.try_recv().is_ok() {}
    let mut samples = 0;
    while samples < 5 {
        let event = tokio::time::timeout(Duration::from_secs(20), events.recv()).await;
        match event.expect("the bus polls on") {
            Ok(Event::Sample(_)) => samples += 1,
            Ok(_) | Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {}
            Err(error) => panic!("{error}"),
        }
    }
    samples_go_on(&watcher, &publisher, since, 5, Duration::from_secs(20)).await;
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn a_retained_set_is_refused_and_not_carried_out() {
    let broker = Broker::start("retained-set").await;
    let watcher = Watcher::start(broker.port, "watcher-retained", "plant/top/#").await;
    // Retained before the publisher subscribes: the broker hands it over at the subscription,
    // with the retain flag (a live message reaches a subscriber without it).
    let (client, _controller) = common::controller(broker.port, "controller");
    client
        .publish("plant/top/light_power/set", QoS::AtLeastOnce, true, "55 %")
        .await
        .unwrap();
    assert!(
        watcher
            .hears(Duration::from_secs(10), "plant/top/light_power/set", |_| {
                true
            })
            .await
    );
    let file = file(broker.port, false);
    let (running, publisher) = start(&file);
    let simulator = running.simulator("top").unwrap();
    let power = P.register("light_power").unwrap();
    let power_before = simulator.peek(power.table, power.address).unwrap();
    let expected = RETAINED_REFUSAL;
    assert!(
        watcher
            .hears(Duration::from_secs(20), POWER_ERROR, |h| h.payload
                == expected)
            .await,
        "{:?}",
        watcher.on(POWER_ERROR)
    );
    let counts = publisher.counts();
    assert_eq!(
        (counts.writes_retained, counts.writes_taken),
        (1, 0),
        "{counts:?}"
    );
    assert_eq!(
        simulator.peek(power.table, power.address).unwrap(),
        power_before
    );
    assert_ne!(power_before, [550]);
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn a_retained_do_is_refused_at_start_and_at_every_reconnection_and_never_runs() {
    // Issue 29: a retained `zero_position_1/do` re-zeroed the head at start and at every
    // reconnection to the broker.
    let mut broker = Broker::start("retained-do").await;
    let watcher = Watcher::start(broker.port, "watcher-retained-do", "plant/top/#").await;
    let (client, controller) = common::controller(broker.port, "controller");
    client
        .publish(
            "plant/top/zero_position_1/do",
            QoS::AtLeastOnce,
            true,
            "PRESS",
        )
        .await
        .unwrap();
    assert!(
        watcher
            .hears(
                Duration::from_secs(10),
                "plant/top/zero_position_1/do",
                |_| true
            )
            .await
    );
    drop(controller);
    let file = file(broker.port, false);
    let (running, publisher) = start(&file);
    let simulator = running.simulator("top").unwrap();
    let zero = P.register("position_1_zero").unwrap();
    let expected = RETAINED_REFUSAL;
    let refusals = |heard: &[Heard]| {
        heard
            .iter()
            .filter(|h| h.topic == "plant/top/zero_position_1/error" && h.payload == expected)
            .count()
    };
    assert!(
        watcher
            .wait_for(Duration::from_secs(20), |heard| refusals(heard) == 1)
            .await,
        "{:?}",
        watcher.on("plant/top/zero_position_1/error")
    );
    wait_counts(&publisher, "the retained command refused at start", |c| {
        c.writes_retained == 1
    })
    .await;
    // The broker restarts (keeping its retained messages): at the new subscription the
    // command comes again, and is refused again.
    broker.stop();
    broker.run().await;
    wait_counts(&publisher, "refused again after the reconnection", |c| {
        c.connections == 2 && c.writes_retained == 2
    })
    .await;
    let counts = publisher.counts();
    assert_eq!(counts.writes_taken, 0, "{counts:?}");
    assert_eq!(
        simulator.peek(zero.table, zero.address).unwrap(),
        [0],
        "the head was never zeroed"
    );
    running.stop();
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn a_payload_over_the_incoming_limit_breaks_one_connection_and_publishing_goes_on() {
    let broker = Broker::start("over-incoming").await;
    let watcher = Watcher::start(broker.port, "watcher-over", "plant/top/distance_1").await;
    let file = file(broker.port, false);
    let (running, publisher) = start(&file);
    subscribed(&publisher).await;
    let (client, _controller) = common::controller(broker.port, "controller");
    client
        .publish(
            "plant/top/light_power/set",
            QoS::AtLeastOnce,
            false,
            vec![b'9'; optobus_mqtt::MAX_INCOMING_PACKET + 1000],
        )
        .await
        .unwrap();
    wait_counts(&publisher, "the break counted and connected again", |c| {
        c.incoming_too_large == 1 && c.connected && c.connections == 2
    })
    .await;
    let since = SystemTime::now();
    samples_go_on(&watcher, &publisher, since, 10, Duration::from_secs(20)).await;
    let counts = publisher.counts();
    assert_eq!(
        (
            counts.connections,
            counts.writes_taken,
            counts.writes_too_large
        ),
        (2, 0, 0),
        "{counts:?}"
    );
    running.stop();
}
