//! Modbus TCP serving: every connection gets the same device.
//!
//! The device is addressed by its IP, so it answers every unit id and echoes it with the
//! transaction id (P series 5.1.2 .. 5.3.2). A frame with a protocol id other than 0 or an
//! impossible length is skipped by its MBAP length; a connection that cannot be framed any
//! more is closed. Devices without a `tcp` transport can be served too, like an RTU-to-TCP
//! gateway would.

use std::io;
use std::net::SocketAddr;

use optobus_codec::{tcp, DecodeError, Decoded};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, ToSocketAddrs};
use tokio::task::{JoinHandle, JoinSet};

use crate::faults::{self, Framing, Plan};
use crate::model::{Envelope, Incoming};
use crate::names;
use crate::sim::Simulator;

/// A running Modbus TCP server; dropping it stops the server and closes its connections.
#[derive(Debug)]
pub struct TcpServer {
    local_addr: SocketAddr,
    task: JoinHandle<()>,
}

impl TcpServer {
    /// The address the server listens on (with the port the system chose for port 0).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// Stops accepting and closes every connection.
    pub fn shutdown(&self) {
        self.task.abort();
    }
}

impl Drop for TcpServer {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl Simulator {
    /// Listens on `addr` (e.g. `"127.0.0.1:0"`) and serves Modbus TCP to any number of
    /// connections on a spawned task.
    pub async fn serve_tcp(&self, addr: impl ToSocketAddrs) -> io::Result<TcpServer> {
        let listener = TcpListener::bind(addr).await?;
        let local_addr = listener.local_addr()?;
        let sim = self.clone();
        let task = tokio::spawn(async move {
            let mut connections = JoinSet::new();
            loop {
                tokio::select! {
                    accepted = listener.accept() => {
                        let Ok((stream, peer)) = accepted else { continue };
                        sim.note_host_port(peer.port());
                        let sim = sim.clone();
                        connections.spawn(async move {
                            // A broken connection ends only itself.
                            let _ = sim.serve_tcp_stream(stream).await;
                        });
                    }
                    Some(_) = connections.join_next(), if !connections.is_empty() => {}
                }
            }
        });
        Ok(TcpServer { local_addr, task })
    }

    /// The P series shows the bound host's port (input 0154).
    fn note_host_port(&self, port: u16) {
        let mut device = self.lock();
        if let Some(index) = device.layout.find(names::HOST_PORT) {
            if let Some(words) = device.words.get_mut(index) {
                if let Some(word) = words.first_mut() {
                    *word = port;
                }
            }
        }
    }

    /// Serves Modbus TCP on one connection (a `TcpStream`, or any byte stream carrying MBAP
    /// frames) until the peer closes it.
    pub async fn serve_tcp_stream<IO>(&self, mut stream: IO) -> io::Result<()>
    where
        IO: AsyncRead + AsyncWrite + Unpin,
    {
        let shape = self.device().frame_shape;
        let mut pending: Vec<u8> = Vec::with_capacity(tcp::MAX_FRAME_LEN);
        let mut chunk = [0u8; tcp::MAX_FRAME_LEN];
        loop {
            loop {
                match tcp::decode_request(&pending, &shape) {
                    Ok(Decoded::NeedMore { .. }) => break,
                    Ok(Decoded::Frame { frame, consumed }) => {
                        pending.drain(..consumed.min(pending.len()));
                        let reply = self.respond(None, Incoming::Request(&frame.pdu));
                        if let Some(bytes) =
                            reply.encode(Envelope::Tcp(frame.header), shape.exception)
                        {
                            if !self.send_tcp(&mut stream, bytes).await? {
                                return Ok(());
                            }
                        }
                    }
                    Err(DecodeError::UnsupportedFunction { function }) => {
                        let Some(len) = tcp::frame_len(&pending) else {
                            break;
                        };
                        if pending.len() < len {
                            break;
                        }
                        let header = header_of(&pending);
                        pending.drain(..len);
                        let reply = self.respond(None, Incoming::Unsupported(function));
                        if let Some(bytes) = reply.encode(Envelope::Tcp(header), shape.exception) {
                            if !self.send_tcp(&mut stream, bytes).await? {
                                return Ok(());
                            }
                        }
                    }
                    Err(DecodeError::BadProtocolId { .. }) => {
                        match tcp::frame_len(&pending).filter(|&len| len <= tcp::MAX_FRAME_LEN) {
                            Some(len) if pending.len() >= len => {
                                pending.drain(..len);
                            }
                            Some(_) => break,
                            None => return Ok(()),
                        }
                    }
                    // The stream cannot be framed any more.
                    Err(_) => return Ok(()),
                }
            }
            let read = stream.read(&mut chunk).await?;
            if read == 0 {
                return Ok(());
            }
            pending.extend_from_slice(chunk.get(..read).unwrap_or_default());
        }
    }
}

impl Simulator {
    /// Sends a reply through the device's faults; `false` when a fault closes the connection.
    async fn send_tcp<IO>(&self, stream: &mut IO, bytes: Vec<u8>) -> io::Result<bool>
    where
        IO: AsyncWrite + Unpin,
    {
        let plan = match self.injector() {
            Some(injector) => injector.plan(bytes, Framing::Tcp),
            None => Plan::clean(bytes),
        };
        faults::send(stream, &plan).await?;
        if plan.close {
            // The peer sees end of file; an error here changes nothing.
            let _ = stream.shutdown().await;
            return Ok(false);
        }
        Ok(true)
    }
}

fn header_of(frame: &[u8]) -> tcp::Header {
    match frame {
        [t0, t1, _, _, _, _, unit, ..] => tcp::Header {
            transaction: u16::from_be_bytes([*t0, *t1]),
            unit: *unit,
        },
        _ => tcp::Header::default(),
    }
}
