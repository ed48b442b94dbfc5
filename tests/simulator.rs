//! The simulator engine on the wire: real request bytes in, real reply bytes out, for every
//! family's generated `DEVICE`, including the golden frames of the five manuals.

use std::time::Duration;

use optobus_codec::{tcp, ExceptionShape, ReadFunction, Request, WriteValue};
use optobus_device::{DeviceInfo, Table};
use optobus_simulator::{Quirks, Reply, Simulator, Slaves};
use optobus_tests::generated::{ccs, lc_rs, mini, p_series, rangefinder};
use optobus_tests::golden::{self, Direction, Transport};
use optobus_tests::specs;
use optobus_tests::wire::{hex, holding, input, read, rtu_frame, with_crc, write, Line};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::time::{sleep, timeout};

// ---------------------------------------------------------------------------- golden frames

/// Replays every golden reply of `family` whose request the golden file gives: the registers
/// the reply reads are poked first, then the request's bytes must earn the reply's bytes.
async fn replay_golden(family: &str, device: &'static DeviceInfo, transport: Transport) -> usize {
    let file = golden::load(family).unwrap();
    let sim = Simulator::new(device).sentinel_every(0);
    let mut line = Line::new(&sim);
    let server = match transport {
        Transport::Tcp => Some(sim.serve_tcp("127.0.0.1:0").await.unwrap()),
        Transport::Rtu => None,
    };
    let mut tcp_stream = match &server {
        Some(server) => Some(TcpStream::connect(server.local_addr()).await.unwrap()),
        None => None,
    };
    let mut replayed = 0;
    for entry in &file.frames {
        if entry.direction != Direction::Response || entry.transport != transport {
            continue;
        }
        let request = entry.request.unwrap().to_request().unwrap();
        if let (Some(words), Request::Read { address, .. }) = (&entry.words, request) {
            let table = if words.function == 3 {
                Table::Holding
            } else {
                Table::Input
            };
            sim.poke(table, address, &words.values)
                .unwrap_or_else(|e| panic!("{}: {e}", entry.id));
        }
        let reply = match &mut tcp_stream {
            None => line.ask(entry.slave, &request).await,
            Some(stream) => {
                let header = tcp::Header {
                    transaction: entry.transaction.unwrap_or(0),
                    unit: entry.slave,
                };
                let mut out = [0; tcp::MAX_FRAME_LEN];
                let len = tcp::encode_request(&mut out, header, &request).unwrap();
                stream.write_all(&out[..len]).await.unwrap();
                let mut reply = vec![0; entry.bytes.0.len()];
                timeout(Duration::from_secs(2), stream.read_exact(&mut reply))
                    .await
                    .unwrap()
                    .unwrap();
                reply
            }
        };
        assert_eq!(
            golden::Hex(reply),
            entry.bytes,
            "{family} {}: reply differs",
            entry.id
        );
        replayed += 1;
    }
    replayed
}

/// `golden_replies::<family>`: the simulator of the spec's runtime description earns every
/// RTU reply of the family's golden file, byte for byte.
async fn replays_golden_rtu(family: &str) {
    let replayed = replay_golden(family, specs::describe(family), Transport::Rtu).await;
    assert!(replayed > 0, "{family}: no golden reply replayed");
}

optobus_tests::golden_cases!(golden_replies, async replays_golden_rtu);

#[tokio::test]
async fn golden_tcp_replies_byte_for_byte() {
    assert_eq!(
        replay_golden("p_series", &p_series::DEVICE, Transport::Tcp).await,
        3
    );
}

#[tokio::test(start_paused = true)]
async fn rangefinder_answers_a_broadcast_read_from_its_own_address() {
    // 3.5: "00 03 00 03 00 01 75 DB" is answered "19 03 02 00 19 59 8C".
    let quirks = Quirks {
        answer_broadcast_reads: true,
        ..Quirks::of(&rangefinder::DEVICE)
    };
    let sim = Simulator::new(&rangefinder::DEVICE).quirks(quirks);
    let mut line = Line::new(&sim);
    let reply = line.send(&hex("00 03 00 03 00 01 75 DB")).await;
    assert_eq!(reply, hex("19 03 02 00 19 59 8C"));
    // By default a broadcast read, like any broadcast, gets no reply.
    let mut plain = Line::new(&Simulator::new(&rangefinder::DEVICE));
    assert!(plain.send(&hex("00 03 00 03 00 01 75 DB")).await.is_empty());
}

