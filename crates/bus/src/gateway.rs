//! A Modbus TCP gateway onto an RTU line, as mbusd is, inside the bus: other masters (a PLC,
//! SCADA, a configuration tool) reach the line's devices while the bus keeps its schedule.
//!
//! Each connection has one request in flight; requests of all connections wait in one bounded
//! queue that the line takes from between its own polls, so clients are served in turn and
//! each request waits for at most one poll. A request beyond the queue is answered busy (0x06)
//! at once. A reply goes back under its request's MBAP header; a device that does not answer
//! in time gives exception 0x0B, a line that cannot be used 0x0A.
//!
//! What can never be carried is answered here, before the queue: a request whose length or
//! counts do not fit its function 0x03, a function whose reply cannot be framed on RTU or a
//! write the bus file does not allow 0x01, a read to the broadcast address (nobody would
//! answer) 0x01, a unit id RTU reserves (248 to 255) 0x0A. A write to one of the bus's
//! devices is checked against its spec by the line (0x02 for an address that holds nothing
//! writable, 0x03 for a value it refuses): nothing invalid reaches the line.
//!
//! A client that sends no whole request for the `idle` time, or does not take its reply
//! within it, is closed. At the client limit a new client closes the one idle the longest (no
//! request in flight), as mbusd and mosquitto do; it is refused only when every client has a
//! request in flight. Everything refused and closed is counted ([`GatewayCounts`]).
//!
//! Where the bus file has measurements, the gateway answers their unit id (`measurements_unit`)
//! itself, from the measurements' latest values (`crate::measurement_unit`): nothing of it
//! reaches the line.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use optobus_codec::passthrough::{encode_tcp_reply, words, Access, PassPdu, MAX_PDU_LEN};
use optobus_codec::tcp::{Header, Mbap, HEADER_LEN};
use optobus_codec::{EncodeError, EXCEPTION_BIT, MAX_SLAVE};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc::error::TrySendError;
use tokio::sync::{mpsc, oneshot};
use tokio::task::{AbortHandle, JoinSet};
use tokio::time::{timeout, Instant};

use crate::file::GatewayConfig;
use crate::measurement_unit::MeasurementUnit;
use crate::policy::{Refusal, RefusalKind};

/// Illegal function: not passed (unframable, or a write the bus file does not allow).
pub(crate) const ILLEGAL_FUNCTION: u8 = 0x01;
/// Illegal data address: a write to an address that holds nothing writable.
pub(crate) const ILLEGAL_ADDRESS: u8 = 0x02;
/// Illegal data value: a write of a value the register refuses.
pub(crate) const ILLEGAL_VALUE: u8 = 0x03;
/// Server device busy: the queue to the line is full.
pub(crate) const BUSY: u8 = 0x06;
/// Gateway path unavailable: the line cannot be used.
pub(crate) const PATH_UNAVAILABLE: u8 = 0x0A;
/// Gateway target device failed to respond.
pub(crate) const TARGET_FAILED: u8 = 0x0B;

/// A client's request, waiting for the line.
#[derive(Debug)]
pub(crate) struct GatewayRequest {
    /// The client who asked, for the audit trail.
    pub(crate) client: SocketAddr,
    pub(crate) unit: u8,
    pub(crate) pdu: Vec<u8>,
    /// The reply PDU, or `None` for a broadcast (nothing is sent back).
    pub(crate) reply: oneshot::Sender<Option<Vec<u8>>>,
}

/// The exception reply PDU to a request of `function`.
pub(crate) fn exception(function: u8, code: u8) -> Vec<u8> {
    optobus_codec::server::exception_pdu(function, code).to_vec()
}

