//! Our own Modbus RTU client over any byte stream, built on `optobus-codec`.

use std::future::poll_fn;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use optobus_codec::passthrough::{self, PassPdu};
use optobus_codec::{
    rtu, DecodeError, Decoded, ExceptionShape, FrameShape, LineFormat, Request, BROADCAST,
};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt, ReadBuf};
use tokio::time::{timeout_at, Instant};

use crate::error::Error;
use crate::frames;
use crate::no_wait::nobody_waits;
use crate::timing::{self, deadline_from, PreciseTimer};
use crate::transact::{Reply, Transact};
use crate::transport::DEFAULT_TIMEOUT;

/// The end of t3.5 before a request is watched on the clock for this long after the kernel's
/// timer wakes the client: a woken thread can wait tens of microseconds for a core, and every
/// microsecond late is line time lost (115200 baud: 0.980 of the line limit without it, 0.994
/// with it, for about 15 us more CPU a transaction).
const GAP_SPIN: Duration = Duration::from_micros(40);

/// How much earlier than the missing bytes of a reply can have arrived the client wakes to
/// read them: more than a timer's wake-up is late on a busy machine.
const REPLY_WAKE_MARGIN: Duration = Duration::from_micros(150);

/// The first bytes of a reply, which tell its length whatever it is (slave, function, then
/// a read's byte count, an echo's address or an exception's code).
const REPLY_HEADER: usize = 3;

/// A device's turnaround is the shortest of its last this many measured (a low quantile: a
/// reply slower than it costs a few wakes more, never a wrong or lost reply).
const TURNAROUND_SAMPLES: usize = 8;

/// Every this many replies slept through (each one until 8 are measured), a device's
/// turnaround is measured again: the client wakes `PROBE_EARLY` characters before the reply
/// can be whole and reads its last bytes as they come, so a turnaround that has become shorter
/// is learned (a reply found whole at once was whole earlier than the client looked, which
/// says nothing about how much earlier). A probe costs two or three wakes: every 32nd reply
/// adds less than a tenth of a wake a transaction; a longer turnaround needs no probe, as a
/// reply found unfinished is measured anyway.
const PROBE_EVERY: u32 = 32;

/// How many characters before its learned end a probing client wakes for a reply.
const PROBE_EARLY: usize = 2;

/// The longest quiet period recovery waits for by default, whatever the timeout.
const MAX_DEFAULT_RECOVERY: Duration = Duration::from_secs(10);

/// Settings of an [`RtuClient`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RtuConfig {
    /// How long to wait for a reply, counted from the end of the request on the line.
    pub timeout: Duration,
    /// How many times a failed read (timeout, garbled reply) is tried again. Writes and reads
    /// that are not [repeatable](crate::ReadRequest::repeatable) are never retried.
    pub read_retries: u8,
    /// The serial line, which sets the silence kept before each request (t3.5) and how long a
    /// request takes to leave; `None` where no line timing applies (an in-memory stream, RTU
    /// tunnelled over TCP).
    pub line: Option<LineFormat>,
    /// The silence kept before each request instead of t3.5 of `line`, e.g. the Modbus
    /// specification's fixed 1.75 ms above 19200 baud for a device that needs it.
    pub frame_gap: Option<Duration>,
    /// After a fault (timeout, garbled reply, a transaction dropped half-way) the line must
    /// have been quiet this long before the next request; `None`: the timeout, at most 10 s.
    pub recovery: Option<Duration>,
    /// How the device frames exception replies.
    pub exception: ExceptionShape,
}

impl Default for RtuConfig {
    fn default() -> Self {
        Self {
            timeout: DEFAULT_TIMEOUT,
            read_retries: 0,
            line: Some(LineFormat::new(115_200)),
            frame_gap: None,
            recovery: None,
            exception: ExceptionShape::Standard,
        }
    }
}

impl RtuConfig {
    /// The silence kept before each request.
    pub fn frame_gap(&self) -> Duration {
        self.frame_gap
            .or(self.line.map(|line| line.frame_gap()))
            .unwrap_or(Duration::ZERO)
    }

    /// How long the line must be quiet after a fault before the next request.
    pub fn recovery(&self) -> Duration {
        self.recovery
            .unwrap_or(self.timeout.min(MAX_DEFAULT_RECOVERY))
            .max(self.frame_gap())
    }

