//! Typed `PSeries::read_measurements()` against raw tokio-modbus `read_input_registers` of
//! the same ten registers, on the same simulator and the same runtime, over an in-memory RTU
//! line and over Modbus TCP on 127.0.0.1. Both sides use tokio-modbus underneath, so the
//! ratio is the cost of the typed layer (plan, decode, sentinels, exact units).
//!
//! Rounds alternate typed and raw batches; the median round of each is compared. Prints the
//! time ratio over the duplex (target ≤ 1.10) and the transactions-per-second ratio over TCP
//! (target ≥ 0.97). Run with `cargo bench -p optobus-tests --bench read_measurements`.

use std::time::{Duration, Instant};

use optobus_driver::transport::ModbusContext;
use optobus_p_series::{PSeries, DEVICE};
use optobus_simulator::Simulator;
use tokio_modbus::client::{Context, Reader};
use tokio_modbus::Slave;

const ROUNDS: usize = 31;
const PER_ROUND: usize = 400;

fn median(mut samples: Vec<Duration>) -> Duration {
    samples.sort();
    samples[samples.len() / 2]
}

/// Median time of a round of `PER_ROUND` transactions: (typed, raw).
async fn measure(typed_context: Context, mut raw: Context) -> (Duration, Duration) {
    let mut sensor = PSeries::new(ModbusContext::new(typed_context), 1).expect("slave 1");
    let (mut typed_rounds, mut raw_rounds) = (Vec::new(), Vec::new());
    for round in 0..=ROUNDS {
        let started = Instant::now();
        for _ in 0..PER_ROUND {
            let m = sensor.read_measurements().await.expect("typed read");
            std::hint::black_box(m);
        }
        let typed = started.elapsed();
        let started = Instant::now();
        for _ in 0..PER_ROUND {
            let words = raw
                .read_input_registers(0, 10)
                .await
                .expect("transport")
                .expect("no exception");
            std::hint::black_box(words);
        }
        let raw_time = started.elapsed();
        // The first round warms up both sides.
        if round > 0 {
            typed_rounds.push(typed);
            raw_rounds.push(raw_time);
        }
    }
    (median(typed_rounds), median(raw_rounds))
}

fn per_transaction(round: Duration) -> f64 {
    round.as_secs_f64() * 1e6 / PER_ROUND as f64
}

fn main() {
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    runtime.block_on(async {
        let sim = Simulator::new(&DEVICE).sentinel_every(0);

        let (typed_stream, _a) = sim.duplex();
        let (raw_stream, _b) = sim.duplex();
        let (typed, raw) = measure(
            tokio_modbus::client::rtu::attach_slave(typed_stream, Slave(1)),
            tokio_modbus::client::rtu::attach_slave(raw_stream, Slave(1)),
        )
        .await;
        let duplex_ratio = typed.as_secs_f64() / raw.as_secs_f64();
        println!(
            "duplex RTU: typed {:.2} us/tx, raw {:.2} us/tx, typed/raw time {duplex_ratio:.3} (target <= 1.10)",
            per_transaction(typed),
            per_transaction(raw)
        );

        let server = sim.serve_tcp("127.0.0.1:0").await.expect("serve");
        let connect = || async {
            tokio_modbus::client::tcp::connect_slave(server.local_addr(), Slave(1))
                .await
                .expect("connect")
        };
        let (typed, raw) = measure(connect().await, connect().await).await;
        let tcp_ratio = raw.as_secs_f64() / typed.as_secs_f64();
        println!(
            "TCP loopback: typed {:.0} tx/s, raw {:.0} tx/s, typed/raw tx/s {tcp_ratio:.3} (target >= 0.97)",
            1e6 / per_transaction(typed),
            1e6 / per_transaction(raw)
        );
    });
}
