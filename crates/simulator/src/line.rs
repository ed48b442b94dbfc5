//! A byte-timed RS-485 line: makes an in-memory RTU connection take as long as a serial line.
//!
//! One half-duplex wire, timed by a [`LineFormat`] (its character time and t3.5 are the only
//! timing arithmetic used):
//!
//! - every byte occupies the wire for one character time; a client's byte starts no earlier
//!   than the end of the previous byte on the wire;
//! - the device sees the end of a request after t3.5 of silence following its last byte,
//!   waits [`Line::turnaround`], then its reply goes out byte by byte (with the pauses of
//!   any [`crate::faults`]), and the client receives each byte when its character time has
//!   completed;
//! - a request cannot start before t3.5 after the last reply byte ended: earlier bytes are
//!   held until then and counted in [`LineStats::gap_violations`], so a client that does not
//!   wait cannot beat the line.
//!
//! Bytes are scheduled on a computed timeline, not on the sum of sleeps, and each wait ends
//! on a kernel timer with the last 50 µs watched on the clock (the transport's
//! `sleep_until_precise_spinning`), so bytes arrive within microseconds of their times
//! although tokio's timer counts milliseconds. A busy machine can make a byte
//! late, never early, and lateness does not add up: the next byte keeps its own time.

use std::collections::VecDeque;
use std::io;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use optobus_codec::{rtu, LineFormat};
use optobus_transport::timing::sleep_until_precise_spinning;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, DuplexStream};
use tokio::task::JoinHandle;
use tokio::time::Instant;

use crate::faults::Plan;
use crate::rtu::Slaves;
use crate::sim::Simulator;

/// How long before each of its times the line stops sleeping on a kernel timer and watches the
/// clock: a woken thread may wait that long for a core, and the line is the instrument the
/// clients are measured against.
const SPIN: Duration = Duration::from_micros(50);

/// Most request bytes kept while a client sends without a pause.
const MAX_REQUEST: usize = 4 * rtu::MAX_FRAME_LEN;

/// The settings of an emulated serial line; see the [module](self) for the timing model.
///
/// ```no_run
/// # async fn demo(device: &'static optobus_device::DeviceInfo) {
/// use optobus_codec::LineFormat;
/// use optobus_simulator::{Line, Simulator};
/// use std::time::Duration;
/// let line = Line::new(LineFormat::new(9_600)).turnaround(Duration::from_millis(1));
/// let stats = line.stats();
/// let (client_end, _server) = Simulator::new(device).duplex_line(line);
/// // ... talk RTU on client_end ...
/// println!("{} requests, {} sent too early", stats.frames(), stats.gap_violations());
/// # }
/// ```
#[derive(Clone, Debug)]
pub struct Line {
    format: LineFormat,
    turnaround: Duration,
    stats: LineStats,
}

impl Line {
    /// A line of `format`, with a device that answers at once (turnaround 0). A format that
    /// fails `LineFormat::check` is timed as the codec times it (baud 0 as 1 baud).
    pub fn new(format: LineFormat) -> Self {
        Self {
            format,
            turnaround: Duration::ZERO,
            stats: LineStats::default(),
        }
    }

    /// The device's reaction time after it saw the end of a request.
    pub fn turnaround(mut self, turnaround: Duration) -> Self {
        self.turnaround = turnaround;
        self
    }

    /// The line's format.
    pub fn format(&self) -> LineFormat {
        self.format
    }

    /// Counters of what crossed the line (shared with clones of this line).
    pub fn stats(&self) -> LineStats {
        self.stats.clone()
    }
}

/// What crossed a [`Line`]; clones share the counters.
#[derive(Clone, Debug, Default)]
pub struct LineStats(Arc<Counters>);

#[derive(Debug, Default)]
struct Counters {
    frames: AtomicU64,
    replies: AtomicU64,
    gap_violations: AtomicU64,
}

impl LineStats {
    /// Requests the device received: runs of bytes ended by t3.5 of silence.
    pub fn frames(&self) -> u64 {
        self.0.frames.load(Ordering::Relaxed)
    }

    /// Replies that went on the wire.
    pub fn replies(&self) -> u64 {
        self.0.replies.load(Ordering::Relaxed)
    }

    /// Requests the client started less than t3.5 after a reply ended (held until then).
    pub fn gap_violations(&self) -> u64 {
        self.0.gap_violations.load(Ordering::Relaxed)
    }
}

/// The run's summary: `line: 4 requests, 4 replies, 0 requests sent within t3.5 of a reply`.
impl std::fmt::Display for LineStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "line: {} requests, {} replies, {} requests sent within t3.5 of a reply",
            self.frames(),
            self.replies(),
            self.gap_violations()
        )
    }
}

fn bump(counter: &AtomicU64) {
    counter.fetch_add(1, Ordering::Relaxed);
}

/// `at + duration`, or a time far beyond any test when that overflows.
fn later(at: Instant, duration: Duration) -> Instant {
    at.checked_add(duration)
        .or_else(|| at.checked_add(Duration::from_secs(1 << 30)))
        .unwrap_or(at)
}

/// The wire's timeline.
struct Wire {
    character: Duration,
    gap: Duration,
    turnaround: Duration,
    /// When the last byte on the wire, either way, ends.
    busy_until: Option<Instant>,
    /// The last reply's end plus t3.5: no request byte starts earlier.
    quiet_until: Option<Instant>,
    /// The request so far, and when its last byte ends.
    request: Vec<u8>,
    request_end: Option<Instant>,
    /// Reply bytes with the times their character ends.
    out: VecDeque<(Instant, u8)>,
}

