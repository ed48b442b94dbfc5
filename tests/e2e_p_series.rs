//! P series end to end: typed driver → transport → simulated device → back, over our RTU
//! client on an in-memory line and over Modbus TCP (tokio-modbus) on 127.0.0.1.

use std::net::Ipv4Addr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use optobus_codec::Request;

use optobus_driver::transport::Error as WireError;
use optobus_driver::units::Percent;
use optobus_driver::{DownloadProgress, Error, Fixed, Transport};
use optobus_p_series::{MeasurementSource, MedianFilterWidth, PSeries, DEVICE};
use optobus_simulator::{Reply, Simulator};
use optobus_tests::e2e;

async fn every_register_and_group<T: Transport>(sensor: &mut PSeries<T>) {
    // Every P-series register is readable, write-only command registers included.
    assert_eq!(e2e::read_every_register(sensor.core()).await, 106);
    assert!(e2e::write_every_register(sensor.core()).await > 60);
    every_group(sensor).await;
}

async fn every_group<T: Transport>(sensor: &mut PSeries<T>) {
    let m = sensor.read_measurements().await.unwrap();
    let d1 = m.distance_1.expect("valid distance");
    assert!((3.0..7.0).contains(&d1.to_f64()), "{d1}");
    sensor.read_sampled_data().await.unwrap();
    let status = sensor.read_buffer_status().await.unwrap();
    assert_eq!(
        (status.buffer_read_count, status.buffer_valid_count),
        (0, 0)
    );
    let page = sensor.read_buffer_page().await.unwrap();
    assert_eq!(page.buffered_value.len(), 60);
    let network = sensor.read_network_info().await.unwrap();
    assert_eq!(network.ip_address, Ipv4Addr::new(192, 168, 0, 10));
    sensor.read_laser().await.unwrap();
    sensor.read_filters().await.unwrap();
    sensor.read_statistics_config().await.unwrap();
    sensor.read_buffer_settings().await.unwrap();
    sensor.read_corrections().await.unwrap();
    let modbus = sensor.read_modbus_settings().await.unwrap();
    assert_eq!(modbus.slave_address, 1);
}

