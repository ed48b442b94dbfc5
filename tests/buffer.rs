//! The one buffer download (`Core::start_buffering`, `Core::download_buffer`), driven by the
//! spec's `buffer:` section: the guarantees of the procedure, through a transport that
//! watches every request, against the simulator.

use std::time::Duration;

use optobus_driver::transport::{
    Error as WireError, ReadRequest, RtuClient, Transport, WriteValue,
};
use optobus_driver::{Core, DownloadProgress, Error, Fixed};
use optobus_p_series::{MeasurementSource, DEVICE};
use optobus_simulator::{BufferReadCount, Quirks, Simulator};
use optobus_tests::{e2e, specs};

/// Passes requests on and keeps what went by: the writes (address, value) and the reads that
/// turn a page; fails the page read numbered `fail_page` (1-based) with a timeout.
struct Watched<T> {
    inner: T,
    writes: Vec<(u16, WriteValue)>,
    page_reads: usize,
    reads: usize,
    fail_page: Option<usize>,
}

impl<T> Watched<T> {
    fn new(inner: T) -> Self {
        Self {
            inner,
            writes: Vec::new(),
            page_reads: 0,
            reads: 0,
            fail_page: None,
        }
    }

    fn requests(&self) -> usize {
        self.reads + self.writes.len()
    }
}

impl<T: Transport> Transport for Watched<T> {
    async fn read_words(&mut self, slave: u8, read: ReadRequest) -> Result<Vec<u16>, WireError> {
        self.reads += 1;
        if !read.repeatable {
            self.page_reads += 1;
            if Some(self.page_reads) == self.fail_page {
                return Err(WireError::Timeout {
                    after: Duration::from_millis(100),
                });
            }
        }
        self.inner.read_words(slave, read).await
    }

    async fn write(&mut self, slave: u8, address: u16, value: WriteValue) -> Result<(), WireError> {
        self.writes.push((address, value));
        self.inner.write(slave, address, value).await
    }
}

/// A driver core on the simulated P series, through a watching transport.
fn watched_core(sim: &Simulator) -> WatchedCore {
    Core::with_default_slave(Watched::new(e2e::rtu(sim)), sim.device())
}

type WatchedCore = Core<Watched<RtuClient<tokio::io::DuplexStream>>>;

/// A P-series simulator, and a watched driver that has started it buffering `count` values
/// of `source`.
async fn buffering(source: MeasurementSource, count: u32) -> (Simulator, WatchedCore) {
    let sim = Simulator::new(&DEVICE);
    let mut core = watched_core(&sim);
    core.start_buffering(Some(&source), count).await.unwrap();
    (sim, core)
}

fn buffer_locked(sim: &Simulator) -> Vec<u16> {
    sim.register("buffer_locked").expect("lock flag").words
}

#[tokio::test(start_paused = true)]
async fn a_count_above_most_or_an_undefined_source_is_refused_before_anything_is_sent() {
    let sim = Simulator::new(&DEVICE);
    let mut core = watched_core(&sim);
    let most = DEVICE.buffer.expect("the P series buffers").most;
    let error = core
        .start_buffering(Some(&MeasurementSource::Distance1), most + 1)
        .await
        .unwrap_err();
    match error {
        Error::OutOfRange {
            register, raw, max, ..
        } => assert_eq!((register, raw, max), ("buffer_report_count", 2501, 2500)),
        other => panic!("{other:?}"),
    }
    let undefined = MeasurementSource::ALL.len() as u32 + 10;
    let error = core
        .start_buffering(Some(&undefined), 10)
        .await
        .unwrap_err();
    assert!(
        matches!(
            error,
            Error::OutOfRange {
                register: "buffer_data_type",
                ..
            } | Error::UndefinedCode { .. }
        ),
        "{error:?}"
    );
    assert_eq!(core.transport_mut().requests(), 0, "nothing may be sent");
}

