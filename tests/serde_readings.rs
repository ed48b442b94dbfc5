//! Readings to JSON and back (feature `serde` of the driver crates): quantities as exact text
//! with their unit, codes with their names, every group of every family equal after the
//! round trip; and the tool's generic values (`optobus --json`) in the very same JSON.

use optobus_ccf::{Ccf, Channel, MovingAverageWindow, SamplingInterval};
use optobus_device::DeviceInfo;
use optobus_driver::Core;
use optobus_p_series::PSeries;
use optobus_simulator::Simulator;
use optobus_tests::e2e::{rtu, simulated};
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::{json, Value};

/// `value` as JSON, checked to read back equal.
fn round_trip<T: Serialize + DeserializeOwned + PartialEq + std::fmt::Debug>(value: &T) -> Value {
    let text = serde_json::to_string(value).unwrap();
    let back: T = serde_json::from_str(&text).unwrap();
    assert_eq!(&back, value, "{text}");
    serde_json::from_str(&text).unwrap()
}

#[tokio::test]
async fn p_series_readings_round_trip_with_exact_quantities() {
    let (_sim, client) = simulated(&optobus_p_series::DEVICE);
    let mut sensor = PSeries::with_default_slave(client);
    let m = sensor.read_measurements().await.unwrap();
    let json = round_trip(&m);
    let d1 = m.distance_1.expect("valid distance");
    // The exact decimal text the register holds, not a float.
    assert_eq!(
        json["distance_1"],
        json!({"value": d1.millimetres().to_string(), "unit": "mm"})
    );
    // 60 samples: longer than serde's own arrays go.
    let page = sensor.read_buffer_page().await.unwrap();
    assert_eq!(
        round_trip(&page)["buffered_value"].as_array().map(Vec::len),
        Some(60)
    );
    round_trip(&sensor.read_sampled_data().await.unwrap());
    round_trip(&sensor.read_buffer_status().await.unwrap());
    round_trip(&sensor.read_network_info().await.unwrap());
    round_trip(&sensor.read_laser().await.unwrap());
    round_trip(&sensor.read_filters().await.unwrap());
    round_trip(&sensor.read_statistics_config().await.unwrap());
    round_trip(&sensor.read_buffer_settings().await.unwrap());
    // A slope in steps of 1/2^20 reads back as the same exact value in decimal steps: equal in
    // value (and in JSON), not in representation.
    let corrections = sensor.read_corrections().await.unwrap();
    let text = serde_json::to_string(&corrections).unwrap();
    let back: optobus_p_series::Corrections = serde_json::from_str(&text).unwrap();
    assert_eq!(serde_json::to_string(&back).unwrap(), text);
    let slope = corrections.position_1_slope;
    assert_eq!(back.position_1_slope.to_scale(slope.scale()), Ok(slope));
    assert_eq!(back.position_1_offset, corrections.position_1_offset);
    round_trip(&sensor.read_modbus_settings().await.unwrap());
}

#[tokio::test]
async fn codes_serialise_with_code_and_name_and_read_back_from_either() {
    let (_sim, client) = simulated(&optobus_ccf::DEVICE);
    let mut sensor = Ccf::with_default_slave(client);
    sensor
        .set_sampling_interval(SamplingInterval::Ms2)
        .await
        .unwrap();
    let settings = sensor.read_measurement_settings().await.unwrap();
    let json = round_trip(&settings);
    assert_eq!(
        json["sampling_interval"],
        json!({"code": 3, "name": "ms_2"})
    );
    let window = settings.moving_average_window;
    assert_eq!(
        json["moving_average_window"],
        json!({"code": window.raw(), "name": window.to_string()})
    );
    for channel in Channel::all() {
        round_trip(&sensor.read_measurements(channel).await.unwrap());
        round_trip(&sensor.read_exposure_settings(channel).await.unwrap());
    }

    let by_name: MovingAverageWindow =
        serde_json::from_value(json!({"name": "window_64"})).unwrap();
    assert_eq!(by_name, MovingAverageWindow::Window64);
    // A code the manual does not define survives as itself.
    let unknown = MovingAverageWindow::from_raw(99);
    assert_eq!(round_trip(&unknown), json!({"code": 99, "name": null}));
    // Contradictions and unknown names are refused, never guessed.
    let contradiction =
        serde_json::from_value::<MovingAverageWindow>(json!({"code": 2, "name": "window_4"}));
    assert!(contradiction
        .unwrap_err()
        .to_string()
        .contains("code 2 is not named `window_4`"));
    let unknown_name = serde_json::from_value::<MovingAverageWindow>(json!({"name": "window_5"}));
    assert!(unknown_name
        .unwrap_err()
        .to_string()
        .contains("no code is named `window_5`"));
}

