//! Our own Modbus RTU client over any byte stream, built on `optobus-codec`.

use std::time::Duration;

use optobus_codec::{rtu, DecodeError, Decoded, ExceptionShape, Request, Response};
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::time::{sleep_until, timeout, timeout_at, Instant};

use crate::{Error, ReadFunction, Transport, WriteValue, DEFAULT_TIMEOUT};

/// Settings of an [`RtuClient`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RtuConfig {
    /// How long to wait for a reply.
    pub timeout: Duration,
    /// How many times a failed read (timeout or garbled reply) is tried again. Writes are
    /// never retried.
    pub read_retries: u8,
    /// Line speed, which sets the 3.5-character silence between frames.
    pub baud: u32,
    /// How the device frames exception replies.
    pub exception: ExceptionShape,
}

impl Default for RtuConfig {
    fn default() -> Self {
        Self {
            timeout: DEFAULT_TIMEOUT,
            read_retries: 0,
            baud: 115_200,
            exception: ExceptionShape::Standard,
        }
    }
}

impl RtuConfig {
    /// The silence that separates frames: 3.5 characters of 11 bits, and 1.75 ms above
    /// 19200 baud (the Modbus serial line specification).
    pub fn frame_gap(&self) -> Duration {
        if self.baud > 19_200 || self.baud == 0 {
            Duration::from_micros(1_750)
        } else {
            Duration::from_micros(38_500_000 / u64::from(self.baud))
        }
    }
}

/// A Modbus RTU client over `stream`.
#[derive(Debug)]
pub struct RtuClient<S> {
    stream: S,
    config: RtuConfig,
    /// When the line was last busy (a byte sent or received).
    last_activity: Option<Instant>,
    buffer: Box<[u8; rtu::MAX_FRAME_LEN + 4]>,
}

impl<S: AsyncRead + AsyncWrite + Unpin + Send> RtuClient<S> {
    /// A client with default settings (1 s timeout, no retries, 115200 baud, standard
    /// exceptions).
    pub fn new(stream: S) -> Self {
        Self::with_config(stream, RtuConfig::default())
    }

    /// A client with `config`.
    pub fn with_config(stream: S, config: RtuConfig) -> Self {
        Self {
            stream,
            config,
            last_activity: None,
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

    /// Waits until the line has been silent for a frame gap.
    async fn wait_for_silence(&mut self) {
        if let Some(last) = self.last_activity {
            sleep_until(last + self.config.frame_gap()).await;
        }
    }

    /// Discards bytes already waiting (a late reply to an earlier request, line noise).
    async fn drain(&mut self) -> Result<(), Error> {
        loop {
            match timeout(Duration::ZERO, self.stream.read(&mut self.buffer[..])).await {
                Ok(Ok(0)) => return Err(Error::Closed),
                Ok(Ok(_)) => self.last_activity = Some(Instant::now()),
                Ok(Err(error)) => return Err(Error::Io(error)),
                Err(_) => return Ok(()),
            }
        }
    }

    /// After a garbled reply: discard bytes until the line is silent for a frame gap, so that
    /// the next transaction starts clean.
    async fn resynchronise(&mut self, deadline: Instant) {
        let gap = self.config.frame_gap();
        loop {
            let quiet_until = Instant::now() + gap;
            match timeout_at(
                quiet_until.min(deadline),
                self.stream.read(&mut self.buffer[..]),
            )
            .await
            {
                Ok(Ok(n)) if n > 0 && Instant::now() < deadline => {
                    self.last_activity = Some(Instant::now());
                }
                _ => return,
            }
        }
    }

    /// One request and its reply; `Ok(None)` for a broadcast.
    async fn transact(&mut self, slave: u8, request: Request) -> Result<Option<Reply>, Error> {
        let mut frame = [0u8; rtu::MAX_FRAME_LEN];
        let len = rtu::encode_request(&mut frame, slave, &request).map_err(Error::Request)?;
        self.wait_for_silence().await;
        self.drain().await?;
        self.stream.write_all(&frame[..len]).await?;
        self.stream.flush().await?;
        self.last_activity = Some(Instant::now());
        if slave == 0 {
            return Ok(None);
        }
        let deadline = Instant::now() + self.config.timeout;
        let mut filled = 0;
        loop {
            match rtu::decode_response(
                &self.buffer[..filled],
                slave,
                &request,
                self.config.exception,
            ) {
                Ok(Decoded::Frame { frame, .. }) => return Ok(Some(Reply::from(frame))),
                Ok(Decoded::NeedMore { .. }) => {}
                Err(DecodeError::Exception { function, code }) => {
                    return Err(Error::Exception { function, code })
                }
                Err(error) => {
                    self.resynchronise(deadline).await;
                    return Err(Error::Frame(error));
                }
            }
            let room = &mut self.buffer[filled..];
            match timeout_at(deadline, self.stream.read(room)).await {
                Err(_) => {
                    return Err(Error::Timeout {
                        after: self.config.timeout,
                    })
                }
                Ok(Ok(0)) => return Err(Error::Closed),
                Ok(Ok(n)) => {
                    filled += n;
                    self.last_activity = Some(Instant::now());
                }
                Ok(Err(error)) => return Err(Error::Io(error)),
            }
        }
    }
}

/// A reply with its data copied out of the receive buffer.
enum Reply {
    Words(Vec<u16>),
    Written,
}

impl From<Response<'_>> for Reply {
    fn from(response: Response<'_>) -> Self {
        match response {
            Response::Read { words, .. } => Self::Words(words.iter().collect()),
            Response::Write { .. } => Self::Written,
        }
    }
}

impl<S: AsyncRead + AsyncWrite + Unpin + Send> Transport for RtuClient<S> {
    async fn read(
        &mut self,
        slave: u8,
        function: ReadFunction,
        address: u16,
        count: u16,
    ) -> Result<Vec<u16>, Error> {
        if slave == 0 {
            return Err(Error::Unsupported("a broadcast read gets no reply"));
        }
        let request = Request::Read {
            function,
            address,
            count,
        };
        let mut attempts_left = self.config.read_retries;
        loop {
            match self.transact(slave, request).await {
                Ok(Some(Reply::Words(words))) => return Ok(words),
                Ok(_) => return Err(Error::Unsupported("a read got no words")),
                Err(error) if error.is_transient() && attempts_left > 0 => attempts_left -= 1,
                Err(error) => return Err(error),
            }
        }
    }

    async fn write(&mut self, slave: u8, address: u16, value: WriteValue) -> Result<(), Error> {
        match self
            .transact(slave, Request::Write { address, value })
            .await?
        {
            Some(Reply::Written) | None => Ok(()),
            Some(Reply::Words(_)) => Err(Error::Unsupported("a write got words back")),
        }
    }
}
