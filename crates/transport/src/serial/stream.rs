//! A serial port in tokio's reactor only while a read or a write waits for it.

use std::io::{self, Read, Write};
use std::pin::Pin;
use std::task::{Context, Poll};

use crate::no_wait::is_nobody;

use tokio::io::unix::AsyncFd;
use tokio::io::{AsyncRead, AsyncWrite, Interest, ReadBuf};

/// An open serial port (see [`SerialSettings::open`](crate::SerialSettings::open)): a
/// non-blocking descriptor that tokio's reactor watches only while a read or a write waits
/// for it.
///
/// Why not tokio-serial's stream: it stays in the reactor, whose edge-triggered epoll wakes
/// the runtime's thread for every byte that arrives, also while nobody reads. The RTU client
/// sleeps while a reply crosses the line and reads it whole near its end; a line delivering a
/// character at a time (a line-timed pty, a UART without a FIFO) would still wake the thread
/// once per character, some 20 times a transaction. This stream leaves the reactor as soon as
/// no read or write is waiting, so bytes arriving meanwhile wake nobody.
#[derive(Debug)]
pub struct SerialStream {
    port: Port,
    /// The last read returned `Pending`: its waker must be told when bytes come.
    read_waits: bool,
    /// The last write or flush returned `Pending`.
    write_waits: bool,
}

#[derive(Debug)]
enum Port {
    /// Out of the reactor.
    Idle(mio_serial::SerialStream),
    /// In the reactor, for these interests.
    Watched(AsyncFd<mio_serial::SerialStream>, Interest),
    /// Only while moving between the two (never seen by a caller unless a registration
    /// failed and gave the port back broken, which it does not).
    Moving,
}

impl SerialStream {
    pub(crate) fn new(port: mio_serial::SerialStream) -> Self {
        Self {
            port: Port::Idle(port),
            read_waits: false,
            write_waits: false,
        }
    }

    /// The port for a system call that does not wait.
    fn port(&self) -> io::Result<&mio_serial::SerialStream> {
        match &self.port {
            Port::Idle(port) => Ok(port),
            Port::Watched(fd, _) => Ok(fd.get_ref()),
            Port::Moving => Err(lost()),
        }
    }

    /// Puts the port in the reactor for `interest` too, if it is not watched for it yet.
    fn watch(&mut self, interest: Interest) -> io::Result<()> {
        let wanted = match &self.port {
            Port::Watched(_, watched) if covers(*watched, interest) => return Ok(()),
            Port::Watched(_, watched) => watched.add(interest),
            _ => interest,
        };
        let port = match std::mem::replace(&mut self.port, Port::Moving) {
            Port::Idle(port) => port,
            Port::Watched(fd, _) => fd.into_inner(),
            Port::Moving => return Err(lost()),
        };
        // tokio 1.54 deprecates the safe constructors for the `unsafe`
        // `register_with_interest` (a type whose `as_raw_fd` could change while registered);
        // the port owns its descriptor for its whole life.
        #[allow(deprecated)]
        match AsyncFd::try_with_interest(port, wanted) {
            Ok(fd) => {
                self.port = Port::Watched(fd, wanted);
                // Precise waits may now use timerfds in this runtime's reactor.
                #[cfg(target_os = "linux")]
                crate::timing::runtime_has_io();
                Ok(())
            }
            Err(error) => {
                let (port, error) = error.into_parts();
                self.port = Port::Idle(port);
                Err(error)
            }
        }
    }

    /// Takes the port out of the reactor once nothing waits for it.
    fn unwatch_if_unwaited(&mut self) {
        if self.read_waits || self.write_waits || !matches!(self.port, Port::Watched(..)) {
            return;
        }
        if let Port::Watched(fd, _) = std::mem::replace(&mut self.port, Port::Moving) {
            self.port = Port::Idle(fd.into_inner());
        }
    }

