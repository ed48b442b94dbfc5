//! Our own Modbus TCP client, built on `optobus-codec`: stale replies skipped by transaction
//! id, broken connections re-established with a bounded backoff.

use std::future::Future;
use std::io;
use std::net::SocketAddr;
use std::time::Duration;

use optobus_codec::{tcp, DecodeError, Decoded, ExceptionShape, Request, BROADCAST};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::time::{sleep_until, timeout_at, Instant};

use crate::error::Error;
use crate::frames;
use crate::timing::deadline_after;
use crate::transact::{Reply, Transact};
use crate::transport::DEFAULT_TIMEOUT;

/// Makes the connection a [`TcpClient`] talks over, again after it broke.
pub trait Connect: Send {
    /// The byte stream of one connection.
    type Stream: AsyncRead + AsyncWrite + Unpin + Send;

    /// Opens a new connection.
    fn connect(&mut self) -> impl Future<Output = io::Result<Self::Stream>> + Send;
}

/// The first socket address `address` resolves to: `host`, `host:port`, an IP address or
/// `[v6]:port`, with `default_port` where it names none.
pub async fn resolve(address: &str, default_port: u16) -> io::Result<SocketAddr> {
    let names_port = address.parse::<SocketAddr>().is_ok()
        || address
            .rsplit_once(':')
            .is_some_and(|(host, port)| !host.contains(':') && port.parse::<u16>().is_ok());
    let first = if names_port {
        tokio::net::lookup_host(address).await?.next()
    } else {
        tokio::net::lookup_host((address, default_port))
            .await?
            .next()
    };
    first.ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, "no address found"))
}

impl Connect for SocketAddr {
    type Stream = TcpStream;

    async fn connect(&mut self) -> io::Result<TcpStream> {
        let stream = TcpStream::connect(*self).await?;
        // Requests are single small frames: send each at once.
        stream.set_nodelay(true)?;
        Ok(stream)
    }
}

/// Settings of a [`TcpClient`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TcpConfig {
    /// How long to wait for a reply, and for a connection to open.
    pub timeout: Duration,
    /// How many times a failed read (timeout, garbled reply, lost connection) is tried again.
    /// Writes and reads that are not [repeatable](crate::ReadRequest::repeatable) are never
    /// retried.
    pub read_retries: u8,
    /// Wait before the first reconnection attempt after a failed one; doubled after every
    /// further failure.
    pub reconnect_delay: Duration,
    /// The longest wait between reconnection attempts.
    pub max_reconnect_delay: Duration,
    /// How the device frames exception replies.
    pub exception: ExceptionShape,
}

impl Default for TcpConfig {
    fn default() -> Self {
        Self {
            timeout: DEFAULT_TIMEOUT,
            read_retries: 0,
            reconnect_delay: Duration::from_millis(100),
            max_reconnect_delay: Duration::from_secs(5),
            exception: ExceptionShape::Standard,
        }
    }
}

/// Why the last connection attempt failed, and when the next may be made.
#[derive(Debug)]
struct Backoff {
    attempts: u32,
    kind: io::ErrorKind,
    message: String,
    next_attempt: Instant,
}

/// A Modbus TCP client.
///
/// # Guarantees
///
/// - A reply is taken only if its MBAP transaction id is the one of the request just sent.
///   A reply to an earlier request (one that timed out, or whose future was dropped) is
///   skipped and the client keeps waiting for its own until the deadline.
/// - A stream that can no longer be framed (an impossible MBAP header, bytes that are no
///   frame, half a frame left when the reply timed out), that ends or fails, or that a
///   dropped future left with half a request in it, is closed; the next request opens a new connection. After a failed attempt the next one
///   waits [`TcpConfig::reconnect_delay`], doubling up to
///   [`TcpConfig::max_reconnect_delay`]; a request whose deadline comes first fails with
///   [`Error::Connect`] at once instead of hammering the server.
/// - Errors are typed: [`Error::Timeout`], [`Error::Closed`], [`Error::Connect`],
///   [`Error::Frame`] (wrong unit, function, length…), [`Error::Exception`].
///
/// Modbus TCP carries no checksum; TCP's own guards the bytes.
#[derive(Debug)]
pub struct TcpClient<C: Connect = SocketAddr> {
    connector: C,
    config: TcpConfig,
    stream: Option<C::Stream>,
    /// A request is being written: if this is still set when the next one starts, the
    /// future was dropped mid-write and the stream holds half a frame.
    writing: bool,
    next_transaction: u16,
    /// Bytes received and not yet consumed, kept across transactions so that a reply cut
    /// off by a dropped future is still skipped whole.
    pending: Vec<u8>,
    backoff: Option<Backoff>,
    /// When the last request began to leave, once connected.
    last_request: Option<Instant>,
}