#[tokio::test(start_paused = true)]
async fn starting_writes_source_and_count_then_unlocks() {
    let (sim, mut core) = buffering(MeasurementSource::Thickness, 120).await;
    let address = |name: &str| DEVICE.register(name).expect(name).address;
    let thickness = DEVICE.register("buffer_data_type").unwrap().codes;
    let thickness = thickness
        .iter()
        .find(|c| c.name == "thickness")
        .unwrap()
        .code;
    let writes: Vec<(u16, WriteValue)> = core.transport_mut().writes.clone();
    assert_eq!(
        writes,
        [
            (
                address("buffer_data_type"),
                WriteValue::Word(u16::try_from(thickness).unwrap())
            ),
            (address("buffer_report_count"), WriteValue::Word(120)),
            (address("buffer_locked"), WriteValue::Word(0)),
        ]
    );
    assert_eq!(sim.register("buffer_report_count").unwrap().words, [120]);
}

#[tokio::test(start_paused = true)]
async fn no_more_pages_than_the_count_needs_and_values_past_it_are_ignored() {
    let sim = Simulator::new(&DEVICE).sentinel_every(0);
    let mut core = watched_core(&sim);
    core.start_buffering(Some(&MeasurementSource::Distance1), 90)
        .await
        .unwrap();
    // Long enough for far more than 90 values; the device stops at its count.
    tokio::time::sleep(Duration::from_secs(2)).await;
    let mut seen = Vec::new();
    let values: Vec<Option<Fixed>> = core
        .download_buffer(|p: DownloadProgress| seen.push(p))
        .await
        .unwrap();
    assert_eq!(values.len(), 90);
    let pages = core.transport_mut().page_reads;
    assert_eq!(pages, 2, "ceil(90 / 60) page reads, each read once");
    assert_eq!(
        seen.iter()
            .map(|p| (p.received, p.pages))
            .collect::<Vec<_>>(),
        [(60, 1), (90, 2)]
    );
    let scale = DEVICE
        .register("buffer_sample_1_buffered_value")
        .and_then(|r| r.scale)
        .expect("a scaled value");
    assert!(values
        .iter()
        .all(|v| v.is_some_and(|v| v.scale() == scale && (3.0..7.0).contains(&v.to_f64()))));
    assert_eq!(buffer_locked(&sim), [0], "unlocked after the download");
}

#[tokio::test(start_paused = true)]
async fn a_failed_page_read_still_unlocks_and_is_not_retried() {
    let (sim, mut core) = buffering(MeasurementSource::Distance1, 300).await;
    tokio::time::sleep(Duration::from_secs(2)).await;
    core.transport_mut().fail_page = Some(2);
    let error = core
        .download_buffer::<Option<Fixed>>(|_| {})
        .await
        .unwrap_err();
    assert!(
        matches!(error, Error::Transport(WireError::Timeout { .. })),
        "{error:?}"
    );
    assert_eq!(
        core.transport_mut().page_reads,
        2,
        "the failed page is not read again"
    );
    let lock = DEVICE.register("buffer_locked").unwrap().address;
    let writes = &core.transport_mut().writes;
    assert_eq!(
        writes[writes.len() - 2..],
        [(lock, WriteValue::Word(1)), (lock, WriteValue::Word(0))],
        "locked, then unlocked after the failure"
    );
    assert_eq!(buffer_locked(&sim), [0]);
}

#[tokio::test(start_paused = true)]
async fn the_spec_loaded_at_run_time_downloads_through_the_same_procedure() {
    let device = specs::describe("p_series");
    let sim = Simulator::new(device).sentinel_every(0);
    let mut core = Core::with_default_slave(e2e::rtu(&sim), device);
    let source = device.buffer.and_then(|b| b.source).expect("a source");
    let first = device.register(source).expect("source register").codes[0].code;
    core.start_buffering(Some(&first), 1000).await.unwrap();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let mut pages = 0;
    let values: Vec<Option<Fixed>> = core.download_buffer(|p| pages = p.pages).await.unwrap();
    assert_eq!(
        (values.len(), pages),
        (1000, 17),
        "17 pages of at most 60 (5.4)"
    );
    assert!(values
        .iter()
        .all(|v| v.is_some_and(|v| (3.0..7.0).contains(&v.to_f64()))));
}

