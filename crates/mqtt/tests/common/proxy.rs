//! A TCP proxy between a publisher and its broker that cuts connections at seeded moments, and
//! reads the MQTT packets it passes on, so that a test knows what reached either side.
//!
//! Each connection gets a [`Cut`] drawn from the [`Plan`]'s seed, in the order connections
//! come: after a number of bytes towards the broker (so most cuts fall inside a PUBLISH),
//! after a number of bytes towards the client (inside a PUBACK), or a hang: the broker's
//! answers held back from that byte on (the client's window of unacknowledged messages fills)
//! for a while, then the cut. A cut closes both sockets with a reset (zero linger), so neither
//! side gets the rest of a packet begun; a hang's cut waits until the broker has acknowledged
//! every QoS 1 PUBLISH that reached it, so that the proxy knows exactly what the broker took.
//! Connections after the planned cuts pass untouched, and so do all once the proxy is calm.

use std::collections::{BTreeMap, BTreeSet};
use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Notify;
use tokio::task::JoinHandle;

/// splitmix64: a small seeded generator, the same numbers for the same seed everywhere.
#[derive(Clone, Debug)]
pub struct Seeded(u64);

impl Seeded {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// A number in `range` (not empty).
    pub fn within(&mut self, range: Range<u64>) -> u64 {
        range.start + self.next_u64() % (range.end - range.start).max(1)
    }
}

/// How one connection is cut.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cut {
    /// After this many bytes from the client towards the broker.
    ToBroker(usize),
    /// After this many bytes from the broker towards the client.
    ToClient(usize),
    /// After this many bytes towards the broker, nothing more reaches the client (bytes towards
    /// the broker still pass); the cut comes `hold` later.
    Hang(usize, Duration),
}

/// The faults of a run, all drawn from `seed`.
#[derive(Clone, Debug)]
pub struct Plan {
    pub seed: u64,
    /// How many connections are cut, the first ones; later ones pass.
    pub cuts: usize,
    /// Weights of [`Cut::ToBroker`], [`Cut::ToClient`] and [`Cut::Hang`].
    pub weights: [u64; 3],
    /// Bytes towards the broker before a cut or a hang.
    pub to_broker: Range<u64>,
    /// Bytes towards the client before a cut (4 for the CONNACK, then 4 per PUBACK).
    pub to_client: Range<u64>,
    /// How long a hang lasts, in milliseconds.
    pub hold_ms: Range<u64>,
    /// After each cut, connections are refused (reset at once) this long: an outage.
    pub outage: Duration,
}

impl Plan {
    /// The cut of each of the first `cuts` connections, in order.
    pub fn cuts(&self) -> Vec<Cut> {
        let mut random = Seeded::new(self.seed);
        (0..self.cuts)
            .map(|_| {
                let total: u64 = self.weights.iter().sum();
                let mut pick = random.within(0..total);
                let kind = self
                    .weights
                    .iter()
                    .position(|w| {
                        if pick < *w {
                            true
                        } else {
                            pick -= w;
                            false
                        }
                    })
                    .unwrap_or(0);
                let to_broker = random.within(self.to_broker.clone()) as usize;
                let to_client = random.within(self.to_client.clone()) as usize;
                let hold = Duration::from_millis(random.within(self.hold_ms.clone()));
                match kind {
                    0 => Cut::ToBroker(to_broker),
                    1 => Cut::ToClient(to_client),
                    _ => Cut::Hang(to_broker, hold),
                }
            })
            .collect()
    }
}

/// A PUBLISH that passed the proxy whole.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Passed {
    pub topic: String,
    pub payload: String,
    pub qos: u8,
    pub pkid: u16,
}

/// What happened on one connection.
#[derive(Clone, Debug, Default)]
pub struct Connection {
    /// Its planned cut (`None`: passed untouched, or refused during an outage).
    pub cut: Option<Cut>,
    /// Whether it was refused (an outage).
    pub refused: bool,
    /// How it ended: which packet a cut fell into, towards whom.
    pub ended: Option<String>,
    /// PUBLISH packets that reached the broker whole, in order.
    pub published: Vec<Passed>,
    /// Packet ids of the PUBACKs that reached the client whole, in order.
    pub acknowledged: Vec<u16>,
    /// QoS 1 PUBLISH packets that reached the broker whole and whose PUBACK has not reached
    /// the client, by packet id (ids are used again once acknowledged).
    outstanding: BTreeMap<u16, Passed>,
    /// QoS 1 PUBLISH packets that reached the broker whole and that it has not acknowledged.
    unconfirmed: BTreeSet<u16>,
    /// Whether its cut (or the hang that ends in one) began.
    cutting: bool,
    /// PUBLISH packets whole towards the broker after a hang began (their PUBACKs held back).
    pub published_in_hang: usize,
}

