//! The line emulator's timing and the fault injector's bytes, with a real device (P series)
//! and real frames.

use std::time::Duration;

use optobus_codec::crc::is_valid_frame;
use optobus_codec::{rtu, tcp, DecodeError, Decoded, LineFormat, ReadFunction, Request};
use optobus_p_series::DEVICE;
use optobus_simulator::{FaultKind, Faults, FaultsError, Line, Simulator};
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};
use tokio::time::{timeout, Instant};

/// Settings: the same words on every read, so a faulted reply can be compared with a clean one.
const SETTINGS: Request = Request::Read {
    function: ReadFunction::Holding,
    address: 0,
    count: 8,
};

/// Measurements: ten input registers, a 25-byte RTU reply.
const MEASUREMENTS: Request = Request::Read {
    function: ReadFunction::Input,
    address: 0,
    count: 10,
};

/// How long a reader waits for more bytes before it decides a reply is over.
const QUIET: Duration = Duration::from_millis(100);

fn rtu_request(slave: u8, request: &Request) -> Vec<u8> {
    let mut buf = [0; rtu::MAX_FRAME_LEN];
    let len = rtu::encode_request(&mut buf, slave, request).unwrap();
    buf[..len].to_vec()
}

fn tcp_request(transaction: u16, request: &Request) -> Vec<u8> {
    let mut buf = [0; tcp::MAX_FRAME_LEN];
    let header = tcp::Header {
        transaction,
        unit: 1,
    };
    let len = tcp::encode_request(&mut buf, header, request).unwrap();
    buf[..len].to_vec()
}

/// Every read until `QUIET` passes without a byte or the peer closes, and whether it closed.
async fn collect(stream: &mut DuplexStream) -> (Vec<Vec<u8>>, bool) {
    let mut reads = Vec::new();
    let mut chunk = [0u8; 512];
    loop {
        match timeout(QUIET, stream.read(&mut chunk)).await {
            Ok(Ok(0)) | Ok(Err(_)) => return (reads, true),
            Ok(Ok(n)) => reads.push(chunk[..n].to_vec()),
            Err(_) => return (reads, false),
        }
    }
}

/// Reads exactly `len` bytes.
async fn read_exact(stream: &mut DuplexStream, len: usize) -> Vec<u8> {
    let mut reply = vec![0; len];
    timeout(Duration::from_secs(10), stream.read_exact(&mut reply))
        .await
        .expect("a reply within 10 s")
        .expect("the stream stays open");
    reply
}

/// An exchange over RTU: every read of the reply.
async fn rtu_exchange(stream: &mut DuplexStream, slave: u8) -> Vec<Vec<u8>> {
    stream
        .write_all(&rtu_request(slave, &SETTINGS))
        .await
        .unwrap();
    collect(stream).await.0
}

/// The clean reply to `SETTINGS` over RTU, then `faults` switched on.
async fn rtu_with(faults: Faults) -> (Simulator, DuplexStream, Vec<u8>) {
    let sim = Simulator::new(&DEVICE);
    let (mut stream, _server) = sim.duplex();
    let clean = rtu_exchange(&mut stream, sim.address()).await.concat();
    assert!(is_valid_frame(&clean));
    sim.set_faults(Some(faults));
    (sim, stream, clean)
}

/// The clean reply to `SETTINGS` over TCP (on an in-memory stream), then `faults` switched on.
async fn tcp_with(faults: Faults) -> (Simulator, DuplexStream, Vec<u8>) {
    let sim = Simulator::new(&DEVICE);
    let (mut stream, server) = tokio::io::duplex(4096);
    let served = sim.clone();
    tokio::spawn(async move { served.serve_tcp_stream(server).await });
    stream.write_all(&tcp_request(7, &SETTINGS)).await.unwrap();
    let clean = collect(&mut stream).await.0.concat();
    assert_eq!(tcp::frame_len(&clean), Some(clean.len()));
    sim.set_faults(Some(faults));
    (sim, stream, clean)
}