/// Tells the audit trail ([`AUDIT_TARGET`](crate::AUDIT_TARGET)) of a write that `client`
/// asked of slave `unit` and how it went: `reply` is what went back (an exception's code says
/// why it was not done).
pub(crate) fn audit_write(
    client: SocketAddr,
    unit: u8,
    pdu: &[u8],
    reply: Option<&[u8]>,
    why: Option<&str>,
) {
    let what = match PassPdu::new(pdu).map(|pass| pass.access()) {
        Ok(Access::WriteRegisters { address, data }) => {
            let words: Vec<u16> = words(data).collect();
            format!("FC{:02X} to slave {unit} at {address}: {words:?}", pdu[0])
        }
        _ => format!(
            "FC{:02X} to slave {unit}: {}",
            pdu[0],
            optobus_codec::Hex(pdu)
        ),
    };
    let exception = reply.filter(|r| r.first().is_some_and(|f| f & EXCEPTION_BIT != 0));
    match (reply, exception) {
        (None, _) => {
            tracing::info!(target: crate::AUDIT_TARGET, "gateway {client}: {what}: broadcast")
        }
        (Some(_), None) => {
            tracing::info!(target: crate::AUDIT_TARGET, "gateway {client}: {what}: done")
        }
        (Some(_), Some(exception)) => {
            let code = exception.get(1).copied().unwrap_or_default();
            let why = why.map(|why| format!(": {why}")).unwrap_or_default();
            tracing::warn!(target: crate::AUDIT_TARGET, "gateway {client}: {what}: not done, exception {code:02X}{why}");
        }
    }
}

/// The exception a request the write policy refused is answered with.
pub(crate) fn refused(refusal: &Refusal) -> u8 {
    match refusal.kind() {
        RefusalKind::NotAllowed => ILLEGAL_FUNCTION,
        RefusalKind::Address => ILLEGAL_ADDRESS,
        RefusalKind::Value => ILLEGAL_VALUE,
        RefusalKind::NoDevice => TARGET_FAILED,
    }
}

/// What a gateway has passed, refused and closed since it started
/// ([`Running::gateway_counts`](crate::Running::gateway_counts)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GatewayCounts {
    /// Requests passed to the line.
    pub requests: u64,
    /// Requests answered busy (exception 06) at once: `queue` requests were waiting for the
    /// line already.
    pub busy: u64,
    /// Requests answered at once with exception 03: their length or counts do not fit their
    /// function (a 2-byte FC03, a read of 0 registers).
    pub malformed: u64,
    /// Requests the write policy refused (exception 01, 02 or 03): a write the bus file's
    /// `writable` does not list or a value the spec refuses, the slave address, a read that
    /// changes the device, a broadcast some device of the line refuses. Nothing was sent.
    pub policy_refused: u64,
    /// Requests answered at once because the line can never carry them: a function whose
    /// reply cannot be framed on RTU, a write on a read-only gateway, a read to the broadcast
    /// address (exception 01), a unit id no device of the bus file has (0B), a unit id RTU
    /// reserves (0A).
    pub not_carried: u64,
    /// Clients closed at once because every client had a request in flight.
    pub refused: u64,
    /// Clients closed at the client limit, the one idle the longest, to admit a new one.
    pub evicted: u64,
    /// Clients closed because they sent no whole request within `idle`.
    pub idle_closed: u64,
    /// Clients closed because they did not take their reply within `idle`.
    pub stalled: u64,
    /// Clients closed because they sent what is not Modbus TCP.
    pub not_modbus: u64,
    /// Requests the measurements' unit answered (reads, and the exceptions it gives to a
    /// write or a read outside its map; a malformed one counts as `malformed`).
    pub measurements: u64,
}

/// A gateway's [`GatewayCounts`], counted as it goes.
#[derive(Debug, Default)]
pub(crate) struct GatewayCounters {
    requests: AtomicU64,
    busy: AtomicU64,
    malformed: AtomicU64,
    pub(crate) policy_refused: AtomicU64,
    not_carried: AtomicU64,
    refused: AtomicU64,
    evicted: AtomicU64,
    idle_closed: AtomicU64,
    stalled: AtomicU64,
    not_modbus: AtomicU64,
    measurements: AtomicU64,
}

pub(crate) fn add(counter: &AtomicU64) {
    counter.fetch_add(1, Ordering::Relaxed);
}

