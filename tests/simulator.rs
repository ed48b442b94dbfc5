//! The simulator engine on the wire: real request bytes in, real reply bytes out, for every
//! family's generated `DEVICE`, including the golden frames of the five manuals.

use std::time::Duration;

use optobus_codec::crc::crc16;
use optobus_codec::value::{join_i32, join_u32, WordOrder};
use optobus_codec::{
    rtu, tcp, Decoded, ExceptionShape, ReadFunction, Request, Response, WriteValue,
};
use optobus_device::{DeviceInfo, Table};
use optobus_simulator::{Bus, Quirks, Reply, Simulator};
use optobus_tests::generated::{ccf, ccs, lc_rs, mini, p_series, rangefinder};
use optobus_tests::golden::{self, Direction, Transport};
use optobus_tests::specs;
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};
use tokio::net::TcpStream;
use tokio::time::{sleep, timeout};

// ---------------------------------------------------------------------------- helpers

fn hex(text: &str) -> Vec<u8> {
    text.split_whitespace()
        .map(|pair| u8::from_str_radix(pair, 16).unwrap())
        .collect()
}

/// `body` with its CRC appended (for frames the codec refuses to encode).
fn with_crc(body: &[u8]) -> Vec<u8> {
    let mut frame = body.to_vec();
    frame.extend_from_slice(&crc16(body).to_le_bytes());
    frame
}

fn rtu_frame(slave: u8, request: &Request) -> Vec<u8> {
    let mut out = [0; rtu::MAX_FRAME_LEN];
    let len = rtu::encode_request(&mut out, slave, request).unwrap();
    out[..len].to_vec()
}

fn read(function: ReadFunction, address: u16, count: u16) -> Request {
    Request::Read {
        function,
        address,
        count,
    }
}

fn holding(address: u16, count: u16) -> Request {
    read(ReadFunction::Holding, address, count)
}

fn input(address: u16, count: u16) -> Request {
    read(ReadFunction::Input, address, count)
}

fn write(address: u16, value: u16) -> Request {
    Request::Write {
        address,
        value: WriteValue::Word(value),
    }
}

/// The client's end of an in-memory RTU line.
struct Line {
    stream: DuplexStream,
    shape: ExceptionShape,
}

impl Line {
    fn new(sim: &Simulator) -> Self {
        let (stream, _server) = sim.duplex();
        Self {
            stream,
            shape: sim.device().frame_shape.exception,
        }
    }

    /// Sends `bytes` and collects what comes back until 30 ms of silence.
    async fn send(&mut self, bytes: &[u8]) -> Vec<u8> {
        self.stream.write_all(bytes).await.unwrap();
        let mut reply = Vec::new();
        let mut chunk = [0; 512];
        while let Ok(read) = timeout(Duration::from_millis(30), self.stream.read(&mut chunk)).await
        {
            let read = read.unwrap();
            assert!(read > 0, "the server closed the line");
            reply.extend_from_slice(&chunk[..read]);
        }
        reply
    }

    async fn ask(&mut self, slave: u8, request: &Request) -> Vec<u8> {
        self.send(&rtu_frame(slave, request)).await
    }

    /// The words a read returns (panics on anything else).
    async fn words(&mut self, slave: u8, request: &Request) -> Vec<u16> {
        let reply = self.ask(slave, request).await;
        match rtu::decode_response(&reply, slave, request, self.shape) {
            Ok(Decoded::Frame {
                frame: Response::Read { words, .. },
                consumed,
            }) if consumed == reply.len() => words.iter().collect(),
            other => panic!("{request:?} -> {reply:02X?}: {other:?}"),
        }
    }

    /// The exception code a request earns (panics on anything else).
    async fn exception(&mut self, slave: u8, request: &Request) -> u16 {
        let reply = self.ask(slave, request).await;
        match rtu::decode_response(&reply, slave, request, self.shape) {
            Err(optobus_codec::DecodeError::Exception { code, .. }) => code.0,
            other => panic!("{request:?} -> {reply:02X?}: expected an exception, {other:?}"),
        }
    }
}