async fn tcp_exchange(stream: &mut DuplexStream) -> (Vec<Vec<u8>>, bool) {
    stream.write_all(&tcp_request(7, &SETTINGS)).await.unwrap();
    collect(stream).await
}

fn only(kind: FaultKind) -> Faults {
    Faults::new()
        .with(kind, 1.0)
        .seed(3)
        .pause(Duration::from_millis(5))
}

fn rtu_decode(reply: &[u8], slave: u8) -> Result<usize, DecodeError> {
    match rtu::decode_response(reply, slave, &SETTINGS, DEVICE.frame_shape.exception)? {
        Decoded::Frame { consumed, .. } => Ok(consumed),
        Decoded::NeedMore { .. } => Ok(0),
    }
}

fn tcp_decode(reply: &[u8]) -> Result<usize, DecodeError> {
    let header = tcp::Header {
        transaction: 7,
        unit: 1,
    };
    match tcp::decode_response(reply, header, &SETTINGS, DEVICE.frame_shape.exception)? {
        Decoded::Frame { consumed, .. } => Ok(consumed),
        Decoded::NeedMore { .. } => Ok(0),
    }
}

fn bit_differences(a: &[u8], b: &[u8]) -> Vec<(usize, u8)> {
    a.iter()
        .zip(b)
        .enumerate()
        .filter(|(_, (x, y))| x != y)
        .map(|(at, (x, y))| (at, x ^ y))
        .collect()
}

// ---------------------------------------------------------------------------------------
// RTU faults

#[tokio::test(start_paused = true)]
async fn rtu_corrupt_flips_one_bit_and_breaks_the_crc() {
    let (sim, mut stream, clean) = rtu_with(only(FaultKind::Corrupt)).await;
    let slave = sim.address();
    for _ in 0..20 {
        let reply = rtu_exchange(&mut stream, slave).await.concat();
        assert_eq!(reply.len(), clean.len());
        let diff = bit_differences(&reply, &clean);
        assert_eq!(diff.len(), 1, "{reply:02X?}");
        assert_eq!(diff[0].1.count_ones(), 1);
        assert!(!is_valid_frame(&reply));
        assert!(rtu_decode(&reply, slave).is_err());
    }
    let stats = sim.fault_stats().unwrap();
    assert_eq!(stats.count(FaultKind::Corrupt), 20);
    assert_eq!(stats.log(), vec![Some(FaultKind::Corrupt); 20]);
}

#[tokio::test(start_paused = true)]
async fn rtu_truncate_sends_a_strict_prefix() {
    let (sim, mut stream, clean) = rtu_with(only(FaultKind::Truncate)).await;
    for _ in 0..20 {
        let reply = rtu_exchange(&mut stream, sim.address()).await.concat();
        assert!(!reply.is_empty() && reply.len() < clean.len());
        assert_eq!(reply, clean[..reply.len()]);
    }
}

#[tokio::test(start_paused = true)]
async fn rtu_garbage_comes_before_the_correct_frame() {
    let (sim, mut stream, clean) = rtu_with(only(FaultKind::Garbage)).await;
    let slave = sim.address();
    for _ in 0..20 {
        let reply = rtu_exchange(&mut stream, slave).await.concat();
        let garbage = reply.len() - clean.len();
        assert!((1..=8).contains(&garbage), "{reply:02X?}");
        assert_eq!(reply[garbage..], clean);
        assert_ne!(reply[0], slave);
    }
}

