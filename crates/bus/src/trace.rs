//! The recent frames of each device: a bounded ring per device, fed by its line's byte stream
//! as requests go out and replies come in, read through [`Handle::frames`](crate::Handle::frames).
//!
//! The line says whose transaction starts ([`LineFrames::begin`]); the stream adds what it
//! writes to that transaction's request and what it reads to its reply, so a reply that
//! arrives in pieces is still one frame. Bytes read before a request (a late reply thrown away
//! before the next request) are kept as received bytes with no request time.

use std::collections::VecDeque;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::{Duration, SystemTime};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::time::Instant;

/// Frames kept per device; older ones are dropped.
pub const FRAMES_KEPT: usize = 256;

/// Which way a frame went.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// From the bus to the device.
    Sent,
    /// From the device (or the line) to the bus.
    Received,
}

/// A frame as it went over the line.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    /// Which way.
    pub direction: Direction,
    /// Its bytes, CRC included.
    pub bytes: Vec<u8>,
    /// When its first byte went or came.
    pub at: SystemTime,
    /// For a reply: how long after its request's first byte its first byte came.
    pub after_request: Option<Duration>,
}

/// The transaction the line is in.
#[derive(Debug, Default)]
struct Current {
    device: Option<usize>,
    /// When its request went, once it has.
    sent: Option<Instant>,
    /// Whether its request and its reply have a frame yet.
    sent_frame: bool,
    received_frame: bool,
}

#[derive(Debug)]
struct Rings {
    current: Current,
    devices: Vec<VecDeque<Frame>>,
}

/// The frame rings of one line's devices (in the line's order).
#[derive(Debug)]
pub(crate) struct LineFrames(Mutex<Rings>);

impl LineFrames {
    pub(crate) fn new(devices: usize) -> Self {
        Self(Mutex::new(Rings {
            current: Current::default(),
            devices: vec![VecDeque::new(); devices],
        }))
    }

    fn rings(&self) -> std::sync::MutexGuard<'_, Rings> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// A transaction with device `device` of the line (`None`: a slave the bus file does not
    /// name, whose frames are not kept) starts.
    pub(crate) fn begin(&self, device: Option<usize>) {
        self.rings().current = Current {
            device,
            ..Current::default()
        };
    }

    /// The frames of device `device` of the line, oldest first.
    pub(crate) fn of(&self, device: usize) -> Vec<Frame> {
        self.rings()
            .devices
            .get(device)
            .map(|ring| ring.iter().cloned().collect())
            .unwrap_or_default()
    }

    fn add(&self, direction: Direction, bytes: &[u8]) {
        if bytes.is_empty() {
            return;
        }
        let mut rings = self.rings();
        let Rings { current, devices } = &mut *rings;
        let Some(ring) = current.device.and_then(|d| devices.get_mut(d)) else {
            return;
        };
        let now = Instant::now();
        let extends = match direction {
            Direction::Sent => std::mem::replace(&mut current.sent_frame, true),
            Direction::Received => std::mem::replace(&mut current.received_frame, true),
        };
        match ring.back_mut() {
            Some(last) if extends && last.direction == direction => {
                last.bytes.extend_from_slice(bytes);
                return;
            }
            _ => {}
        }
        if direction == Direction::Sent {
            current.sent = Some(now);
        }
        let after_request = match direction {
            Direction::Sent => None,
            Direction::Received => current.sent.map(|sent| now.saturating_duration_since(sent)),
        };
        if ring.len() == FRAMES_KEPT {
            ring.pop_front();
        }
        ring.push_back(Frame {
            direction,
            bytes: bytes.to_vec(),
            at: SystemTime::now(),
            after_request,
        });
    }
}

/// A line's stream, its bytes both ways added to the frame rings.
pub(crate) struct TracedStream<S> {
    pub(crate) inner: S,
    pub(crate) frames: Arc<LineFrames>,
}

impl<S: AsyncRead + Unpin> AsyncRead for TracedStream<S> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        let before = buf.filled().len();
        let poll = Pin::new(&mut self.inner).poll_read(cx, buf);
        if let Poll::Ready(Ok(())) = poll {
            self.frames
                .add(Direction::Received, &buf.filled()[before..]);
        }
        poll
    }
}

impl<S: AsyncWrite + Unpin> AsyncWrite for TracedStream<S> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        let poll = Pin::new(&mut self.inner).poll_write(cx, buf);
        if let Poll::Ready(Ok(written)) = poll {
            self.frames.add(Direction::Sent, &buf[..written]);
        }
        poll
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<std::io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}
