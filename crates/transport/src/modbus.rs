//! tokio-modbus as a backend: a bridge for users who share a tokio-modbus `Context` with
//! other Modbus devices.

use std::time::Duration;

use std::pin::Pin;

use tokio::time::{sleep, Sleep};
use tokio_modbus::client::{Client, Context};
use tokio_modbus::slave::{Slave, SlaveContext};
use tokio_modbus::ProtocolError;
use tokio_modbus::{Request, Response};

use crate::error::Error;
use crate::timing::deadline_after;
use crate::transport::{ReadRequest, Transport, DEFAULT_TIMEOUT};
use optobus_codec::{ExceptionCode, ReadFunction, WriteValue};

/// A tokio-modbus client context (TCP or RTU), possibly shared with other Modbus devices.
///
/// Requests go through `Client::call` and their replies are checked here, not through the
/// `read_*_registers` helpers, which `debug_assert!` on the word count a device returns.
///
/// # What it guarantees, and what it does not
///
/// A reply whose header or function code does not match the request is refused
/// ([`Error::Desynchronised`]), so no value of another request is returned. But tokio-modbus
/// reads one frame per request: after a reply arrives late (or a call is dropped), every later
/// call gets the reply of the call before it and fails, and a broken connection is not
/// re-established. Use [`crate::TcpClient`] (Modbus TCP: stale replies skipped, reconnects)
/// or [`crate::RtuClient`] (RTU: recovers the line after a fault) unless the context must be
/// shared.
pub struct ModbusContext {
    context: Context,
    timeout: Duration,
    /// One timer, re-armed for every request: cheaper than a new one each time.
    deadline: Pin<Box<Sleep>>,
}

impl std::fmt::Debug for ModbusContext {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ModbusContext")
            .field("timeout", &self.timeout)
            .finish_non_exhaustive()
    }
}

impl ModbusContext {
    /// Wraps a context with the default 1 s timeout.
    pub fn new(context: Context) -> Self {
        Self {
            context,
            timeout: DEFAULT_TIMEOUT,
            deadline: Box::pin(sleep(DEFAULT_TIMEOUT)),
        }
    }

    /// Sets the reply timeout.
    pub fn with_timeout(mut self, timeout: Duration) -> Self {
        self.timeout = timeout;
        self
    }

    /// Gives the context back.
    pub fn into_inner(self) -> Context {
        self.context
    }

    async fn call(&mut self, slave: u8, request: Request<'static>) -> Result<Response, Error> {
        let function = request.function_code().value();
        self.context.set_slave(Slave(slave));
        self.deadline.as_mut().reset(deadline_after(self.timeout));
        let outcome = tokio::select! {
            biased;
            outcome = self.context.call(request) => Some(outcome),
            () = self.deadline.as_mut() => None,
        };
        match outcome {
            None => Err(Error::Timeout {
                after: self.timeout,
            }),
            Some(outcome) => match outcome {
                Err(tokio_modbus::Error::Transport(error)) => Err(error.into()),
                Err(tokio_modbus::Error::Protocol(ProtocolError::HeaderMismatch { .. })) => Err(
                    Error::Desynchronised("tokio-modbus got a reply with another header"),
                ),
                Err(tokio_modbus::Error::Protocol(ProtocolError::FunctionCodeMismatch {
                    ..
                })) => Err(Error::Desynchronised(
                    "tokio-modbus got a reply with another function code",
                )),
                Ok(Err(code)) => Err(Error::Exception {
                    function,
                    code: ExceptionCode(u16::from(u8::from(code))),
                }),
                Ok(Ok(response)) => Ok(response),
            },
        }
    }
}

impl Transport for ModbusContext {
    async fn read_words(&mut self, slave: u8, read: ReadRequest) -> Result<Vec<u16>, Error> {
        // tokio-modbus makes one attempt: every read is read once.
        let ReadRequest {
            function,
            address,
            count,
            ..
        } = read;
        let request = match function {
            ReadFunction::Holding => Request::ReadHoldingRegisters(address, count),
            ReadFunction::Input => Request::ReadInputRegisters(address, count),
        };
        let words = match self.call(slave, request).await? {
            Response::ReadHoldingRegisters(words) | Response::ReadInputRegisters(words) => words,
            _ => {
                return Err(Error::Unsupported(
                    "tokio-modbus returned another response kind",
                ))
            }
        };
        if words.len() != usize::from(count) {
            return Err(Error::WordCount {
                expected: count,
                received: words.len(),
            });
        }
        Ok(words)
    }

    async fn write(&mut self, slave: u8, address: u16, value: WriteValue) -> Result<(), Error> {
        let WriteValue::Word(word) = value else {
            return Err(Error::Unsupported(
                "a 4-byte FC06 needs the optobus RTU client (tokio-modbus cannot frame it)",
            ));
        };
        if slave == 0 {
            return Err(Error::Unsupported(
                "tokio-modbus waits for a reply to a broadcast; use the optobus RTU client",
            ));
        }
        match self
            .call(slave, Request::WriteSingleRegister(address, word))
            .await?
        {
            Response::WriteSingleRegister(echo_address, echo)
                if (echo_address, echo) == (address, word) =>
            {
                Ok(())
            }
            Response::WriteSingleRegister(echo_address, echo) => {
                Err(Error::Frame(optobus_codec::DecodeError::EchoMismatch {
                    address,
                    value: u32::from(word),
                    received_address: echo_address,
                    received_value: u32::from(echo),
                }))
            }
            _ => Err(Error::Unsupported(
                "tokio-modbus returned another response kind",
            )),
        }
    }
}
