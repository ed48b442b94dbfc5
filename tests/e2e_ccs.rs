//! CCS end to end over our RTU client.

use optobus_ccs::{Ccs, ExposureMode, SamplingInterval, DEVICE};
use optobus_tests::e2e;

#[tokio::test(start_paused = true)]
async fn every_register_and_group() {
    let (_sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = Ccs::with_default_slave(client);
    assert!(e2e::sweep(sensor.core()).await > 20);
    let m = sensor.read_measurements().await.unwrap();
    assert!(m.distance_1.is_some());
    sensor.read_encoder_counts().await.unwrap();
    sensor.read_peak_heights().await.unwrap();
    sensor.read_exposure_settings().await.unwrap();
    sensor.read_measurement_settings().await.unwrap();
}

#[tokio::test(start_paused = true)]
async fn typed_settings_and_commands() {
    let (_sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = Ccs::with_default_slave(client);
    sensor
        .set_exposure_mode(ExposureMode::ALL[1])
        .await
        .unwrap();
    sensor
        .set_exposure_time("1234.5".parse().unwrap())
        .await
        .unwrap();
    let settings = sensor.read_exposure_settings().await.unwrap();
    assert_eq!(settings.exposure_mode, ExposureMode::ALL[1]);
    assert_eq!(settings.exposure_time.to_string(), "1234.5 us");
    sensor
        .set_sampling_interval(SamplingInterval::ALL[2])
        .await
        .unwrap();
    assert_eq!(
        sensor.sampling_interval().await.unwrap(),
        SamplingInterval::ALL[2]
    );
    sensor.zero_position().await.unwrap();
    let zeroed = sensor.distance_1().await.unwrap().unwrap();
    assert!(zeroed.to_f64().abs() < 0.5, "{zeroed}");
    sensor.clear_position_zero().await.unwrap();
    sensor.reset_trigger_count().await.unwrap();
    sensor.save_parameters().await.unwrap();
}
