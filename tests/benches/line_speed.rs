//! Our `RtuClient` on the byte-timed RS-485 line emulator, against the line's own limit.
//!
//! 1. Measurement reads: typed `PSeries::read_measurements()` through our `RtuClient` (one
//!    FC04 of 10 registers: an 8-byte request, a 25-byte reply), keeping t3.5 itself
//!    (`RtuConfig { line: Some(format), ..rtu_config(&DEVICE) }`), and tokio-modbus's RTU
//!    client (`read_input_registers(0, 10)`, which does not wait: the emulator holds its early
//!    requests and counts them as gap violations), each on its own emulated line at 9600,
//!    19200 and 115200 baud 8N1, device turnaround 0. Rounds alternate ours and theirs; the
//!    median round of each is compared with the line limit of
//!    `(8 + 25) characters + 2 t3.5 + turnaround` per transaction (target for ours: ≥ 0.98).
//!    The median single transaction (all but a round's first) is printed beside it: a
//!    process preempted for a few milliseconds moves the rounds, hardly that.
//! 2. The P-series buffer download of 2500 values at 115200 baud: `download_buffer` timed
//!    against the line time of its own frames, each transaction's request and reply
//!    characters (counted on the client's stream) plus 2 t3.5 plus turnaround, for the
//!    transactions the emulator received (target: ≤ 1.02).
//!
//! A run's last transaction does not wait for its closing t3.5, so one t3.5 is added to every
//! measured run before it is compared. Run with
//! `cargo bench -p optobus-tests --bench line_speed`.

mod common;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use optobus_p_series::transport::{Flow, LineFormat, RtuClient, RtuConfig, Tap, Transport};
use optobus_p_series::{rtu_config, MeasurementSource, PSeries, DEVICE};
use optobus_simulator::{Line, LineStats, Simulator};
use tokio_modbus::Slave;

/// The device answers as soon as it has seen the end of a request.
const TURNAROUND: Duration = Duration::ZERO;
/// Measured rounds per client and baud rate (one more warms up).
const ROUNDS: usize = 11;
/// About how long one round of one client takes on the line.
const ROUND_TIME: Duration = Duration::from_millis(200);
/// Bytes of the measurement read: the FC04 request and its reply of 10 registers.
const REQUEST: usize = 8;
const REPLY: usize = 5 + 2 * 10;
/// Downloads timed (each after the buffer has filled again).
const DOWNLOADS: usize = 5;

/// The line's shortest transaction: its characters, t3.5 after the request (the device sees
/// its end), the turnaround, and t3.5 after the reply before the next request.
fn line_cycle(format: LineFormat, bytes: usize) -> Duration {
    format.transmit_time(bytes) + format.frame_gap() * 2 + TURNAROUND
}

/// Our client's settings on `format`: the driver's, with the line's own t3.5.
fn our_config(format: LineFormat) -> RtuConfig {
    RtuConfig {
        line: Some(format),
        ..rtu_config(&DEVICE)
    }
}

/// Times of one client's rounds and of its single transactions.
#[derive(Default)]
struct Times {
    rounds: Vec<f64>,
    /// Every transaction but the first of a round, which had no t3.5 to wait for.
    transactions: Vec<f64>,
}

impl Times {
    /// Times a round of `per_round` transactions of `transaction`; kept unless `warm_up`.
    async fn round(&mut self, per_round: usize, warm_up: bool, mut transaction: impl AsyncFnMut()) {
        let started = Instant::now();
        let mut previous = started;
        for n in 0..per_round {
            transaction().await;
            let now = Instant::now();
            if !warm_up && n > 0 {
                self.transactions.push((now - previous).as_secs_f64());
            }
            previous = now;
        }
        if !warm_up {
            self.rounds.push(started.elapsed().as_secs_f64());
        }
    }

    /// Prints what the client achieved against the line limit per transaction.
    fn report(self, who: &str, per_round: usize, format: LineFormat, stats: &LineStats) {
        let limit = line_cycle(format, REQUEST + REPLY).as_secs_f64();
        // A round's last transaction does not wait for its closing t3.5.
        let per_transaction =
            (common::median(self.rounds) + format.frame_gap().as_secs_f64()) / per_round as f64;
        let single = common::median(self.transactions);
        println!(
            "         {who}: {:.2} tx/s = {:.3} of the limit (median round), {:.3} (median \
             transaction), gap violations {} of {} requests",
            1.0 / per_transaction,
            limit / per_transaction,
            limit / single,
            stats.gap_violations(),
            stats.frames()
        );
    }
}