    /// How long to sleep before reading more of a reply of which `filled` bytes are in and
    /// at least `at_least` more are needed; `None`: read at once (and wake as bytes come).
    ///
    /// The missing bytes cannot all be here before they had time to cross the line (a real
    /// line and a timed pty hand them over one character time apart): sleeping through most
    /// of that saves a wake per byte. The sleep ends a timer's lateness early
    /// (`REPLY_WAKE_MARGIN`), and the read then wakes as the last bytes arrive, so the reply
    /// is taken no later than without it. Once the reply has begun, while the decoder asks for
    /// its header a byte at a time, the sleep lasts until the header is in (its end is later
    /// still, so no margin): one wake instead of one a byte. It comes after each read that
    /// brought bytes, so a stray byte costs one such sleep, not one every header time. Before
    /// the first byte nothing is slept: the device's turnaround is unknown.
    fn reply_wait(&self, filled: usize, at_least: usize) -> Option<Duration> {
        let wait = if filled > 0 && filled + at_least <= REPLY_HEADER {
            self.transmit_time(REPLY_HEADER - filled)
        } else {
            self.transmit_time(at_least.saturating_sub(1))
                .checked_sub(REPLY_WAKE_MARGIN)?
        };
        (!wait.is_zero()).then_some(wait)
    }

    /// How long `bytes` take to leave on the line (zero without line timing).
    fn transmit_time(&self, bytes: usize) -> Duration {
        self.line
            .map_or(Duration::ZERO, |line| line.transmit_time(bytes))
    }
}

/// What a device's last replies tell of its turnaround: how long after its request's last
/// byte left (plus the reply's own time on the line) its reply was in.
#[derive(Clone, Debug, Default)]
struct Turnaround {
    /// The last measurements, `len` of them, the oldest at `next` once full.
    samples: [Duration; TURNAROUND_SAMPLES],
    len: usize,
    next: usize,
    /// Replies slept through since the last measurement.
    slept: u32,
}

impl Turnaround {
    /// The shortest of the last measurements; `None` before the first.
    fn shortest(&self) -> Option<Duration> {
        self.samples[..self.len].iter().min().copied()
    }

    fn record(&mut self, turnaround: Duration) {
        self.samples[self.next] = turnaround;
        self.next = (self.next + 1) % TURNAROUND_SAMPLES;
        self.len = (self.len + 1).min(TURNAROUND_SAMPLES);
        self.slept = 0;
    }

    /// Whether the next reply slept through is a probe, and counts it: until the device's
    /// last `TURNAROUND_SAMPLES` replies are measured each one is (a measurement read after
    /// a late wake is too long, so one alone is a poor guess), then every `PROBE_EVERY`th.
    fn probe_due(&mut self) -> bool {
        self.slept += 1;
        self.len < TURNAROUND_SAMPLES || self.slept >= PROBE_EVERY
    }
}

/// How the client waits for a reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ReplyWait {
    /// Its first byte awaited as it comes (the turnaround is unknown).
    AsItComes,
    /// Slept through until it can be whole, by the device's learned turnaround.
    SleptThrough,
    /// Slept through until a little before that, to measure the turnaround again.
    Probe,
}

/// The line state is unknown since `since`: the line must be quiet for `quiet` (the recovery
/// of the transaction that left it so, which a late reply to it needs) before the next request.
#[derive(Clone, Copy, Debug)]
struct Unsettled {
    since: Instant,
    quiet: Duration,
}

/// A Modbus RTU client over `stream`.
///
/// # A reply is only ever taken as the answer to its own request
///
/// RTU frames carry no transaction id: a reply that arrives after its request timed out
/// looks exactly like the reply to the next request of the same shape. So after anything
/// that leaves the line in an unknown state (a timeout, a garbled or foreign reply, or a
/// transaction whose future was dropped before its reply was read) the client recovers before
/// its next request: it discards input until the line has been quiet for
/// [`RtuConfig::recovery`] (by default the timeout) since the failed transaction's deadline,
/// or since the last byte seen if that is later. A late reply therefore lands during the
/// recovery and is thrown away, never answers a later request; libmodbus's error recovery
/// does the same. Recovery costs time only after a fault.
///
/// Before every request the client also keeps the line silent for t3.5 after the last byte
/// seen (of the actual character format, within microseconds rather than tokio's 1 ms timer
/// tick), and discards any byte already waiting.
#[derive(Debug)]
pub struct RtuClient<S> {
    stream: S,
    config: RtuConfig,
    /// When the line was last busy (a byte sent or received), for the frame gap.
    last_activity: Option<Instant>,
    /// Set while the line state is unknown: when a transaction starts, cleared when it
    /// completes cleanly, so a dropped transaction leaves it set. Recovery waits for quiet
    /// counted from its `since`, as long as the transaction that left it needs.
    unsettled: Option<Unsettled>,
    /// When the last request began to leave, once the line was ready.
    last_request: Option<Instant>,
    /// The precise waits: t3.5 before each request, and a reply's time on the line.
    timer: PreciseTimer,
    /// Each slave's turnaround as measured from its last replies (a line has a few devices,
    /// at most 247).
    turnarounds: Vec<(u8, Turnaround)>,
    buffer: Box<[u8; rtu::MAX_FRAME_LEN + 4]>,
}