    /// Runs `io` until it does not block; when it does, waits for `interest` in the reactor.
    fn poll_io<R>(
        &mut self,
        cx: &mut Context<'_>,
        interest: Interest,
        mut io: impl FnMut(&mio_serial::SerialStream) -> io::Result<R>,
    ) -> Poll<io::Result<R>> {
        let reading = interest.is_readable();
        loop {
            let result = match &self.port {
                // Out of the reactor: try first, register only if it would block.
                Port::Idle(port) => io(port),
                Port::Watched(fd, watched) if covers(*watched, interest) => {
                    let ready = if reading {
                        fd.poll_read_ready(cx)
                    } else {
                        fd.poll_write_ready(cx)
                    };
                    match ready {
                        Poll::Ready(Ok(mut guard)) => match guard.try_io(|fd| io(fd.get_ref())) {
                            Ok(result) => result,
                            // The readiness was stale and is cleared: poll it again.
                            Err(_would_block) => continue,
                        },
                        Poll::Ready(Err(error)) => Err(error),
                        Poll::Pending => {
                            *self.waits(reading) = true;
                            return Poll::Pending;
                        }
                    }
                }
                // Watched for the other direction only: try first, as out of it.
                Port::Watched(fd, _) => io(fd.get_ref()),
                Port::Moving => Err(lost()),
            };
            match result {
                // A caller that will not wait (a no-op waker: the RTU client looking for
                // stray bytes) leaves the port out of the reactor: two system calls saved.
                Err(error)
                    if error.kind() == io::ErrorKind::WouldBlock && is_nobody(cx.waker()) =>
                {
                    return Poll::Pending;
                }
                // Watched from now on; the next pass waits for readiness (epoll reports a
                // descriptor that is already ready when it is added).
                Err(error) if error.kind() == io::ErrorKind::WouldBlock => {
                    if let Err(error) = self.watch(interest) {
                        *self.waits(reading) = false;
                        return Poll::Ready(Err(error));
                    }
                }
                result => {
                    *self.waits(reading) = false;
                    self.unwatch_if_unwaited();
                    return Poll::Ready(result);
                }
            }
        }
    }

    fn waits(&mut self, reading: bool) -> &mut bool {
        if reading {
            &mut self.read_waits
        } else {
            &mut self.write_waits
        }
    }
}

/// `watched` includes `interest`.
fn covers(watched: Interest, interest: Interest) -> bool {
    (watched.is_readable() || !interest.is_readable())
        && (watched.is_writable() || !interest.is_writable())
}

fn lost() -> io::Error {
    io::Error::other("serial port lost")
}

impl AsyncRead for SerialStream {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        // No room: nothing to read, and a read that waited before is given up (its caller
        // polls no more), so the port leaves the reactor: bytes arriving while the RTU client
        // sleeps through a reply would wake the thread each.
        if buf.remaining() == 0 {
            this.read_waits = false;
            this.unwatch_if_unwaited();
            return Poll::Ready(Ok(()));
        }
        let unfilled = buf.initialize_unfilled();
        match this.poll_io(cx, Interest::READABLE, |mut port| port.read(unfilled)) {
            Poll::Ready(Ok(read)) => {
                buf.advance(read);
                Poll::Ready(Ok(()))
            }
            Poll::Ready(Err(error)) => Poll::Ready(Err(error)),
            Poll::Pending => Poll::Pending,
        }
    }
}

impl AsyncWrite for SerialStream {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        self.get_mut()
            .poll_io(cx, Interest::WRITABLE, |mut port| port.write(buf))
    }

    /// Nothing to do: a write hands its bytes to the kernel's driver, which sends them, and
    /// the RTU client times the line itself. Waiting until they have left (`tcdrain`, as
    /// tokio-serial's flush does) would block the runtime's thread while they go (8.3 ms for
    /// a request at 9600 baud) and cost a system call a request.
    fn poll_flush(self: Pin<&mut Self>, _cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Poll::Ready(self.port().map(|_| ()))
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        self.poll_flush(cx)
    }
}