#[tokio::test(start_paused = true)]
async fn a_device_without_a_buffer_is_refused_without_a_request() {
    let device = &optobus_ccs::DEVICE;
    assert!(device.buffer.is_none());
    let sim = Simulator::new(device);
    let mut core = Core::with_default_slave(Watched::new(e2e::rtu(&sim)), device);
    let error = core.start_buffering(None, 10).await.unwrap_err();
    assert!(matches!(error, Error::NotAllowed { .. }), "{error:?}");
    let error = core
        .download_buffer::<Option<Fixed>>(|_| {})
        .await
        .unwrap_err();
    assert!(error.to_string().contains("no such buffer"), "{error}");
    assert_eq!(core.transport_mut().requests(), 0);
}

/// A P-series simulator that reads the manual's buffer read count (appendix 3 (3)) the
/// other way: the values handed out before this page.
fn counting_before_the_page(sim: &Simulator) -> Quirks {
    Quirks {
        buffer_read_count: BufferReadCount::BeforePage,
        ..sim.current_quirks()
    }
}

#[tokio::test(start_paused = true)]
async fn a_device_counting_before_the_page_downloads_in_full() {
    let sim = Simulator::new(&DEVICE).sentinel_every(0);
    sim.set_quirks(counting_before_the_page(&sim));
    let mut core = watched_core(&sim);
    core.start_buffering(Some(&MeasurementSource::Distance1), 130)
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_secs(2)).await;
    // Page 2 as this device shows it: 60 handed out before it, 60 valid.
    let read_count = DEVICE.register("buffer_read_count").unwrap();
    let mut counts = Vec::new();
    let values: Vec<Option<Fixed>> = core
        .download_buffer(|_| counts.push(sim.peek(read_count.table, read_count.address)))
        .await
        .unwrap();
    assert_eq!(
        counts,
        [Some(vec![0]), Some(vec![60]), Some(vec![120])],
        "the device reports the count before each page"
    );
    assert_eq!(values.len(), 130);
    assert_eq!(core.transport_mut().page_reads, 3);
    // The same values as a device counting the page in: the buffered distance 1 of the
    // first 130 sampling intervals, which the simulator computes alike for both readings.
    let reference = Simulator::new(&DEVICE).sentinel_every(0);
    let mut plain = watched_core(&reference);
    plain
        .start_buffering(Some(&MeasurementSource::Distance1), 130)
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_secs(2)).await;
    let expected: Vec<Option<Fixed>> = plain.download_buffer(|_| {}).await.unwrap();
    assert!(values.iter().all(|v| v.is_some()));
    assert_eq!(values, expected);
}

#[tokio::test(start_paused = true)]
async fn a_device_switching_its_count_reading_mid_download_is_out_of_step() {
    let sim = Simulator::new(&DEVICE).sentinel_every(0);
    let mut core = watched_core(&sim);
    core.start_buffering(Some(&MeasurementSource::Distance1), 300)
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_secs(2)).await;
    // Page 1 counts itself in (60), page 2 does not (60 again, where 120 was due).
    let switched = counting_before_the_page(&sim);
    let error = core
        .download_buffer::<Option<Fixed>>(|_| sim.set_quirks(switched))
        .await
        .unwrap_err();
    match error {
        Error::OutOfStep {
            received, reported, ..
        } => assert_eq!((received, reported), (120, 60)),
        other => panic!("{other:?}"),
    }
    assert_eq!(core.transport_mut().page_reads, 2, "stopped at page 2");
    assert_eq!(buffer_locked(&sim), [0], "unlocked after the failure");
}