impl<S: AsyncRead + AsyncWrite + Unpin + Send> RtuClient<S> {
    /// A client with default settings (1 s timeout, no retries, 115200 baud 8N1 line
    /// timing, standard exceptions).
    pub fn new(stream: S) -> Self {
        Self::with_config(stream, RtuConfig::default())
    }

    /// A client with `config`.
    pub fn with_config(stream: S, config: RtuConfig) -> Self {
        Self {
            stream,
            config,
            last_activity: None,
            unsettled: None,
            last_request: None,
            timer: PreciseTimer::new(),
            turnarounds: Vec::new(),
            buffer: Box::new([0; rtu::MAX_FRAME_LEN + 4]),
        }
    }

    /// The settings.
    pub fn config(&self) -> &RtuConfig {
        &self.config
    }

    /// Changes the settings.
    pub fn config_mut(&mut self) -> &mut RtuConfig {
        &mut self.config
    }

    /// Gives the stream back.
    pub fn into_inner(self) -> S {
        self.stream
    }

    /// When the last request began to leave: after the recovery from a fault and the t3.5
    /// silence before it, which can hold a request back well past the call that made it.
    pub fn last_request(&self) -> Option<Instant> {
        self.last_request
    }

    /// Takes in bytes already waiting, without waiting for more; `true` if there were any.
    /// It polls with a waker that does nothing, which tells a stream that no read will wait
    /// (the transport's serial port then stays out of tokio's reactor).
    fn discard_waiting(&mut self) -> Result<bool, Error> {
        let mut discarded = false;
        let mut nobody = Context::from_waker(nobody_waits());
        loop {
            let mut buf = ReadBuf::new(&mut self.buffer[..]);
            match Pin::new(&mut self.stream).poll_read(&mut nobody, &mut buf) {
                Poll::Pending => return Ok(discarded),
                Poll::Ready(Ok(())) if buf.filled().is_empty() => return Err(Error::Closed),
                Poll::Ready(Ok(())) => {
                    frames::discarded(buf.filled());
                    discarded = true;
                    self.last_activity = Some(Instant::now());
                }
                Poll::Ready(Err(error)) => return Err(error.into()),
            }
        }
    }

    /// Tells the stream that no read waits any more, by a read with no room (the transport's
    /// serial port then leaves tokio's reactor, so bytes arriving unread wake nobody; other
    /// streams read nothing), whatever it answers.
    async fn give_up_read(&mut self) {
        let stream = &mut self.stream;
        poll_fn(|cx| {
            let _ = Pin::new(&mut *stream).poll_read(cx, &mut ReadBuf::new(&mut []));
            Poll::Ready(())
        })
        .await;
    }

    /// Discards input until the line has been quiet for the recovery time of the transaction
    /// that left it unsettled, counted from then or the last byte seen, whichever is later.
    async fn recover(&mut self, unsettled: Unsettled) -> Result<(), Error> {
        let Unsettled { since, quiet } = unsettled;
        let mut heard = since;
        if self.discard_waiting()? {
            heard = Instant::now();
        }
        loop {
            let until = deadline_from(heard.max(since), quiet);
            match timeout_at(until, self.stream.read(&mut self.buffer[..])).await {
                Err(_quiet) => break,
                Ok(Ok(0)) => return Err(Error::Closed),
                Ok(Ok(n)) => {
                    frames::discarded(&self.buffer[..n]);
                    heard = Instant::now();
                }
                Ok(Err(error)) => return Err(error.into()),
            }
            self.last_activity = Some(heard);
        }
        self.unsettled = None;
        Ok(())
    }

