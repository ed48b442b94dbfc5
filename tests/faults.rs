//! Never a wrong value: seeded fault injection against our RTU and TCP clients.
//!
//! Per fault kind and client, 2,000 reads of registers holding known, distinct values, with
//! the fault in 10 % of the replies: no read may return another register's value, every
//! failure is a typed error, and the transaction after a fault is right. Time is tokio's
//! paused clock, so timeouts and late replies cost no wall time. Case names are
//! `faults::<client>::<kind>`.

use std::time::Duration;

use optobus_device::Table;
use optobus_driver::transport::{Error as WireError, ReadRequest, RtuClient, RtuConfig, Transport};
use optobus_driver::{rtu_config, Core, Error};
use optobus_p_series::{PSeries, DEVICE};
use optobus_simulator::{FaultKind, Faults, Simulator};
use optobus_tests::fault_run::{self, Client, FaultReport, MemoryTcp, TIMEOUT};

const TRANSACTIONS: usize = 2_000;
const PROBABILITY: f64 = 0.1;

fn check(kind: FaultKind, client: Client, report: &FaultReport) {
    let case = format!("{client}::{}", kind.name());
    assert_eq!(report.wrong, 0, "{case}: wrong values: {report:?}");
    assert_eq!(report.untyped, 0, "{case}: untyped errors: {report:?}");
    assert_eq!(report.transactions, TRANSACTIONS, "{case}");
    assert!(report.injected > 100, "{case}: too few faults: {report:?}");
    let failed: usize = report.errors.values().sum();
    assert_eq!(report.correct + failed, TRANSACTIONS, "{case}: {report:?}");
    if kind == FaultKind::Split {
        // A reply in pieces is still the reply.
        assert_eq!(report.correct, TRANSACTIONS, "{case}: {report:?}");
    } else {
        assert!(failed > 0, "{case}: faults went unnoticed: {report:?}");
        assert!(
            report.recovery_rate() >= 0.99,
            "{case}: next transaction right after only {:.3} of faults: {report:?}",
            report.recovery_rate()
        );
    }
}

macro_rules! cases {
    ($client:ident: $($kind:ident),*) => {
        mod $client {
            use super::*;
            $(
                #[tokio::test(start_paused = true)]
                async fn $kind() {
                    let kind = FaultKind::from_name(stringify!($kind)).expect("a fault kind");
                    let client = if stringify!($client) == "rtu" { Client::Rtu } else { Client::Tcp };
                    let report = fault_run::run(kind, client, TRANSACTIONS, PROBABILITY, 7).await;
                    check(kind, client, &report);
                }
            )*
        }
    };
}

cases!(rtu: corrupt, truncate, garbage, wrong_slave, split, drop, delay);
cases!(tcp: corrupt, truncate, garbage, wrong_slave, split, drop, delay, disconnect);

