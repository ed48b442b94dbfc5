//! One transport shared by several drivers and tasks: each transaction holds the port.

use std::sync::Arc;

use tokio::sync::Mutex;

use optobus_codec::WriteValue;

use crate::error::Error;
use crate::transport::{ReadRequest, Transport};

/// A cloneable handle to one transport; transactions from all clones are serialised, so
/// sensors at different slave addresses on one serial line can be used from different tasks.
#[derive(Debug)]
pub struct Shared<T> {
    inner: Arc<Mutex<T>>,
}

impl<T> Clone for Shared<T> {
    fn clone(&self) -> Self {
        Self {
            inner: Arc::clone(&self.inner),
        }
    }
}

impl<T> Shared<T> {
    /// Wraps a transport for sharing.
    pub fn new(transport: T) -> Self {
        Self {
            inner: Arc::new(Mutex::new(transport)),
        }
    }
}

impl<T: Transport> Transport for Shared<T> {
    async fn read_words(&mut self, slave: u8, read: ReadRequest) -> Result<Vec<u16>, Error> {
        self.inner.lock().await.read_words(slave, read).await
    }

    async fn write(&mut self, slave: u8, address: u16, value: WriteValue) -> Result<(), Error> {
        self.inner.lock().await.write(slave, address, value).await
    }
}