// ---------------------------------------------------------------------------- exceptions

#[tokio::test(start_paused = true)]
async fn standard_exceptions_01_02_03() {
    let sim = Simulator::new(&p_series::DEVICE);
    let mut line = Line::new(&sim);
    // 01: FC01 (read coils) and FC16 are not among the P series' functions 3, 4, 6.
    let coils = with_crc(&[0x01, 0x01, 0x00, 0x00, 0x00, 0x08]);
    assert_eq!(line.send(&coils).await, with_crc(&[0x01, 0x81, 0x01]));
    let multiple = with_crc(&[0x01, 0x10, 0x00, 0x00, 0x00, 0x01, 0x02, 0x00, 0x01]);
    assert_eq!(line.send(&multiple).await, with_crc(&[0x01, 0x90, 0x01]));
    // 02: past the 160 input registers, over 125 words, undefined holding address.
    assert_eq!(line.exception(1, &input(159, 2)).await, 2);
    let too_many = with_crc(&[0x01, 0x04, 0x00, 0x00, 0x00, 0x7E]);
    assert_eq!(line.send(&too_many).await, with_crc(&[0x01, 0x84, 0x02]));
    assert_eq!(line.exception(1, &write(37, 1)).await, 2, "reserved");
    assert_eq!(line.exception(1, &write(60, 1)).await, 2, "past the table");
    // 03: out of range, undefined enum code, packed field with an undefined code.
    assert_eq!(line.exception(1, &write(2, 1001)).await, 3);
    assert_eq!(line.exception(1, &write(6, 0x07)).await, 3);
    assert_eq!(line.exception(1, &write(5, 0x0306)).await, 3);
    assert_eq!(
        line.exception(1, &write(20, 0)).await,
        3,
        "save takes only 1"
    );
    // Refused writes leave the registers as they were.
    assert_eq!(line.words(1, &holding(2, 5)).await, [5, 0, 0, 0, 0x08]);
    // Reserved ranges read as zeros.
    assert_eq!(line.words(1, &holding(36, 4)).await, [0, 0, 0, 0]);
    assert_eq!(line.words(1, &input(138, 2)).await, [0, 0]);
}

#[tokio::test(start_paused = true)]
async fn lc_rs_exceptions_in_its_counted_word_shape() {
    let sim = Simulator::new(&lc_rs::DEVICE);
    let mut line = Line::new(&sim);
    // At most 8 registers per read (2.2 4)): 9 is a register address error, 7-byte frame.
    let reply = line.ask(1, &holding(0x80, 9)).await;
    assert_eq!(reply, with_crc(&[0x01, 0x83, 0x02, 0x00, 0x01]));
    // FC04 is not supported: the counted-word frame with code 0x0001.
    let reply = line.ask(1, &input(0, 1)).await;
    assert_eq!(reply, with_crc(&[0x01, 0x84, 0x02, 0x00, 0x01]));
    // Undefined (reserved) addresses are refused too.
    assert_eq!(line.exception(1, &holding(0x0008, 1)).await, 0x0001);
    assert_eq!(
        line.exception(1, &holding(0x0080, 1)).await,
        0x0001,
        "write-only"
    );
    // A bad value: 0x0002, and the parity stays.
    assert_eq!(line.exception(1, &write(0x86, 3)).await, 0x0002);
    assert_eq!(line.words(1, &holding(0x86, 1)).await, [0]);
    // Writing the read-only distance: an address error.
    assert_eq!(line.exception(1, &write(0, 5)).await, 0x0001);
}

// ---------------------------------------------------------------------------- writes

// ---------------------------------------------------------------------------- commands

// ---------------------------------------------------------------------------- addressing

