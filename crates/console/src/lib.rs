//! A console in the browser for a running [`optobus_bus`] bus: every device with its health,
//! live values with their units and a chart of the last minutes, the register map from the
//! spec with editing checked by the server, commands (drastic ones confirmed), the frame trace
//! of a device, and CSV export of what is on screen.
//!
//! The server is [axum](https://docs.rs/axum); the page, its script and its style are carried in
//! the binary (nothing is fetched from elsewhere at run time). What it serves:
//!
//! | Route | What |
//! |---|---|
//! | `GET /` | the page |
//! | `GET /api/devices` | the devices with their health and errors, and the lines' statistics |
//! | `GET /api/measurements` | the bus file's measurements: each with its unit, limits, latest value (exact text, number, reason, judgement, skew, statistics), its last 600 values and its judgement counts |
//! | `GET /api/values` | the latest value of every register polled, per device: its `text`, JSON `value`, `number` for charts, and for a packed or record register its `fields` (name, unit, text, number each, in the spec's order; the page shows a row per field); `current` is false once the device is down |
//! | `GET /api/devices/{device}` | the device's register map, commands and groups, from its spec |
//! | `GET /api/devices/{device}/frames` | its recent frames: direction, hex, time, reply delay |
//! | `POST /api/devices/{device}/read` | `{"register": "distance_1"}`: the register read now, between the polls (a line with the console's share already waiting answers `429` with `Retry-After`) |
//! | `POST /api/devices/{device}/set` | `{"register": "light_power", "value": "12.5 %"}`: set as `optobus set` does, if the bus file's `writable` lists it; the value read back. A JSON number (`"value": 12.5`) is taken as the text written, never through a float |
//! | `POST /api/devices/{device}/do` | `{"command": "zero_position_1"}`: run as `optobus do` does, if listed (a drastic one only when named there) |
//! | `POST /api/devices/{device}/buffer` | its data buffer read out (if `writable` lists the buffer's lock and unlock), as CSV: `index,time_s,value_UNIT` |
//! | `GET /api/stream` | server-sent events: a batch of samples, health, line statistics and measurement values every 100 ms |
//! | `GET /api/status` | the stream's clients and the batches dropped for slow ones, requests refused as busy, the listener's connections |
//!
//! Safe by default: it listens on 127.0.0.1; against DNS rebinding it answers only requests
//! whose `Host` is one of its names (the loopback's, then the bus file's `hosts:`, by default
//! the address it listens on, or any IP address at its port when bound to 0.0.0.0 or `::`), any
//! other with `421`; a request from a page of another origin is refused unless the bus file
//! lists that origin; bodies are limited to [`BODY_LIMIT`] bytes; every refusal is a 4xx whose
//! JSON `error` is the tool's one-line message. Writes are checked by the bus
//! ([`optobus_bus::Handle::set_listed`]): nothing refused reaches the line. Everything that
//! takes the line's time (writes, commands, reads now) is a POST with a JSON body, which no
//! page of another site can send without asking; a console given a token file, or listening
//! beyond the loopback, takes them only with its token (`Authorization: Bearer …`, the scheme
//! in any case); beyond the loopback without a token file it takes none. The console's jobs
//! have their own bounded queue on each line ([`optobus_bus::Source::Console`]): beyond it a
//! request is answered `429` at once and counted. The listener has the limits of
//! [`optobus_http`] ([`LIMITS`]): header, idle and request timeouts and a cap on connections.
//!
//! ```no_run
//! # async fn demo(running: &optobus_bus::Running) -> Result<(), Box<dyn std::error::Error>> {
//! let config = optobus_console::HttpConfig::new("127.0.0.1:8080".parse()?);
//! let server = optobus_console::serve(running, &config).await?;
//! println!("the console is on {}", server.url());
//! # Ok(())
//! # }
//! ```
#![forbid(unsafe_code)]

mod api;
mod batch;
mod error;
mod guard;
mod map;
mod page;
mod reply;
pub mod settings;
mod state;
mod stream;
mod write;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;

use axum::Router;
use optobus_bus::{Running, Source};
use optobus_http::Limits;

pub use batch::{BATCH_EVERY, BATCH_QUEUE};
pub use page::PAGE_BYTES;
pub use settings::{HttpConfig, DEFAULT_HTTP_PORT};

