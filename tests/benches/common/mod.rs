//! What the benches share: the transaction both sides of a comparison make (one FC04 of the
//! P series' ten measurement registers), typed through a driver or raw through tokio-modbus,
//! the runtime they run on and the median they compare.

use optobus_p_series::transport::Transport;
use optobus_p_series::PSeries;
use tokio_modbus::client::{Context, Reader};

/// The typed side: `read_measurements()`, its result kept from the optimiser.
pub(crate) async fn read_typed<T: Transport>(sensor: &mut PSeries<T>) {
    let m = sensor.read_measurements().await.expect("typed read");
    std::hint::black_box(m);
}

/// The raw side: tokio-modbus `read_input_registers(0, 10)`, the same ten registers.
pub(crate) async fn read_raw(context: &mut Context) {
    let words = context
        .read_input_registers(0, 10)
        .await
        .expect("transport")
        .expect("no exception");
    std::hint::black_box(words);
}

/// The runtime a bench runs on: one thread, real time (the line emulator and the sockets keep
/// their own timing).
pub(crate) fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime")
}

/// The middle sample (the upper one of an even count).
pub(crate) fn median<T: PartialOrd>(mut samples: Vec<T>) -> T {
    samples.sort_by(|a, b| a.partial_cmp(b).unwrap_or(std::cmp::Ordering::Equal));
    samples.swap_remove(samples.len() / 2)
}
