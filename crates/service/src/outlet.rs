//! Output that never holds up the runtime: a writer on a thread of its own, fed through a
//! bounded queue that drops its **oldest** items when full, and counts them.
//!
//! A run (`optobus run`) prints samples, redraws the terminal view, records CSVs and writes its notes
//! on a current-thread runtime that also serves the gateway, the console, /metrics and MQTT.
//! A blocking write there to a pipe nobody reads (`optobus run --json | consumer` with a
//! consumer that stopped reading) would freeze all of them. Through an [`Outlet`], the runtime
//! only hands items over; a stalled reader costs its own oldest items, counted, like a lagging
//! receiver of tokio's `broadcast` channel, and nobody else's time.

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// Where an outlet's items go, on the outlet's thread.
pub trait Sink<T>: Send + 'static {
    /// Writes `items` (everything queued since the last call, oldest first). `dropped` is how
    /// many items the outlet has dropped so far, for a sink that tells it in its own stream.
    fn write(&mut self, items: Vec<T>, dropped: u64);
}

/// Lines of text for a stream people read (stderr), each batch written at once; write errors
/// ignored (a closed or broken stream is no reason to stop). Lines the outlet dropped are
/// told, as `optobus: NAME is not being read: N of its oldest lines dropped`, before the next
/// batch that gets through.
pub struct TextLines<W> {
    out: W,
    /// The stream, for the line that tells of drops.
    name: &'static str,
    /// Dropped lines already told about.
    told: u64,
}

impl<W: std::io::Write> TextLines<W> {
    /// Lines written to `out`, called `name` when drops are told.
    pub fn new(out: W, name: &'static str) -> Self {
        Self { out, name, told: 0 }
    }
}

impl<W: std::io::Write + Send + 'static> Sink<String> for TextLines<W> {
    fn write(&mut self, lines: Vec<String>, dropped: u64) {
        let mut text = String::new();
        if dropped > self.told {
            text += &format!(
                "optobus: {} is not being read: {} of its oldest lines dropped\n",
                self.name,
                dropped - self.told
            );
            self.told = dropped;
        }
        text.extend(lines);
        let _ = self.out.write_all(text.as_bytes());
        let _ = self.out.flush();
    }
}

/// A line being formatted (a `tracing` event), handed to its outlet whole when done: the
/// writer [`crate::journal::install`] takes, which never waits.
pub struct LineInto<S: Sink<String>> {
    line: Vec<u8>,
    outlet: &'static Outlet<String, S>,
}

impl<S: Sink<String>> LineInto<S> {
    /// A line for `outlet`.
    pub fn new(outlet: &'static Outlet<String, S>) -> Self {
        Self {
            line: Vec::new(),
            outlet,
        }
    }
}

impl<S: Sink<String>> std::io::Write for LineInto<S> {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        self.line.extend_from_slice(bytes);
        Ok(bytes.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl<S: Sink<String>> Drop for LineInto<S> {
    fn drop(&mut self) {
        if !self.line.is_empty() {
            self.outlet
                .push(String::from_utf8_lossy(&self.line).into_owned());
        }
    }
}

/// What [`Outlet::push`] did with an item.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pushed {
    /// Queued behind the others.
    Queued,
    /// Queued, the queue being full: its oldest item was dropped. `first` on the outlet's
    /// first drop, for a caller that says once that its reader fell behind.
    DroppedOldest {
        /// Whether this was the outlet's first drop.
        first: bool,
    },
}

impl Pushed {
    /// Whether this push made the outlet drop an item for the first time.
    pub fn first_drop(self) -> bool {
        self == Self::DroppedOldest { first: true }
    }
}

/// A bounded queue that a thread of its own empties into a [`Sink`]; pushing never waits.
pub struct Outlet<T, S> {
    shared: Arc<Shared<T, S>>,
    /// No thread could be started: each item is written on the pusher's thread.
    inline: bool,
}

struct Shared<T, S> {
    state: Mutex<State<T>>,
    /// Signalled when items arrive or the outlet closes (the writer waits on it).
    arrived: Condvar,
    /// Signalled when the writer has written a batch or stopped (flushes wait on it).
    written: Condvar,
    /// `None` once the writer has stopped and handed it back.
    sink: Mutex<Option<S>>,
}

struct State<T> {
    items: VecDeque<T>,
    capacity: usize,
    dropped: u64,
    /// Items taken from `items` and being written.
    in_hand: usize,
    /// No more items: the writer ends when `items` is empty.
    closed: bool,
    /// The writer has ended.
    stopped: bool,
}

fn lock<G>(mutex: &Mutex<G>) -> MutexGuard<'_, G> {
    // A sink that panicked leaves consistent data behind (a queue, counts); go on with it.
    mutex.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Waits on `signal` with `guard` until it is signalled or `deadline` has passed; `None` once
/// the deadline has passed.
fn wait_until<'a, G>(
    signal: &Condvar,
    guard: MutexGuard<'a, G>,
    deadline: Instant,
) -> Option<MutexGuard<'a, G>> {
    let left = deadline.saturating_duration_since(Instant::now());
    if left.is_zero() {
        return None;
    }
    Some(
        signal
            .wait_timeout(guard, left)
            .unwrap_or_else(PoisonError::into_inner)
            .0,
    )
}