/// Two holding registers of one word each with distinct values poked in.
fn two_registers(sim: &Simulator) -> [(&'static optobus_device::RegisterInfo, u16); 2] {
    let a = DEVICE.register("light_power").expect("light_power");
    let b = DEVICE
        .register("sampling_interval")
        .expect("sampling_interval");
    sim.poke(Table::Holding, a.address, &[0x0123])
        .expect("poke");
    sim.poke(Table::Holding, b.address, &[0x0004])
        .expect("poke");
    [(a, 0x0123), (b, 0x0004)]
}

/// A read cut off by the application (its future dropped while the reply is on its way)
/// must not hand its late reply to the next read of another register of the same shape.
async fn cancelled_read_then_another(transport: impl Transport, sim: &Simulator) {
    let [(a, _), (b, b_value)] = two_registers(sim);
    let mut core = Core::with_default_slave(transport, &DEVICE);
    let cut = tokio::time::timeout(Duration::from_millis(50), core.read_words(a)).await;
    assert!(cut.is_err(), "the read was cut off");
    assert_eq!(core.read_words(b).await.expect("the next read"), [b_value]);
    assert_eq!(
        core.read_words(a).await.expect("and the one after").len(),
        1
    );
}

#[tokio::test(start_paused = true)]
async fn rtu_a_cancelled_read_never_answers_the_next() {
    // Every reply 150 ms late; the client waits up to 1 s.
    let sim =
        Simulator::new(&DEVICE).faults(Faults::new().delay(1.0).late(Duration::from_millis(150)));
    let (line, _server) = sim.duplex();
    let config = RtuConfig {
        line: None,
        ..rtu_config(&DEVICE)
    };
    cancelled_read_then_another(RtuClient::with_config(line, config), &sim).await;
}

#[tokio::test(start_paused = true)]
async fn tcp_a_cancelled_read_never_answers_the_next() {
    let sim =
        Simulator::new(&DEVICE).faults(Faults::new().delay(1.0).late(Duration::from_millis(150)));
    let client = optobus_driver::transport::TcpClient::new(
        MemoryTcp(sim.clone()),
        optobus_driver::tcp_config(&DEVICE),
    );
    cancelled_read_then_another(client, &sim).await;
}

/// The buffer download with replies dropped at random and retries switched on: it either
/// returns every value or fails, never fewer values as `Ok`.
#[tokio::test(start_paused = true)]
async fn buffer_download_with_lost_replies_is_never_short() {
    let (mut complete, mut failed) = (0, 0);
    for seed in 0..12 {
        let sim = Simulator::new(&DEVICE).sentinel_every(0);
        let (line, _server) = sim.duplex();
        let config = RtuConfig {
            line: None,
            timeout: TIMEOUT,
            read_retries: 3,
            ..rtu_config(&DEVICE)
        };
        let mut sensor = PSeries::with_default_slave(RtuClient::with_config(line, config));
        sensor
            .start_buffering(optobus_p_series::MeasurementSource::Distance1, 1000)
            .await
            .expect("buffering starts");
        tokio::time::sleep(Duration::from_secs(2)).await;
        // Faults only during the download: pages, lock and unlock.
        sim.set_faults(Some(Faults::new().drop(0.05).seed(seed)));
        match sensor.download_buffer(|_| {}).await {
            Ok(values) => {
                assert_eq!(values.len(), 1000, "seed {seed}: a short download");
                complete += 1;
            }
            Err(error) => {
                assert!(
                    matches!(error, Error::Transport(WireError::Timeout { .. })),
                    "seed {seed}: {error}"
                );
                failed += 1;
            }
        }
    }
    assert!(
        failed > 0 && complete > 0,
        "{complete} complete, {failed} failed"
    );
}

/// A transport that loses one page on the way: it makes every read that must not be repeated
/// twice and returns the second reply (as a careless retrying layer would). The device's own
/// count gives it away.
struct LosesAPage<T> {
    inner: T,
    page_reads: usize,
}

impl<T: Transport> Transport for LosesAPage<T> {
    async fn read_words(&mut self, slave: u8, read: ReadRequest) -> Result<Vec<u16>, WireError> {
        if !read.repeatable {
            self.page_reads += 1;
            if self.page_reads == 3 {
                let _lost = self.inner.read_words(slave, read).await?;
            }
        }
        self.inner.read_words(slave, read).await
    }

    async fn write(
        &mut self,
        slave: u8,
        address: u16,
        value: optobus_driver::transport::WriteValue,
    ) -> Result<(), WireError> {
        self.inner.write(slave, address, value).await
    }
}

#[tokio::test(start_paused = true)]
async fn a_lost_buffer_page_fails_the_download() {
    let sim = Simulator::new(&DEVICE).sentinel_every(0);
    let (line, _server) = sim.duplex();
    let config = RtuConfig {
        line: None,
        ..rtu_config(&DEVICE)
    };
    let transport = LosesAPage {
        inner: RtuClient::with_config(line, config),
        page_reads: 0,
    };
    let mut sensor = PSeries::with_default_slave(transport);
    sensor
        .start_buffering(optobus_p_series::MeasurementSource::Distance1, 1000)
        .await
        .expect("buffering starts");
    tokio::time::sleep(Duration::from_secs(2)).await;
    match sensor.download_buffer(|_| {}).await {
        Err(Error::OutOfStep {
            received, reported, ..
        }) => {
            assert_eq!((received, reported), (180, 240));
        }
        other => panic!("{other:?}"),
    }
}