fn i32_at(words: &[u16], at: usize) -> i32 {
    join_i32([words[at], words[at + 1]], WordOrder::HighFirst)
}

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

#[tokio::test(start_paused = true)]
async fn rangefinder_reads_one_field_at_its_own_width() {
    let sim = Simulator::new(&rangefinder::DEVICE);
    let mut line = Line::new(&sim);
    // Factory serial parameters: no parity, 115200 (3.6 reads 00 01 C2 00).
    assert_eq!(line.words(25, &holding(4, 2)).await, [0x0001, 0xC200]);
    // 3.6's printed count 1 and a read over two fields are refused.
    assert_eq!(line.exception(25, &holding(4, 1)).await, 2);
    assert_eq!(line.exception(25, &holding(2, 3)).await, 2);
    assert_eq!(line.exception(25, &holding(0x19, 7)).await, 2);
    // A reserved field reads as one zero word; FC04 is not supported.
    assert_eq!(line.words(25, &holding(0x12, 1)).await, [0]);
    assert_eq!(line.exception(25, &input(0, 1)).await, 1);
    // The 4-byte FC06 is echoed as the 10-byte frame, and reads back.
    let wide = Request::Write {
        address: 0x0C,
        value: WriteValue::DoubleWord(650_000),
    };
    let frame = rtu_frame(25, &wide);
    assert_eq!(frame.len(), 10);
    assert_eq!(line.send(&frame).await, frame);
    assert_eq!(line.words(25, &holding(0x0C, 2)).await, [0x0009, 0xEB10]);
    // Out of range (0-900000) and an undefined parity code: 03, nothing changes.
    let too_far = Request::Write {
        address: 0x0C,
        value: WriteValue::DoubleWord(900_001),
    };
    assert_eq!(line.exception(25, &too_far).await, 3);
    let parity = Request::Write {
        address: 4,
        value: WriteValue::DoubleWord(0x0301_C200),
    };
    assert_eq!(line.exception(25, &parity).await, 3);
    assert_eq!(line.words(25, &holding(0x0C, 2)).await, [0x0009, 0xEB10]);
    // The read-only error status cannot be written.
    assert_eq!(line.exception(25, &write(0, 1)).await, 2);
}

// ---------------------------------------------------------------------------- writes

#[tokio::test(start_paused = true)]
async fn p_series_split_writes_latch_on_the_high_word() {
    let sim = Simulator::new(&p_series::DEVICE);
    let mut line = Line::new(&sim);
    // 4.1.2 note 4: slope 2 = 0x0020_0000, write 28 (low) first, then 27 (high).
    assert_eq!(
        line.ask(1, &write(28, 0x0000)).await,
        rtu_frame(1, &write(28, 0))
    );
    assert_eq!(
        line.words(1, &holding(27, 2)).await,
        [0, 0],
        "held until the high word"
    );
    line.ask(1, &write(27, 0x0020)).await;
    assert_eq!(line.words(1, &holding(27, 2)).await, [0x0020, 0x0000]);
    // Offset 0.5 mm = 0x0007_A120: 30 then 29.
    line.ask(1, &write(30, 0xA120)).await;
    line.ask(1, &write(29, 0x0007)).await;
    assert_eq!(i32_at(&line.words(1, &holding(29, 2)).await, 0), 500_000);
    // A high word alone pairs with the stored low word.
    line.ask(1, &write(29, 0xFFFF)).await;
    assert_eq!(
        i32_at(&line.words(1, &holding(29, 2)).await, 0),
        -0x1_0000 + 0xA120
    );
}

