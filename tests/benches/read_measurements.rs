//! Typed `PSeries::read_measurements()` against raw tokio-modbus `read_input_registers` of
//! the same ten registers, on the same simulator and the same runtime, over an in-memory RTU
//! line and over Modbus TCP on 127.0.0.1. Both sides use tokio-modbus underneath, so the
//! ratio is the cost of the typed layer (plan, decode, sentinels, exact units).
//!
//! Over the duplex a third contender runs the same typed read through our own `RtuClient`
//! (no line timing: `line: None`), compared with raw tokio-modbus: our client's cost per
//! transaction.
//!
//! Rounds alternate typed, (ours,) raw batches; the median round of each is compared. Prints
//! the typed/raw time ratio over the duplex (target ≤ 1.10), our RtuClient's time per
//! transaction as a ratio to raw tokio-modbus RTU on the duplex (target ≤ 1.5), and the
//! transactions-per-second ratio over TCP (target ≥ 0.97). Run with
//! `cargo bench -p optobus-tests --bench read_measurements`.

mod common;

use std::time::{Duration, Instant};

use optobus_driver::transport::{ModbusContext, RtuClient, RtuConfig};
use optobus_p_series::{rtu_config, PSeries, DEVICE};
use optobus_simulator::Simulator;
use tokio::io::DuplexStream;
use tokio_modbus::client::Context;
use tokio_modbus::Slave;

const ROUNDS: usize = 31;
const PER_ROUND: usize = 400;

/// One side of the comparison.
enum Contender {
    /// Typed reads through tokio-modbus.
    Typed(PSeries<ModbusContext>),
    /// Typed reads through our own RTU client.
    Ours(PSeries<RtuClient<DuplexStream>>),
    /// Raw tokio-modbus reads of the same registers.
    Raw(Context),
}

impl Contender {
    /// Time of a round of `PER_ROUND` transactions.
    async fn round(&mut self) -> Duration {
        let started = Instant::now();
        for _ in 0..PER_ROUND {
            match self {
                Self::Typed(sensor) => common::read_typed(sensor).await,
                Self::Ours(sensor) => common::read_typed(sensor).await,
                Self::Raw(raw) => common::read_raw(raw).await,
            }
        }
        started.elapsed()
    }
}

/// Median time of a round of `PER_ROUND` transactions of each contender, rounds interleaved.
async fn measure<const N: usize>(mut contenders: [Contender; N]) -> [Duration; N] {
    let mut rounds: [Vec<Duration>; N] = std::array::from_fn(|_| Vec::new());
    for round in 0..=ROUNDS {
        for (contender, times) in contenders.iter_mut().zip(&mut rounds) {
            let time = contender.round().await;
            // The first round warms up every side.
            if round > 0 {
                times.push(time);
            }
        }
    }
    rounds.map(common::median)
}

fn typed_contender(context: Context) -> Contender {
    Contender::Typed(PSeries::new(ModbusContext::new(context), 1).expect("slave 1"))
}

fn per_transaction(round: Duration) -> f64 {
    round.as_secs_f64() * 1e6 / PER_ROUND as f64
}

fn main() {
    common::runtime().block_on(async {
        let sim = Simulator::new(&DEVICE).sentinel_every(0);

        let (typed_stream, _a) = sim.duplex();
        let (ours_stream, _b) = sim.duplex();
        let (raw_stream, _c) = sim.duplex();
        let no_line = RtuConfig {
            line: None,
            ..rtu_config(&DEVICE)
        };
        let [typed_time, ours, raw] = measure([
            typed_contender(tokio_modbus::client::rtu::attach_slave(typed_stream, Slave(1))),
            Contender::Ours(PSeries::with_default_slave(RtuClient::with_config(
                ours_stream,
                no_line,
            ))),
            Contender::Raw(tokio_modbus::client::rtu::attach_slave(raw_stream, Slave(1))),
        ])
        .await;
        let duplex_ratio = typed_time.as_secs_f64() / raw.as_secs_f64();
        println!(
            "duplex RTU: typed {:.2} us/tx, raw {:.2} us/tx, typed/raw time {duplex_ratio:.3} (target <= 1.10)",
            per_transaction(typed_time),
            per_transaction(raw)
        );
        let ours_ratio = ours.as_secs_f64() / raw.as_secs_f64();
        println!(
            "duplex RTU: ours (RtuClient, typed) {:.2} us/tx, ours/raw tokio-modbus time {ours_ratio:.3} (target <= 1.5)",
            per_transaction(ours)
        );

        let server = sim.serve_tcp("127.0.0.1:0").await.expect("serve");
        let connect = || async {
            tokio_modbus::client::tcp::connect_slave(server.local_addr(), Slave(1))
                .await
                .expect("connect")
        };
        let [typed, raw] =
            measure([typed_contender(connect().await), Contender::Raw(connect().await)]).await;
        let tcp_ratio = raw.as_secs_f64() / typed.as_secs_f64();
        println!(
            "TCP loopback: typed {:.0} tx/s, raw {:.0} tx/s, typed/raw tx/s {tcp_ratio:.3} (target >= 0.97)",
            1e6 / per_transaction(typed),
            1e6 / per_transaction(raw)
        );
    });
}
