//! Following a subscription to the bus's events: the one receive / lagged / closed loop every
//! consumer of [`Bus::subscribe`](crate::Bus::subscribe) runs (the MQTT publisher, the metrics
//! exporter, the console, a run's recorder and display).
//!
//! A consumer too slow for the channel loses its oldest events (tokio's `broadcast`); a
//! [`Follower`] hands each loss to the consumer's own count, so that every output says how
//! many events it missed, and ends when the bus has stopped.

use std::future::Future;

use tokio::sync::broadcast::{self, error::RecvError, error::TryRecvError};

/// A subscription to the bus's events and where the events it misses are counted.
#[derive(Debug)]
pub struct Follower<E, M> {
    events: broadcast::Receiver<E>,
    missed: M,
}

impl<E: Clone, M: FnMut(u64)> Follower<E, M> {
    /// Follows `events`; `missed` is told how many events each lag cost (the receiver fell
    /// further behind than the channel holds).
    pub fn new(events: broadcast::Receiver<E>, missed: M) -> Self {
        Self { events, missed }
    }

    /// The next event; `None` once the bus has stopped. Cancel-safe (a lag is counted when it
    /// is seen, and no event is taken by a cancelled call).
    pub async fn next(&mut self) -> Option<E> {
        loop {
            match self.events.recv().await {
                Ok(event) => return Some(event),
                Err(RecvError::Lagged(count)) => (self.missed)(count),
                Err(RecvError::Closed) => return None,
            }
        }
    }

    /// The next event already waiting, without waiting; `None` when there is none.
    pub fn next_waiting(&mut self) -> Option<E> {
        loop {
            match self.events.try_recv() {
                Ok(event) => return Some(event),
                Err(TryRecvError::Lagged(count)) => (self.missed)(count),
                Err(TryRecvError::Empty | TryRecvError::Closed) => return None,
            }
        }
    }

    /// Gives every event to `take` until the bus stops or `stop` ends; then the events
    /// already waiting (the samples of the last poll before the stop, which a stop that won
    /// the race would leave behind).
    pub async fn until(&mut self, stop: impl Future<Output = ()>, mut take: impl FnMut(E)) {
        tokio::pin!(stop);
        loop {
            let event = tokio::select! {
                event = self.next() => event,
                () = &mut stop => break,
            };
            match event {
                Some(event) => take(event),
                None => return,
            }
        }
        while let Some(event) = self.next_waiting() {
            take(event);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sends the events `0..count` on a channel of `capacity`, then follows it with the stop
    /// already come: what was counted as missed, and the events taken.
    async fn sent_then_stopped(capacity: usize, count: u32) -> (u64, Vec<u32>) {
        let (sender, events) = broadcast::channel(capacity);
        for event in 0..count {
            sender.send(event).unwrap();
        }
        let mut missed = 0;
        let mut taken = Vec::new();
        Follower::new(events, |lost| missed += lost)
            .until(std::future::ready(()), |e| taken.push(e))
            .await;
        (missed, taken)
    }

    #[tokio::test]
    async fn with_duration_the_last_polls_samples_are_taken_at_the_stop() {
        // The last poll's events are in the receiver when the stop comes, in the same turn
        // of the runtime: every one of them is still taken.
        let (missed, taken) = sent_then_stopped(256, 100).await;
        assert_eq!(missed, 0);
        assert_eq!(taken, (0..100).collect::<Vec<_>>());
    }

    #[tokio::test]
    async fn events_beyond_the_channel_are_counted_as_missed() {
        let (missed, taken) = sent_then_stopped(4, 10).await;
        assert_eq!(missed, 6);
        assert_eq!(taken, [6, 7, 8, 9]);
    }

    #[tokio::test]
    async fn a_lag_while_waiting_is_counted_and_the_end_of_the_bus_ends_the_follow() {
        let (sender, events) = broadcast::channel(2);
        for event in 0..5u32 {
            sender.send(event).unwrap();
        }
        drop(sender);
        let mut missed = 0;
        let mut taken = Vec::new();
        let mut follower = Follower::new(events, |count| missed += count);
        while let Some(event) = follower.next().await {
            taken.push(event);
        }
        drop(follower);
        assert_eq!((missed, taken), (3, vec![3, 4]));
    }
}
