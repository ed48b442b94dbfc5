//! A byte stream that shows what passes through it: a frame log, a byte count.

use std::io;
use std::pin::Pin;
use std::task::{Context, Poll};

use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};

/// Which way bytes passed through a [`Tap`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Flow {
    /// Written to the stream (requests, from a client).
    Sent,
    /// Read from the stream (replies, to a client).
    Received,
}

/// Sees the bytes passing through a [`Tap`]; any `FnMut(Flow, &[u8])` closure is one.
pub trait Observe: Unpin {
    /// Called with every chunk as it passes, in order.
    fn observe(&mut self, flow: Flow, bytes: &[u8]);
}

impl<F: FnMut(Flow, &[u8]) + Unpin> Observe for F {
    fn observe(&mut self, flow: Flow, bytes: &[u8]) {
        self(flow, bytes);
    }
}

/// A byte stream that hands every byte read or written to an observer, e.g. to count or time
/// what crossed a line (frames in hex are the [`frames`](crate::frames) events).
#[derive(Debug)]
pub struct Tap<S, O> {
    inner: S,
    observer: O,
}

impl<S, O: Observe> Tap<S, O> {
    /// `inner`, observed by `observer`.
    pub fn new(inner: S, observer: O) -> Self {
        Self { inner, observer }
    }

    /// Gives the stream back.
    pub fn into_inner(self) -> S {
        self.inner
    }
}

impl<S: AsyncRead + Unpin, O: Observe> AsyncRead for Tap<S, O> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let before = buf.filled().len();
        let polled = Pin::new(&mut self.inner).poll_read(cx, buf);
        if let Some(read) = buf.filled().get(before..).filter(|b| !b.is_empty()) {
            self.observer.observe(Flow::Received, read);
        }
        polled
    }
}

impl<S: AsyncWrite + Unpin, O: Observe> AsyncWrite for Tap<S, O> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bytes: &[u8],
    ) -> Poll<io::Result<usize>> {
        let polled = Pin::new(&mut self.inner).poll_write(cx, bytes);
        if let Poll::Ready(Ok(written)) = &polled {
            if let Some(sent) = bytes.get(..*written).filter(|b| !b.is_empty()) {
                self.observer.observe(Flow::Sent, sent);
            }
        }
        polled
    }

    fn poll_flush(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_flush(cx)
    }

    fn poll_shutdown(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.inner).poll_shutdown(cx)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tokio::io::{AsyncReadExt, AsyncWriteExt};

    #[tokio::test]
    async fn every_byte_is_seen_once_in_order() {
        let (a, mut b) = tokio::io::duplex(64);
        let mut seen = Vec::new();
        let mut tap = Tap::new(a, |flow: Flow, bytes: &[u8]| {
            seen.push((flow, bytes.to_vec()))
        });
        tap.write_all(&[1, 4, 0, 0]).await.unwrap();
        b.write_all(&[1, 4, 2]).await.unwrap();
        let mut reply = [0u8; 3];
        tap.read_exact(&mut reply).await.unwrap();
        drop(tap);
        assert_eq!(
            seen,
            [
                (Flow::Sent, vec![1, 4, 0, 0]),
                (Flow::Received, vec![1, 4, 2])
            ]
        );
    }
}