#[tokio::test(start_paused = true)]
async fn rtu_wrong_slave_is_a_valid_foreign_reply() {
    let (sim, mut stream, clean) = rtu_with(only(FaultKind::WrongSlave)).await;
    let slave = sim.address();
    for _ in 0..20 {
        let reply = rtu_exchange(&mut stream, slave).await.concat();
        assert_eq!(reply.len(), clean.len());
        assert!(is_valid_frame(&reply), "{reply:02X?}");
        assert_ne!(reply[0], slave);
        assert!((1..=247).contains(&reply[0]));
        assert_eq!(reply[1..clean.len() - 2], clean[1..clean.len() - 2]);
        assert!(matches!(
            rtu_decode(&reply, slave),
            Err(DecodeError::UnexpectedSlave { .. })
        ));
        // The reply is what that slave would have said.
        assert_eq!(rtu_decode(&reply, reply[0]), Ok(clean.len()));
    }
}

#[tokio::test(start_paused = true)]
async fn rtu_split_pieces_join_to_the_correct_frame() {
    let (sim, mut stream, clean) = rtu_with(only(FaultKind::Split)).await;
    let mut three = false;
    for _ in 0..20 {
        let start = Instant::now();
        let pieces = rtu_exchange(&mut stream, sim.address()).await;
        let elapsed = start.elapsed() - QUIET;
        assert!((2..=3).contains(&pieces.len()), "{pieces:02X?}");
        assert!(pieces.iter().all(|piece| !piece.is_empty()));
        assert_eq!(pieces.concat(), clean);
        // A pause of 5 ms before every piece but the first.
        assert!(elapsed >= Duration::from_millis(5) * (pieces.len() as u32 - 1));
        three |= pieces.len() == 3;
    }
    assert!(three, "some replies come in three pieces");
}

#[tokio::test(start_paused = true)]
async fn rtu_drop_and_disconnect_send_nothing() {
    for kind in [FaultKind::Drop, FaultKind::Disconnect] {
        let (sim, mut stream, _) = rtu_with(only(kind)).await;
        for _ in 0..5 {
            assert_eq!(
                rtu_exchange(&mut stream, sim.address()).await,
                Vec::<Vec<u8>>::new()
            );
        }
        assert_eq!(sim.fault_stats().unwrap().count(kind), 5);
    }
}

#[tokio::test(start_paused = true)]
async fn rtu_delay_sends_the_correct_frame_late() {
    let late = Duration::from_millis(1500);
    let faults = only(FaultKind::Delay).client_timeout(Duration::from_secs(1));
    assert_eq!(faults.to_string(), "delay=1,seed=3,pause=5ms");
    let (sim, mut stream, clean) = rtu_with(faults).await;
    let start = Instant::now();
    stream
        .write_all(&rtu_request(sim.address(), &SETTINGS))
        .await
        .unwrap();
    let reply = read_exact(&mut stream, clean.len()).await;
    assert!(start.elapsed() >= late);
    assert_eq!(reply, clean);
}

// ---------------------------------------------------------------------------------------
// TCP faults

#[tokio::test(start_paused = true)]
async fn tcp_corrupt_flips_one_header_bit_a_client_detects() {
    let (_sim, mut stream, clean) = tcp_with(only(FaultKind::Corrupt)).await;
    for _ in 0..20 {
        let (reads, _) = tcp_exchange(&mut stream).await;
        let reply = reads.concat();
        assert_eq!(reply.len(), clean.len());
        let diff = bit_differences(&reply, &clean);
        assert_eq!(diff.len(), 1, "{reply:02X?}");
        let (at, bit) = diff[0];
        assert!(
            at <= tcp::HEADER_LEN,
            "header or function code, not byte {at}"
        );
        assert_eq!(bit.count_ones(), 1);
        assert!(tcp_decode(&reply).is_err(), "{reply:02X?}");
    }
}

