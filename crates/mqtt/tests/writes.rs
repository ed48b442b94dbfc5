//! Writes from MQTT on a real mosquitto: `/set` and `/do` for what the bus file lists, checked
//! exactly as `optobus set` and `optobus do` check; every refusal answered on `…/error` with
//! the tool's message, nothing sent to the device, and the bus polling on.

mod common;

use std::time::Duration;

use common::{Broker, Watcher};
use optobus_bus::{Bus, Event};
use rumqttc::QoS;

const P: &optobus_device::DeviceInfo = &optobus_p_series::DEVICE;

fn file(port: u16) -> common::File {
    common::parse(&common::top_alone(
        "poll: [{ read: distance_1, every: 50ms }], writable: [light_power, zero_position_1]",
        &format!("broker: 127.0.0.1:{port}, prefix: plant"),
    ))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn writes_from_topics_are_checked_like_optobus_set_and_refusals_go_to_error_topics() {
    let broker = Broker::start("writes").await;
    let watcher = Watcher::start(broker.port, "watcher-writes", "plant/#").await;
    let file = file(broker.port);
    let bus = Bus::new(file.bus.clone());
    let mut events = bus.subscribe();
    let (running, _publisher) = common::start_taking_writes(bus, &file);
    let handle = running.handle();
    let simulator = running.simulator("top").unwrap();
    let power = P.register("light_power").unwrap();
    let laser = P.register("laser_enabled").unwrap();
    let words = |register: &optobus_device::RegisterInfo| {
        simulator.peek(register.table, register.address).unwrap()
    };
    let laser_before = words(laser);
    // The publisher subscribes once connected.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (client, _controller) = common::controller(broker.port, "controller");

    // A listed register, with a unit prefix as `optobus set` takes it: written, read back.
    client
        .publish("plant/top/light_power/set", QoS::AtLeastOnce, false, "55 %")
        .await
        .unwrap();
    assert!(
        watcher
            .hears(Duration::from_secs(10), "plant/top/light_power", |h| h
                .payload
                .contains("\"55.0\""))
            .await,
        "{:?}",
        watcher.heard.lock().unwrap()
    );
    assert_eq!(words(power), [550], "the device holds 55.0 %");

    // Refusals: out of range, not a number, not listed, no such device; the messages are the
    // ones the handle (and so `optobus set`) gives.
    let cases = [
        (
            "plant/top/light_power/set",
            "150",
            "top",
            "light_power",
            Some("150"),
        ),
        (
            "plant/top/light_power/set",
            "lots",
            "top",
            "light_power",
            Some("lots"),
        ),
        (
            "plant/top/laser_enabled/set",
            "false",
            "top",
            "laser_enabled",
            Some("false"),
        ),
        ("plant/top/reboot/do", "PRESS", "top", "reboot", None),
        (
            "plant/nobody/light_power/set",
            "50",
            "nobody",
            "light_power",
            Some("50"),
        ),
    ];
    for (topic, payload, device, name, _) in &cases {
        client
            .publish(*topic, QoS::AtLeastOnce, false, *payload)
            .await
            .unwrap();
        let error_topic = format!("plant/{device}/{name}/error");
        assert!(
            watcher
                .hears(Duration::from_secs(10), &error_topic, |_| true)
                .await,
            "no answer on {error_topic}"
        );
    }
    for (_, _, device, name, value) in &cases {
        let expected = match value {
            Some(text) => handle.set_listed(device, name, text).await.unwrap_err(),
            None => handle.do_listed(device, name).await.unwrap_err(),
        };
        let heard = watcher.on(&format!("plant/{device}/{name}/error"));
        assert!(
            heard.iter().any(|h| h.payload == expected.to_string()),
            "{name}: {heard:?} against {expected}"
        );
    }
    assert!(watcher.on("plant/top/laser_enabled/error")[0]
        .payload
        .contains("not writable here"));
    assert_eq!(words(power), [550], "nothing was written by a refusal");
    assert_eq!(words(laser), laser_before);

    // A listed command runs.
    client
        .publish(
            "plant/top/zero_position_1/do",
            QoS::AtLeastOnce,
            false,
            "PRESS",
        )
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(500)).await;
    assert!(watcher.on("plant/top/zero_position_1/error").is_empty());

    // The bus polls on.
    while events.try_recv().is_ok() {}
    let mut samples = 0;
    while samples < 3 {
        if let Ok(Ok(Event::Sample(_))) =
            tokio::time::timeout(Duration::from_secs(5), events.recv()).await
        {
            samples += 1;
        }
    }
    running.stop();
}
