//! `identify::<family>`, for every spec in `specs/`: a simulator of the family, over Modbus
//! TCP and over RTU, is identified as that family and as no other; with its own spec left out
//! of the candidates, no model fits (never a wrong one). Nothing is written: the simulator
//! holds its factory values afterwards.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use optobus_device::DeviceInfo;
use optobus_driver::identify::{identify, ConnectAs, Finding, Identification, Verdict};
use optobus_driver::transport::{
    Error as WireError, ReadRequest, RtuClient, RtuConfig, TcpClient, TcpConfig, WriteValue,
};
use optobus_driver::{rtu_config, tcp_config, Transport};
use optobus_simulator::Simulator;
use optobus_tests::generated::FAMILIES;
use optobus_tests::specs;
use tokio::io::DuplexStream;

/// A candidate that does not fit waits out a timeout; short, as the replies are local.
const TIMEOUT: Duration = Duration::from_millis(100);

/// A link that records every read and fails the test at any write.
struct ReadOnly<T> {
    link: T,
    reads: Arc<Mutex<Vec<ReadRequest>>>,
}

impl<T: Transport> Transport for ReadOnly<T> {
    async fn read_words(&mut self, slave: u8, read: ReadRequest) -> Result<Vec<u16>, WireError> {
        self.reads.lock().expect("reads").push(read);
        self.link.read_words(slave, read).await
    }

    async fn write(&mut self, _: u8, address: u16, _: WriteValue) -> Result<(), WireError> {
        panic!("identify wrote to address {address}")
    }
}

/// Fresh in-memory RTU lines to one simulator, framed for each candidate; every read recorded.
struct Rtu<'a> {
    sim: &'a Simulator,
    reads: Arc<Mutex<Vec<ReadRequest>>>,
}

impl ConnectAs for Rtu<'_> {
    type Link = ReadOnly<RtuClient<DuplexStream>>;
    type Error = std::convert::Infallible;

    async fn connect_as(&mut self, model: &'static DeviceInfo) -> Result<Self::Link, Self::Error> {
        let (stream, _server) = self.sim.duplex();
        let config = RtuConfig {
            line: None,
            timeout: TIMEOUT,
            ..rtu_config(model)
        };
        Ok(ReadOnly {
            link: RtuClient::with_config(stream, config),
            reads: self.reads.clone(),
        })
    }
}

/// Modbus TCP connections to one served simulator, framed for each candidate.
struct Tcp(std::net::SocketAddr);

impl ConnectAs for Tcp {
    type Link = TcpClient;
    type Error = optobus_driver::transport::Error;

    async fn connect_as(&mut self, model: &'static DeviceInfo) -> Result<Self::Link, Self::Error> {
        let config = TcpConfig {
            timeout: TIMEOUT,
            ..tcp_config(model)
        };
        TcpClient::connect(self.0, config).await
    }
}

/// Every spec in `specs/`, described as the tool describes a spec file.
fn all() -> Vec<&'static DeviceInfo> {
    FAMILIES.iter().map(|f| specs::describe(f)).collect()
}

/// The identification names `device`, and every other candidate is ruled out by a finding
/// of its own.
fn names(found: &Identification, device: &'static DeviceInfo, how: &str) {
    let named = match found.verdict() {
        Verdict::One(model) => Some(model.family),
        _ => None,
    };
    assert_eq!(named, Some(device.family), "{how}:\n{}", summary(found));
    for evidence in &found.candidates {
        if evidence.model.family == device.family {
            assert!(evidence
                .findings
                .iter()
                .any(|f| matches!(f, Finding::RefusedPastTable { .. })));
        } else {
            let against = evidence.findings.iter().any(Finding::rules_out);
            assert!(
                against,
                "{how}: {}: {:?}",
                evidence.model.family, evidence.findings
            );
        }
    }
}

/// No read of `reads` touched a register whose read changes the device (the P series' buffer
/// page) of a candidate the device was not shown beyond doubt not to be: the device's own
/// model among them.
fn no_side_effect(reads: &Mutex<Vec<ReadRequest>>, found: &Identification) {
    let reads = std::mem::take(&mut *reads.lock().expect("reads"));
    assert!(reads.len() >= found.candidates.len(), "{reads:?}");
    let possible = found
        .candidates
        .iter()
        .filter(|e| !e.findings.iter().any(Finding::excludes));
    let possible: Vec<&DeviceInfo> = possible.map(|e| e.model).collect();
    for read in &reads {
        for model in &possible {
            let touched = model.registers.iter().filter(|r| {
                r.table.read_function() == read.function
                    && r.address < read.address.saturating_add(read.count)
                    && read.address < r.address.saturating_add(r.words)
            });
            for register in touched {
                assert!(
                    register.read_is_repeatable(),
                    "{read:?} reads {}",
                    register.name
                );
            }
        }
    }
}

/// Each candidate's findings, a line each.
fn summary(found: &Identification) -> String {
    let lines = found.candidates.iter().map(|e| {
        let findings: Vec<String> = e.findings.iter().map(ToString::to_string).collect();
        format!("{}: {}", e.model.family, findings.join("; "))
    });
    lines.collect::<Vec<_>>().join("\n")
}

fn identified(family: &str) {
    let candidates = all();
    let device = *candidates
        .iter()
        .find(|d| d.family == family)
        .expect("the family's spec");
    let others: Vec<&'static DeviceInfo> = candidates
        .iter()
        .copied()
        .filter(|d| d.family != family)
        .collect();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime");
    runtime.block_on(async {
        let sim = Simulator::new(device);
        let settings = || -> Vec<_> {
            let registers = sim.registers().into_iter();
            registers.filter(|r| r.info.access.writable()).collect()
        };
        let before = settings();
        // RTU, at each candidate's factory slave.
        let mut rtu = Rtu {
            sim: &sim,
            reads: Arc::default(),
        };
        let found = identify(&mut rtu, &candidates, None).await.unwrap();
        names(&found, device, "rtu");
        no_side_effect(&rtu.reads, &found);
        // Its own spec left out: none fits.
        let found = identify(&mut rtu, &others, None).await.unwrap();
        assert_eq!(found.verdict(), Verdict::None, "rtu:\n{}", summary(&found));
        no_side_effect(&rtu.reads, &found);
        // Modbus TCP, at the slave given.
        let server = sim.serve_tcp("127.0.0.1:0").await.expect("serve TCP");
        let mut tcp = Tcp(server.local_addr());
        let found = identify(&mut tcp, &candidates, Some(device.default_slave)).await;
        names(&found.expect("TCP connects"), device, "tcp");
        let found = identify(&mut tcp, &others, Some(device.default_slave)).await;
        let found = found.expect("TCP connects");
        assert_eq!(found.verdict(), Verdict::None, "tcp:\n{}", summary(&found));
        // Read only: the settings are as they were.
        assert_eq!(settings(), before);
    });
}

optobus_tests::family_cases!(identify, identified);
