//! Seeded fault runs: a client reads registers holding known, distinct values from a
//! P-series simulator that injects one kind of fault into its replies, and every outcome is
//! classified: the right value, a wrong value (must never happen), or a typed error.
//!
//! Used by `tests/faults.rs` (CI-sized runs) and `benches/faults.rs` (the 10,000-transaction
//! table). Everything is in memory, so a runtime with tokio's clock paused runs timeouts,
//! late replies and recovery in virtual time: deterministic and fast.

use std::collections::BTreeMap;
use std::fmt;
use std::io;
use std::time::Duration;

use optobus_device::{Access, Table};
use optobus_driver::transport::{
    Connect, Error as WireError, ReadFunction, RtuClient, RtuConfig, TcpClient, TcpConfig,
    Transport,
};
use optobus_driver::{rtu_config, tcp_config};
use optobus_p_series::DEVICE;
use optobus_simulator::{FaultKind, Faults, Simulator};
use tokio::io::DuplexStream;

/// The client under test.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Client {
    /// Our RTU client on an in-memory line (no line timing).
    Rtu,
    /// Our Modbus TCP client over in-memory connections (a new one after each disconnect).
    Tcp,
}

impl fmt::Display for Client {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Rtu => "rtu",
            Self::Tcp => "tcp",
        })
    }
}

/// The client's reply timeout in these runs.
pub const TIMEOUT: Duration = Duration::from_millis(100);

/// When a delayed reply comes: past the timeout, while the client sends or awaits its next
/// request. The device reads nothing meanwhile, so a run of delays puts it behind by 20 ms
/// each; with 1.5 × the timeout two in a row would already make the next reply late too.
pub const LATE: Duration = Duration::from_millis(120);

/// What a run saw.
#[derive(Clone, Debug, Default)]
pub struct FaultReport {
    /// Transactions made.
    pub transactions: usize,
    /// Transactions that returned the register's own value.
    pub correct: usize,
    /// Transactions that returned `Ok` with another value: must stay 0.
    pub wrong: usize,
    /// Failed transactions by error kind (`timeout`, `frame`, `closed`, …).
    pub errors: BTreeMap<&'static str, usize>,
    /// Faults the simulator injected.
    pub injected: usize,
    /// Injected faults (other than `split`, which a client must simply accept) whose next
    /// transaction had no fault of its own.
    pub followed: usize,
    /// Of those, the ones whose next transaction returned the right value.
    pub recovered: usize,
    /// Failures that were not typed as a wire error (must stay 0).
    pub untyped: usize,
}

impl FaultReport {
    /// Share of faults after which the next transaction was right (1.0 when none were
    /// followed).
    pub fn recovery_rate(&self) -> f64 {
        if self.followed == 0 {
            1.0
        } else {
            self.recovered as f64 / self.followed as f64
        }
    }
}

/// A name for each kind of wire error.
pub fn error_kind(error: &WireError) -> &'static str {
    match error {
        WireError::Timeout { .. } => "timeout",
        WireError::Exception { .. } => "exception",
        WireError::Frame(_) => "frame",
        WireError::Request(_) => "request",
        WireError::WordCount { .. } => "word_count",
        WireError::Unsupported(_) => "unsupported",
        WireError::Closed => "closed",
        WireError::Connect { .. } => "connect",
        WireError::Desynchronised(_) => "desynchronised",
        WireError::Line(_) => "line",
        WireError::Io(_) => "io",
        _ => "other",
    }
}

/// The single-word holding registers that plain settings live in: each gets a distinct
/// value, so a reply to another request would show.
fn targets(sim: &Simulator) -> Vec<(u16, u16)> {
    let commanded: Vec<&str> = DEVICE.commands.iter().map(|c| c.register).collect();
    DEVICE
        .registers
        .iter()
        .filter(|r| {
            r.table == Table::Holding
                && r.words == 1
                && r.access == Access::ReadWrite
                && !commanded.contains(&r.name)
                && DEVICE.slave_address_register().map(|s| s.name) != Some(r.name)
        })
        .enumerate()
        .map(|(i, r)| {
            // Distinct and unlike the factory values.
            let value = 0xA000 + i as u16;
            sim.poke(Table::Holding, r.address, &[value])
                .expect("a register of the table");
            (r.address, value)
        })
        .collect()
}