impl TcpClient<SocketAddr> {
    /// Connects to the Modbus TCP server at `address`.
    pub async fn connect(address: SocketAddr, config: TcpConfig) -> Result<Self, Error> {
        let mut client = Self::new(address, config);
        client.open().await?;
        Ok(client)
    }
}

impl<C: Connect> TcpClient<C> {
    /// A client that connects through `connector` when the first request is made.
    pub fn new(connector: C, config: TcpConfig) -> Self {
        Self {
            connector,
            config,
            stream: None,
            writing: false,
            next_transaction: 0,
            pending: Vec::with_capacity(tcp::MAX_FRAME_LEN),
            backoff: None,
            last_request: None,
        }
    }

    /// When the last request began to leave: after connecting, which can hold a request
    /// back past the call that made it.
    pub fn last_request(&self) -> Option<Instant> {
        self.last_request
    }

    /// The settings.
    pub fn config(&self) -> &TcpConfig {
        &self.config
    }

    /// Changes the settings.
    pub fn config_mut(&mut self) -> &mut TcpConfig {
        &mut self.config
    }

    /// Whether a connection is open now.
    pub fn is_connected(&self) -> bool {
        self.stream.is_some()
    }

    /// Opens the connection now, unless one is open (requests open it when needed too).
    pub async fn open(&mut self) -> Result<(), Error> {
        let deadline = deadline_after(self.config.timeout);
        self.connected(deadline).await
    }

    /// Closes the connection; the next request opens a new one.
    pub fn disconnect(&mut self) {
        self.stream = None;
        self.pending.clear();
        self.writing = false;
    }

    /// The open connection, opening one (after the backoff) if there is none.
    async fn connected(&mut self, deadline: Instant) -> Result<(), Error> {
        if self.writing {
            // A dropped future left half a request in the stream.
            self.disconnect();
        }
        if self.stream.is_none() {
            let stream = self.reconnect(deadline).await?;
            self.stream = Some(stream);
        }
        Ok(())
    }

    async fn reconnect(&mut self, deadline: Instant) -> Result<C::Stream, Error> {
        if let Some(backoff) = &self.backoff {
            if backoff.next_attempt > deadline {
                return Err(Error::Connect {
                    attempts: backoff.attempts,
                    source: io::Error::new(backoff.kind, backoff.message.clone()),
                });
            }
            sleep_until(backoff.next_attempt).await;
        }
        let outcome = match timeout_at(deadline, self.connector.connect()).await {
            Ok(outcome) => outcome,
            Err(_) => Err(io::Error::new(
                io::ErrorKind::TimedOut,
                format!(
                    "no connection within {} ms",
                    self.config.timeout.as_millis()
                ),
            )),
        };
        match outcome {
            Ok(stream) => {
                self.backoff = None;
                self.pending.clear();
                Ok(stream)
            }
            Err(error) => {
                let attempts = self.backoff.as_ref().map_or(1, |b| b.attempts + 1);
                let delay = self
                    .config
                    .reconnect_delay
                    .saturating_mul(1 << (attempts - 1).min(16))
                    .min(self.config.max_reconnect_delay);
                self.backoff = Some(Backoff {
                    attempts,
                    kind: error.kind(),
                    message: error.to_string(),
                    next_attempt: deadline_after(delay),
                });
                Err(Error::Connect {
                    attempts,
                    source: error,
                })
            }
        }
    }

    /// Fails the transaction and closes the connection, which cannot be trusted any more.
    fn broken(&mut self, error: Error) -> Error {
        self.disconnect();
        error
    }

