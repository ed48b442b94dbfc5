//! The [`Transport`] trait every client implements, and the [`ReadRequest`] it reads with.

use std::future::Future;
use std::time::Duration;

use optobus_codec::{ReadFunction, WriteValue};

use crate::error::Error;

/// The default time to wait for a reply.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_secs(1);

/// One read: `count` words from `address` with FC03 or FC04, and whether a failed attempt may
/// be tried again.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReadRequest {
    /// FC03 (holding registers) or FC04 (input registers).
    pub function: ReadFunction,
    /// The first register.
    pub address: u16,
    /// How many words.
    pub count: u16,
    /// False for registers whose read has a side effect (turns a buffer page), where a second
    /// attempt would read something else: one attempt whatever the retry setting.
    pub repeatable: bool,
}

impl ReadRequest {
    /// A repeatable read of `count` words from `address`.
    pub const fn new(function: ReadFunction, address: u16, count: u16) -> Self {
        Self {
            function,
            address,
            count,
            repeatable: true,
        }
    }

    /// The same read, made once whatever the retry setting.
    pub const fn once(self) -> Self {
        Self {
            repeatable: false,
            ..self
        }
    }
}

/// Reads and writes registers of Modbus slaves.
///
/// An implementor provides [`Transport::read_words`] and [`Transport::write`];
/// [`Transport::read`] is the shorthand for a repeatable read ([`ReadRequest::once`] marks a
/// read that must not be repeated).
pub trait Transport: Send {
    /// Carries out `read` at slave `slave`, retrying it (where the transport retries) only if
    /// it is repeatable.
    fn read_words(
        &mut self,
        slave: u8,
        read: ReadRequest,
    ) -> impl Future<Output = Result<Vec<u16>, Error>> + Send;

    /// Reads `count` words from `address` of slave `slave` with FC03 or FC04 (a repeatable
    /// read).
    fn read(
        &mut self,
        slave: u8,
        function: ReadFunction,
        address: u16,
        count: u16,
    ) -> impl Future<Output = Result<Vec<u16>, Error>> + Send {
        self.read_words(slave, ReadRequest::new(function, address, count))
    }

    /// Writes one register with FC06 (two or four data bytes). Slave 0 broadcasts: the write
    /// is sent and no reply is awaited.
    fn write(
        &mut self,
        slave: u8,
        address: u16,
        value: WriteValue,
    ) -> impl Future<Output = Result<(), Error>> + Send;
}