#[tokio::test(start_paused = true)]
async fn broadcasts_are_carried_out_and_never_answered() {
    let a = Simulator::new(&p_series::DEVICE);
    let b = Simulator::new(&p_series::DEVICE).slave(2);
    let slaves = Slaves::new([a.clone(), b.clone()]);
    let (stream, _server) = slaves.duplex();
    let mut line = Line {
        stream,
        shape: ExceptionShape::Standard,
    };
    assert!(line.ask(0, &write(2, 321)).await.is_empty());
    assert!(line.ask(0, &holding(2, 1)).await.is_empty());
    assert_eq!(line.words(1, &holding(2, 1)).await, [321]);
    assert_eq!(line.words(2, &holding(2, 1)).await, [321]);
    // Each slave answers its own requests; nobody answers slave 3.
    line.ask(2, &write(2, 7)).await;
    assert_eq!(line.words(1, &holding(2, 1)).await, [321]);
    assert_eq!(line.words(2, &holding(2, 1)).await, [7]);
    assert!(line.ask(3, &holding(2, 1)).await.is_empty());
}

#[tokio::test(start_paused = true)]
async fn two_families_share_one_line() {
    // A rangefinder (10-byte FC06) and an LC-RS (counted-word exceptions) on one port.
    let slaves = Slaves::new([
        Simulator::new(&rangefinder::DEVICE),
        Simulator::new(&lc_rs::DEVICE),
    ]);
    let (stream, _server) = slaves.duplex();
    let mut line = Line {
        stream,
        shape: ExceptionShape::Standard,
    };
    let wide = hex("19 06 00 0C 00 09 EB 10 68 52");
    assert_eq!(line.send(&wide).await, wide);
    let reply = line.ask(1, &holding(9, 1)).await;
    assert_eq!(reply, with_crc(&[0x01, 0x83, 0x02, 0x00, 0x01]));
}

#[tokio::test(start_paused = true)]
async fn silent_devices_do_not_answer() {
    let sim = Simulator::new(&ccs::DEVICE);
    let mut line = Line::new(&sim);
    sim.set_silent(true);
    assert!(line.ask(1, &holding(0, 1)).await.is_empty());
    assert!(line.ask(1, &write(0, 1)).await.is_empty());
    sim.set_silent(false);
    assert_eq!(
        line.words(1, &holding(0, 1)).await,
        [0],
        "the write was not carried out"
    );
}

#[tokio::test(start_paused = true)]
async fn split_back_to_back_and_garbled_input() {
    let sim = Simulator::new(&p_series::DEVICE);
    let mut line = Line::new(&sim);
    let request = rtu_frame(1, &holding(0, 3));
    let expected = line.ask(1, &holding(0, 3)).await;
    // One byte at a time.
    for byte in &request {
        line.stream.write_all(&[*byte]).await.unwrap();
        sleep(Duration::from_millis(1)).await;
    }
    assert_eq!(line.send(&[]).await, expected);
    // Two frames back to back: two replies.
    let twice = [request.clone(), request.clone()].concat();
    assert_eq!(
        line.send(&twice).await,
        [expected.clone(), expected.clone()].concat()
    );
    // Garbage, a frame, a frame with a broken CRC, a frame for slave 9, a frame.
    let mut broken = request.clone();
    broken[7] ^= 0xFF;
    let garbled = [
        vec![0xFF, 0x00, 0x13, 0x37, 0x03],
        request.clone(),
        broken,
        rtu_frame(9, &holding(0, 3)),
        vec![0x01],
        request.clone(),
    ]
    .concat();
    assert_eq!(
        line.send(&garbled).await,
        [expected.clone(), expected.clone()].concat()
    );
    // A partial frame followed by silence is dropped; the next frame is answered.
    line.send(&request[..5]).await;
    assert_eq!(line.send(&request).await, expected);
}

#[tokio::test(start_paused = true)]
async fn random_bytes_never_break_the_server() {
    let sim = Simulator::new(&rangefinder::DEVICE);
    let mut line = Line::new(&sim);
    let mut state = 0x1234_5678_u32;
    let mut noise = vec![0u8; 20_000];
    for byte in &mut noise {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        *byte = state as u8;
    }
    for chunk in noise.chunks(997) {
        line.stream.write_all(chunk).await.unwrap();
    }
    sleep(Duration::from_millis(50)).await;
    let mut drain = [0; 4096];
    while let Ok(Ok(n)) = timeout(Duration::from_millis(30), line.stream.read(&mut drain)).await {
        assert!(n > 0);
    }
    assert_eq!(line.words(25, &holding(3, 1)).await, [25]);
}

