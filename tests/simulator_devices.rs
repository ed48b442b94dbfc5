//! The simulator acting out each device's own behaviour, from its spec: field-wise reads,
//! split and validated writes, settings that apply after save and power cycle, commands
//! (zero, save, reboot, resets), the P-series buffer, moving measurements and statistics,
//! factory defaults, and values outside a register's allowed list.

use std::time::Duration;

use optobus_codec::value::{join_u32, WordOrder};
use optobus_codec::{Request, WriteValue};
use optobus_device::{DeviceInfo, Table};
use optobus_simulator::Simulator;
use optobus_tests::generated::{ccf, ccs, lc_rs, p_series, rangefinder};
use optobus_tests::wire::{hex, holding, i32_at, input, rtu_frame, with_crc, write, Line};
use tokio::time::sleep;

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
