//! Who asks a line for work besides its polls, and how much of it a line keeps queued for each.

/// Jobs a line keeps queued for an in-process caller ([`Source::Api`]), who waits for room.
pub(crate) const API_QUEUE: usize = 64;

/// Jobs a line keeps queued for each network source; one more is refused at once
/// ([`JobError::Busy`](crate::JobError::Busy)).
pub const NETWORK_QUEUE: usize = 8;

/// Who asks a line for work. Each source has its own bounded queue on every line, and the
/// line serves at most one job of each (and one gateway request per client) between its
/// polls: what the network asks for gets a bounded share of the line, the polls keep their
/// schedule.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Source {
    /// The program that runs the bus: it waits for room in its queue rather than being refused.
    Api,
    /// The console in the browser.
    Console,
    /// Writes arriving over MQTT.
    Mqtt,
}

impl Source {
    /// Every source, in the order a line serves them.
    pub const ALL: [Self; 3] = [Self::Api, Self::Console, Self::Mqtt];

    pub(crate) fn index(self) -> usize {
        match self {
            Self::Api => 0,
            Self::Console => 1,
            Self::Mqtt => 2,
        }
    }

    /// How many jobs a line keeps queued for it.
    pub(crate) fn queue(self) -> usize {
        match self {
            Self::Api => API_QUEUE,
            Self::Console | Self::Mqtt => NETWORK_QUEUE,
        }
    }

    /// Its name in messages and metrics.
    pub fn name(self) -> &'static str {
        match self {
            Self::Api => "api",
            Self::Console => "console",
            Self::Mqtt => "mqtt",
        }
    }
}