impl Wire {
    fn new(line: &Line) -> Self {
        Self {
            character: line.format.character_time(),
            gap: line.format.frame_gap(),
            turnaround: line.turnaround,
            busy_until: None,
            quiet_until: None,
            request: Vec::new(),
            request_end: None,
            out: VecDeque::new(),
        }
    }

    /// When the device sees the end of the request.
    fn request_due(&self) -> Option<Instant> {
        self.request_end.map(|end| later(end, self.gap))
    }

    fn next_event(&self) -> Option<Instant> {
        let reply = self.out.front().map(|&(at, _)| at);
        match (self.request_due(), reply) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Puts bytes the client wrote at `now` on the wire.
    fn receive(&mut self, bytes: &[u8], now: Instant, stats: &LineStats) {
        let quiet = self.quiet_until.filter(|&quiet| quiet > now);
        if self.request.is_empty() && quiet.is_some() {
            bump(&stats.0.gap_violations);
        }
        let mut at = [Some(now), self.busy_until, quiet]
            .into_iter()
            .flatten()
            .max()
            .unwrap_or(now);
        for &byte in bytes {
            at = later(at, self.character);
            self.request.push(byte);
        }
        if self.request.len() > MAX_REQUEST {
            let excess = self.request.len() - MAX_REQUEST;
            self.request.drain(..excess);
        }
        self.busy_until = Some(at);
        self.request_end = Some(at);
    }

    /// Puts a reply on the wire from `start` on (after anything already on it).
    fn send(&mut self, start: Instant, plan: &Plan) {
        let mut at = self.busy_until.map_or(start, |busy| busy.max(start));
        let mut sent = false;
        for (pause, bytes) in &plan.pieces {
            at = later(at, *pause);
            for &byte in bytes {
                at = later(at, self.character);
                self.out.push_back((at, byte));
                sent = true;
            }
        }
        if sent {
            self.busy_until = Some(at);
            self.quiet_until = Some(later(at, self.gap));
        }
    }

    /// Reply bytes whose character has ended by `now`.
    fn take_due(&mut self, now: Instant) -> Vec<u8> {
        let mut due = Vec::new();
        while let Some(&(at, byte)) = self.out.front() {
            if at > now {
                break;
            }
            due.push(byte);
            self.out.pop_front();
        }
        due
    }
}

impl Slaves {
    /// An in-memory RTU line timed like a serial line: the returned stream is the client's
    /// end; the line is served on a spawned task until the client's end is dropped. Needs a
    /// tokio runtime.
    pub fn duplex_line(&self, line: Line) -> (DuplexStream, JoinHandle<io::Result<()>>) {
        let (client, server) = tokio::io::duplex(4096);
        let slaves = self.clone();
        let task = tokio::spawn(async move { slaves.serve_line(server, &line).await });
        (client, task)
    }

    /// Serves RTU on `io` timed as `line` until it reaches end of file or fails.
    pub async fn serve_line<IO>(&self, mut io: IO, line: &Line) -> io::Result<()>
    where
        IO: AsyncRead + AsyncWrite + Unpin,
    {
        let mut wire = Wire::new(line);
        let mut chunk = [0u8; rtu::MAX_FRAME_LEN];
        loop {
            let next = wire.next_event();
            tokio::select! {
                biased;
                () = sleep_until_precise_spinning(next.unwrap_or_else(Instant::now), SPIN), if next.is_some() => {
                    let now = Instant::now();
                    self.end_request(&mut wire, now, &line.stats);
                    let due = wire.take_due(now);
                    if !due.is_empty() {
                        io.write_all(&due).await?;
                        io.flush().await?;
                    }
                }
                read = io.read(&mut chunk) => {
                    let read = read?;
                    let now = Instant::now();
                    // The silence may have ended the request before these bytes came.
                    self.end_request(&mut wire, now, &line.stats);
                    match chunk.get(..read) {
                        Some(bytes) if !bytes.is_empty() => wire.receive(bytes, now, &line.stats),
                        _ => return Ok(()),
                    }
                }
            }
        }
    }

    /// Answers the request once t3.5 of silence has ended it.
    fn end_request(&self, wire: &mut Wire, now: Instant, stats: &LineStats) {
        let Some(due) = wire.request_due().filter(|&due| due <= now) else {
            return;
        };
        let mut pending = std::mem::take(&mut wire.request);
        wire.request_end = None;
        bump(&stats.0.frames);
        let start = later(due, wire.turnaround);
        // The silence ends the burst: what is left after its frames is dropped.
        while let Some((used, answer)) = self.step(&pending) {
            pending.drain(..used.min(pending.len()));
            if let Some(answer) = answer {
                let plan = self.plan(answer);
                if plan.pieces.iter().any(|(_, bytes)| !bytes.is_empty()) {
                    bump(&stats.0.replies);
                }
                wire.send(start, &plan);
            }
        }
    }
}

impl Simulator {
    /// An in-memory RTU line to this device timed as `line`; see [`Slaves::duplex_line`].
    pub fn duplex_line(&self, line: Line) -> (DuplexStream, JoinHandle<io::Result<()>>) {
        Slaves::new([self.clone()]).duplex_line(line)
    }

    /// Serves Modbus RTU on any byte stream timed as `line`; see [`Slaves::serve_line`].
    pub async fn serve_line<IO>(&self, io: IO, line: &Line) -> io::Result<()>
    where
        IO: AsyncRead + AsyncWrite + Unpin,
    {
        Slaves::new([self.clone()]).serve_line(io, line).await
    }
}