impl GatewayCounters {
    /// The counts so far.
    pub(crate) fn counts(&self) -> GatewayCounts {
        let load = |counter: &AtomicU64| counter.load(Ordering::Relaxed);
        GatewayCounts {
            requests: load(&self.requests),
            busy: load(&self.busy),
            malformed: load(&self.malformed),
            policy_refused: load(&self.policy_refused),
            not_carried: load(&self.not_carried),
            refused: load(&self.refused),
            evicted: load(&self.evicted),
            idle_closed: load(&self.idle_closed),
            stalled: load(&self.stalled),
            not_modbus: load(&self.not_modbus),
            measurements: load(&self.measurements),
        }
    }
}

/// The connected clients, from which the acceptor closes one to admit another.
#[derive(Debug, Default)]
struct Clients {
    next_id: u64,
    connected: Vec<Client>,
}

#[derive(Debug)]
struct Client {
    id: u64,
    /// Since when it has had no request in flight; `None` while it has one.
    idle_since: Option<Instant>,
    /// Its task, aborted to close it.
    task: Option<AbortHandle>,
}

impl Clients {
    /// A place for a new client: a free one, or the place of the client idle the longest,
    /// whose task is given back to be closed; `None` when `limit` clients all have a request
    /// in flight.
    fn admit(
        &mut self,
        limit: usize,
        counters: &GatewayCounters,
    ) -> Option<(u64, Option<AbortHandle>)> {
        let mut closed = None;
        if self.connected.len() >= limit {
            // The earliest idle, and of two idle since the same instant the first admitted.
            let (_, _, longest) = self
                .connected
                .iter()
                .enumerate()
                .filter_map(|(at, client)| client.idle_since.map(|since| (since, client.id, at)))
                .min()?;
            closed = self.connected.remove(longest).task;
            add(&counters.evicted);
        }
        let id = self.next_id;
        self.next_id += 1;
        self.connected.push(Client {
            id,
            idle_since: Some(Instant::now()),
            task: None,
        });
        Some((id, closed))
    }

    fn get(&mut self, id: u64) -> Option<&mut Client> {
        self.connected.iter_mut().find(|client| client.id == id)
    }
}

fn lock(clients: &Mutex<Clients>) -> std::sync::MutexGuard<'_, Clients> {
    // The lock is never held across a panic that could leave the list half-changed.
    clients.lock().unwrap_or_else(PoisonError::into_inner)
}

/// A client's place among the connected ones, given up when its task ends (or is aborted).
struct Place {
    clients: Arc<Mutex<Clients>>,
    id: u64,
}

impl Place {
    /// Marks a request in flight; false if the client was closed to admit another meanwhile.
    fn busy(&self) -> bool {
        lock(&self.clients)
            .get(self.id)
            .map(|client| client.idle_since = None)
            .is_some()
    }

    /// Marks the client idle from now (its request is answered).
    fn idle(&self) {
        if let Some(client) = lock(&self.clients).get(self.id) {
            client.idle_since = Some(Instant::now());
        }
    }
}

impl Drop for Place {
    fn drop(&mut self) {
        lock(&self.clients)
            .connected
            .retain(|client| client.id != self.id);
    }
}

/// The slave addresses of the bus file's devices on a gateway's line.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Slaves([u64; 4]);

impl Slaves {
    /// The set of `slaves`.
    pub(crate) fn of(slaves: impl IntoIterator<Item = u8>) -> Self {
        let mut set = Self::default();
        for slave in slaves {
            set.0[usize::from(slave / 64)] |= 1 << (slave % 64);
        }
        set
    }

    fn contains(&self, slave: u8) -> bool {
        self.0[usize::from(slave / 64)] & (1 << (slave % 64)) != 0
    }
}

/// What each connection needs of the gateway's settings.
#[derive(Clone)]
struct Settings {
    idle: Duration,
    writes: bool,
    /// The devices it reaches: a request to another unit id is answered 0B at once.
    slaves: Slaves,
    /// The measurements' unit id and registers, where the bus has measurements.
    measurements: Option<(u8, Arc<MeasurementUnit>)>,
}