#[tokio::test(start_paused = true)]
async fn lc_rs_validates_the_32_bit_baud_rate_once_whole() {
    let sim = Simulator::new(&lc_rs::DEVICE);
    let mut line = Line::new(&sim);
    assert_eq!(
        line.words(1, &holding(0x83, 2)).await,
        [0, 9600],
        "factory 9600"
    );
    // High word first (2.3); 0x0002_0000 = 131072 is over 115200: refused when whole.
    line.ask(1, &write(0x83, 2)).await;
    assert_eq!(line.exception(1, &write(0x84, 0)).await, 0x0002);
    assert_eq!(line.words(1, &holding(0x83, 2)).await, [0, 9600]);
    line.ask(1, &write(0x83, 1)).await;
    line.ask(1, &write(0x84, 0xC200)).await;
    assert_eq!(line.words(1, &holding(0x83, 2)).await, [1, 0xC200]);
}

#[tokio::test(start_paused = true)]
async fn lc_rs_settings_take_effect_after_save_and_power_cycle() {
    let sim = Simulator::new(&lc_rs::DEVICE);
    let mut line = Line::new(&sim);
    // 2.3: device ID 2. Echoed from 01, read back at once, but the device stays at 01.
    let id = hex("01 06 00 85 00 02 19 E2");
    assert_eq!(line.send(&id).await, id);
    assert_eq!(line.words(1, &holding(0x85, 1)).await, [2]);
    assert!(line.ask(2, &holding(0x85, 1)).await.is_empty());
    // Without a save the power cycle forgets the change.
    sim.power_cycle();
    assert_eq!(line.words(1, &holding(0x85, 1)).await, [1]);
    line.send(&id).await;
    let save = hex("01 06 00 80 00 00 88 22");
    assert_eq!(line.send(&save).await, save);
    sim.power_cycle();
    assert_eq!(sim.address(), 2);
    assert!(line.ask(1, &holding(0x85, 1)).await.is_empty());
    assert_eq!(line.words(2, &holding(0x85, 1)).await, [2]);
    // Factory reset (any value): ID 1 again after the next restart.
    line.ask(2, &write(0x89, 0)).await;
    sim.power_cycle();
    assert_eq!(line.words(1, &holding(0x85, 1)).await, [1]);
}

#[tokio::test(start_paused = true)]
async fn p_series_slave_address_applies_to_the_next_request() {
    let sim = Simulator::new(&p_series::DEVICE);
    let mut line = Line::new(&sim);
    assert_eq!(
        line.ask(1, &write(31, 7)).await,
        rtu_frame(1, &write(31, 7))
    );
    assert!(line.ask(1, &holding(31, 1)).await.is_empty());
    assert_eq!(
        line.words(7, &holding(31, 2)).await,
        [7, 4],
        "baud code 4 = 115200"
    );
}

// ---------------------------------------------------------------------------- commands

#[tokio::test(start_paused = true)]
async fn p_series_zero_and_clear_zero() {
    let sim = Simulator::new(&p_series::DEVICE).sentinel_every(0);
    let mut line = Line::new(&sim);
    let before = i32_at(&line.words(1, &input(0, 2)).await, 0);
    assert!(
        (4_000_000..6_000_000).contains(&before),
        "about 5 mm: {before}"
    );
    line.ask(1, &write(7, 1)).await;
    let zeroed = line.words(1, &input(0, 16)).await;
    assert!(
        i32_at(&zeroed, 0).abs() < 5_000,
        "distance 1 ~0: {}",
        i32_at(&zeroed, 0)
    );
    assert!(i32_at(&zeroed, 10).abs() < 5_000, "sampled distance 1 ~0");
    assert!(i32_at(&zeroed, 2) > 4_000_000, "distance 2 untouched");
    sleep(Duration::from_secs(3)).await;
    line.ask(1, &write(7, 0)).await;
    let cleared = i32_at(&line.words(1, &input(0, 2)).await, 0);
    assert!((4_000_000..6_000_000).contains(&cleared));
}