impl Connection {
    /// QoS 1 PUBLISH packets the broker took (it acknowledged them) whose PUBACK never reached
    /// the client: the broker has them, the client does not know it. Exact for a connection
    /// cut after a hang, which waits for the broker's acknowledgements before it cuts.
    pub fn unacknowledged(&self) -> Vec<&Passed> {
        self.outstanding.values().collect()
    }

    /// Whole packets that passed `way` (`hung`: after a hang began; `held`: read from the
    /// broker and kept from the client).
    fn take_in(&mut self, way: Way, packets: Vec<Packet>, hung: bool, held: bool) {
        for packet in packets {
            match (way, packet.kind()) {
                (Way::ToBroker, PUBLISH) => {
                    if let Some(passed) = packet.publish() {
                        if hung {
                            self.published_in_hang += 1;
                        }
                        if passed.qos > 0 {
                            self.unconfirmed.insert(passed.pkid);
                            self.outstanding.insert(passed.pkid, passed.clone());
                        }
                        self.published.push(passed);
                    }
                }
                (Way::ToClient, PUBACK) => {
                    if let Some(pkid) = packet.pkid() {
                        self.unconfirmed.remove(&pkid);
                        if !held {
                            self.outstanding.remove(&pkid);
                            self.acknowledged.push(pkid);
                        }
                    }
                }
                _ => {}
            }
        }
    }
}

/// A running proxy on a free 127.0.0.1 port.
pub struct Proxy {
    pub port: u16,
    shared: Arc<Mutex<Shared>>,
    task: JoinHandle<()>,
}

/// What the connections share: whether cuts are called off, and what happened on each.
#[derive(Default)]
struct Shared {
    calm: bool,
    connections: Vec<Connection>,
}

impl Proxy {
    /// Listens on a free port and passes connections on to the broker on `broker_port`,
    /// cutting them as `plan` says.
    pub async fn start(broker_port: u16, plan: &Plan) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").await.expect("a free port");
        let port = listener.local_addr().unwrap().port();
        let shared = Arc::new(Mutex::new(Shared::default()));
        let task = tokio::spawn(accept(
            listener,
            broker_port,
            plan.cuts(),
            plan.outage,
            Arc::clone(&shared),
        ));
        Self { port, shared, task }
    }

    /// No cut from now on: a cut or hang under way ends (waited for), a cut planned and not
    /// reached is called off, later connections pass untouched.
    pub async fn calm(&self) {
        self.shared.lock().unwrap().calm = true;
        for _ in 0..500 {
            let cutting = self
                .shared
                .lock()
                .unwrap()
                .connections
                .iter()
                .any(|c| c.cutting && c.ended.is_none());
            if !cutting {
                return;
            }
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        panic!("a cut under way did not end in 5 s");
    }

    /// What happened on each connection so far, in the order they came.
    pub fn connections(&self) -> Vec<Connection> {
        self.shared.lock().unwrap().connections.clone()
    }
}

impl Drop for Proxy {
    fn drop(&mut self) {
        self.task.abort();
    }
}

async fn accept(
    listener: TcpListener,
    broker_port: u16,
    cuts: Vec<Cut>,
    outage: Duration,
    shared: Arc<Mutex<Shared>>,
) {
    let mut cuts = cuts.into_iter();
    // When the last cut came: an outage follows it. The cut's connection task tells it.
    let last_cut = Arc::new(Mutex::new(None::<tokio::time::Instant>));
    // Dropped with this task (the proxy's): every connection ends with it.
    let mut links = tokio::task::JoinSet::new();
    loop {
        let Ok((client, _)) = listener.accept().await else {
            return;
        };
        let index = {
            let connections = &mut shared.lock().unwrap().connections;
            connections.push(Connection::default());
            connections.len() - 1
        };
        let refused = last_cut
            .lock()
            .unwrap()
            .is_some_and(|at| tokio::time::Instant::now() < at + outage);
        if refused {
            shared.lock().unwrap().connections[index].refused = true;
            let _ = client.set_zero_linger();
            drop(client);
            continue;
        }
        let Ok(broker) = TcpStream::connect(("127.0.0.1", broker_port)).await else {
            continue;
        };
        let cut = {
            let mut shared = shared.lock().unwrap();
            let cut = if shared.calm { None } else { cuts.next() };
            shared.connections[index].cut = cut;
            cut
        };
        let link = Arc::new(Link {
            index,
            shared: Arc::clone(&shared),
            hung: AtomicBool::new(false),
            sealed: AtomicBool::new(false),
            hang: Notify::new(),
        });
        let last_cut = Arc::clone(&last_cut);
        links.spawn(async move {
            let ended = pass(client, broker, cut, &link).await;
            if cut.is_some() {
                *last_cut.lock().unwrap() = Some(tokio::time::Instant::now());
            }
            link.record(|c| c.ended = Some(ended));
        });
    }
}

