//! Rangefinder end to end over our RTU client: one address per field, 32-bit settings in one
//! 4-byte FC06 whose 10-byte echo the client checks.

use optobus_device::Table;
use optobus_rangefinder::{MeasurementFrequency, Rangefinder, DEVICE};
use optobus_simulator::Simulator;
use optobus_tests::e2e;

fn sensor() -> (Simulator, Rangefinder<impl optobus_driver::Transport>) {
    let (sim, client) = e2e::simulated(&DEVICE);
    let sensor = Rangefinder::with_default_slave(client);
    (sim, sensor)
}

#[tokio::test(start_paused = true)]
async fn every_register_and_group() {
    let (_sim, mut sensor) = sensor();
    assert!(e2e::sweep(sensor.core()).await > 40);
    let m = sensor.read_measurements().await.unwrap();
    assert!(m.measurement_results.distance > 0);
    let status = sensor.read_status().await.unwrap();
    assert!(status.distance.is_some());
    sensor.read_serial_settings().await.unwrap();
    sensor.read_measurement_settings().await.unwrap();
    let info = sensor.read_device_info().await.unwrap();
    assert!(info.max_measuring_distance >= info.min_measuring_distance);
    sensor.read_analog_output().await.unwrap();
    sensor.read_switch_io().await.unwrap();
    sensor.read_can_settings().await.unwrap();
}

#[tokio::test(start_paused = true)]
async fn four_byte_writes() {
    let (sim, mut sensor) = sensor();
    sensor.set_dac_range_max(654_321).await.unwrap();
    // One address holds the whole field.
    assert_eq!(sim.peek(Table::Holding, 12), Some(vec![0x0009, 0xFBF1]));
    assert_eq!(sensor.dac_range_max().await.unwrap(), 654_321);
    sensor.set_can_transmit_id(0x1234_5678).await.unwrap();
    assert_eq!(sensor.can_transmit_id().await.unwrap(), 0x1234_5678);
    let error = sensor.set_can_transmit_id(0x2000_0000).await.unwrap_err();
    assert!(
        matches!(error, optobus_driver::Error::OutOfRange { .. }),
        "{error}"
    );
}

#[tokio::test(start_paused = true)]
async fn typed_settings_and_commands() {
    let (_sim, mut sensor) = sensor();
    sensor
        .set_distance_offset("-12.5".parse().unwrap())
        .await
        .unwrap();
    assert_eq!(
        sensor.distance_offset().await.unwrap().to_string(),
        "-12.5 mm"
    );
    for frequency in MeasurementFrequency::ALL {
        sensor.set_measurement_frequency(frequency).await.unwrap();
        assert_eq!(sensor.measurement_frequency().await.unwrap(), frequency);
    }
    sensor.switch_laser_on().await.unwrap();
    sensor.start_measurement().await.unwrap();
    sensor.stop_measurement().await.unwrap();
    sensor.save_parameters().await.unwrap();
}