#[tokio::test]
async fn every_family_reads_its_first_group_back_equal() {
    let (_sim, client) = simulated(&optobus_ccs::DEVICE);
    let mut ccs = optobus_ccs::Ccs::with_default_slave(client);
    round_trip(&ccs.read_measurements().await.unwrap());
    let (_sim, client) = simulated(&optobus_rangefinder::DEVICE);
    let mut rangefinder = optobus_rangefinder::Rangefinder::with_default_slave(client);
    round_trip(&rangefinder.read_measurements().await.unwrap());
    let (_sim, client) = simulated(&optobus_lc_rs::DEVICE);
    let mut lc_rs = optobus_lc_rs::LcRs::with_default_slave(client);
    round_trip(&lc_rs.read_measurements().await.unwrap());
}

/// The registers of `group` read from `sim` through the generic runtime and decoded as the
/// `optobus` tool does for `--json` (`optobus_inspect::decode_value`), as one object.
async fn generic_json(sim: &Simulator, device: &'static DeviceInfo, group: &str) -> Value {
    let group = device.group(group).expect("group");
    let registers: Vec<_> = group
        .registers
        .iter()
        .map(|name| device.register(name).expect("register"))
        .collect();
    let mut core = Core::new(rtu(sim), device.default_slave, device).unwrap();
    let readings = core.read_group(&registers).await.unwrap();
    let values = registers.iter().map(|r| {
        let value = optobus_inspect::decode_value(r, readings.words(r));
        (r.name.to_owned(), serde_json::to_value(value).unwrap())
    });
    Value::Object(values.collect())
}

#[tokio::test]
async fn the_tools_json_is_the_typed_readings_json() {
    // Settings, which hold still between two reads: quantities, codes, packed fields, an
    // IPv4 address and integers.
    let (sim, client) = simulated(&optobus_p_series::DEVICE);
    let mut p = PSeries::with_default_slave(client);
    let typed = serde_json::to_value(p.read_filters().await.unwrap()).unwrap();
    assert_eq!(
        typed,
        generic_json(&sim, &optobus_p_series::DEVICE, "filters").await
    );
    let typed = serde_json::to_value(p.read_network_info().await.unwrap()).unwrap();
    assert_eq!(
        typed,
        generic_json(&sim, &optobus_p_series::DEVICE, "network_info").await
    );
    let typed = serde_json::to_value(p.read_laser().await.unwrap()).unwrap();
    assert_eq!(
        typed,
        generic_json(&sim, &optobus_p_series::DEVICE, "laser").await
    );

    let (sim, client) = simulated(&optobus_ccf::DEVICE);
    let mut ccf = Ccf::with_default_slave(client);
    let typed = serde_json::to_value(ccf.read_measurement_settings().await.unwrap()).unwrap();
    let generic = generic_json(&sim, &optobus_ccf::DEVICE, "measurement_settings").await;
    assert_eq!(typed, generic);

    // A version: named parts, as the typed struct serialises.
    let (sim, client) = simulated(&optobus_lc_rs::DEVICE);
    let mut lc_rs = optobus_lc_rs::LcRs::with_default_slave(client);
    let typed = serde_json::to_value(lc_rs.firmware_version().await.unwrap()).unwrap();
    let register = optobus_lc_rs::DEVICE.register("firmware_version").unwrap();
    let mut core = Core::new(rtu(&sim), 1, &optobus_lc_rs::DEVICE).unwrap();
    let words = core.read_words(register).await.unwrap();
    let generic = serde_json::to_value(optobus_inspect::decode_value(register, &words)).unwrap();
    assert_eq!(typed, generic);
    assert_eq!(typed, json!({"major": 1, "minor": 0, "patch": 0}));
    let typed = serde_json::to_value(lc_rs.read_serial_settings().await.unwrap()).unwrap();
    assert_eq!(
        typed,
        generic_json(&sim, &optobus_lc_rs::DEVICE, "serial_settings").await
    );
}
