//! Modbus RTU over a byte stream: one or several virtual slaves on one line.
//!
//! Requests may arrive split across reads and back to back. Bytes that do not start a valid
//! frame are skipped one at a time until one does (resynchronisation), and a frame for
//! another slave is passed over. A frame with a bad CRC is ignored, as every manual says
//! (P series 3.4, CCS/CCF 3.3). A partial frame followed by a silence longer than the frame
//! gap is dropped, as the line's 3.5-character silence would end it.

use std::io;
use std::time::Duration;

use optobus_codec::crc::is_valid_frame;
use optobus_codec::{rtu, DecodeError, Decoded, Request};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, DuplexStream};
use tokio::task::JoinHandle;
use tokio::time::timeout;

use crate::faults::{self, FaultStats, Faults, Framing, Injector, Plan};
use crate::model::{Envelope, Incoming, Reply};
use crate::sim::Simulator;

/// Default silence after which a partial frame is dropped.
const DEFAULT_FRAME_GAP: Duration = Duration::from_millis(20);

/// Most bytes kept while waiting for a frame to complete.
const MAX_PENDING: usize = 4 * rtu::MAX_FRAME_LEN;

/// Several virtual slaves sharing one RTU line (two drivers on one port, a broadcast reaching
/// everyone).
///
/// Each frame is decoded with every member's frame shape; the member whose address it
/// carries answers, and a broadcast is carried out by all of them.
#[derive(Clone, Debug)]
pub struct Slaves {
    members: Vec<Simulator>,
    frame_gap: Duration,
    faults: Option<Injector>,
}

/// A reply's bytes and the faults of the member that sent it.
pub(crate) type Answer = (Vec<u8>, Option<Injector>);

impl Slaves {
    /// A line with `members` on it.
    pub fn new(members: impl IntoIterator<Item = Simulator>) -> Self {
        Self {
            members: members.into_iter().collect(),
            frame_gap: DEFAULT_FRAME_GAP,
            faults: None,
        }
    }

    /// Injects `faults` into every reply on the line, instead of the members' own
    /// ([`Simulator::faults`]). See [`crate::faults`].
    pub fn faults(mut self, faults: Faults) -> Self {
        self.faults = Some(Injector::new(faults));
        self
    }

    /// Counts and log of the faults given with [`Slaves::faults`].
    pub fn fault_stats(&self) -> Option<FaultStats> {
        self.faults.as_ref().map(Injector::stats)
    }

    /// How `answer` goes out: the line's faults, else its sender's, else as it is.
    pub(crate) fn plan(&self, (bytes, member): Answer) -> Plan {
        match self.faults.as_ref().or(member.as_ref()) {
            Some(injector) => injector.plan(bytes, Framing::Rtu),
            None => Plan::clean(bytes),
        }
    }

    /// Drops a partial frame after `gap` of silence (default 20 ms).
    pub fn frame_gap(mut self, gap: Duration) -> Self {
        self.frame_gap = gap;
        self
    }

    /// The devices on the line.
    pub fn members(&self) -> &[Simulator] {
        &self.members
    }

    /// An in-memory line: the returned stream is the client's end; the line is served on a
    /// spawned task until the client's end is dropped. Needs a tokio runtime.
    pub fn duplex(&self) -> (DuplexStream, JoinHandle<io::Result<()>>) {
        let (client, server) = tokio::io::duplex(4096);
        let slaves = self.clone();
        let task = tokio::spawn(async move { slaves.serve(server).await });
        (client, task)
    }

    /// Serves RTU on `io` until it reaches end of file or fails.
    pub async fn serve<IO>(&self, mut io: IO) -> io::Result<()>
    where
        IO: AsyncRead + AsyncWrite + Unpin,
    {
        let mut pending: Vec<u8> = Vec::with_capacity(rtu::MAX_FRAME_LEN);
        let mut chunk = [0u8; rtu::MAX_FRAME_LEN];
        loop {
            while let Some(step) = self.step(&pending) {
                let (used, reply) = step;
                pending.drain(..used.min(pending.len()));
                if let Some(answer) = reply {
                    faults::send(&mut io, &self.plan(answer)).await?;
                }
            }
            let read = if pending.is_empty() {
                io.read(&mut chunk).await?
            } else {
                match timeout(self.frame_gap, io.read(&mut chunk)).await {
                    Ok(read) => read?,
                    Err(_silence) => {
                        pending.clear();
                        continue;
                    }
                }
            };
            if read == 0 {
                return Ok(());
            }
            pending.extend_from_slice(chunk.get(..read).unwrap_or_default());
            if pending.len() > MAX_PENDING {
                let excess = pending.len() - MAX_PENDING;
                pending.drain(..excess);
            }
        }
    }