#[tokio::test(start_paused = true)]
async fn tcp_truncate_wrong_unit_and_garbage() {
    let (_sim, mut stream, clean) = tcp_with(only(FaultKind::Truncate)).await;
    let reply = tcp_exchange(&mut stream).await.0.concat();
    assert!(!reply.is_empty() && reply.len() < clean.len());
    assert_eq!(reply, clean[..reply.len()]);

    let (_sim, mut stream, clean) = tcp_with(only(FaultKind::WrongSlave)).await;
    for _ in 0..10 {
        let reply = tcp_exchange(&mut stream).await.0.concat();
        assert_eq!(bit_differences(&reply, &clean).len(), 1);
        assert_ne!(reply[6], clean[6]);
        assert!(matches!(
            tcp_decode(&reply),
            Err(DecodeError::UnexpectedSlave { .. })
        ));
    }

    let (_sim, mut stream, clean) = tcp_with(only(FaultKind::Garbage)).await;
    for _ in 0..10 {
        let reply = tcp_exchange(&mut stream).await.0.concat();
        let garbage = reply.len() - clean.len();
        assert!((4..=8).contains(&garbage), "{reply:02X?}");
        assert_eq!(reply[garbage..], clean);
        assert_ne!([reply[2], reply[3]], [0, 0], "not an MBAP header");
        assert!(matches!(
            tcp_decode(&reply),
            Err(DecodeError::BadProtocolId { .. })
        ));
    }
}

#[tokio::test(start_paused = true)]
async fn tcp_split_drop_delay_and_disconnect() {
    let (_sim, mut stream, clean) = tcp_with(only(FaultKind::Split)).await;
    for _ in 0..10 {
        let (pieces, closed) = tcp_exchange(&mut stream).await;
        assert!(!closed);
        assert!((2..=3).contains(&pieces.len()));
        assert_eq!(pieces.concat(), clean);
        assert_eq!(tcp_decode(&clean), Ok(clean.len()));
    }

    let (_sim, mut stream, _) = tcp_with(only(FaultKind::Drop)).await;
    assert_eq!(tcp_exchange(&mut stream).await, (vec![], false));

    let late = Duration::from_millis(700);
    let (_sim, mut stream, clean) = tcp_with(only(FaultKind::Delay).late(late)).await;
    let start = Instant::now();
    stream.write_all(&tcp_request(7, &SETTINGS)).await.unwrap();
    assert_eq!(read_exact(&mut stream, clean.len()).await, clean);
    assert!(start.elapsed() >= late);

    let (sim, mut stream, _) = tcp_with(only(FaultKind::Disconnect)).await;
    assert_eq!(tcp_exchange(&mut stream).await, (vec![], true));
    assert_eq!(sim.fault_stats().unwrap().count(FaultKind::Disconnect), 1);
}

// ---------------------------------------------------------------------------------------
// Determinism and text

/// The bytes of 60 exchanges under `faults`, and the fault log.
async fn run(faults: Faults) -> (Vec<Vec<u8>>, Vec<Option<FaultKind>>) {
    let sim = Simulator::new(&DEVICE).faults(faults);
    let (mut stream, _server) = sim.duplex();
    let mut replies = Vec::new();
    for _ in 0..60 {
        replies.push(rtu_exchange(&mut stream, sim.address()).await.concat());
    }
    (replies, sim.fault_stats().unwrap().log())
}

#[tokio::test(start_paused = true)]
async fn the_same_seed_gives_the_same_faults() {
    let faults: Faults = "corrupt=0.1,truncate=0.1,garbage=0.1,wrong_slave=0.1,split=0.1,drop=0.1"
        .parse()
        .unwrap();
    let (bytes_a, log_a) = run(faults.clone().seed(11)).await;
    let (bytes_b, log_b) = run(faults.clone().seed(11)).await;
    let (_, log_c) = run(faults.seed(12)).await;
    assert_eq!(log_a.len(), 60);
    assert_eq!(log_a, log_b);
    assert_eq!(bytes_a, bytes_b);
    assert_ne!(log_a, log_c);
    // Roughly 60 % of replies are faulted, and clean ones exist.
    let faulted = log_a.iter().filter(|f| f.is_some()).count();
    assert!((20..=55).contains(&faulted), "{faulted}");
    // The log says which reply got what: a dropped reply is empty, a clean one valid.
    for (reply, fault) in bytes_a.iter().zip(&log_a) {
        match fault {
            None | Some(FaultKind::Split) => assert!(is_valid_frame(reply)),
            Some(FaultKind::Drop) => assert!(reply.is_empty()),
            Some(FaultKind::Corrupt) => assert!(!is_valid_frame(reply)),
            _ => {}
        }
    }
}