    /// One request and its reply; `Ok(None)` for a broadcast.
    async fn transact(&mut self, unit: u8, request: Request) -> Result<Option<Reply>, Error> {
        let header = tcp::Header {
            transaction: self.next_transaction,
            unit,
        };
        let mut frame = [0u8; tcp::MAX_FRAME_LEN];
        let len = tcp::encode_request(&mut frame, header, &request).map_err(Error::Request)?;
        let deadline = deadline_after(self.config.timeout);
        self.next_transaction = self.next_transaction.wrapping_add(1);
        self.connected(deadline).await?;
        let Some(stream) = self.stream.as_mut() else {
            return Err(Error::Closed);
        };
        self.writing = true;
        self.last_request = Some(Instant::now());
        let written = async {
            stream.write_all(&frame[..len]).await?;
            stream.flush().await
        }
        .await;
        self.writing = false;
        if let Err(error) = written {
            return Err(self.broken(error.into()));
        }
        let written = Instant::now();
        frames::sent(unit, &frame[..len]);
        if unit == BROADCAST && matches!(request, Request::Write { .. }) {
            // Nothing answers a broadcast; a gateway's reply would be skipped as stale.
            return Ok(None);
        }
        loop {
            if let Some(outcome) = self.take_reply(header, &request, written) {
                return outcome.map(Some);
            }
            let Some(stream) = self.stream.as_mut() else {
                return Err(Error::Closed);
            };
            let mut chunk = [0u8; tcp::MAX_FRAME_LEN];
            match timeout_at(deadline, stream.read(&mut chunk)).await {
                Err(_) => {
                    let error = Error::Timeout {
                        after: self.config.timeout,
                    };
                    // Half a frame waiting means the stream lost a part: out of step.
                    if !self.pending.is_empty() {
                        let elapsed = written.elapsed();
                        frames::received(unit, &self.pending, elapsed, Some("incomplete"));
                        return Err(self.broken(error));
                    }
                    return Err(error);
                }
                Ok(Ok(0)) => return Err(self.broken(Error::Closed)),
                Ok(Ok(n)) => self.pending.extend_from_slice(&chunk[..n]),
                Ok(Err(error)) => return Err(self.broken(error.into())),
            }
        }
    }

    /// The outcome of the transaction if `pending` holds its reply; stale replies are
    /// skipped on the way. `None`: more bytes are needed.
    fn take_reply(
        &mut self,
        header: tcp::Header,
        request: &Request,
        written: Instant,
    ) -> Option<Result<Reply, Error>> {
        let unit = header.unit;
        loop {
            let decoded =
                tcp::decode_response(&self.pending, header, request, self.config.exception);
            let whole_frame = tcp::frame_len(&self.pending).filter(|&n| n <= self.pending.len());
            let outcome = match decoded {
                Ok(Decoded::NeedMore { .. }) => return None,
                Ok(Decoded::Frame { frame, consumed }) => {
                    let bytes = &self.pending[..consumed];
                    frames::received(unit, bytes, written.elapsed(), None);
                    let reply = Reply::from(frame);
                    self.pending.drain(..consumed);
                    return Some(Ok(reply));
                }
                // A reply to an earlier request: skip it whole and keep waiting.
                Err(DecodeError::UnexpectedTransaction { .. }) => match whole_frame {
                    Some(len) => {
                        let stale = &self.pending[..len];
                        frames::received(unit, stale, written.elapsed(), Some("stale"));
                        self.pending.drain(..len);
                        continue;
                    }
                    None => return None,
                },
                Err(
                    error @ (DecodeError::BadProtocolId { .. } | DecodeError::BadLength { .. }),
                ) => {
                    // No frame boundary can be trusted any more.
                    frames::received(unit, &self.pending, written.elapsed(), Some("garbled"));
                    return Some(Err(self.broken(Error::Frame(error))));
                }
                Err(DecodeError::Exception { function, code }) => {
                    Err(Error::Exception { function, code })
                }
                Err(error) => Err(Error::Frame(error)),
            };
            // Our transaction's frame, but an exception or not what was asked: consume it
            // by its MBAP length, which was checked.
            return match whole_frame {
                Some(len) => {
                    let bytes = &self.pending[..len];
                    let what = matches!(outcome, Err(Error::Frame(_))).then_some("garbled");
                    frames::received(unit, bytes, written.elapsed(), what);
                    self.pending.drain(..len);
                    Some(outcome)
                }
                None => {
                    frames::received(unit, &self.pending, written.elapsed(), Some("garbled"));
                    Some(outcome.map_err(|error| self.broken(error)))
                }
            };
        }
    }
}

impl<C: Connect> Transact for TcpClient<C> {
    async fn transact(&mut self, unit: u8, request: Request) -> Result<Option<Reply>, Error> {
        TcpClient::transact(self, unit, request).await
    }

    fn read_retries(&self) -> u8 {
        self.config.read_retries
    }
}
