//! A waker that does nothing, by which a caller polling a stream tells it that no read will
//! wait: the transport's serial port then stays out of tokio's reactor.

use std::sync::{Arc, LazyLock};
use std::task::{Wake, Waker};

struct Nobody;

impl Wake for Nobody {
    fn wake(self: Arc<Self>) {}
}

static NOBODY: LazyLock<Waker> = LazyLock::new(|| Waker::from(Arc::new(Nobody)));

/// The waker to poll a stream with when no read will wait for what the poll did not find
/// (the RTU client's look for stray bytes): the transport's serial port then stays out of
/// tokio's reactor, where bytes arriving would wake the thread each.
pub fn nobody_waits() -> &'static Waker {
    &NOBODY
}

/// `waker` is [`nobody_waits`]'s (compared by its data, which is unique to it; a waker's vtable
/// address need not be).
#[cfg(all(feature = "serial", unix))]
pub(crate) fn is_nobody(waker: &Waker) -> bool {
    waker.data() == NOBODY.data()
}
