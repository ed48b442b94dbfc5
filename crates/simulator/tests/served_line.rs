//! A line of simulated devices served as one: every exchange seen once, and the line's
//! faults where the protocol puts them.

use std::sync::{Arc, Mutex};

use optobus_device::Table;
use optobus_p_series::DEVICE;
use optobus_simulator::{Faults, Member, Protocol, ServedLine, Simulator};
use optobus_transport::{ReadFunction, RtuClient, Transport};

fn members() -> Vec<Member> {
    [1, 2]
        .into_iter()
        .map(|slave| Member {
            name: format!("device {slave}"),
            simulator: Simulator::new(&DEVICE).slave(slave),
            faults: None,
        })
        .collect()
}

#[tokio::test]
async fn a_served_line_logs_each_exchange_once() {
    let seen = Arc::new(Mutex::new(Vec::new()));
    let log = Arc::clone(&seen);
    let served = ServedLine::new(members(), Protocol::Rtu, None, move |exchange| {
        log.lock().unwrap().push(exchange.to_string());
    });
    let (client_end, server_end) = tokio::io::duplex(1024);
    let _task = served.serve_stream(server_end, None);
    let register = DEVICE
        .registers
        .iter()
        .find(|r| r.table == Table::Holding && r.readable())
        .expect("a readable holding register");
    let mut client = RtuClient::new(client_end);
    let words = client
        .read(2, ReadFunction::Holding, register.address, 1)
        .await
        .expect("slave 2 answers");
    assert_eq!(words.len(), 1);
    // Nobody is at slave 9: the request is seen once (by the first device), unanswered.
    client
        .read(9, ReadFunction::Holding, register.address, 1)
        .await
        .expect_err("nobody answers slave 9");
    let address = register.address;
    assert_eq!(
        *seen.lock().unwrap(),
        [
            format!("slave 2 read holding {address} x1 -> 1 words"),
            format!("slave 9 read holding {address} x1 -> no reply"),
        ]
    );
}

#[test]
fn a_lines_faults_go_to_the_line_on_rtu_and_to_each_device_over_tcp() {
    let faults: Faults = "drop=0.5,seed=1".parse().unwrap();
    let rtu = ServedLine::new(members(), Protocol::Rtu, Some(faults.clone()), |_| {});
    assert!(rtu.members().iter().all(|member| member.faults.is_none()));
    assert_eq!(rtu.faults(), Some(&faults));
    let tcp = ServedLine::new(members(), Protocol::Tcp, Some(faults.clone()), |_| {});
    assert!(tcp
        .members()
        .iter()
        .all(|member| member.faults.as_ref() == Some(&faults)));
}

#[tokio::test]
async fn one_served_device_answers_every_unit_id_over_tcp_and_its_summary_is_unnamed() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    let faults: Faults = "delay=1,seed=3".parse().unwrap();
    let alone = Member {
        name: "alone".to_owned(),
        simulator: Simulator::new(&DEVICE).slave(1),
        faults: None,
    };
    let served = ServedLine::one(alone, Some(faults.clone()), |_| {});
    let server = served
        .serve_tcp("127.0.0.1:0".parse().unwrap())
        .await
        .expect("a local port");
    let register = DEVICE
        .registers
        .iter()
        .find(|r| r.table == Table::Holding && r.readable())
        .expect("a readable holding register");
    let [high, low] = register.address.to_be_bytes();
    let mut stream = tokio::net::TcpStream::connect(server.local_addr())
        .await
        .unwrap();
    // Transaction 7, unit 9 (not the device's slave 1): read one holding register.
    let request = [0, 7, 0, 0, 0, 6, 9, 0x03, high, low, 0, 1];
    stream.write_all(&request).await.unwrap();
    let mut reply = [0u8; 11];
    tokio::time::timeout(
        std::time::Duration::from_secs(10),
        stream.read_exact(&mut reply),
    )
    .await
    .expect("a reply within 10 s")
    .expect("the connection stays open");
    assert_eq!(reply[..9], [0, 7, 0, 0, 0, 5, 9, 0x03, 2]);
    let stats = served.members()[0].simulator.fault_stats().unwrap();
    assert_eq!(
        served.fault_summaries(),
        [stats.summary(&faults).to_string()]
    );
}