    /// Recovers the line now if a fault left it unsettled, rather than before the next request:
    /// a scheduler that shares the line can so count the quiet to whoever caused the fault.
    pub async fn settle(&mut self) -> Result<(), Error> {
        match self.unsettled {
            Some(unsettled) => self.recover(unsettled).await,
            None => Ok(()),
        }
    }

    /// The line is unsettled since `since` by a transaction made with the present settings:
    /// its own recovery time, not that of whoever asks next, is what a late reply needs.
    fn unsettled_since(&self, since: Instant) -> Unsettled {
        Unsettled {
            since,
            quiet: self.config.recovery(),
        }
    }

    /// Makes the line ready for a request: recovered after a fault, stray bytes discarded,
    /// and silent for a frame gap.
    async fn prepare(&mut self) -> Result<(), Error> {
        match self.unsettled {
            Some(unsettled) => self.recover(unsettled).await?,
            None => {
                self.discard_waiting()?;
            }
        }
        if let Some(last) = self.last_activity {
            let gap_end = deadline_from(last, self.config.frame_gap());
            if timing::gap_spins() {
                self.timer.sleep_until_spinning(gap_end, GAP_SPIN).await;
            } else {
                self.timer.sleep_until(gap_end).await;
            }
        }
        Ok(())
    }

    /// One request and its reply; `Ok(None)` for a broadcast.
    async fn transact(&mut self, slave: u8, request: Request) -> Result<Option<Reply>, Error> {
        let mut frame = [0u8; rtu::MAX_FRAME_LEN];
        let len = rtu::encode_request(&mut frame, slave, &request).map_err(Error::Request)?;
        let exception = self.config.exception;
        let reply_len = request.reply_pdu_len() + 3;
        self.exchange(slave, &frame[..len], Some(reply_len), |buf| {
            rtu::decode_response(buf, slave, &request, exception).map(|d| d.map(Reply::from))
        })
        .await
    }

    /// Passes a request PDU on unread and gives the reply's PDU as it came, an exception reply
    /// included (what a gateway does); `Ok(None)` for a broadcast. `shape` frames the reply
    /// (the device's four-byte writes and exception shape). The line is kept and recovered as
    /// for every other request, so a late or garbled reply never answers another one.
    pub async fn transact_pdu(
        &mut self,
        slave: u8,
        pdu: &PassPdu<'_>,
        shape: &FrameShape<'_>,
    ) -> Result<Option<Vec<u8>>, Error> {
        let mut frame = [0u8; rtu::MAX_FRAME_LEN];
        let len = passthrough::encode_rtu(&mut frame, slave, pdu).map_err(Error::Request)?;
        // A register read's reply has the length its count asks for; other functions are
        // awaited as they come.
        let reply_len = match pdu.bytes() {
            [0x03 | 0x04, _, _, high, low] => {
                Some(5 + 2 * usize::from(u16::from_be_bytes([*high, *low])))
            }
            _ => None,
        };
        self.exchange(slave, &frame[..len], reply_len, |buf| {
            passthrough::decode_rtu_reply(buf, slave, pdu, shape).map(|d| d.map(<[u8]>::to_vec))
        })
        .await
    }

    /// Sleeps through the reply of `reply_len` bytes to a request whose last byte leaves at
    /// `sent`, until it can be whole by the device's learned turnaround (a probe: a little
    /// before), so that it is read in one go: one wake instead of one for its first byte, one
    /// for its header and one or two for its end. Only where turned on
    /// ([`timing::set_sleep_through_replies`]); nothing is slept without line timing or
    /// before the device's first reply measured its turnaround. Waking too early costs only
    /// wakes: the reply is then read as it comes, as without this sleep.
    async fn sleep_through_reply(
        &mut self,
        slave: u8,
        sent: Instant,
        reply_len: usize,
        deadline: Instant,
    ) -> ReplyWait {
        if self.config.line.is_none() || !timing::sleeps_through_replies() {
            return ReplyWait::AsItComes;
        }
        let on_line = self.config.transmit_time(reply_len);
        let early = self.config.transmit_time(PROBE_EARLY);
        let turnaround = self.turnaround(slave);
        let Some(shortest) = turnaround.shortest() else {
            return ReplyWait::AsItComes;
        };
        let whole = deadline_from(sent, shortest.saturating_add(on_line));
        let (wake, wait) = if turnaround.probe_due() {
            (whole.checked_sub(early).unwrap_or(whole), ReplyWait::Probe)
        } else {
            (whole, ReplyWait::SleptThrough)
        };
        // The look for stray bytes before the request left a read waiting: given up, so that
        // the reply's bytes arriving meanwhile wake nobody.
        self.give_up_read().await;
        self.timer.sleep_until(wake.min(deadline)).await;
        wait
    }