#[tokio::test(start_paused = true)]
async fn ccf_per_channel_zero_acts_on_its_own_channel() {
    let sim = Simulator::new(&ccf::DEVICE).sentinel_every(0);
    let mut line = Line::new(&sim);
    // Channel 2's position zero is holding 3 + 8; its distance 1 is input 6.
    line.ask(1, &write(11, 1)).await;
    let words = line.words(1, &input(0, 24)).await;
    assert!(i32_at(&words, 6).abs() < 5_000, "channel 2 zeroed");
    for channel in [0, 2, 3] {
        assert!(
            i32_at(&words, channel * 6) > 1_000_000,
            "channel {}",
            channel + 1
        );
    }
    assert_eq!(line.words(1, &holding(11, 1)).await, [1]);
}

#[tokio::test(start_paused = true)]
async fn saves_clear_their_flag_and_busy_devices_stay_silent() {
    // CCS: save (holding 13 = 1) takes about 400 ms with no answers (4.1.2).
    let sim = Simulator::new(&ccs::DEVICE);
    let mut line = Line::new(&sim);
    let save = rtu_frame(1, &write(13, 1));
    assert_eq!(line.send(&save).await, save);
    assert!(sim.is_busy());
    assert!(line.ask(1, &holding(13, 1)).await.is_empty());
    sleep(Duration::from_millis(400)).await;
    assert_eq!(
        line.words(1, &holding(13, 1)).await,
        [0],
        "the flag clears itself"
    );
    // P series: 0020 returns to 0 after the save.
    let p = Simulator::new(&p_series::DEVICE);
    let mut line = Line::new(&p);
    line.ask(1, &write(20, 1)).await;
    assert_eq!(line.words(1, &holding(20, 1)).await, [0]);
}

#[tokio::test(start_paused = true)]
async fn p_series_network_reset_and_reboot() {
    let sim = Simulator::new(&p_series::DEVICE);
    let mut line = Line::new(&sim);
    assert_eq!(line.words(1, &input(150, 4)).await, [192, 168, 0, 10]);
    sim.poke(Table::Input, 150, &[10, 0, 0, 5]).unwrap();
    line.ask(1, &write(19, 1)).await;
    assert_eq!(line.words(1, &input(150, 4)).await, [192, 168, 0, 10]);
    // An unsaved light power is lost by the soft reboot; the device restarts for 5 s.
    line.ask(1, &write(2, 500)).await;
    line.ask(1, &write(19, 170)).await;
    assert!(line.ask(1, &holding(2, 1)).await.is_empty());
    sleep(Duration::from_secs(5)).await;
    assert_eq!(line.words(1, &holding(2, 1)).await, [5]);
    // A saved one survives.
    line.ask(1, &write(2, 500)).await;
    line.ask(1, &write(20, 1)).await;
    line.ask(1, &write(19, 170)).await;
    sleep(Duration::from_secs(5)).await;
    assert_eq!(line.words(1, &holding(2, 1)).await, [500]);
}