/// The limits of the console's listener: [`Limits::DEFAULT`] (a silent socket or a half-sent head
/// closed within 10 s, an idle connection after 15 s, a handler answers within 20 s, at most
/// 128 connections); the live stream is exempt from the request timeout but holds a
/// connection.
pub const LIMITS: Limits = Limits::DEFAULT;

/// The largest request body accepted, in bytes.
pub const BODY_LIMIT: usize = 4096;

/// Why the console cannot start.
#[derive(Debug)]
#[non_exhaustive]
pub enum ConsoleError {
    /// The token file cannot be read or holds no usable token.
    Token {
        /// The file.
        path: PathBuf,
        /// Why.
        why: String,
    },
    /// An entry of `hosts` names no host.
    Host {
        /// The entry.
        host: String,
    },
    /// The address cannot be listened on.
    Listen {
        /// The address.
        address: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
}

impl std::fmt::Display for ConsoleError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Token { path, why } => {
                write!(f, "the console's token file {}: {why}", path.display())
            }
            Self::Host { host } => write!(
                f,
                "the console's `hosts:` entry `{host}` is no host name (`name`, `name:port`, \
                 `192.0.2.7:8080` or `[2001:db8::7]:8080`)"
            ),
            Self::Listen { address, source } => {
                write!(f, "the console cannot listen on {address}: {source}")
            }
        }
    }
}

impl std::error::Error for ConsoleError {}

/// The console of a running bus: its router, and a task that follows the bus's events while
/// the bus runs and the router (or a clone of it) lives.
#[derive(Debug)]
pub struct Console {
    router: Router,
    shared: Arc<state::Shared>,
}

impl Console {
    /// The console of `running` as `config` sets it up, answering at `address` (the address
    /// it is reached at, which the `Host` check compares with). Subscribes to the bus's events
    /// at once: values sampled from now on are shown.
    pub fn new(
        running: &Running,
        config: &HttpConfig,
        address: SocketAddr,
    ) -> Result<Self, ConsoleError> {
        let guard = guard::Guard::new(config, address)?;
        let handle = running.handle().for_source(Source::Console);
        let shared = Arc::new(state::Shared::new(handle, guard));
        tokio::spawn(state::collect(Arc::downgrade(&shared), running.subscribe()));
        Ok(Self {
            router: api::router(Arc::clone(&shared)),
            shared,
        })
    }

    /// Its routes, to serve or to send requests to directly (tests).
    pub fn router(&self) -> Router {
        self.router.clone()
    }

    /// Batches of the live stream dropped because a client fell behind, since it started.
    pub fn dropped_batches(&self) -> u64 {
        self.shared.dropped()
    }
}

/// A console serving on its address; dropping it stops it and closes its connections.
#[derive(Debug)]
pub struct Server {
    console: Console,
    server: optobus_http::Server,
}

impl Server {
    /// Where it listens (its port, when the configuration asked for port 0).
    pub fn address(&self) -> SocketAddr {
        self.server.address()
    }

    /// The page's address, for people.
    pub fn url(&self) -> String {
        format!("http://{}/", self.address())
    }

    /// The console it serves.
    pub fn console(&self) -> &Console {
        &self.console
    }

    /// What the listener did with its connections so far.
    pub fn connections(&self) -> optobus_http::Counts {
        self.server.counts()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        // The live streams end, as a stopped process's would.
        self.console.shared.stopped.send_replace(true);
    }
}

/// Serves the console of `running` on `config.listen` (within a tokio runtime), with the
/// listener's [`LIMITS`].
pub async fn serve(running: &Running, config: &HttpConfig) -> Result<Server, ConsoleError> {
    serve_with_limits(running, config, LIMITS).await
}

/// Serves the console of `running` on `config.listen` with `limits` for its listener.
pub async fn serve_with_limits(
    running: &Running,
    config: &HttpConfig,
    limits: Limits,
) -> Result<Server, ConsoleError> {
    let listen_error = |source| ConsoleError::Listen {
        address: config.listen,
        source,
    };
    let listener = tokio::net::TcpListener::bind(config.listen)
        .await
        .map_err(listen_error)?;
    let address = listener.local_addr().map_err(listen_error)?;
    let console = Console::new(running, config, address)?;
    let server =
        optobus_http::Server::start(listener, console.router(), limits).map_err(listen_error)?;
    let _ = console.shared.connections.set(server.tally());
    Ok(Server { console, server })
}