// ------------------------------------------------ sampling interval × ratio (appendix 3 (5))

/// A P-series simulator sampling every 100 µs with sampling ratio `ratio`, buffering `count`
/// values of distance 1 for one second, and a watched driver on it.
async fn buffering_at_ratio(ratio: u32, count: u32) -> (Simulator, WatchedCore) {
    let sim = Simulator::new(&DEVICE).sentinel_every(0);
    let mut core = watched_core(&sim);
    let interval = DEVICE.register("sampling_interval").unwrap();
    let us_100 = interval
        .codes
        .iter()
        .find(|c| c.meaning == "100us")
        .unwrap();
    core.write(interval, &us_100.code).await.unwrap();
    let ratio_register = DEVICE.register("sampled_data_ratio").unwrap();
    core.write(ratio_register, &ratio).await.unwrap();
    core.start_buffering(Some(&MeasurementSource::Distance1), count)
        .await
        .unwrap();
    tokio::time::sleep(Duration::from_secs(1)).await;
    (sim, core)
}

#[tokio::test(start_paused = true)]
async fn ratio_10_buffers_every_tenth_value() {
    let (_every, mut core) = buffering_at_ratio(1, 500).await;
    let every: Vec<Option<Fixed>> = core.download_buffer(|_| {}).await.unwrap();
    let (_tenth, mut core) = buffering_at_ratio(10, 50).await;
    let tenth: Vec<Option<Fixed>> = core.download_buffer(|_| {}).await.unwrap();
    assert_eq!((every.len(), tenth.len()), (500, 50));
    assert!(tenth.iter().all(Option::is_some));
    // The k-th buffered value at ratio 10 is the (10k + 10)-th measurement: value 10k + 9 of
    // the buffer at ratio 1 (appendix 3 (5): "每采集到 10 个数据，就将第 10 个数据写入缓存").
    let tenths: Vec<Option<Fixed>> = every.iter().skip(9).step_by(10).copied().collect();
    assert_eq!(tenth, tenths);
    // The measurement moves, so every value is not every tenth.
    assert_ne!(tenth[..], every[..50]);
}

#[tokio::test(start_paused = true)]
async fn the_time_axis_at_ratio_10_is_the_interval_times_10() {
    let (_sim, mut core) = buffering_at_ratio(10, 20).await;
    let timing = core.read_buffer_timing().await.unwrap().expect("a timing");
    assert_eq!(
        (timing.interval, timing.ratio),
        (Duration::from_micros(100), 10)
    );
    assert_eq!(timing.period(), Duration::from_millis(1));
    let axis: Vec<Duration> = (0..20).map(|i| timing.time_of(i)).collect();
    assert_eq!(axis[1], Duration::from_millis(1));
    assert_eq!(axis[19], Duration::from_millis(19));
}

#[tokio::test(start_paused = true)]
async fn changing_the_ratio_clears_the_buffer_and_its_lock() {
    let (sim, mut core) = buffering_at_ratio(10, 50).await;
    // One second at 1 ms per value: the 50 asked for are buffered.
    let ratio = DEVICE.register("sampled_data_ratio").unwrap();
    let lock = DEVICE.command("lock_buffer").unwrap();
    let lock_register = DEVICE.register(lock.register).unwrap();
    core.run(lock, lock_register).await.unwrap();
    assert_eq!(buffer_locked(&sim), [1]);
    // 4.2.2 note 5, appendix 3 (5) note 1: changing the ratio resets the buffer and its lock.
    core.write(ratio, &5u32).await.unwrap();
    assert_eq!(buffer_locked(&sim), [0], "the lock flag is reset");
    let values: Vec<Option<Fixed>> = core.download_buffer(|_| {}).await.unwrap();
    assert!(values.is_empty(), "{} values survived", values.len());
}