/// `simulator::<family>`: the simulator of the spec's runtime description answers a read of
/// every readable register with its words, and no request panics it.
fn answers_and_survives(family: &str) {
    let device = specs::describe(family);
    answers_every_readable_register(family, device);
    no_request_panics(family, device);
}

optobus_tests::family_cases!(simulator, answers_and_survives);

#[test]
fn mini_answers_and_survives() {
    answers_every_readable_register("mini", &mini::DEVICE);
    no_request_panics("mini", &mini::DEVICE);
}

fn no_request_panics(family: &str, device: &'static DeviceInfo) {
    let sim = Simulator::new(device);
    for function in [ReadFunction::Holding, ReadFunction::Input] {
        for address in (0..=200).chain([u16::MAX - 1, u16::MAX]) {
            for count in [0, 1, 2, 3, 6, 8, 9, 60, 122, 125, 126, u16::MAX] {
                let reply = sim.request(sim.address(), &read(function, address, count));
                if let Reply::Read { words, .. } = reply {
                    assert_eq!(words.len(), usize::from(count), "{family}");
                }
            }
        }
    }
    for address in (0..=200).chain([u16::MAX]) {
        for value in [0, 1, 2, 170, 0x00FF, 0x7FFF, 0x8000, 0xFFFF] {
            sim.request(sim.address(), &write(address, value));
            let wide = Request::Write {
                address,
                value: WriteValue::DoubleWord(u32::from(value) << 8),
            };
            sim.request(sim.address(), &wide);
        }
    }
    // Whatever was written, the device still answers (busy commands aside).
    sim.power_cycle();
}

// ---------------------------------------------------------------------------- TCP

#[tokio::test]
async fn tcp_echoes_transaction_and_unit_on_many_connections() {
    let sim = Simulator::new(&p_series::DEVICE);
    let server = sim.serve_tcp("127.0.0.1:0").await.unwrap();
    let mut first = TcpStream::connect(server.local_addr()).await.unwrap();
    let mut second = TcpStream::connect(server.local_addr()).await.unwrap();
    for (stream, transaction, unit) in [(&mut first, 0x1234, 7), (&mut second, 0xBEEF, 0xFF)] {
        let header = tcp::Header { transaction, unit };
        let mut out = [0; tcp::MAX_FRAME_LEN];
        let len = tcp::encode_request(&mut out, header, &holding(2, 1)).unwrap();
        // Split across two writes.
        stream.write_all(&out[..5]).await.unwrap();
        stream.flush().await.unwrap();
        stream.write_all(&out[5..len]).await.unwrap();
        let mut reply = [0; 11];
        stream.read_exact(&mut reply).await.unwrap();
        let [t0, t1] = u16::to_be_bytes(transaction);
        assert_eq!(reply, [t0, t1, 0, 0, 0, 5, unit, 3, 2, 0, 5]);
    }
    // Exceptions travel over TCP too, and the bound host's port shows in input 154.
    let header = tcp::Header {
        transaction: 9,
        unit: 1,
    };
    let mut out = [0; tcp::MAX_FRAME_LEN];
    let len = tcp::encode_request(&mut out, header, &write(2, 0)).unwrap();
    first.write_all(&out[..len]).await.unwrap();
    let mut reply = [0; 9];
    first.read_exact(&mut reply).await.unwrap();
    assert_eq!(reply, [0, 9, 0, 0, 0, 3, 1, 0x86, 3]);
    let port = sim.peek(Table::Input, 154).unwrap()[0];
    assert_eq!(port, second.local_addr().unwrap().port());
    // A silent device leaves the client waiting.
    sim.set_silent(true);
    second.write_all(&out[..len]).await.unwrap();
    let mut byte = [0; 1];
    assert!(timeout(Duration::from_millis(100), second.read(&mut byte))
        .await
        .is_err());
}

// ---------------------------------------------------------------------------- pty

#[cfg(unix)]
#[tokio::test]
async fn pty_speaks_rtu() {
    use std::io::{Read, Write};
    let sim = Simulator::new(&ccs::DEVICE);
    let pty = sim.serve_pty().unwrap();
    let path = pty.path().to_owned();
    let reply = tokio::task::spawn_blocking(move || {
        let mut port = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .unwrap();
        port.write_all(&rtu_frame(1, &holding(8, 2))).unwrap();
        let mut reply = [0; 9];
        port.read_exact(&mut reply).unwrap();
        reply
    });
    let reply = timeout(Duration::from_secs(5), reply)
        .await
        .unwrap()
        .unwrap();
    assert_eq!(reply.to_vec(), with_crc(&[0x01, 0x03, 0x04, 0, 0, 0, 0]));
}