impl Settings {
    /// The measurements' registers, if `unit` is their unit id.
    fn measurements_at(&self, unit: u8) -> Option<&MeasurementUnit> {
        self.measurements
            .as_ref()
            .filter(|(id, _)| *id == unit)
            .map(|(_, registers)| &**registers)
    }
}

/// Accepts clients on `listener` until the task is aborted, which closes every client.
pub(crate) async fn serve(
    listener: TcpListener,
    config: GatewayConfig,
    slaves: Slaves,
    measurements: Option<Arc<MeasurementUnit>>,
    queue: mpsc::Sender<GatewayRequest>,
    counters: Arc<GatewayCounters>,
) {
    let settings = Settings {
        idle: config.idle,
        writes: config.writes,
        slaves,
        measurements: measurements.map(|registers| (config.measurements_unit, registers)),
    };
    let clients = Arc::new(Mutex::new(Clients::default()));
    let mut tasks = JoinSet::new();
    loop {
        let accepted = tokio::select! {
            accepted = listener.accept() => accepted,
            Some(_) = tasks.join_next(), if !tasks.is_empty() => continue,
        };
        let Ok((socket, peer)) = accepted else {
            // Out of file descriptors or similar: try again shortly rather than spin.
            tokio::time::sleep(Duration::from_millis(100)).await;
            continue;
        };
        let admitted = lock(&clients).admit(config.clients, &counters);
        let Some((id, closed)) = admitted else {
            add(&counters.refused);
            drop(socket);
            continue;
        };
        // Aborted outside the lock, which the closed client's place takes when it goes.
        if let Some(task) = closed {
            task.abort();
        }
        let place = Place {
            clients: Arc::clone(&clients),
            id,
        };
        let task = tasks.spawn(connection(
            socket,
            peer,
            place,
            settings.clone(),
            queue.clone(),
            Arc::clone(&counters),
        ));
        // A client already gone has left its place: nothing to attach to then.
        if let Some(client) = lock(&clients).get(id) {
            client.task = Some(task);
        }
    }
}

/// Why a connection stopped reading requests.
enum Stop {
    /// The client closed it or the socket failed.
    Closed,
    /// The client sent what is not Modbus TCP: nothing after it can be trusted to be framed.
    NotModbus,
}

/// Reads one whole request: its MBAP header, and its PDU into `pdu`, whose length it gives.
async fn read_request(
    socket: &mut TcpStream,
    pdu: &mut [u8; MAX_PDU_LEN],
) -> Result<(Mbap, usize), Stop> {
    let mut header = [0u8; HEADER_LEN];
    socket
        .read_exact(&mut header)
        .await
        .map_err(|_| Stop::Closed)?;
    let mbap = Mbap::parse(&header).ok_or(Stop::NotModbus)?;
    let len = mbap
        .pdu_len()
        .filter(|_| mbap.check().is_ok())
        .ok_or(Stop::NotModbus)?;
    socket
        .read_exact(&mut pdu[..len])
        .await
        .map_err(|_| Stop::Closed)?;
    Ok((mbap, len))
}

/// Why a request is answered here, before the queue.
enum OwnAnswer {
    /// Its length or counts do not fit its function: exception 03.
    Malformed,
    /// The line can never carry it: exception 01 or 0A.
    NotCarried(u8),
}

/// The gateway's own answer to a request the line must not see, if it is one.
fn own_answer(unit: u8, pdu: &[u8], settings: &Settings) -> Option<OwnAnswer> {
    let pass = match PassPdu::new(pdu) {
        Ok(pass) => pass,
        Err(EncodeError::MalformedRequest { .. }) => return Some(OwnAnswer::Malformed),
        // A function whose reply cannot be framed (an MBAP header holds 1 to 253 bytes).
        Err(_) => return Some(OwnAnswer::NotCarried(ILLEGAL_FUNCTION)),
    };
    if unit > MAX_SLAVE {
        return Some(OwnAnswer::NotCarried(PATH_UNAVAILABLE));
    }
    // The line's devices are the bus file's: waiting out a timeout for another unit id would
    // only make the client wait as long (mbpoll's own timeout is the usual 1 s).
    if unit != optobus_codec::BROADCAST && !settings.slaves.contains(unit) {
        return Some(OwnAnswer::NotCarried(TARGET_FAILED));
    }
    if unit == optobus_codec::BROADCAST && !pass.may_broadcast() {
        return Some(OwnAnswer::NotCarried(ILLEGAL_FUNCTION));
    }
    // The write policy's answer on a read-only gateway, given before the queue.
    if pass.writes() && !settings.writes {
        return Some(OwnAnswer::NotCarried(refused(&Refusal::ReadOnly)));
    }
    None
}