#[tokio::test(start_paused = true)]
async fn rtu_every_register_and_group() {
    let (_sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = PSeries::with_default_slave(client);
    every_register_and_group(&mut sensor).await;
}

#[tokio::test]
async fn tcp_every_register_and_group() {
    let sim = Simulator::new(&DEVICE).sentinel_every(0);
    let (context, _server) = e2e::tcp(&sim).await;
    let mut sensor = PSeries::with_default_slave(context);
    every_register_and_group(&mut sensor).await;
}

#[tokio::test(start_paused = true)]
async fn typed_values_round_trip() {
    let (sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = PSeries::with_default_slave(client);
    sensor
        .set_light_power("42.5".parse().unwrap())
        .await
        .unwrap();
    assert_eq!(sim.peek(optobus_device::Table::Holding, 2), Some(vec![425]));
    assert_eq!(
        sensor.light_power().await.unwrap(),
        "42.5".parse::<Percent>().unwrap()
    );
    sensor
        .set_median_filter_width(MedianFilterWidth::ALL[1])
        .await
        .unwrap();
    assert_eq!(
        sensor.median_filter_width().await.unwrap(),
        MedianFilterWidth::ALL[1]
    );
    // Slope 2.0 (×2^20) and offset -1.5 mm, each written low word first.
    sensor.set_position_1_slope(Fixed::from(2)).await.unwrap();
    assert_eq!(sensor.position_1_slope().await.unwrap().to_string(), "2");
    sensor
        .set_position_1_offset("-1.5".parse().unwrap())
        .await
        .unwrap();
    let offset = sensor.position_1_offset().await.unwrap();
    assert_eq!(offset.micrometres().to_string(), "-1500.000");
    let words = [29, 30].map(|a| sim.peek(optobus_device::Table::Holding, a));
    assert_eq!(words, [Some(vec![0xFFE9]), Some(vec![0x1CA0])]);
    // A pinned reading is exact: 0x0036B0BE is 3.584190 mm (5.3.1).
    sim.set("distance_1", &[0x0036, 0xB0BE]).unwrap();
    let distance = sensor.distance_1().await.unwrap().unwrap();
    assert_eq!(distance.to_string(), "3.584190 mm");
    // The invalid sentinel reads as None.
    sim.set("distance_1", &[0x7FFF, 0xFFFF]).unwrap();
    assert_eq!(sensor.distance_1().await.unwrap(), None);
    // An undefined code reads as Unknown, never an error.
    sim.set("median_filter_width", &[0x00EE]).unwrap();
    assert_eq!(
        sensor.median_filter_width().await.unwrap(),
        MedianFilterWidth::Unknown(0xEE)
    );
}

#[tokio::test(start_paused = true)]
async fn commands_act_on_the_device() {
    let (_sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = PSeries::with_default_slave(client);
    let before = sensor.distance_1().await.unwrap().unwrap();
    assert!(before.to_f64() > 1.0);
    sensor.zero_position_1().await.unwrap();
    let zeroed = sensor.distance_1().await.unwrap().unwrap();
    assert!(zeroed.to_f64().abs() < 0.5, "{zeroed}");
    sensor.clear_zero_position_1().await.unwrap();
    let back = sensor.distance_1().await.unwrap().unwrap();
    assert!(back.to_f64() > 1.0, "{back}");
    sensor.save_parameters().await.unwrap();
    // The reboot keeps the device busy: the driver waits it out, then the device answers.
    let started = tokio::time::Instant::now();
    sensor.reboot().await.unwrap();
    assert!(started.elapsed() >= Duration::from_millis(5000));
    sensor.laser_enabled().await.unwrap();
}

#[tokio::test(start_paused = true)]
async fn download_1000_buffered_values() {
    let (_sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = PSeries::with_default_slave(client);
    sensor
        .start_buffering(MeasurementSource::ALL[0], 1000)
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut seen = Vec::new();
    let values = sensor
        .download_buffer(|p: DownloadProgress| seen.push(p))
        .await
        .unwrap();
    assert_eq!(values.len(), 1000);
    assert!(values
        .iter()
        .all(|v| v.is_some_and(|d| d.to_f64() > 3.0 && d.to_f64() < 7.0)));
    assert_eq!(seen.len(), 17, "17 pages of at most 60 (5.4)");
    assert_eq!(
        seen.last().map(|p| (p.received, p.expected)),
        Some((1000, 1000))
    );
    // Unlocked again afterwards, which clears the buffer.
    assert!(!sensor.buffer_locked().await.unwrap());
    assert_eq!(
        sensor.read_buffer_status().await.unwrap().buffer_read_count,
        0
    );
    // Over the limit the manual gives: refused before the wire.
    let error = sensor
        .start_buffering(MeasurementSource::ALL[0], 2501)
        .await
        .unwrap_err();
    assert!(
        matches!(error, Error::OutOfRange { max: 2500, .. }),
        "{error}"
    );
}

#[tokio::test(start_paused = true)]
async fn device_exceptions_are_typed() {
    let (_sim, mut client) = e2e::simulated(&DEVICE);
    // Reserved input 141: reads as zeros (spec README); past the table: 02.
    let error = client
        .read(1, optobus_driver::transport::ReadFunction::Input, 158, 4)
        .await
        .unwrap_err();
    assert!(
        matches!(error, WireError::Exception { function: 4, code } if code.0 == 2),
        "{error}"
    );
    // A value the device refuses when written raw (light power 0): 03, register unchanged.
    let error = client
        .write(1, 2, optobus_driver::transport::WriteValue::Word(0))
        .await
        .unwrap_err();
    assert!(
        matches!(error, WireError::Exception { function: 6, code } if code.0 == 3),
        "{error}"
    );
}

#[tokio::test(start_paused = true)]
async fn wait_ready_after_a_power_cycle() {
    let (sim, client) = e2e::simulated(&DEVICE);
    let mut sensor = PSeries::with_default_slave(client);
    sim.power_cycle();
    let took = sensor.wait_ready().await.unwrap();
    assert!(took >= Duration::from_millis(4000), "{took:?}");
    sim.set_silent(true);
    let error = sensor
        .core()
        .wait_ready(Duration::from_secs(3))
        .await
        .unwrap_err();
    assert!(matches!(error, Error::NotReady { .. }), "{error}");
}

/// The words each read of the save flag (holding 20) got, and the writes to it, in order
/// (`W` for a write).
fn save_flag_log(sim: Simulator) -> (Simulator, Arc<Mutex<Vec<String>>>) {
    let log = Arc::new(Mutex::new(Vec::new()));
    let seen = Arc::clone(&log);
    let sim = sim.observe(move |exchange| {
        let entry = match (exchange.request, exchange.reply) {
            (Some(Request::Read { address: 20, .. }), Reply::Read { words, .. }) => {
                format!("{words:?}")
            }
            (Some(Request::Write { address: 20, .. }), _) => "W".to_owned(),
            _ => return,
        };
        seen.lock().unwrap().push(entry);
    });
    (sim, log)
}

/// 4.1.2 (0020): the save flag "returns to 0 automatically when storing is over": the command
/// is done only once a read of the register shows 0, never at the echo.
#[tokio::test(start_paused = true)]
async fn save_parameters_is_done_only_once_its_flag_reads_0_again() {
    let (sim, log) = save_flag_log(Simulator::new(&DEVICE).finish_time(Duration::from_millis(300)));
    let mut sensor = PSeries::with_default_slave(e2e::rtu(&sim));
    let started = tokio::time::Instant::now();
    sensor.save_parameters().await.unwrap();
    assert!(started.elapsed() >= Duration::from_millis(300));
    let log = log.lock().unwrap().clone();
    // The write, reads of 1 while the flash write goes on, and the read of 0 that ended it.
    assert_eq!(log.first().map(String::as_str), Some("W"), "{log:?}");
    assert_eq!(log.last().map(String::as_str), Some("[0]"), "{log:?}");
    let busy = &log[1..log.len() - 1];
    assert!(busy.len() >= 2, "{log:?}");
    assert!(busy.iter().all(|read| read == "[1]"), "{log:?}");
}

/// A device whose save flag never clears: the typed error once the spec's bound (2 s) has
/// passed, never "done".
#[tokio::test(start_paused = true)]
async fn a_save_that_never_finishes_is_a_typed_error_within_the_bound() {
    let (sim, log) = save_flag_log(Simulator::new(&DEVICE).finish_time(Duration::MAX));
    let mut sensor = PSeries::with_default_slave(e2e::rtu(&sim));
    let started = tokio::time::Instant::now();
    let error = sensor.save_parameters().await.unwrap_err();
    let waited = started.elapsed();
    match &error {
        Error::CommandNotFinished {
            command,
            register,
            expected,
            last_read,
            last_error,
            ..
        } => {
            assert_eq!(
                (*command, *register),
                ("save_parameters", "save_parameters")
            );
            assert_eq!((*expected, *last_read), (0, Some(1)));
            assert!(last_error.is_none(), "{error}");
        }
        other => panic!("expected CommandNotFinished, got {other:?}"),
    }
    assert_eq!(
        error.to_string(),
        format!(
            "`save_parameters` did not finish within {} ms: `save_parameters` still reads 1, not 0",
            waited.as_millis()
        )
    );
    let bound = Duration::from_millis(2000);
    assert!(
        waited <= bound && waited + optobus_driver::COMPLETION_POLL > bound,
        "{waited:?}"
    );
    let reads = log.lock().unwrap().len() - 1;
    assert!(reads >= 30, "polled {reads} times");
}