#[tokio::test(start_paused = true)]
async fn p_series_buffer_of_1000_values_reads_in_17_pages() {
    let sim = Simulator::new(&p_series::DEVICE).sentinel_every(0);
    let mut line = Line::new(&sim);
    // 5.4: data type distance 1, report count 1000, unlocked; buffer; lock; read 17 times.
    line.ask(1, &write(24, 0)).await;
    line.ask(1, &write(22, 1000)).await;
    line.ask(1, &write(23, 0)).await;
    sleep(Duration::from_millis(50)).await; // 1000 x 6.25 us fills it
    line.ask(1, &write(23, 1)).await;
    let request = hex("01 04 00 10 00 7A 70 2C");
    let mut values = Vec::new();
    for page in 1..=17u16 {
        let reply = line.send(&request).await;
        assert_eq!(reply.len(), 5 + 244, "page {page}");
        let words: Vec<u16> = reply[3..247]
            .chunks(2)
            .map(|pair| u16::from_be_bytes([pair[0], pair[1]]))
            .collect();
        let valid = if page < 17 { 60 } else { 40 };
        assert_eq!(words[0], (page * 60).min(1000), "read count, page {page}");
        assert_eq!(words[1], valid, "valid count, page {page}");
        for slot in 0..60 {
            let value = i32_at(&words, 2 + 2 * slot);
            if slot < usize::from(valid) {
                assert!(
                    (4_000_000..6_000_000).contains(&value),
                    "page {page}: {value}"
                );
                values.push(value);
            } else {
                assert_eq!(value, 0x7FFF_FFFF, "past the valid count");
            }
        }
    }
    assert_eq!(values.len(), 1000);
    // Read out: nothing valid any more; the counts alone do not turn the page.
    assert_eq!(
        line.words(1, &input(16, 4)).await,
        [1000, 0, 0x7FFF, 0xFFFF]
    );
    assert_eq!(line.words(1, &input(16, 2)).await, [1000, 0]);
    // Unlocking clears it.
    line.ask(1, &write(23, 0)).await;
    assert_eq!(line.words(1, &input(16, 2)).await, [0, 0]);
    // Changing the report count resets the lock flag (4.2.2 note 5).
    line.ask(1, &write(23, 1)).await;
    line.ask(1, &write(22, 60)).await;
    assert_eq!(line.words(1, &holding(22, 2)).await, [60, 0]);
}

#[tokio::test(start_paused = true)]
async fn p_series_buffer_reports_what_it_holds() {
    // Appendix 3 (4) example 1: report count 60 with only 20 buffered gives 20 valid.
    let sim = Simulator::new(&p_series::DEVICE);
    let mut line = Line::new(&sim);
    // Set up without the wire, whose replies take time to wait for.
    sim.request(1, &write(6, 0x1E)); // 1 ms sampling interval
    sim.request(1, &write(22, 60));
    tokio::time::advance(Duration::from_micros(20_500)).await;
    sim.request(1, &write(23, 1));
    assert_eq!(line.words(1, &input(16, 122)).await[..2], [20, 20]);
}

// ---------------------------------------------------------------------------- addressing