/// Opens in-memory Modbus TCP connections to a simulator.
#[derive(Debug)]
pub struct MemoryTcp(pub Simulator);

impl Connect for MemoryTcp {
    type Stream = DuplexStream;

    async fn connect(&mut self) -> io::Result<DuplexStream> {
        let (client, server) = tokio::io::duplex(4096);
        let sim = self.0.clone();
        tokio::spawn(async move { sim.serve_tcp_stream(server).await });
        Ok(client)
    }
}

/// A simulator injecting `kind` with `probability` into its replies.
pub fn faulty_simulator(kind: FaultKind, probability: f64, seed: u64) -> Simulator {
    let faults = Faults::new().with(kind, probability).seed(seed).late(LATE);
    Simulator::new(&DEVICE).sentinel_every(0).faults(faults)
}

/// Our client of `kind` to `sim`, with the run's timeout.
pub fn client_to(sim: &Simulator, client: Client) -> Box<dyn DynTransport> {
    match client {
        Client::Rtu => {
            let (line, _server) = sim.duplex();
            let config = RtuConfig {
                line: None,
                timeout: TIMEOUT,
                ..rtu_config(&DEVICE)
            };
            Box::new(RtuClient::with_config(line, config))
        }
        Client::Tcp => {
            let config = TcpConfig {
                timeout: TIMEOUT,
                ..tcp_config(&DEVICE)
            };
            Box::new(TcpClient::new(MemoryTcp(sim.clone()), config))
        }
    }
}

/// One read through either client, boxed so that a run can hold either.
pub trait DynTransport {
    /// [`Transport::read`] of holding registers.
    fn read_holding(
        &mut self,
        address: u16,
        count: u16,
    ) -> std::pin::Pin<Box<dyn std::future::Future<Output = Result<Vec<u16>, WireError>> + '_>>;
}

impl<T: Transport> DynTransport for T {
    fn read_holding(
        &mut self,
        address: u16,
        count: u16,
    ) -> std::pin::Pin<Box<dyn std::future::Future<Output = Result<Vec<u16>, WireError>> + '_>>
    {
        Box::pin(self.read(DEVICE.default_slave, ReadFunction::Holding, address, count))
    }
}

/// `transactions` reads of random registers (chosen by `seed`) through `client`, with `kind`
/// injected into each reply with `probability`.
pub async fn run(
    kind: FaultKind,
    client: Client,
    transactions: usize,
    probability: f64,
    seed: u64,
) -> FaultReport {
    let sim = faulty_simulator(kind, probability, seed);
    let targets = targets(&sim);
    let mut transport = client_to(&sim, client);
    let mut report = FaultReport::default();
    let mut outcomes = Vec::with_capacity(transactions);
    let mut pick = seed ^ 0x9E37_79B9_7F4A_7C15;
    for _ in 0..transactions {
        pick = splitmix(pick);
        let (address, value) = targets[(pick % targets.len() as u64) as usize];
        let outcome = transport.read_holding(address, 1).await;
        report.transactions += 1;
        let right = match outcome {
            Ok(words) if words == [value] => {
                report.correct += 1;
                true
            }
            Ok(_) => {
                report.wrong += 1;
                false
            }
            Err(error) => {
                *report.errors.entry(error_kind(&error)).or_default() += 1;
                if matches!(error, WireError::Io(_)) {
                    report.untyped += 1;
                }
                false
            }
        };
        outcomes.push(right);
    }
    let stats = sim.fault_stats().expect("faults are on");
    let log = stats.log();
    report.injected = stats.injected() as usize;
    for (i, fault) in log.iter().enumerate() {
        let followed = matches!(fault, Some(k) if *k != FaultKind::Split)
            && log.get(i + 1).is_some_and(Option::is_none)
            && i + 1 < outcomes.len();
        if followed {
            report.followed += 1;
            if outcomes[i + 1] {
                report.recovered += 1;
            }
        }
    }
    report
}

/// SplitMix64: the register chooser.
fn splitmix(state: u64) -> u64 {
    let mut z = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The kinds that apply to `client` (a serial line cannot hang up).
pub fn kinds(client: Client) -> Vec<FaultKind> {
    FaultKind::ALL
        .into_iter()
        .filter(|k| client == Client::Tcp || *k != FaultKind::Disconnect)
        .collect()
}