/// Serves one client, one request at a time, until it closes, sends what is not Modbus TCP,
/// stays idle or stops taking its replies, or is closed to admit another.
async fn connection(
    mut socket: TcpStream,
    peer: SocketAddr,
    place: Place,
    settings: Settings,
    queue: mpsc::Sender<GatewayRequest>,
    counters: Arc<GatewayCounters>,
) {
    let _ = socket.set_nodelay(true);
    let mut pdu = [0u8; MAX_PDU_LEN];
    let mut out = [0u8; HEADER_LEN + MAX_PDU_LEN];
    loop {
        let (mbap, len) = match timeout(settings.idle, read_request(&mut socket, &mut pdu)).await {
            Ok(Ok(request)) => request,
            Ok(Err(Stop::Closed)) => return,
            Ok(Err(Stop::NotModbus)) => return add(&counters.not_modbus),
            Err(_) => return add(&counters.idle_closed),
        };
        if !place.busy() {
            return;
        }
        let pdu = &pdu[..len];
        let function = pdu[0];
        let own = match settings.measurements_at(mbap.unit) {
            Some(measurements) => Err(measurements.answer(pdu)),
            None => Ok(own_answer(mbap.unit, pdu, &settings)),
        };
        let reply = match own {
            Err(reply) => {
                let malformed = reply == exception(function, ILLEGAL_VALUE);
                add(if malformed {
                    &counters.malformed
                } else {
                    &counters.measurements
                });
                if PassPdu::new(pdu).is_ok_and(|pass| pass.writes()) {
                    audit_write(peer, mbap.unit, pdu, Some(&reply), None);
                }
                reply
            }
            Ok(own) => match own {
                Some(OwnAnswer::Malformed) => {
                    add(&counters.malformed);
                    exception(function, ILLEGAL_VALUE)
                }
                Some(OwnAnswer::NotCarried(code)) => {
                    add(&counters.not_carried);
                    let reply = exception(function, code);
                    if PassPdu::new(pdu).is_ok_and(|pass| pass.writes()) {
                        audit_write(peer, mbap.unit, pdu, Some(&reply), None);
                    }
                    reply
                }
                None => {
                    let (reply, answer) = oneshot::channel();
                    let request = GatewayRequest {
                        client: peer,
                        unit: mbap.unit,
                        pdu: pdu.to_vec(),
                        reply,
                    };
                    match queue.try_send(request) {
                        Ok(()) => {
                            add(&counters.requests);
                            match answer.await {
                                Ok(Some(reply)) => reply,
                                // A broadcast: nothing goes back.
                                Ok(None) => {
                                    place.idle();
                                    continue;
                                }
                                Err(_) => return,
                            }
                        }
                        Err(TrySendError::Full(_)) => {
                            add(&counters.busy);
                            exception(function, BUSY)
                        }
                        Err(TrySendError::Closed(_)) => return,
                    }
                }
            },
        };
        let header = Header {
            transaction: mbap.transaction,
            unit: mbap.unit,
        };
        let Ok(n) = encode_tcp_reply(&mut out, header, &reply) else {
            return;
        };
        // The request is answered: a client that does not take its reply is as idle as one
        // that asks nothing.
        place.idle();
        match timeout(settings.idle, socket.write_all(&out[..n])).await {
            Ok(Ok(())) => {}
            Ok(Err(_)) => return,
            Err(_) => return add(&counters.stalled),
        }
    }
}
