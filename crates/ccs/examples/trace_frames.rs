//! The frames and register values behind a group read, through `tracing`: run with
//! `RUST_LOG=trace cargo run -p optobus-ccs --example trace_frames`
//! (`RUST_LOG=optobus_driver=debug` for the register values alone).
//!
//! The transport emits every frame sent and received at TRACE (target `optobus_transport`:
//! hex, slave, microseconds since the request left); the driver emits each register it
//! decodes at DEBUG (target `optobus_driver`). Without a subscriber they cost nothing.

use optobus_ccs::transport::RtuClient;
use optobus_ccs::{rtu_config, Ccs, DEVICE};
use tracing_subscriber::EnvFilter;

#[tokio::main(flavor = "current_thread")]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    tracing_subscriber::fmt()
        .with_env_filter(EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
    let (line, _server) = optobus_simulator::Simulator::new(&DEVICE).duplex();
    let mut sensor = Ccs::with_default_slave(RtuClient::with_config(line, rtu_config(&DEVICE)));
    let readings = sensor.read_measurements().await?;
    println!("{readings:?}");
    Ok(())
}