#[tokio::test(start_paused = true)]
async fn broadcasts_are_carried_out_and_never_answered() {
    let a = Simulator::new(&p_series::DEVICE);
    let b = Simulator::new(&p_series::DEVICE).slave(2);
    let bus = Bus::new([a.clone(), b.clone()]);
    let (stream, _server) = bus.duplex();
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
    let bus = Bus::new([
        Simulator::new(&rangefinder::DEVICE),
        Simulator::new(&lc_rs::DEVICE),
    ]);
    let (stream, _server) = bus.duplex();
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

#[tokio::test(start_paused = true)]
async fn measurements_move_and_sometimes_read_invalid() {
    let sim = Simulator::new(&ccs::DEVICE).seed(7);
    let twin = Simulator::new(&ccs::DEVICE).seed(7);
    let other = Simulator::new(&ccs::DEVICE).seed(8);
    let mut line = Line::new(&sim);
    let mut distances = Vec::new();
    let mut counts = Vec::new();
    let start = tokio::time::Instant::now();
    for _ in 0..500 {
        let words = line.words(1, &input(0, 12)).await;
        distances.push(i32_at(&words, 0));
        counts.push(join_u32([words[6], words[7]], WordOrder::HighFirst));
        sleep(Duration::from_millis(10)).await;
    }
    let invalid = distances.iter().filter(|&&d| d == i32::MIN).count();
    assert!(
        (2..=30).contains(&invalid),
        "about 1 in 50 invalid: {invalid}"
    );
    let valid: Vec<i32> = distances
        .iter()
        .copied()
        .filter(|&d| d != i32::MIN)
        .collect();
    let (low, high) = (valid.iter().min().unwrap(), valid.iter().max().unwrap());
    assert!(*low > 4_000_000 && *high < 6_000_000 && high - low > 1_000);
    // The encoder counts up, about 1000 per second.
    assert!(counts.windows(2).all(|w| w[0] <= w[1]));
    let per_second = f64::from(counts[499] - counts[0]) / start.elapsed().as_secs_f64();
    assert!((900.0..1100.0).contains(&per_second), "{per_second}");
    // The same seed gives the same readings, another seed others.
    assert_eq!(twin.peek(Table::Input, 0), sim.peek(Table::Input, 0));
    assert_ne!(other.peek(Table::Input, 0), sim.peek(Table::Input, 0));
}

#[tokio::test(start_paused = true)]
async fn p_series_statistics_follow_their_configuration() {
    let sim = Simulator::new(&p_series::DEVICE).sentinel_every(0);
    let mut line = Line::new(&sim);
    // Statistic 1 defaults to the maximum of distance 1 (0x0000); statistic 2 is set to the
    // peak-to-peak of distance 1 (0x0002).
    line.ask(1, &write(13, 0x0002)).await;
    let mut highest = i32::MIN;
    for _ in 0..100 {
        let words = line.words(1, &input(0, 10)).await;
        highest = highest.max(i32_at(&words, 0));
        assert!(
            i32_at(&words, 6) >= i32_at(&words, 0) - 2_000,
            "max >= current"
        );
        assert!(i32_at(&words, 8) >= 0, "peak-to-peak >= 0");
        sleep(Duration::from_millis(100)).await;
    }
    let maximum = i32_at(&line.words(1, &input(6, 2)).await, 0);
    assert!((maximum - highest).abs() < 3_000, "{maximum} vs {highest}");
    // A reset restarts the window: the peak-to-peak shrinks to about 0.
    line.ask(1, &write(14, 1)).await;
    assert!(i32_at(&line.words(1, &input(8, 2)).await, 0) < 2_000);
    // An undefined statistic type is refused.
    assert_eq!(line.exception(1, &write(10, 0x0003)).await, 3);
}

#[tokio::test(start_paused = true)]
async fn factory_defaults_follow_the_spec() {
    let p = Simulator::new(&p_series::DEVICE).slave(5);
    let mut line = Line::new(&p);
    assert_eq!(
        line.words(5, &holding(31, 2)).await,
        [5, 4],
        "slave 5, 115200"
    );
    assert_eq!(
        line.words(5, &holding(2, 1)).await,
        [5],
        "lowest light power"
    );
    let lc = Simulator::new(&lc_rs::DEVICE);
    let mut line = Line::new(&lc);
    // Baud 9600, ID 1, no parity, query mode (table 1 marks it default), version 1.0.0.
    assert_eq!(line.words(1, &holding(0x83, 5)).await, [0, 9600, 1, 0, 1]);
    assert_eq!(line.words(1, &holding(6, 2)).await, [0x0001, 0x0000]);
    let rf = Simulator::new(&rangefinder::DEVICE);
    let mut line = Line::new(&rf);
    assert_eq!(
        line.words(25, &holding(0x0A, 1)).await,
        [3],
        "4-20 mA (3.15)"
    );
    let registers = rf.registers();
    assert_eq!(registers.len(), rangefinder::DEVICE.registers.len());
    let distance = rf.register("distance").unwrap();
    let millimetres = f64::from(join_u32(
        [distance.words[0], distance.words[1]],
        WordOrder::HighFirst,
    ));
    assert!(distance.words == [0, 0] || (10_000.0..20_000.0).contains(&millimetres));
}

fn answers_every_readable_register(family: &str, device: &'static DeviceInfo) {
    let sim = Simulator::new(device);
    for register in device.readable_registers() {
        let function = match register.table {
            Table::Holding => ReadFunction::Holding,
            Table::Input => ReadFunction::Input,
        };
        let request = read(function, register.address, register.words);
        match sim.request(sim.address(), &request) {
            Reply::Read { words, .. } => assert_eq!(words.len(), usize::from(register.words)),
            other => panic!("{family} {}: {other:?}", register.name),
        }
    }
}

// ---------------------------------------------------------------------------- drivers

#[tokio::test(start_paused = true)]
async fn the_generated_driver_downloads_the_buffer_from_the_simulator() {
    use optobus_transport::RtuClient;
    let sim = Simulator::new(&optobus_p_series::DEVICE).sentinel_every(0);
    let (stream, _server) = sim.duplex();
    let mut sensor = optobus_p_series::PSeries::new(RtuClient::new(stream), 1).expect("slave 1");
    sensor
        .start_buffering(optobus_p_series::MeasurementSource::Distance1, 1000)
        .await
        .unwrap();
    sleep(Duration::from_millis(20)).await;
    let mut pages = 0;
    let values = sensor.download_buffer(|p| pages = p.pages).await.unwrap();
    assert_eq!((values.len(), pages), (1000, 17));
    assert!(values.iter().all(Option::is_some));
    assert_eq!(sim.register("buffer_locked").unwrap().words, [0]);
    let distance = sensor.distance_1().await.unwrap().unwrap();
    assert!((4.0..6.0).contains(&distance.to_f64()), "{distance:?}");
}

/// mbpoll, when installed, reads holding registers through the pseudo-terminal and over TCP.
#[tokio::test]
async fn mbpoll_reads_the_simulator_when_installed() {
    let Ok(found) = std::process::Command::new("mbpoll").arg("-V").output() else {
        eprintln!("mbpoll not installed: skipped");
        return;
    };
    assert!(found.status.success() || !found.stdout.is_empty());
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

/// `device` with `register` accepting only `allowed` (raw values), leaked for the simulator.
fn with_allowed(
    device: &'static DeviceInfo,
    register: &str,
    allowed: &'static [i64],
) -> &'static DeviceInfo {
    let mut registers = device.registers.to_vec();
    let target = registers.iter_mut().find(|r| r.name == register).unwrap();
    target.allowed_values = allowed;
    Box::leak(Box::new(DeviceInfo {
        registers: Box::leak(registers.into_boxed_slice()),
        ..*device
    }))
}

#[tokio::test(start_paused = true)]
async fn an_unlisted_value_earns_exception_03_and_changes_nothing() {
    // CCS exposure time with a list of values (no real spec lists values for a
    // standard-frame device yet): 300 lies in 0 ..= 50000 but is not listed.
    let device = with_allowed(&ccs::DEVICE, "exposure_time", &[100, 200, 400]);
    let sim = Simulator::new(device);
    let mut line = Line::new(&sim);
    let before = line.words(1, &holding(2, 1)).await;
    let reply = line.ask(1, &write(2, 300)).await;
    assert_eq!(reply, with_crc(&[0x01, 0x86, 0x03]));
    assert_eq!(line.words(1, &holding(2, 1)).await, before);
    // A listed value is taken and echoed.
    let request = write(2, 200);
    assert_eq!(line.ask(1, &request).await, rtu_frame(1, &request));
    assert_eq!(line.words(1, &holding(2, 1)).await, [200]);
}

#[tokio::test(start_paused = true)]
async fn lc_rs_refuses_an_unlisted_baud_rate_with_its_value_error() {
    let sim = Simulator::new(&lc_rs::DEVICE);
    let mut line = Line::new(&sim);
    // 57600 = 0x0000 E100, high word first (2.3): the high half is held and echoed, the low
    // half completes a rate table 1 does not list: 0x0002 in the 7-byte frame.
    let high = write(0x83, 0x0000);
    assert_eq!(line.ask(1, &high).await, rtu_frame(1, &high));
    let reply = line.ask(1, &write(0x84, 0xE100)).await;
    assert_eq!(reply, with_crc(&[0x01, 0x86, 0x02, 0x00, 0x02]));
    assert_eq!(line.words(1, &holding(0x83, 2)).await, [0x0000, 0x2580]);
}

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