    /// What the bytes at the front of `buf` are: `Some((bytes used, reply))`, or `None` when
    /// more bytes are needed.
    pub(crate) fn step(&self, buf: &[u8]) -> Option<(usize, Option<Answer>)> {
        if buf.is_empty() {
            return None;
        }
        let mut need_more = false;
        let mut frames: Vec<(&Simulator, rtu::Frame<Request>, usize)> = Vec::new();
        for member in &self.members {
            match rtu::decode_request(buf, &member.device().frame_shape) {
                Ok(Decoded::Frame { frame, consumed }) => frames.push((member, frame, consumed)),
                Ok(Decoded::NeedMore { .. }) => need_more = true,
                Err(DecodeError::UnsupportedFunction { function }) => {
                    // The whole buffer is one valid frame with a function code the codec
                    // does not know: its addressee answers "illegal function".
                    return Some((buf.len(), self.unsupported(buf, function)));
                }
                Err(_) => {}
            }
        }
        if let Some(&(_, _, consumed)) = frames.first() {
            let mut reply = None;
            for (member, frame, _) in frames.iter().filter(|(_, _, c)| *c == consumed) {
                let answer = member.respond(Some(frame.slave), Incoming::Request(&frame.pdu));
                // One slave answers; a broadcast reaches every member.
                if reply.is_none() {
                    reply = encode(member, frame.slave, &answer).map(|b| (b, member.injector()));
                }
            }
            return Some((consumed, reply));
        }
        if need_more {
            // Perhaps garbage sits in front of a complete frame: skip to it.
            let start =
                (1..buf.len()).find(|&at| buf.get(at..).is_some_and(|rest| self.frame_at(rest)))?;
            let skipped = buf.get(..start)?;
            // What is skipped may itself be a frame with an unknown function code.
            let reply = match skipped {
                [_, function, ..] if skipped.len() >= 4 && is_valid_frame(skipped) => {
                    self.unsupported(skipped, *function)
                }
                _ => None,
            };
            return Some((start, reply));
        }
        // Not a frame start for anyone: resynchronise one byte further.
        Some((1, None))
    }

    /// Whether a complete frame (of a known or unknown function) starts `buf`.
    fn frame_at(&self, buf: &[u8]) -> bool {
        self.members.iter().any(|member| {
            matches!(
                rtu::decode_request(buf, &member.device().frame_shape),
                Ok(Decoded::Frame { .. }) | Err(DecodeError::UnsupportedFunction { .. })
            )
        })
    }

    /// The reply to a valid frame with a function code the codec does not implement.
    fn unsupported(&self, frame: &[u8], function: u8) -> Option<Answer> {
        let slave = *frame.first()?;
        let mut reply = None;
        for member in &self.members {
            let answer = member.respond(Some(slave), Incoming::Unsupported(function));
            if reply.is_none() {
                reply = encode(member, slave, &answer).map(|b| (b, member.injector()));
            }
        }
        reply
    }
}

/// The RTU bytes of `member`'s `reply` to a request sent to `slave`.
fn encode(member: &Simulator, slave: u8, reply: &Reply) -> Option<Vec<u8>> {
    // A broadcast read that is answered comes from the device's own address (rangefinder 3.5).
    let from = if slave == 0 { member.address() } else { slave };
    let shape = member.device().frame_shape.exception;
    reply.encode(Envelope::Rtu { slave: from }, shape)
}

impl Simulator {
    /// An in-memory RTU line to this device; see [`Slaves::duplex`].
    pub fn duplex(&self) -> (DuplexStream, JoinHandle<io::Result<()>>) {
        Slaves::new([self.clone()]).duplex()
    }

    /// Serves Modbus RTU on any byte stream until it reaches end of file or fails.
    pub async fn serve_rtu<IO>(&self, io: IO) -> io::Result<()>
    where
        IO: AsyncRead + AsyncWrite + Unpin,
    {
        Slaves::new([self.clone()]).serve(io).await
    }
}