impl<T: Send + 'static, S: Sink<T>> Outlet<T, S> {
    /// Starts a thread called `name` that writes to `sink`, queueing at most `capacity` items
    /// (at least 1) besides the batch being written. If no thread can be started, items are
    /// written on the caller's thread instead, as without an outlet.
    pub fn start(name: &str, capacity: usize, sink: S) -> Self {
        let shared = Arc::new(Shared {
            state: Mutex::new(State {
                items: VecDeque::new(),
                capacity: capacity.max(1),
                dropped: 0,
                in_hand: 0,
                closed: false,
                stopped: false,
            }),
            arrived: Condvar::new(),
            written: Condvar::new(),
            sink: Mutex::new(Some(sink)),
        });
        let writer = Arc::clone(&shared);
        let inline = std::thread::Builder::new()
            .name(name.to_owned())
            .spawn(move || writer.write_until_closed())
            .is_err();
        Self { shared, inline }
    }

    /// Hands `item` to the writer; never waits for it. When the queue is full, its oldest
    /// item is dropped and counted.
    pub fn push(&self, item: T) -> Pushed {
        if self.inline {
            if let Some(sink) = lock(&self.shared.sink).as_mut() {
                sink.write(vec![item], 0);
            }
            return Pushed::Queued;
        }
        let mut state = lock(&self.shared.state);
        if state.closed {
            return Pushed::Queued;
        }
        let pushed = if state.items.len() >= state.capacity {
            state.items.pop_front();
            state.dropped += 1;
            Pushed::DroppedOldest {
                first: state.dropped == 1,
            }
        } else {
            Pushed::Queued
        };
        state.items.push_back(item);
        drop(state);
        self.shared.arrived.notify_one();
        pushed
    }

    /// Items dropped so far.
    pub fn dropped(&self) -> u64 {
        lock(&self.shared.state).dropped
    }

    /// Waits until everything pushed so far is written, at most `within` (the reader may
    /// never read again); gives the items still unwritten then (0: all written).
    pub fn flush(&self, within: Duration) -> usize {
        let deadline = Instant::now() + within;
        let mut state = lock(&self.shared.state);
        loop {
            let waiting = state.items.len() + state.in_hand;
            if waiting == 0 || state.stopped {
                return state.items.len();
            }
            state = match wait_until(&self.shared.written, state, deadline) {
                Some(state) => state,
                None => return waiting,
            };
        }
    }

    /// Writes what is queued, waiting at most `within`, stops the writer and gives the sink
    /// back (for its last words: a CSV's last row, an error). `None` if the writer is still
    /// stuck in a write when the time is up; it is left to the process's end.
    pub fn finish(self, within: Duration) -> Option<S> {
        let deadline = Instant::now() + within;
        let mut state = lock(&self.shared.state);
        state.closed = true;
        self.shared.arrived.notify_one();
        while !self.inline && !state.stopped {
            state = wait_until(&self.shared.written, state, deadline)?;
        }
        drop(state);
        lock(&self.shared.sink).take()
    }
}

/// Lets the writer end once it has written what is queued (it is not waited for).
impl<T, S> Drop for Outlet<T, S> {
    fn drop(&mut self) {
        lock(&self.shared.state).closed = true;
        self.shared.arrived.notify_one();
    }
}