    /// Learns `slave`'s turnaround from a reply of `len` bytes whose last bytes were read at
    /// `read` (at most a wake-up after they came, as they were awaited), its request sent at
    /// `sent`.
    fn learn_turnaround(&mut self, slave: u8, sent: Instant, len: usize, read: Instant) {
        let on_line = self.config.transmit_time(len);
        let turnaround = read.saturating_duration_since(sent).saturating_sub(on_line);
        self.turnaround(slave).record(turnaround);
    }

    /// What `slave`'s replies told of its turnaround so far.
    fn turnaround(&mut self, slave: u8) -> &mut Turnaround {
        let index = match self
            .turnarounds
            .iter()
            .position(|(known, _)| *known == slave)
        {
            Some(index) => index,
            None => {
                self.turnarounds.push((slave, Turnaround::default()));
                self.turnarounds.len() - 1
            }
        };
        &mut self.turnarounds[index].1
    }

    /// Sends `frame` to `slave` and reads until `decode` takes a reply from the bytes received
    /// (or fails, or the timeout passes); `Ok(None)` for a broadcast. A reply expected to be
    /// `reply_len` bytes long may be slept through (see `sleep_through_reply`).
    async fn exchange<R>(
        &mut self,
        slave: u8,
        frame: &[u8],
        reply_len: Option<usize>,
        mut decode: impl FnMut(&[u8]) -> Result<Decoded<R>, DecodeError>,
    ) -> Result<Option<R>, Error> {
        self.prepare().await?;
        // From here until the reply is complete the line state is unknown, also if this
        // future is dropped: the next transaction then recovers first.
        let now = Instant::now();
        self.last_request = Some(now);
        let sent = now + self.config.transmit_time(frame.len());
        let deadline = deadline_from(sent, self.config.timeout);
        self.unsettled = Some(self.unsettled_since(deadline_from(
            sent,
            self.config.timeout.min(MAX_DEFAULT_RECOVERY),
        )));
        self.stream.write_all(frame).await?;
        self.stream.flush().await?;
        let written = Instant::now();
        frames::sent(slave, frame);
        self.last_activity = Some(sent.max(written));
        if slave == BROADCAST {
            self.unsettled = None;
            return Ok(None);
        }
        let wait = match reply_len {
            Some(len) => self.sleep_through_reply(slave, sent, len, deadline).await,
            None => ReplyWait::AsItComes,
        };
        let mut filled = 0;
        let mut reads = 0u32;
        loop {
            match decode(&self.buffer[..filled]) {
                Ok(Decoded::Frame { frame, consumed }) => {
                    let (reply, after) = self.buffer[..filled].split_at(consumed);
                    if rtu::another_reply_follows(reply, after) {
                        // Two replies to one request: one of them answered another request
                        // (a reply still under way from before, another master).
                        self.unsettled = Some(self.unsettled_since(Instant::now()));
                        let bytes = &self.buffer[..filled];
                        frames::received(slave, bytes, written.elapsed(), Some("two replies"));
                        return Err(Error::Frame(DecodeError::SecondReply));
                    }
                    frames::received(slave, &self.buffer[..filled], written.elapsed(), None);
                    // A reply slept through and found whole in one read was in earlier than
                    // the client looked, by an unknown time: it measures nothing.
                    if wait != ReplyWait::SleptThrough || reads > 1 {
                        let read = self.last_activity.unwrap_or(written);
                        self.learn_turnaround(slave, sent, consumed, read);
                    }
                    // Bytes behind a good reply mean something else is talking: recover
                    // before the next request.
                    self.unsettled =
                        (consumed < filled).then(|| self.unsettled_since(Instant::now()));
                    return Ok(Some(frame));
                }
                Ok(Decoded::NeedMore { at_least }) => {
                    if let Some(sleep) = self.config.reply_wait(filled, at_least) {
                        let ready = Instant::now().max(sent) + sleep;
                        self.timer.sleep_until(ready.min(deadline)).await;
                    }
                }
                Err(DecodeError::Exception { function, code }) => {
                    frames::received(slave, &self.buffer[..filled], written.elapsed(), None);
                    self.unsettled = None;
                    return Err(Error::Exception { function, code });
                }
                Err(error) => {
                    // The device may still be sending, or this was another slave's reply
                    // and ours is yet to come: quiet is counted from now.
                    self.unsettled = Some(self.unsettled_since(Instant::now()));
                    let bytes = &self.buffer[..filled];
                    frames::received(slave, bytes, written.elapsed(), Some("garbled"));
                    return Err(Error::Frame(error));
                }
            }
            let room = &mut self.buffer[filled..];
            match timeout_at(deadline, self.stream.read(room)).await {
                Err(_) => {
                    if filled > 0 {
                        let bytes = &self.buffer[..filled];
                        frames::received(slave, bytes, written.elapsed(), Some("incomplete"));
                    }
                    return Err(Error::Timeout {
                        after: self.config.timeout,
                    });
                }
                Ok(Ok(0)) => return Err(Error::Closed),
                Ok(Ok(n)) => {
                    filled += n;
                    reads += 1;
                    self.last_activity = Some(Instant::now());
                }
                Ok(Err(error)) => return Err(error.into()),
            }
        }
    }
}