#[test]
fn faults_parse_and_print() {
    let faults: Faults = " delay=0.1 , corrupt=0.05,seed=42,late=250ms,pause=1.5ms"
        .parse()
        .unwrap();
    assert_eq!(faults.probability(FaultKind::Delay), 0.1);
    assert_eq!(faults.probability(FaultKind::Corrupt), 0.05);
    assert_eq!(faults.probability(FaultKind::Drop), 0.0);
    let text = faults.to_string();
    assert_eq!(
        text,
        "corrupt=0.05,delay=0.1,seed=42,late=250ms,pause=1500us"
    );
    assert_eq!(text.parse::<Faults>(), Ok(faults));
    assert_eq!("none".parse::<Faults>(), Ok(Faults::new()));
    assert_eq!("".parse::<Faults>(), Ok(Faults::new()));
    assert_eq!(Faults::new().to_string(), "none");
    assert_eq!(
        "timeout=2s".parse::<Faults>(),
        Ok(Faults::new().late(Duration::from_secs(3)))
    );
    let all = FaultKind::ALL
        .iter()
        .map(|kind| format!("{kind}=0.125"))
        .collect::<Vec<_>>()
        .join(",");
    assert!(all.parse::<Faults>().unwrap().check().is_ok());
}

#[test]
fn bad_fault_text_is_refused_with_a_typed_error() {
    let err = |text: &str| text.parse::<Faults>().unwrap_err();
    assert_eq!(
        err("lightning=0.5"),
        FaultsError::UnknownKind("lightning".into())
    );
    assert_eq!(
        err("corrupt=1.5"),
        FaultsError::BadProbability {
            kind: FaultKind::Corrupt,
            value: "1.5".into()
        }
    );
    assert!(matches!(
        err("drop=-0.1"),
        FaultsError::BadProbability { .. }
    ));
    assert!(matches!(
        err("drop=NaN"),
        FaultsError::BadProbability { .. }
    ));
    assert!(matches!(
        err("split=often"),
        FaultsError::BadProbability { .. }
    ));
    assert!(matches!(
        err("corrupt=0.6,drop=0.5"),
        FaultsError::SumAboveOne { .. }
    ));
    assert_eq!(err("corrupt"), FaultsError::MissingValue("corrupt".into()));
    assert_eq!(
        err("drop=0.1,drop=0.2"),
        FaultsError::Duplicate("drop".into())
    );
    assert!(matches!(
        err("late=soon"),
        FaultsError::BadDuration { name: "late", .. }
    ));
    assert!(matches!(
        err("pause=5"),
        FaultsError::BadDuration { name: "pause", .. }
    ));
    assert_eq!(err("seed=-1"), FaultsError::BadSeed("-1".into()));
    // Every error explains itself in one line.
    assert!(err("corrupt=2").to_string().contains("0..=1"));
    // Builders clamp instead.
    assert_eq!(Faults::new().drop(7.0).probability(FaultKind::Drop), 1.0);
    assert!(Faults::new().drop(0.8).corrupt(0.8).check().is_err());
}

// ---------------------------------------------------------------------------------------
// The line

