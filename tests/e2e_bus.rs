//! Several drivers on one serial line, and what a silent device looks like.

use std::time::Duration;

use optobus_ccs::Ccs;
use optobus_driver::transport::{Error as WireError, RtuClient, Shared};
use optobus_driver::{rtu_config, Error};
use optobus_p_series::PSeries;
use optobus_simulator::{Simulator, Slaves};
use optobus_tests::e2e;

#[tokio::test(start_paused = true)]
async fn two_drivers_share_one_port_from_two_tasks() {
    let p_sim = Simulator::new(&optobus_p_series::DEVICE)
        .slave(1)
        .sentinel_every(0);
    let ccs_sim = Simulator::new(&optobus_ccs::DEVICE)
        .slave(2)
        .sentinel_every(0);
    let (stream, _server) = Slaves::new([p_sim.clone(), ccs_sim.clone()]).duplex();
    let line = Shared::new(RtuClient::with_config(
        stream,
        rtu_config(&optobus_p_series::DEVICE),
    ));
    let mut p_series = PSeries::new(line.clone(), 1).expect("slave 1");
    let mut ccs = Ccs::new(line, 2).expect("slave 2");
    let p_task = tokio::spawn(async move {
        for round in 0..50u16 {
            let power = format!("{}.{}", 10 + round, round % 10);
            p_series
                .set_light_power(power.parse().unwrap())
                .await
                .unwrap();
            assert_eq!(
                p_series.light_power().await.unwrap().to_string(),
                format!("{power} %")
            );
            assert!(p_series
                .read_measurements()
                .await
                .unwrap()
                .distance_1
                .is_some());
        }
    });
    let ccs_task = tokio::spawn(async move {
        for round in 0..50u16 {
            let time = format!("{}.5", 100 + round);
            ccs.set_exposure_time(time.parse().unwrap()).await.unwrap();
            let settings = ccs.read_exposure_settings().await.unwrap();
            assert_eq!(settings.exposure_time.to_string(), format!("{time} us"));
        }
    });
    p_task.await.unwrap();
    ccs_task.await.unwrap();
    // Each device saw its own writes only.
    assert_eq!(
        p_sim.peek(optobus_device::Table::Holding, 2),
        Some(vec![599])
    );
    assert_eq!(
        ccs_sim.peek(optobus_device::Table::Holding, 2),
        Some(vec![1495])
    );
}

#[tokio::test(start_paused = true)]
async fn a_silent_device_times_out_and_the_line_recovers() {
    let sim = Simulator::new(&optobus_p_series::DEVICE);
    let mut client = e2e::rtu(&sim);
    client.config_mut().timeout = Duration::from_millis(200);
    let mut sensor = PSeries::with_default_slave(client);
    sim.set_silent(true);
    let started = tokio::time::Instant::now();
    let error = sensor.laser_enabled().await.unwrap_err();
    assert!(
        matches!(error, Error::Transport(WireError::Timeout { after }) if after == Duration::from_millis(200)),
        "{error}"
    );
    assert!(started.elapsed() >= Duration::from_millis(200));
    // Writes time out too, and are not retried.
    let error = sensor.set_laser_enabled(true).await.unwrap_err();
    assert!(
        matches!(error, Error::Transport(WireError::Timeout { .. })),
        "{error}"
    );
    sim.set_silent(false);
    sensor.laser_enabled().await.unwrap();
}

#[tokio::test]
async fn a_silent_device_times_out_over_tcp() {
    let sim = Simulator::new(&optobus_p_series::DEVICE);
    let (mut client, _server) = e2e::tcp(&sim).await;
    client.config_mut().timeout = Duration::from_millis(100);
    let mut sensor = PSeries::with_default_slave(client);
    sim.set_silent(true);
    let error = sensor.laser_enabled().await.unwrap_err();
    assert!(
        matches!(error, Error::Transport(WireError::Timeout { .. })),
        "{error}"
    );
    // The connection survives the timeout, and the next transaction is answered.
    sim.set_silent(false);
    assert!(sensor.laser_enabled().await.is_ok());
}

#[tokio::test]
async fn tcp_reconnects_after_the_server_restarts() {
    let sim = Simulator::new(&optobus_p_series::DEVICE);
    let (mut client, server) = e2e::tcp(&sim).await;
    client.config_mut().timeout = Duration::from_millis(500);
    client.config_mut().reconnect_delay = Duration::from_millis(20);
    let address = server.local_addr();
    let mut sensor = PSeries::with_default_slave(client);
    assert!(sensor.laser_enabled().await.is_ok());
    drop(server);
    // The server is gone: a typed error (closed, or no connection), never an errno dump.
    let error = sensor.laser_enabled().await.unwrap_err();
    assert!(
        matches!(
            error,
            Error::Transport(WireError::Closed | WireError::Connect { .. })
        ),
        "{error:?}"
    );
    let error = sensor.laser_enabled().await.unwrap_err();
    assert!(
        matches!(error, Error::Transport(WireError::Connect { .. })),
        "{error:?}"
    );
    // Back on the same port: the next request reconnects (after the backoff).
    let _server = sim.serve_tcp(address).await.expect("serve again");
    tokio::time::sleep(Duration::from_millis(100)).await;
    assert!(sensor.laser_enabled().await.is_ok());
    assert!(sensor.core().transport_mut().is_connected());
}
