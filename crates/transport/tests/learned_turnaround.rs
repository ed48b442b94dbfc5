//! Issue 28, point 9: an RTU client on a timed line, where turned on
//! (`timing::set_sleep_through_replies`), sleeps through a reply by its device's turnaround
//! as learned from its last replies, and reads it in one go; a reply slower than that is
//! still read whole and right. The device here hands its reply over a character at a time,
//! as a line-timed pty or a UART without a FIFO does.

mod common;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use common::{counting_words, DeviceSide};
use optobus_codec::{rtu, Request, Response, Words};
use optobus_transport::timing::{set_sleep_through_replies, sleep_until_precise};
use optobus_transport::{
    Flow, LineFormat, Observe, ReadFunction, RtuClient, RtuConfig, Tap, Transport,
};
use tokio::io::DuplexStream;
use tokio::time::Instant;

/// 9600 baud: a character is 1.04 ms, so a busy test machine's lateness of a few hundred
/// microseconds does not reorder the device's bytes.
const BAUD: u32 = 9_600;

/// Registers read per request: a reply of 5 + 2 × 6 = 17 bytes.
const COUNT: u16 = 6;

/// A device that answers each read after the request's time on the line and the turnaround
/// `turnaround` holds at that moment, its reply's bytes one character time apart, each word
/// `address + i`.
fn timed_device(stream: DuplexStream, turnaround: Arc<Mutex<Duration>>) {
    let format = LineFormat::new(BAUD);
    tokio::spawn(async move {
        let mut side = DeviceSide::new(stream, Vec::new());
        while let Some((frame, consumed)) = side.next_request().await {
            let Request::Read {
                function,
                address,
                count,
            } = frame.pdu
            else {
                continue;
            };
            let data = counting_words(address, count);
            let response = Response::Read {
                function,
                words: Words::from_bytes(&data).unwrap(),
            };
            let mut out = [0u8; rtu::MAX_FRAME_LEN];
            let len = rtu::encode_response(&mut out, frame.slave, &response).unwrap();
            let wait = *turnaround.lock().unwrap();
            // The request took its own time to cross the line, as it does on a wire.
            let start = Instant::now() + format.transmit_time(consumed) + wait;
            for (i, byte) in out[..len].iter().enumerate() {
                sleep_until_precise(start + format.transmit_time(i + 1)).await;
                if !side.send(&[*byte]).await {
                    return;
                }
            }
        }
    });
}

/// Counts the reads that brought reply bytes.
struct CountReads(Arc<AtomicU64>);

impl Observe for CountReads {
    fn observe(&mut self, flow: Flow, _bytes: &[u8]) {
        if flow == Flow::Received {
            self.0.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// A client whose reads are counted.
type Client = RtuClient<Tap<DuplexStream, CountReads>>;

/// A client on a timed device, the device's turnaround (to change), and the count of the
/// client's reads that brought reply bytes.
fn client_and_device(turnaround: Duration) -> (Client, Arc<Mutex<Duration>>, Arc<AtomicU64>) {
    // Every test of this binary wants it; it is off by default.
    set_sleep_through_replies(true);
    let (client_end, device_end) = tokio::io::duplex(1024);
    let turnaround = Arc::new(Mutex::new(turnaround));
    timed_device(device_end, Arc::clone(&turnaround));
    let reads = Arc::new(AtomicU64::new(0));
    let tap = Tap::new(client_end, CountReads(Arc::clone(&reads)));
    let config = RtuConfig {
        timeout: Duration::from_millis(500),
        line: Some(LineFormat::new(BAUD)),
        ..RtuConfig::default()
    };
    (RtuClient::with_config(tap, config), turnaround, reads)
}

/// Reads `COUNT` registers at `address` from slave 7, checks every word, and gives how many
/// reads brought the reply.
async fn read_checked(client: &mut impl Transport, reads: &AtomicU64, address: u16) -> u64 {
    let before = reads.load(Ordering::Relaxed);
    let words = client
        .read(7, ReadFunction::Holding, address, COUNT)
        .await
        .unwrap_or_else(|error| panic!("read at {address}: {error}"));
    let expected: Vec<u16> = (0..COUNT).map(|i| address + i).collect();
    assert_eq!(words, expected, "read at {address}");
    reads.load(Ordering::Relaxed) - before
}

/// How many of `counts` are a single read.
fn in_one_read(counts: &[u64]) -> usize {
    counts.iter().filter(|&&count| count == 1).count()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_learned_turnaround_reads_a_reply_whole_in_one_read() {
    let (mut client, _, reads) = client_and_device(Duration::from_millis(2));
    let mut counts = Vec::new();
    for i in 0..24u16 {
        counts.push(read_checked(&mut client, &reads, 100 + i).await);
    }
    // The first replies are read as they come (the turnaround unknown), then in one read but
    // for a probe every 8 replies and a busy machine's late byte (read as it comes: a few
    // reads, never less than the whole reply).
    let learned = &counts[4..];
    assert!(
        in_one_read(learned) >= learned.len() / 2,
        "reads a reply: {counts:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_device_whose_turnaround_grows_is_still_answered_correctly() {
    let (mut client, turnaround, reads) = client_and_device(Duration::from_millis(1));
    for i in 0..12u16 {
        read_checked(&mut client, &reads, i).await;
    }
    // Six characters slower: the next replies are found unfinished when the client wakes,
    // read as they come, whole and right all the same, and the longer turnaround is learned
    // within a few replies.
    *turnaround.lock().unwrap() = Duration::from_millis(7);
    let mut counts = Vec::new();
    for i in 0..32u16 {
        counts.push(read_checked(&mut client, &reads, 1_000 + i).await);
    }
    let relearned = &counts[16..];
    assert!(
        in_one_read(relearned) >= relearned.len() / 2,
        "reads a reply: {counts:?}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reply_late_beyond_the_learned_turnaround_still_arrives() {
    let (mut client, turnaround, reads) = client_and_device(Duration::from_millis(1));
    for i in 0..12u16 {
        read_checked(&mut client, &reads, i).await;
    }
    // One reply 40 ms late (within the 500 ms timeout): read right, after waiting for it.
    *turnaround.lock().unwrap() = Duration::from_millis(40);
    read_checked(&mut client, &reads, 5_000).await;
    // The one slow reply does not make the device's turnaround long: the next replies are
    // still slept through and read in one go.
    *turnaround.lock().unwrap() = Duration::from_millis(1);
    let mut counts = Vec::new();
    for i in 0..16u16 {
        counts.push(read_checked(&mut client, &reads, 6_000 + i).await);
    }
    assert!(
        in_one_read(&counts) >= counts.len() / 2,
        "reads a reply: {counts:?}"
    );
}