// ---------------------------------------------------------------------------- measurements

fn answers_every_readable_register(family: &str, device: &'static DeviceInfo) {
    let sim = Simulator::new(device);
    for register in device.readable_registers() {
        let request = read(
            register.table.read_function(),
            register.address,
            register.words,
        );
        match sim.request(sim.address(), &request) {
            Reply::Read { words, .. } => assert_eq!(words.len(), usize::from(register.words)),
            other => panic!("{family} {}: {other:?}", register.name),
        }
    }
}

// ---------------------------------------------------------------------------- drivers

/// mbpoll, when installed, reads holding registers through the pseudo-terminal and over TCP.
#[tokio::test]
#[cfg_attr(
    not(peer_mbpoll),
    ignore = "mbpoll is not installed (Debian package mbpoll)"
)]
async fn mbpoll_reads_the_simulator_when_installed() {
    let sim = Simulator::new(&p_series::DEVICE);
    let pty = sim.serve_pty().unwrap();
    let server = sim.serve_tcp("127.0.0.1:0").await.unwrap();
    let port = server.local_addr().port().to_string();
    let path = pty.path().display().to_string();
    // Holding 0031-0032 (mbpoll counts from 1): slave address 1, baud code 4.
    let rtu = [
        "-m", "rtu", "-a", "1", "-b", "115200", "-P", "none", "-t", "4", "-r", "32",
    ];
    let tcp = ["-m", "tcp", "-a", "1", "-p", &port, "-t", "4", "-r", "32"];
    for (args, target) in [(&rtu[..], path.as_str()), (&tcp[..], "127.0.0.1")] {
        let mut command = std::process::Command::new("mbpoll");
        command
            .args(args)
            .args(["-c", "2", "-1", "-o", "2", target]);
        let output = tokio::task::spawn_blocking(move || command.output());
        let output = timeout(Duration::from_secs(10), output)
            .await
            .unwrap()
            .unwrap()
            .unwrap();
        let text = String::from_utf8_lossy(&output.stdout);
        assert!(
            text.contains("[32]: \t1") && text.contains("[33]: \t4"),
            "{text}"
        );
    }
}

// ------------------------------------------------- allowed values, reserved reads, actions

#[tokio::test(start_paused = true)]
async fn readable_reserved_ranges_answer_zeros_and_action_registers_are_not_read() {
    // P series 4.2.2 note 1: the 160 input registers may be read, reserved rows included.
    let sim = Simulator::new(&p_series::DEVICE);
    let mut line = Line::new(&sim);
    let words = line.words(1, &input(138, 17)).await;
    assert_eq!(&words[..2], [0, 0], "reserved 138-139");
    assert_eq!(&words[3..12], [0; 9], "reserved 141-149");
    assert_eq!(&words[12..16], [192, 168, 0, 10], "the IP address at 150");
    // LC-RS: the undefined 0088H is refused (table 2 code 0x0001), and so is factory reset,
    // whose read the manual leaves undefined.
    let sim = Simulator::new(&lc_rs::DEVICE);
    let mut line = Line::new(&sim);
    assert_eq!(line.exception(1, &holding(0x88, 1)).await, 0x0001);
    assert_eq!(line.exception(1, &holding(0x89, 1)).await, 0x0001, "action");
    // A range the spec marks readable answers zeros even on a device that refuses the others.
    let mut reserved = lc_rs::DEVICE.reserved.to_vec();
    for range in &mut reserved {
        range.readable = range.from == 0x88;
    }
    let device: &'static DeviceInfo = Box::leak(Box::new(DeviceInfo {
        reserved: Box::leak(reserved.into_boxed_slice()),
        ..lc_rs::DEVICE
    }));
    let sim = Simulator::new(device);
    let mut line = Line::new(&sim);
    assert_eq!(line.words(1, &holding(0x86, 3)).await, [0, 1, 0]);
    assert_eq!(line.exception(1, &holding(0x81, 1)).await, 0x0001);
}