/// `cycles` back-to-back measurement reads through a line of `baud`: the total time, and
/// the bytes of every reply.
async fn line_cycles(
    baud: u32,
    turnaround: Duration,
    faults: Option<Faults>,
    cycles: u32,
) -> (Duration, Line, Vec<Vec<u8>>) {
    let sim = Simulator::new(&DEVICE);
    if let Some(faults) = faults {
        sim.set_faults(Some(faults));
    }
    let line = Line::new(LineFormat::new(baud)).turnaround(turnaround);
    let (mut stream, _server) = sim.duplex_line(line.clone());
    let request = rtu_request(sim.address(), &MEASUREMENTS);
    let mut replies = Vec::new();
    let start = std::time::Instant::now();
    for _ in 0..cycles {
        // No waiting between cycles: the line holds the request until t3.5 has passed.
        stream.write_all(&request).await.unwrap();
        replies.push(read_exact(&mut stream, 25).await);
    }
    (start.elapsed(), line, replies)
}

/// (request + reply) characters + 2 t3.5 + turnaround.
fn cycle_time(format: LineFormat, turnaround: Duration) -> Duration {
    format.transmit_time(8 + 25) + format.frame_gap() * 2 + turnaround
}

async fn check_line(baud: u32, turnaround: Duration) {
    let format = LineFormat::new(baud);
    let cycles = 5;
    let (elapsed, line, replies) = line_cycles(baud, turnaround, None, cycles).await;
    for reply in &replies {
        assert!(is_valid_frame(reply), "{reply:02X?}");
        let decoded = rtu::decode_response(
            reply,
            DEVICE.default_slave,
            &MEASUREMENTS,
            DEVICE.frame_shape.exception,
        )
        .unwrap();
        assert!(matches!(decoded, Decoded::Frame { consumed: 25, .. }));
    }
    let theory = cycle_time(format, turnaround);
    // The last cycle's closing t3.5 is not waited for.
    let per_cycle = (elapsed + format.frame_gap()) / cycles;
    eprintln!("{baud} baud: {per_cycle:?} per cycle, theory {theory:?}");
    assert!(per_cycle >= theory, "{per_cycle:?} < {theory:?}");
    let stats = line.stats();
    assert_eq!(stats.frames(), u64::from(cycles));
    assert_eq!(stats.replies(), u64::from(cycles));
}

#[tokio::test]
async fn a_line_at_9600_takes_the_time_of_its_characters() {
    check_line(9_600, Duration::ZERO).await;
}

#[tokio::test]
async fn a_line_at_115200_takes_the_time_of_its_characters() {
    check_line(115_200, Duration::from_micros(500)).await;
}

#[tokio::test]
async fn a_request_sent_during_a_reply_is_held_and_counted() {
    // Slow, so the reply is still on the wire (100 ms to go) even on a busy machine.
    let format = LineFormat::new(2_400);
    let sim = Simulator::new(&DEVICE);
    let line = Line::new(format);
    let (mut stream, _server) = sim.duplex_line(line.clone());
    let request = rtu_request(sim.address(), &MEASUREMENTS);
    stream.write_all(&request).await.unwrap();
    let first = read_exact(&mut stream, 1).await;
    let sent = std::time::Instant::now();
    stream.write_all(&request).await.unwrap();
    let rest = read_exact(&mut stream, 24 + 25).await;
    let elapsed = sent.elapsed();
    let replies = [first, rest].concat();
    assert!(is_valid_frame(&replies[..25]), "{replies:02X?}");
    assert!(is_valid_frame(&replies[25..]), "{replies:02X?}");
    // At least the request, t3.5 and the second reply; the hold comes on top.
    let least = format.transmit_time(8 + 25) + format.frame_gap();
    assert!(elapsed >= least, "{elapsed:?} < {least:?}");
    let stats = line.stats();
    assert_eq!(stats.gap_violations(), 1);
    assert_eq!((stats.frames(), stats.replies()), (2, 2));
}

