//! One line's client (the transport's [`Client`]), and each device's view of it: the device's own timeout, retries,
//! exception framing and silences applied to every request it makes.

use std::sync::Arc;
use std::time::Duration;

use optobus_codec::{ExceptionShape, WriteValue};
use optobus_transport::{Client, Error, ReadRequest, Requests, Transport};
use tokio::sync::Mutex;
use tokio::time::Instant;

use crate::event::ErrorCounts;
use crate::trace::LineFrames;

/// How a device's requests are made.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DeviceSettings {
    pub(crate) timeout: Duration,
    pub(crate) retries: u8,
    pub(crate) exception: ExceptionShape,
    pub(crate) silence_before: Duration,
    pub(crate) silence_after: Duration,
}

impl DeviceSettings {
    /// For a slave the bus file does not describe: the default timeout, no retries, standard
    /// framing, no extra silence.
    pub(crate) fn standard() -> Self {
        Self {
            timeout: optobus_transport::DEFAULT_TIMEOUT,
            retries: 0,
            exception: ExceptionShape::Standard,
            silence_before: Duration::ZERO,
            silence_after: Duration::ZERO,
        }
    }
}

/// A line's client and what it has done.
#[derive(Debug)]
pub(crate) struct LineState {
    /// `None` while the port is closed.
    pub(crate) client: Option<Client>,
    /// t3.5 of the line's format (zero on Modbus TCP).
    pub(crate) frame_gap: Duration,
    /// Silence owed before the next request, set by the last device's `silence_after` or a
    /// broadcast's turnaround.
    pub(crate) owed: Duration,
    pub(crate) transactions: u64,
    pub(crate) errors: ErrorCounts,
    pub(crate) busy: Duration,
    /// The port failed in a way that needs it reopened.
    pub(crate) broken: bool,
    /// The recent frames of the line's devices.
    pub(crate) frames: Arc<LineFrames>,
}

impl LineState {
    pub(crate) fn new(frame_gap: Duration, frames: Arc<LineFrames>) -> Self {
        Self {
            client: None,
            frame_gap,
            owed: Duration::ZERO,
            transactions: 0,
            errors: ErrorCounts::default(),
            busy: Duration::ZERO,
            broken: false,
            frames,
        }
    }
}

/// Counts `error` in `counts`.
pub(crate) fn count(counts: &mut ErrorCounts, error: &Error) {
    match error {
        Error::Timeout { .. } => counts.timeouts += 1,
        Error::Exception { .. } => counts.exceptions += 1,
        Error::Frame(_) | Error::WordCount { .. } | Error::Desynchronised(_) => counts.frames += 1,
        _ => counts.line += 1,
    }
}

/// Whether `error` means the port itself must be reopened.
fn breaks_the_port(error: &Error) -> bool {
    matches!(error, Error::Closed | Error::Io(_))
}

/// A device's handle on its line: what its driver core talks through.
#[derive(Clone, Debug)]
pub(crate) struct DeviceLink {
    pub(crate) line: Arc<Mutex<LineState>>,
    pub(crate) settings: DeviceSettings,
    /// Its index among its line's devices.
    pub(crate) index: usize,
    /// This device's errors.
    pub(crate) errors: Arc<std::sync::Mutex<ErrorCounts>>,
}

impl LineState {
    /// The client, set up for a request to device `device` of the line (`None`: a slave the
    /// bus file does not name) with `settings`; `Closed` while the port is.
    pub(crate) fn client_for(
        &mut self,
        device: Option<usize>,
        settings: &DeviceSettings,
    ) -> Result<&mut Client, Error> {
        self.frames.begin(device);
        let gap = self.owed.max(self.frame_gap + settings.silence_before);
        let client = self.client.as_mut().ok_or(Error::Closed)?;
        client.set_requests(Requests {
            timeout: settings.timeout,
            retries: settings.retries,
            exception: settings.exception,
        });
        // Without the `tcp` feature an RTU client is the only kind.
        #[allow(irrefutable_let_patterns)]
        if let Client::Rtu(rtu) = client {
            rtu.config_mut().frame_gap = Some(gap);
        }
        Ok(client)
    }

    /// Counts a finished request made with `settings`: its time, its error, the silence it
    /// leaves owed.
    pub(crate) fn record<R>(
        &mut self,
        settings: &DeviceSettings,
        started: Instant,
        result: &Result<R, Error>,
    ) {
        self.busy += started.elapsed();
        self.transactions += 1;
        self.owed = settings.silence_after;
        if let Err(error) = result {
            count(&mut self.errors, error);
            if breaks_the_port(error) {
                self.broken = true;
            }
        }
    }
}

impl DeviceLink {
    fn count_error<R>(&self, result: &Result<R, Error>) {
        if let Err(error) = result {
            count(
                &mut self.errors.lock().unwrap_or_else(|e| e.into_inner()),
                error,
            );
        }
    }
}

impl Transport for DeviceLink {
    async fn read_words(&mut self, slave: u8, read: ReadRequest) -> Result<Vec<u16>, Error> {
        let mut line = self.line.lock().await;
        let started = Instant::now();
        let result = line
            .client_for(Some(self.index), &self.settings)?
            .read_words(slave, read)
            .await;
        line.record(&self.settings, started, &result);
        self.count_error(&result);
        result
    }

    async fn write(&mut self, slave: u8, address: u16, value: WriteValue) -> Result<(), Error> {
        let mut line = self.line.lock().await;
        let started = Instant::now();
        let result = line
            .client_for(Some(self.index), &self.settings)?
            .write(slave, address, value)
            .await;
        line.record(&self.settings, started, &result);
        self.count_error(&result);
        result
    }
}
