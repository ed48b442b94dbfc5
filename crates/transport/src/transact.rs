//! What the optobus clients share: one request and its reply, retried where allowed.

use std::future::Future;

use optobus_codec::{Request, Response};

use optobus_codec::WriteValue;

use crate::error::Error;
use crate::transport::{ReadRequest, Transport};

/// A reply with its data copied out of the receive buffer.
pub(crate) enum Reply {
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

/// A client that can carry out one transaction; [`Transport`] follows.
pub(crate) trait Transact: Send {
    /// One request and its reply; `Ok(None)` for a broadcast.
    fn transact(
        &mut self,
        slave: u8,
        request: Request,
    ) -> impl Future<Output = Result<Option<Reply>, Error>> + Send;

    /// How often a failed repeatable read is tried again.
    fn read_retries(&self) -> u8;
}

impl<T: Transact> Transport for T {
    async fn read_words(&mut self, slave: u8, read: ReadRequest) -> Result<Vec<u16>, Error> {
        let mut attempts_left = if read.repeatable {
            self.read_retries()
        } else {
            0
        };
        let request = Request::Read {
            function: read.function,
            address: read.address,
            count: read.count,
        };
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