#[tokio::test]
async fn faults_compose_with_the_line() {
    let pause = Duration::from_millis(3);
    let faults = only(FaultKind::Split).pause(pause);
    let format = LineFormat::new(115_200);
    let (elapsed, _, replies) = line_cycles(115_200, Duration::ZERO, Some(faults), 3).await;
    for reply in &replies {
        assert!(is_valid_frame(reply));
    }
    // Each reply has at least one pause in it.
    let theory = cycle_time(format, Duration::ZERO) + pause;
    assert!((elapsed + format.frame_gap()) / 3 >= theory);
}

#[tokio::test(start_paused = true)]
async fn a_late_reply_on_a_line_under_paused_time() {
    let late = Duration::from_secs(2);
    let format = LineFormat::new(9_600);
    let sim = Simulator::new(&DEVICE).faults(only(FaultKind::Delay).late(late));
    let line = Line::new(format).turnaround(Duration::from_millis(1));
    let (mut stream, _server) = sim.duplex_line(line);
    let start = Instant::now();
    stream
        .write_all(&rtu_request(sim.address(), &MEASUREMENTS))
        .await
        .unwrap();
    let reply = read_exact(&mut stream, 25).await;
    assert!(is_valid_frame(&reply));
    let least = cycle_time(format, Duration::from_millis(1)) - format.frame_gap() + late;
    assert!(
        start.elapsed() >= least,
        "{:?} < {least:?}",
        start.elapsed()
    );
}

// ---------------------------------------------------------------------------------------
// A real client on the line

#[tokio::test]
async fn the_p_series_driver_keeps_the_gap_and_accepts_split_replies() {
    use optobus_p_series::transport::RtuClient;
    use optobus_p_series::{rtu_config, PSeries};

    for baud in [9_600, 115_200] {
        let format = LineFormat::new(baud);
        let sim = Simulator::new(&DEVICE)
            .faults(only(FaultKind::Split).pause(Duration::from_micros(300)));
        let line = Line::new(format);
        let (stream, _server) = sim.duplex_line(line.clone());
        let config = optobus_p_series::transport::RtuConfig {
            line: Some(format),
            ..rtu_config(&DEVICE)
        };
        let mut sensor = PSeries::with_default_slave(RtuClient::with_config(stream, config));
        let start = std::time::Instant::now();
        for _ in 0..4 {
            sensor.read_measurements().await.unwrap();
        }
        let elapsed = start.elapsed();
        let stats = line.stats();
        assert_eq!(
            stats.gap_violations(),
            0,
            "the driver waits t3.5 between frames"
        );
        assert_eq!(stats.frames(), 4);
        assert_eq!(sim.fault_stats().unwrap().count(FaultKind::Split), 4);
        let least = (cycle_time(format, Duration::ZERO) * 4).saturating_sub(format.frame_gap());
        assert!(elapsed >= least, "{baud}: {elapsed:?} < {least:?}");
    }
}

// ---------------------------------------------------------------------------------------
// Log lines

#[tokio::test(start_paused = true)]
async fn exchanges_and_fault_counts_read_as_log_lines() {
    let lines = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let sim = Simulator::new(&DEVICE).observe({
        let lines = std::sync::Arc::clone(&lines);
        move |exchange| lines.lock().unwrap().push(exchange.to_string())
    });
    let (mut stream, _server) = sim.duplex();
    let slave = sim.address();
    rtu_exchange(&mut stream, slave).await;
    let faults = only(FaultKind::Drop);
    sim.set_faults(Some(faults.clone()));
    rtu_exchange(&mut stream, slave).await;
    let line = format!("slave {slave} read holding 0 x8 -> 8 words");
    assert_eq!(*lines.lock().unwrap(), [line.clone(), line]);
    let stats = sim.fault_stats().unwrap();
    assert_eq!(
        stats.summary(&faults).to_string(),
        "faults injected: 1 of 1 replies (drop 1)"
    );
    assert_eq!(
        stats.summary(&Faults::new()).to_string(),
        "faults injected: 1 of 1 replies (drop 1)"
    );
}