impl<T, S: Sink<T>> Shared<T, S> {
    /// The writer thread: each batch as it comes, until the outlet is closed and empty.
    fn write_until_closed(&self) {
        loop {
            let (batch, dropped) = {
                let mut state = lock(&self.state);
                while state.items.is_empty() && !state.closed {
                    state = self
                        .arrived
                        .wait(state)
                        .unwrap_or_else(PoisonError::into_inner);
                }
                if state.items.is_empty() {
                    state.stopped = true;
                    drop(state);
                    self.written.notify_all();
                    return;
                }
                state.in_hand = state.items.len();
                (Vec::from(std::mem::take(&mut state.items)), state.dropped)
            };
            if let Some(sink) = lock(&self.sink).as_mut() {
                sink.write(batch, dropped);
            }
            lock(&self.state).in_hand = 0;
            self.written.notify_all();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc;

    /// A sink that waits for a go before each write, and reports what it wrote.
    struct Gated {
        go: mpsc::Receiver<()>,
        wrote: mpsc::Sender<Vec<u32>>,
    }

    impl Sink<u32> for Gated {
        fn write(&mut self, items: Vec<u32>, _: u64) {
            let _ = self.go.recv();
            let _ = self.wrote.send(items);
        }
    }

    fn gated(
        capacity: usize,
    ) -> (
        Outlet<u32, Gated>,
        mpsc::Sender<()>,
        mpsc::Receiver<Vec<u32>>,
    ) {
        let (go, go_rx) = mpsc::channel();
        let (wrote_tx, wrote) = mpsc::channel();
        let sink = Gated {
            go: go_rx,
            wrote: wrote_tx,
        };
        (Outlet::start("test-outlet", capacity, sink), go, wrote)
    }

    #[test]
    fn a_stuck_writer_costs_the_oldest_items_counted_never_a_wait() {
        let (outlet, go, wrote) = gated(4);
        // The writer takes 0 and is stuck writing it.
        assert_eq!(outlet.push(0), Pushed::Queued);
        while lock(&outlet.shared.state).in_hand == 0 {
            std::thread::yield_now();
        }
        let pushed: Vec<Pushed> = (1..=10).map(|i| outlet.push(i)).collect();
        assert_eq!(pushed[..4], [Pushed::Queued; 4]);
        assert!(pushed[4].first_drop());
        assert!(pushed[5..]
            .iter()
            .all(|p| *p == Pushed::DroppedOldest { first: false }));
        assert_eq!(outlet.dropped(), 6);
        // Unstuck, it writes what it held, then the newest four.
        go.send(()).unwrap();
        go.send(()).unwrap();
        assert_eq!(wrote.recv().unwrap(), [0]);
        assert_eq!(wrote.recv().unwrap(), [7, 8, 9, 10]);
        assert_eq!(outlet.flush(Duration::from_secs(60)), 0);
    }

    #[test]
    fn finishing_gives_up_on_a_stuck_writer_after_its_time() {
        let (outlet, _go, _wrote) = gated(4);
        outlet.push(1);
        outlet.push(2);
        assert_eq!(
            outlet.flush(Duration::from_millis(50)),
            2,
            "1 in hand, 2 queued"
        );
        assert!(outlet.finish(Duration::from_millis(50)).is_none());
    }

    #[test]
    fn finishing_writes_everything_and_gives_the_sink_back() {
        let (outlet, go, wrote) = gated(100);
        for i in 0..50 {
            outlet.push(i);
        }
        for _ in 0..50 {
            go.send(()).unwrap();
        }
        let sink = outlet
            .finish(Duration::from_secs(60))
            .expect("the writer ended");
        drop(sink);
        let written: Vec<u32> = wrote.iter().flatten().collect();
        assert_eq!(written, (0..50).collect::<Vec<_>>());
    }

    #[test]
    fn text_lines_tell_the_lines_dropped_once_before_the_next_that_get_through() {
        let mut lines = TextLines::new(Vec::new(), "stderr");
        lines.write(vec!["a\n".to_owned()], 0);
        lines.write(vec!["b\n".to_owned(), "c\n".to_owned()], 3);
        lines.write(vec!["d\n".to_owned()], 3);
        assert_eq!(
            String::from_utf8(lines.out).unwrap(),
            "a\noptobus: stderr is not being read: 3 of its oldest lines dropped\nb\nc\nd\n"
        );
    }

    /// A sink that hands what it is given to the test.
    struct Sent(mpsc::Sender<Vec<String>>);

    impl Sink<String> for Sent {
        fn write(&mut self, items: Vec<String>, _: u64) {
            let _ = self.0.send(items);
        }
    }

    #[test]
    fn a_line_written_in_pieces_reaches_the_outlet_whole_when_done() {
        let (sent, received) = mpsc::channel();
        let outlet = Box::leak(Box::new(Outlet::start("test-lines", 8, Sent(sent))));
        {
            let mut line = LineInto::new(outlet);
            std::io::Write::write_all(&mut line, b"12:00:00.000 +00:00 -> ").unwrap();
            std::io::Write::write_all(&mut line, b"01 03 00 1F\n").unwrap();
        }
        let whole = received.recv_timeout(Duration::from_secs(60)).unwrap();
        assert_eq!(whole, ["12:00:00.000 +00:00 -> 01 03 00 1F\n"]);
    }
}
