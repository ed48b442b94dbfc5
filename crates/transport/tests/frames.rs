//! Frame tracing: a subscriber sees every frame sent and received, in hex, with its slave and
//! the time since the request left.

use std::sync::{Arc, Mutex};
use std::time::Duration;

use optobus_transport::{Error, ReadFunction, ReadRequest, RtuClient, RtuConfig, Transport};
use tokio::io::{AsyncReadExt, AsyncWriteExt, DuplexStream};
use tracing::field::{Field, Visit};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::layer::{Context, Layer, SubscriberExt};

/// One event as a test reads it.
#[derive(Clone, Debug, Default, PartialEq)]
struct Seen {
    target: String,
    level: Option<Level>,
    message: String,
    slave: Option<u64>,
    elapsed_us: Option<u64>,
}

impl Visit for Seen {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            self.message = format!("{value:?}");
        }
    }

    fn record_u64(&mut self, field: &Field, value: u64) {
        match field.name() {
            "slave" => self.slave = Some(value),
            "elapsed_us" => self.elapsed_us = Some(value),
            _ => {}
        }
    }
}

/// Collects every event.
#[derive(Clone, Default)]
struct Collect(Arc<Mutex<Vec<Seen>>>);

impl<S: Subscriber> Layer<S> for Collect {
    fn on_event(&self, event: &Event<'_>, _: Context<'_, S>) {
        let mut seen = Seen {
            target: event.metadata().target().to_owned(),
            level: Some(*event.metadata().level()),
            ..Seen::default()
        };
        event.record(&mut seen);
        self.0.lock().unwrap().push(seen);
    }
}

/// Runs `body` on a current-thread runtime with `Collect` as the subscriber; gives the events.
fn traced<F: std::future::Future<Output = ()>>(body: impl FnOnce() -> F) -> Vec<Seen> {
    let collect = Collect::default();
    let subscriber = tracing_subscriber::registry().with(collect.clone());
    tracing::subscriber::with_default(subscriber, || {
        tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .build()
            .unwrap()
            .block_on(body());
    });
    let seen = collect.0.lock().unwrap().clone();
    seen
}

/// A device that reads one request of `request_len` bytes and answers `reply`.
fn answer(mut device: DuplexStream, request_len: usize, reply: &'static [u8]) {
    tokio::spawn(async move {
        let mut request = vec![0u8; request_len];
        device.read_exact(&mut request).await.unwrap();
        device.write_all(reply).await.unwrap();
        // Keep the line open until the client is done.
        let _ = device.read(&mut [0u8; 1]).await;
    });
}

const READ_TWO: ReadRequest = ReadRequest {
    function: ReadFunction::Holding,
    address: 0,
    count: 2,
    repeatable: true,
};

fn client(line: DuplexStream) -> RtuClient<DuplexStream> {
    RtuClient::with_config(
        line,
        RtuConfig {
            line: None,
            timeout: Duration::from_millis(200),
            ..RtuConfig::default()
        },
    )
}

/// Reads two holding registers from slave 1 of a device that answers `reply`: the outcome
/// and the transport's trace events.
fn read_two_traced(reply: &'static [u8]) -> (Result<Vec<u16>, Error>, Vec<Seen>) {
    let outcome = Arc::new(Mutex::new(None));
    let kept = Arc::clone(&outcome);
    let seen = traced(|| async move {
        let (line, device) = tokio::io::duplex(64);
        answer(device, 8, reply);
        let read = client(line).read_words(1, READ_TWO).await;
        *kept.lock().unwrap() = Some(read);
    });
    let outcome = outcome.lock().unwrap().take().expect("the read ended");
    let frames = seen
        .into_iter()
        .filter(|s| s.target == "optobus_transport")
        .collect();
    (outcome, frames)
}

#[test]
fn a_request_and_its_reply_are_traced_in_hex() {
    // The Modbus specification's read of two holding registers, and a reply of 1 and 2.
    let (words, frames) = read_two_traced(&[0x01, 0x03, 0x04, 0x00, 0x01, 0x00, 0x02, 0x2A, 0x32]);
    assert_eq!(words.unwrap(), [1, 2]);
    assert_eq!(frames.len(), 2, "{frames:?}");
    assert_eq!(frames[0].message, "-> 01 03 00 00 00 02 C4 0B");
    assert_eq!(frames[0].level, Some(Level::TRACE));
    assert_eq!(frames[0].slave, Some(1));
    assert_eq!(frames[0].elapsed_us, None);
    assert_eq!(frames[1].message, "<- 01 03 04 00 01 00 02 2A 32");
    assert_eq!(frames[1].level, Some(Level::TRACE));
    assert_eq!(frames[1].slave, Some(1));
    assert!(frames[1].elapsed_us.is_some_and(|us| us < 200_000));
}

#[test]
fn a_garbled_reply_is_traced_and_marked() {
    // The reply above with its checksum's bytes swapped.
    let (outcome, frames) =
        read_two_traced(&[0x01, 0x03, 0x04, 0x00, 0x01, 0x00, 0x02, 0x32, 0x2A]);
    assert!(matches!(outcome, Err(Error::Frame(_))), "{outcome:?}");
    let messages: Vec<&str> = frames.iter().map(|s| s.message.as_str()).collect();
    assert_eq!(
        messages,
        [
            "-> 01 03 00 00 00 02 C4 0B",
            "<- 01 03 04 00 01 00 02 32 2A (garbled)"
        ]
    );
}