impl<S: AsyncRead + AsyncWrite + Unpin + Send> Transact for RtuClient<S> {
    async fn transact(&mut self, slave: u8, request: Request) -> Result<Option<Reply>, Error> {
        if slave == BROADCAST && matches!(request, Request::Read { .. }) {
            return Err(Error::Unsupported("a broadcast read gets no reply"));
        }
        RtuClient::transact(self, slave, request).await
    }

    fn read_retries(&self) -> u8 {
        self.config.read_retries
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 28, point 9: how long an RTU client sleeps before reading more of a reply, at
    /// 115200 baud (a character 86.8 µs).
    #[test]
    fn a_reply_is_read_in_few_wakes_not_one_a_byte() {
        let config = RtuConfig::default();
        let character = config.transmit_time(1);
        // Before the first byte: read at once (the turnaround is unknown).
        assert_eq!(config.reply_wait(0, 2), None);
        // The reply has begun and the decoder asks for its header a byte at a time: sleep
        // until the header's three bytes are in, not a wake per byte.
        assert_eq!(config.reply_wait(1, 1), Some(config.transmit_time(2)));
        assert_eq!(config.reply_wait(2, 1), Some(character));
        // The length is known (a 45-byte read reply, 3 bytes in): sleep until 150 µs before
        // the missing 42 can have crossed.
        assert_eq!(
            config.reply_wait(3, 42),
            Some(config.transmit_time(41) - REPLY_WAKE_MARGIN)
        );
        // A byte or two missing: read at once.
        assert_eq!(config.reply_wait(43, 2), None);
        // Without line timing nothing is slept.
        let untimed = RtuConfig {
            line: None,
            ..RtuConfig::default()
        };
        assert_eq!(untimed.reply_wait(1, 1), None);
        assert_eq!(untimed.reply_wait(3, 42), None);
    }

    /// Issue 28, point 9: a device's turnaround is the shortest of its last 8 measured, so
    /// one slow reply does not lengthen it and a lasting change replaces it within 8 replies;
    /// every 32nd reply slept through is a probe that measures it again.
    #[test]
    fn a_turnaround_is_the_shortest_of_the_last_eight_measured() {
        let micros = Duration::from_micros;
        let mut turnaround = Turnaround::default();
        assert_eq!(turnaround.shortest(), None);
        turnaround.record(micros(400));
        turnaround.record(micros(9_000));
        assert_eq!(turnaround.shortest(), Some(micros(400)));
        // Slower for good: the old turnaround is gone once 7 more are measured after it.
        for _ in 0..6 {
            turnaround.record(micros(2_000));
            assert_eq!(turnaround.shortest(), Some(micros(400)));
        }
        turnaround.record(micros(2_000));
        assert_eq!(turnaround.shortest(), Some(micros(2_000)));
        // Until 8 are measured, each reply is a probe.
        let mut young = Turnaround::default();
        young.record(micros(400));
        assert!(young.probe_due());
        let probes: Vec<bool> = (0..40).map(|_| turnaround.probe_due()).collect();
        assert_eq!(probes.iter().filter(|&&probe| probe).count(), 9);
        assert!(!probes[..31].contains(&true) && probes[31]);
        // A measurement starts the count again.
        turnaround.record(micros(2_000));
        assert!(!turnaround.probe_due());
    }
}