/// Measurement reads at `baud`: ours and tokio-modbus's, rounds interleaved.
async fn line_speed(baud: u32) {
    let format = LineFormat::new(baud);
    let sim = Simulator::new(&DEVICE).sentinel_every(0);
    let ours_line = Line::new(format).turnaround(TURNAROUND);
    let theirs_line = Line::new(format).turnaround(TURNAROUND);
    let (ours_stream, _ours_server) = sim.duplex_line(ours_line.clone());
    let (theirs_stream, _theirs_server) = sim.duplex_line(theirs_line.clone());
    let mut ours =
        PSeries::with_default_slave(RtuClient::with_config(ours_stream, our_config(format)));
    let mut theirs = tokio_modbus::client::rtu::attach_slave(theirs_stream, Slave(1));

    let limit = line_cycle(format, REQUEST + REPLY);
    let per_round = (ROUND_TIME.as_secs_f64() / limit.as_secs_f64())
        .ceil()
        .max(4.0) as usize;
    let (mut ours_times, mut theirs_times) = (Times::default(), Times::default());
    for round in 0..=ROUNDS {
        // The first round warms up both sides.
        let warm_up = round == 0;
        ours_times
            .round(per_round, warm_up, async || {
                common::read_typed(&mut ours).await
            })
            .await;
        theirs_times
            .round(per_round, warm_up, async || {
                common::read_raw(&mut theirs).await
            })
            .await;
    }
    println!(
        "{baud:>6} baud 8N1, turnaround {} us: line limit {:.2} tx/s ({:.3} ms/tx), {ROUNDS} rounds of {per_round} (target for ours >= 0.98)",
        TURNAROUND.as_micros(),
        1.0 / limit.as_secs_f64(),
        limit.as_secs_f64() * 1e3,
    );
    ours_times.report(
        "ours (RtuClient, typed)",
        per_round,
        format,
        &ours_line.stats(),
    );
    theirs_times.report(
        "tokio-modbus (raw)     ",
        per_round,
        format,
        &theirs_line.stats(),
    );
}

/// Bytes written and read through a stream.
#[derive(Clone, Debug, Default)]
struct Bytes(Arc<AtomicU64>);

impl Bytes {
    /// Total bytes written and read so far.
    fn get(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
}

/// How long the device takes to buffer `count` values at its sampling interval.
async fn fill_time<T: Transport>(sensor: &mut PSeries<T>, count: u16) -> Duration {
    let code = sensor
        .sampling_interval()
        .await
        .expect("sampling interval")
        .raw();
    let meaning = DEVICE
        .register("sampling_interval")
        .and_then(|r| r.codes.iter().find(|c| c.code == code))
        .map(|c| c.meaning)
        .expect("a defined sampling interval");
    let (number, per_second) = match meaning.strip_suffix("us") {
        Some(us) => (us, 1e6),
        None => (meaning.strip_suffix("ms").expect("us or ms"), 1e3),
    };
    let interval: f64 = number.parse().expect("a number");
    Duration::from_secs_f64(interval / per_second * f64::from(count))
}

/// The buffer download of the most values the spec lets be read out, at 115200 baud, against
/// its line time.
async fn download() {
    let most = DEVICE.buffer.map_or(0, |buffer| buffer.most);
    let most = u16::try_from(most).expect("the buffer count is one word");
    let format = LineFormat::new(115_200);
    let sim = Simulator::new(&DEVICE);
    let line = Line::new(format).turnaround(TURNAROUND);
    let stats = line.stats();
    let (stream, _server) = sim.duplex_line(line);
    let bytes = Bytes::default();
    let counter = bytes.clone();
    let stream = Tap::new(stream, move |_: Flow, chunk: &[u8]| {
        counter.0.fetch_add(chunk.len() as u64, Ordering::Relaxed);
    });
    let mut sensor =
        PSeries::with_default_slave(RtuClient::with_config(stream, our_config(format)));
    sensor
        .start_buffering(MeasurementSource::ALL[0], most)
        .await
        .expect("start buffering");
    // Unlocking after a download clears the buffer and buffering starts anew.
    let fill = fill_time(&mut sensor, most).await;
    let gap = format.frame_gap();
    let per_transaction = gap * 2 + TURNAROUND;
    let mut ratios = Vec::new();
    let mut last = String::new();
    for _ in 0..DOWNLOADS {
        tokio::time::sleep(fill + Duration::from_millis(20)).await;
        let (frames, bytes_before, violations) =
            (stats.frames(), bytes.get(), stats.gap_violations());
        let mut pages = 0;
        let started = Instant::now();
        let values = sensor
            .download_buffer(|progress| pages = progress.pages)
            .await
            .expect("download");
        let elapsed = started.elapsed();
        let transactions = stats.frames() - frames;
        let on_wire = bytes.get() - bytes_before;
        let line_time = format.transmit_time(on_wire as usize)
            + per_transaction * u32::try_from(transactions).expect("a few transactions");
        let ratio = (elapsed + gap).as_secs_f64() / line_time.as_secs_f64();
        ratios.push(ratio);
        last = format!(
            "{} values, {transactions} transactions (report-count read, lock, {pages} page reads, unlock), \
             {on_wire} bytes, gap violations {}: {:.1} ms, line time {:.1} ms",
            values.len(),
            stats.gap_violations() - violations,
            elapsed.as_secs_f64() * 1e3,
            line_time.as_secs_f64() * 1e3,
        );
    }
    println!(
        "download of {most} values at 115200 baud, turnaround {} us, buffered in {:.1} ms:",
        TURNAROUND.as_micros(),
        fill.as_secs_f64() * 1e3
    );
    println!("         last run: {last}");
    println!(
        "         time / line time {:.4} (median of {DOWNLOADS}; target <= 1.02)",
        common::median(ratios)
    );
}

fn main() {
    common::runtime().block_on(async {
        for baud in [9_600, 19_200, 115_200] {
            line_speed(baud).await;
        }
        download().await;
    });
}
