//! Modbus TCP serving: every connection gets the same device, or the same line of devices.
//!
//! The device is addressed by its IP, so it answers every unit id and echoes it with the
//! transaction id (P series 5.1.2 .. 5.3.2). A frame with a protocol id other than 0 or an
//! impossible length is skipped by its MBAP length; a connection that cannot be framed any
//! more is closed. Devices without a `tcp` transport can be served too, like an RTU-to-TCP
//! gateway would. [`Slaves`] served over TCP are such a gateway in front of their line: the unit
//! id picks the device, and a unit id no device has gets exception 0B (gateway target device
//! failed to respond), as mbusd and the bus's own gateway answer.

use std::io;
use std::net::SocketAddr;

use optobus_codec::server::{self, RequestError, ServerRequest, WRITE_MULTIPLE};
use optobus_codec::{tcp, DecodeError, ExceptionCode, ExceptionShape, Request, EXCEPTION_BIT};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, ToSocketAddrs};
use tokio::task::{JoinHandle, JoinSet};

use crate::faults::{self, Framing, Plan};
use crate::model::{Envelope, Incoming, Reply};
use crate::names;
use crate::rtu::Slaves;
use crate::sim::Simulator;

/// Who answers a Modbus TCP request.
#[derive(Clone, Copy)]
enum Answerer<'a> {
    /// One device, whatever the unit id.
    Device(&'a Simulator),
    /// The device of a line whose address is the unit id.
    Line(&'a [Simulator]),
}

impl<'a> Answerer<'a> {
    /// The device for unit id `unit`, and the slave address it is asked as (`None`: any).
    fn pick(self, unit: u8) -> Option<(&'a Simulator, Option<u8>)> {
        match self {
            Self::Device(sim) => Some((sim, None)),
            Self::Line(members) => members
                .iter()
                .find(|member| unit != 0 && member.address() == unit)
                .map(|member| (member, Some(unit))),
        }
    }
}

/// Exception 0B, gateway target device failed to respond.
const TARGET_FAILED: u16 = 0x0B;

impl Slaves {
    /// Listens on `addr` and serves the line's devices over Modbus TCP on a spawned task, as
    /// a TCP-to-RTU gateway in front of them would: the unit id picks the device (by its
    /// address), and a unit id no device has is answered with exception 0B (gateway target
    /// device failed to respond). Each device's own faults apply to its replies.
    pub async fn serve_tcp(&self, addr: impl ToSocketAddrs) -> io::Result<TcpServer> {
        let members = self.members().to_vec();
        listen(addr, move |stream| {
            let members = members.clone();
            async move { serve_stream(Answerer::Line(&members), stream).await }
        })
        .await
    }
}

/// Accepts connections on `addr` and serves each with `serve` on a task of its own.
async fn listen<F, Fut>(addr: impl ToSocketAddrs, serve: F) -> io::Result<TcpServer>
where
    F: Fn(tokio::net::TcpStream) -> Fut + Send + 'static,
    Fut: std::future::Future<Output = io::Result<()>> + Send + 'static,
{
    let listener = TcpListener::bind(addr).await?;
    let local_addr = listener.local_addr()?;
    let task = tokio::spawn(async move {
        let mut connections = JoinSet::new();
        loop {
            tokio::select! {
                accepted = listener.accept() => {
                    let Ok((stream, _)) = accepted else { continue };
                    // A broken connection ends only itself.
                    let served = serve(stream);
                    connections.spawn(async move {
                        let _ = served.await;
                    });
                }
                Some(_) = connections.join_next(), if !connections.is_empty() => {}
            }
        }
    });
    Ok(TcpServer { local_addr, task })
}

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
        let sim = self.clone();
        listen(addr, move |stream| {
            if let Ok(peer) = stream.peer_addr() {
                sim.note_host_port(peer.port());
            }
            let sim = sim.clone();
            async move { sim.serve_tcp_stream(stream).await }
        })
        .await
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
    pub async fn serve_tcp_stream<IO>(&self, stream: IO) -> io::Result<()>
    where
        IO: AsyncRead + AsyncWrite + Unpin,
    {
        serve_stream(Answerer::Device(self), stream).await
    }
}

/// Serves Modbus TCP on one connection until the peer closes it, each request answered by
/// the device `who` picks for its unit id. The codec's server framing reads each request: the
/// MBAP header, then the PDU as a typed request ([`server::parse_request`], with the device's
/// frame shape); a function the device does not take is answered by its own rules, a request
/// malformed for its function with exception 03, before the device's registers see it.
async fn serve_stream<IO>(who: Answerer<'_>, mut stream: IO) -> io::Result<()>
where
    IO: AsyncRead + AsyncWrite + Unpin,
{
    let mut pending: Vec<u8> = Vec::with_capacity(tcp::MAX_FRAME_LEN);
    let mut chunk = [0u8; tcp::MAX_FRAME_LEN];
    loop {
        while let Some(mbap) = tcp::Mbap::parse(&pending) {
            let len = mbap.frame_len();
            match mbap.check() {
                Ok(()) => {}
                // Another protocol's frame is skipped by its length, if it has a length.
                Err(DecodeError::BadProtocolId { .. }) if len <= tcp::MAX_FRAME_LEN => {}
                // The stream cannot be framed any more.
                Err(_) => return Ok(()),
            }
            if pending.len() < len {
                break;
            }
            let header = tcp::Header {
                transaction: mbap.transaction,
                unit: mbap.unit,
            };
            let frame: Vec<u8> = pending.drain(..len).collect();
            if mbap.check().is_err() {
                continue;
            }
            // `check` holds a length of at least the unit id and a function code.
            let pdu = &frame[tcp::HEADER_LEN..];
            let Some((sim, slave)) = who.pick(mbap.unit) else {
                // No device at that unit id: answered 0B, as a gateway does.
                let reply = Reply::Exception {
                    function: pdu[0] & !EXCEPTION_BIT,
                    code: ExceptionCode(TARGET_FAILED),
                };
                if let Some(bytes) = reply.encode(Envelope::Tcp(header), ExceptionShape::Standard) {
                    stream.write_all(&bytes).await?;
                }
                continue;
            };
            let shape = sim.device().frame_shape;
            let request;
            let reply = match server::parse_request(pdu, &shape) {
                Ok(ServerRequest::Read {
                    function,
                    address,
                    count,
                }) => {
                    request = Request::Read {
                        function,
                        address,
                        count,
                    };
                    sim.respond(slave, Incoming::Request(&request))
                }
                Ok(ServerRequest::WriteSingle { address, value }) => {
                    request = Request::Write { address, value };
                    sim.respond(slave, Incoming::Request(&request))
                }
                // The devices served write one register at a time: FC16 is theirs to refuse.
                Ok(ServerRequest::WriteMultiple { .. }) => {
                    sim.respond(slave, Incoming::Unsupported(WRITE_MULTIPLE))
                }
                Err(RequestError::Unsupported { function }) => {
                    sim.respond(slave, Incoming::Unsupported(function))
                }
                Err(malformed) => Reply::Exception {
                    function: malformed.function(),
                    code: malformed.exception(),
                },
            };
            if let Some(bytes) = reply.encode(Envelope::Tcp(header), shape.exception) {
                if !sim.send_tcp(&mut stream, bytes).await? {
                    return Ok(());
                }
            }
        }
        let read = stream.read(&mut chunk).await?;
        if read == 0 {
            return Ok(());
        }
        pending.extend_from_slice(chunk.get(..read).unwrap_or_default());
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
