//! CCF end to end over our RTU client: four channels through one accessor each.

use optobus_ccf::{Ccf, Channel, ExposureMode, DEVICE};
use optobus_tests::e2e;

#[tokio::test(start_paused = true)]
async fn every_register_and_group() {
    let (_sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = Ccf::with_default_slave(client);
    assert!(e2e::sweep(sensor.core()).await > 40);
    for channel in Channel::all() {
        let m = sensor.read_measurements(channel).await.unwrap();
        assert!(m.distance_1.is_some());
        sensor.read_peak_heights(channel).await.unwrap();
        sensor.read_exposure_settings(channel).await.unwrap();
    }
    sensor.read_math().await.unwrap();
    sensor.read_encoder_counts().await.unwrap();
    sensor.read_measurement_settings().await.unwrap();
}

#[tokio::test(start_paused = true)]
async fn channels_are_independent() {
    let (_sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = Ccf::with_default_slave(client);
    for channel in Channel::all() {
        let tenths = 1000 + u16::from(channel.number());
        let time = format!("{}.{}", tenths / 10, tenths % 10);
        sensor
            .set_exposure_time(channel, time.parse().unwrap())
            .await
            .unwrap();
    }
    for channel in Channel::all() {
        let settings = sensor.read_exposure_settings(channel).await.unwrap();
        assert_eq!(
            settings.exposure_time.to_string(),
            format!("100.{} us", channel.number())
        );
    }
    let third = Channel::new(3).unwrap();
    sensor
        .set_exposure_mode(third, ExposureMode::ALL[1])
        .await
        .unwrap();
    assert_eq!(
        sensor.exposure_mode(third).await.unwrap(),
        ExposureMode::ALL[1]
    );
    assert_eq!(
        sensor
            .exposure_mode(Channel::new(2).unwrap())
            .await
            .unwrap(),
        ExposureMode::ALL[0]
    );
    sensor.zero_position(third).await.unwrap();
    let zeroed = sensor.distance_1(third).await.unwrap().unwrap();
    assert!(zeroed.to_f64().abs() < 0.5, "{zeroed}");
    let other = sensor
        .distance_1(Channel::new(1).unwrap())
        .await
        .unwrap()
        .unwrap();
    assert!(other.to_f64() > 1.0, "{other}");
    sensor.clear_position_zero(third).await.unwrap();
    assert!(Channel::new(5).is_none());
}

#[tokio::test(start_paused = true)]
async fn point_10_a_refused_value_names_its_unit_and_step_as_numbers() {
    let (_sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = Ccf::with_default_slave(client);
    let channel = Channel::new(2).expect("channel 2");
    let error = sensor
        .set_exposure_time(channel, "5000.1".parse().unwrap())
        .await
        .unwrap_err();
    assert_eq!(
        error.to_string(),
        "5000.1 us is out of range for `channel_2_exposure_time` (0.0 us ..= 5000.0 us)"
    );
    let error = sensor
        .set_exposure_time(channel, "100.05".parse().unwrap())
        .await
        .unwrap_err();
    assert_eq!(
        error.to_string(),
        "100.05 us cannot be written to `channel_2_exposure_time` exactly: it holds whole \
         steps of 0.1 us within its width"
    );
}
