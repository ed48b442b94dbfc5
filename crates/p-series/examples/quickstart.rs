//! Quick start: a P-series sensor from an application. Runs against the simulator; for a
//! real sensor, open the serial port instead (see the comment).

use optobus_p_series::transport::RtuClient;
use optobus_p_series::{rtu_config, PSeries, DEVICE};

#[tokio::main(flavor = "current_thread")]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (line, _server) = optobus_simulator::Simulator::new(&DEVICE).duplex();
    // Real sensor: let line = optobus_p_series::serial_settings(&DEVICE, "/dev/ttyUSB0").open()?;
    let mut sensor = PSeries::with_default_slave(RtuClient::with_config(line, rtu_config(&DEVICE)));
    sensor.wait_ready().await?;
    sensor.set_light_power("42.5".parse()?).await?; // checked against 0.5 ..= 100 % first
    sensor.zero_position_1().await?;
    let readings = sensor.read_measurements().await?; // one FC04 of 10 registers
    match readings.distance_1 {
        Some(distance) => println!("distance 1: {distance} ({} um)", distance.micrometres()),
        None => println!("distance 1: invalid reading"),
    }
    Ok(())
}