/// Which way bytes go.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Way {
    ToBroker,
    ToClient,
}

/// One connection's state, shared by its two directions.
struct Link {
    index: usize,
    shared: Arc<Mutex<Shared>>,
    /// The broker's answers no longer reach the client.
    hung: AtomicBool,
    /// Nothing more from the client reaches the broker.
    sealed: AtomicBool,
    /// Told when the hang begins.
    hang: Notify,
}

impl Link {
    fn record<T>(&self, change: impl FnOnce(&mut Connection) -> T) -> T {
        change(&mut self.shared.lock().unwrap().connections[self.index])
    }

    /// Whether the cut (or hang) goes ahead: not once the proxy is calm.
    fn cut_goes_ahead(&self) -> bool {
        let mut shared = self.shared.lock().unwrap();
        let go = !shared.calm;
        shared.connections[self.index].cutting = go;
        go
    }
}

/// Passes bytes both ways until either side closes or the cut comes; says how it ended.
async fn pass(client: TcpStream, broker: TcpStream, cut: Option<Cut>, link: &Link) -> String {
    let _ = client.set_nodelay(true);
    let _ = broker.set_nodelay(true);
    // A cut resets both sockets: no FIN, nothing more of a packet begun.
    let _ = client.set_zero_linger();
    let _ = broker.set_zero_linger();
    let (from_client, to_client) = client.into_split();
    let (from_broker, to_broker) = broker.into_split();
    let (to_broker_budget, to_client_budget, hold) = match cut {
        Some(Cut::ToBroker(bytes)) => (Some(bytes), None, None),
        Some(Cut::ToClient(bytes)) => (None, Some(bytes), None),
        Some(Cut::Hang(bytes, hold)) => (Some(bytes), None, Some(hold)),
        None => (None, None, None),
    };
    let upstream = pump(
        from_client,
        to_broker,
        Way::ToBroker,
        to_broker_budget,
        hold.is_some(),
        link,
    );
    let downstream = pump(
        from_broker,
        to_client,
        Way::ToClient,
        to_client_budget,
        false,
        link,
    );
    let hanging = async {
        let Some(hold) = hold else {
            return std::future::pending().await;
        };
        link.hang.notified().await;
        tokio::time::sleep(hold).await;
        // Nothing more reaches the broker; the cut waits until it has acknowledged all it
        // took (its PUBACKs are read, and kept from the client), so that the proxy knows
        // exactly what the broker has.
        link.sealed.store(true, Ordering::SeqCst);
        for _ in 0..400 {
            if link.record(|c| c.unconfirmed.is_empty()) {
                break;
            }
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        format!("cut after a hang of {hold:?}")
    };
    tokio::select! {
        ended = upstream => ended,
        ended = downstream => ended,
        ended = hanging => ended,
    }
    // The halves drop here: both sockets reset.
}

/// Bytes from `from` to `to`, read as MQTT packets on the way. With a `budget`, only that many
/// pass: then the connection is cut, or with `hang_at_budget` the hang begins: the broker's
/// answers are kept from the client, and bytes this way go on until the hang seals it.
async fn pump(
    mut from: OwnedReadHalf,
    mut to: OwnedWriteHalf,
    way: Way,
    mut budget: Option<usize>,
    hang_at_budget: bool,
    link: &Link,
) -> String {
    let mut frames = Frames::default();
    let mut buffer = vec![0u8; 16 * 1024];
    let closed = format!("{way:?}: closed by the receiver");
    loop {
        let read = match from.read(&mut buffer).await {
            Ok(0) | Err(_) => return format!("{way:?}: closed by the sender"),
            Ok(read) => read,
        };
        if way == Way::ToBroker && link.sealed.load(Ordering::SeqCst) {
            continue;
        }
        let hung = link.hung.load(Ordering::SeqCst);
        if way == Way::ToClient && hung {
            // Read for the broker's acknowledgements, kept from the client.
            link.record(|c| c.take_in(way, frames.push(&buffer[..read]), true, true));
            continue;
        }
        let passing = budget.map_or(read, |left| read.min(left));
        // Recorded before it is written, so that the broker's answer is never recorded first.
        link.record(|c| c.take_in(way, frames.push(&buffer[..passing]), hung, false));
        if to.write_all(&buffer[..passing]).await.is_err() {
            return closed;
        }
        let Some(left) = budget.as_mut() else {
            continue;
        };
        *left -= passing;
        if *left > 0 {
            continue;
        }
        budget = None;
        if !link.cut_goes_ahead() {
            // Called off: the rest passes.
            link.record(|c| c.take_in(way, frames.push(&buffer[passing..read]), hung, false));
            if to.write_all(&buffer[passing..read]).await.is_err() {
                return closed;
            }
            continue;
        }
        if !hang_at_budget {
            let within = match frames.begun() {
                Some(kind) => format!("inside a {}", packet_name(kind)),
                None => "between packets".to_owned(),
            };
            return format!("cut {way:?} {within}");
        }
        link.hung.store(true, Ordering::SeqCst);
        link.hang.notify_one();
        // The rest of what was read passes, after the hang began.
        link.record(|c| c.take_in(way, frames.push(&buffer[passing..read]), true, false));
        if to.write_all(&buffer[passing..read]).await.is_err() {
            return closed;
        }
    }
}

pub const PUBLISH: u8 = 3;
pub const PUBACK: u8 = 4;

fn packet_name(kind: u8) -> &'static str {
    match kind {
        1 => "CONNECT",
        2 => "CONNACK",
        PUBLISH => "PUBLISH",
        PUBACK => "PUBACK",
        8 => "SUBSCRIBE",
        9 => "SUBACK",
        12 => "PINGREQ",
        13 => "PINGRESP",
        14 => "DISCONNECT",
        _ => "packet",
    }
}

