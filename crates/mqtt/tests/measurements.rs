//! Issue 32 on MQTT: each value of a bus file's measurement published on
//! `<prefix>/measurements/<name>` as its JSON contract, on a real mosquitto.

mod common;

use std::path::Path;
use std::time::Duration;

use common::{Broker, Watcher};
use optobus_bus::{Bus, BusFile, Catalogue};
use optobus_codec::value::Fixed;
use serde_json::Value as Json;

fn file(port: u16) -> BusFile {
    let text = format!(
        "
lines:
  - {{ name: rs485, simulated: true, baud: 115200, any_format: true }}
devices:
  - {{ name: top, model: p-series, slave: 1, poll: [{{ read: distance_1, every: 50ms }}] }}
  - {{ name: bottom, model: p-series, slave: 2, poll: [{{ read: distance_1, every: 50ms }}] }}
measurements:
  - name: gap
    expr: 20mm - top.distance_1 - bottom.distance_1
    limits: {{ lo: 9.9mm, hi: 10.1mm }}
    stats: 100
    max_skew: 1s
outputs:
  mqtt: {{ broker: 127.0.0.1:{port}, prefix: plant }}
"
    );
    let catalogue = Catalogue::new([&optobus_p_series::DEVICE]);
    BusFile::parse("bus.yaml", &text, Path::new("."), &catalogue)
        .unwrap_or_else(|e| panic!("{}", e.render()))
}

/// An exact decimal of the JSON.
fn exact(json: &Json) -> Fixed {
    json["value"]
        .as_str()
        .expect("exact text")
        .parse()
        .expect("a decimal")
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
#[cfg_attr(
    not(peer_mosquitto),
    ignore = "mosquitto is not installed (Debian package mosquitto)"
)]
async fn a_measurement_is_published_as_its_json_with_the_inputs_it_was_made_of() {
    let broker = Broker::start("measurements").await;
    let watcher = Watcher::start(broker.port, "watcher-measurements", "plant/measurements/#").await;
    let file = file(broker.port);
    let bus = Bus::new(file.clone());
    let _publisher = common::publish(&file, &bus);
    let _running = bus.start().expect("starts");
    assert!(
        watcher
            .wait_for(Duration::from_secs(15), |heard| heard.len() >= 5)
            .await,
        "no measurement on plant/measurements/gap"
    );
    for heard in watcher.on("plant/measurements/gap") {
        let json: Json = serde_json::from_str(&heard.payload).expect("JSON");
        assert!(!heard.retain);
        assert_eq!(json["measurement"], "gap");
        assert_eq!(json["value"]["unit"], "mm");
        // The value is the exact arithmetic of the inputs it carries.
        let (top, bottom) = (
            exact(&json["inputs"]["top.distance_1"]),
            exact(&json["inputs"]["bottom.distance_1"]),
        );
        let gap = exact(&json["value"]);
        let scale = gap.scale();
        let expected =
            20_000_000 - top.to_scale(scale).unwrap().raw() - bottom.to_scale(scale).unwrap().raw();
        assert_eq!(gap.raw(), expected, "{json}");
        assert!(["ll", "lo", "go", "hi", "hh"].contains(&json["judgement"].as_str().unwrap()));
        assert!(json["stats"]["count"].as_u64().unwrap() >= 1);
        assert!(json["skew_us"].is_u64());
    }
}