/// One whole MQTT 3.1.1 packet: its first byte and the rest after the length.
pub struct Packet {
    first: u8,
    body: Vec<u8>,
}

impl Packet {
    pub fn kind(&self) -> u8 {
        self.first >> 4
    }

    pub fn publish(&self) -> Option<Passed> {
        let qos = (self.first >> 1) & 3;
        let length = usize::from(u16::from_be_bytes([
            *self.body.first()?,
            *self.body.get(1)?,
        ]));
        let topic = std::str::from_utf8(self.body.get(2..2 + length)?).ok()?;
        let mut at = 2 + length;
        let mut pkid = 0;
        if qos > 0 {
            pkid = u16::from_be_bytes([*self.body.get(at)?, *self.body.get(at + 1)?]);
            at += 2;
        }
        Some(Passed {
            topic: topic.to_owned(),
            payload: String::from_utf8_lossy(self.body.get(at..)?).into_owned(),
            qos,
            pkid,
        })
    }

    pub fn pkid(&self) -> Option<u16> {
        Some(u16::from_be_bytes([
            *self.body.first()?,
            *self.body.get(1)?,
        ]))
    }
}

/// Splits a byte stream into MQTT packets.
#[derive(Default)]
pub struct Frames {
    pending: Vec<u8>,
}

impl Frames {
    /// Takes in `bytes`; gives the packets they completed.
    pub fn push(&mut self, bytes: &[u8]) -> Vec<Packet> {
        self.pending.extend_from_slice(bytes);
        let mut packets = Vec::new();
        while let Some((header, length)) = self.header() {
            if self.pending.len() < header + length {
                break;
            }
            let first = self.pending[0];
            let body = self.pending[header..header + length].to_vec();
            self.pending.drain(..header + length);
            packets.push(Packet { first, body });
        }
        packets
    }

    /// The kind of the packet begun and not complete, if any.
    pub fn begun(&self) -> Option<u8> {
        self.pending.first().map(|first| first >> 4)
    }

    /// The length of the fixed header and of the rest, once both are known.
    fn header(&self) -> Option<(usize, usize)> {
        let mut length = 0usize;
        for (i, byte) in self.pending.iter().skip(1).take(4).enumerate() {
            length |= usize::from(byte & 0x7f) << (7 * i);
            if byte & 0x80 == 0 {
                return Some((i + 2, length));
            }
        }
        None
    }
}
