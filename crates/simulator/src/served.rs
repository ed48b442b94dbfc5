//! A line of simulated devices served as one: each device named for its log, the line's
//! faults placed where the protocol puts them, every exchange seen once, and what the faults
//! did told at the end.

use std::io;
use std::net::SocketAddr;
use std::sync::Arc;

use tokio::io::{AsyncRead, AsyncWrite};
use tokio::task::JoinHandle;

use crate::{Exchange, Faults, Line, Reply, Simulator, Slaves, TcpServer};

/// A device of a [`ServedLine`].
#[derive(Clone, Debug)]
pub struct Member {
    /// How its log lines and its fault summary name it (`p-series`, or a model and a bus
    /// file's name for it).
    pub name: String,
    /// The device, at its slave address.
    pub simulator: Simulator,
    /// The faults already in its own replies (a bus file's `faults:`), for its summary.
    pub faults: Option<Faults>,
}

/// How a served line is reached.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Protocol {
    /// RTU frames on one line (a pty, a serial port): every device hears every request.
    Rtu,
    /// Modbus TCP: the unit id picks the device.
    Tcp,
}

/// Devices served on one line.
#[derive(Clone, Debug)]
pub struct ServedLine {
    members: Vec<Member>,
    slaves: Slaves,
    /// The faults given for the whole line.
    faults: Option<Faults>,
    /// Whether they are in the line's replies (RTU) rather than each device's (TCP).
    on_the_line: bool,
    /// A line of one device, made by [`ServedLine::one`]: over Modbus TCP it answers every
    /// unit id, and its fault summary is not prefixed with its name.
    one_device: bool,
}

impl ServedLine {
    /// `members` on one line reached over `protocol`, with `faults` in every reply: on RTU
    /// in the line's (whichever device answers), over Modbus TCP in each device's own.
    /// `observe` sees every exchange once: each device's answers, and a request nobody
    /// answers by its addressee, or by the first device when no device has that address.
    pub fn new(
        members: Vec<Member>,
        protocol: Protocol,
        faults: Option<Faults>,
        observe: impl Fn(&Exchange<'_>) + Send + Sync + 'static,
    ) -> Self {
        let observe = Arc::new(observe);
        let addresses: Vec<u8> = members.iter().map(|m| m.simulator.address()).collect();
        let on_the_line = protocol == Protocol::Rtu;
        let members: Vec<Member> = members
            .into_iter()
            .enumerate()
            .map(|(index, member)| {
                let own = member.simulator.address();
                let addresses = addresses.clone();
                let observe = Arc::clone(&observe);
                let sees_silence_to =
                    move |slave: u8| slave == own || (index == 0 && !addresses.contains(&slave));
                let mut simulator = member.simulator.observe(move |exchange| {
                    let silent = matches!(exchange.reply, Reply::Silent);
                    if !silent || exchange.slave.is_none_or(&sees_silence_to) {
                        observe(exchange);
                    }
                });
                let mut own_faults = member.faults;
                if let Some(each) = faults.as_ref().filter(|_| !on_the_line) {
                    simulator = simulator.faults(each.clone());
                    own_faults = Some(each.clone());
                }
                Member {
                    name: member.name,
                    simulator,
                    faults: own_faults,
                }
            })
            .collect();
        let mut slaves = Slaves::new(members.iter().map(|member| member.simulator.clone()));
        if let Some(faults) = faults.as_ref().filter(|_| on_the_line) {
            slaves = slaves.faults(faults.clone());
        }
        Self {
            members,
            slaves,
            faults,
            on_the_line,
            one_device: false,
        }
    }

    /// One device served alone, `faults` in its own replies (on RTU as over TCP): over Modbus
    /// TCP it answers every unit id, and [`ServedLine::fault_summaries`] says what its faults
    /// did without naming it.
    pub fn one(
        member: Member,
        faults: Option<Faults>,
        observe: impl Fn(&Exchange<'_>) + Send + Sync + 'static,
    ) -> Self {
        let mut line = Self::new(vec![member], Protocol::Tcp, faults, observe);
        line.one_device = true;
        line
    }

    /// The devices, as served (each with the faults in its own replies).
    pub fn members(&self) -> &[Member] {
        &self.members
    }

    /// The faults given for the whole line.
    pub fn faults(&self) -> Option<&Faults> {
        self.faults.as_ref()
    }

    /// Serves the line on a new pseudo-terminal, timed as `timing` says (untimed without).
    #[cfg(unix)]
    pub fn serve_pty(&self, timing: Option<Line>) -> io::Result<crate::Pty> {
        match timing {
            Some(line) => self.slaves.serve_pty_line(line),
            None => self.slaves.serve_pty(),
        }
    }

    /// Serves the line on `io` (an opened serial port), timed as `timing` says, in a task of
    /// its own.
    pub fn serve_stream<IO>(&self, io: IO, timing: Option<Line>) -> JoinHandle<io::Result<()>>
    where
        IO: AsyncRead + AsyncWrite + Unpin + Send + 'static,
    {
        let slaves = self.slaves.clone();
        tokio::spawn(async move {
            match timing {
                Some(line) => slaves.serve_line(io, &line).await,
                None => slaves.serve(io).await,
            }
        })
    }

    /// Serves the devices over Modbus TCP on `address` (the unit id picks the device; a line
    /// of [`ServedLine::one`] device answers every unit id).
    pub async fn serve_tcp(&self, address: SocketAddr) -> io::Result<TcpServer> {
        match self.members.first().filter(|_| self.one_device) {
            Some(member) => member.simulator.serve_tcp(address).await,
            None => self.slaves.serve_tcp(address).await,
        }
    }

    /// What the faults did, a line each: the line's (when its replies carry them), then each
    /// device's as `name: summary` (a line of [`ServedLine::one`] device: its summary alone).
    pub fn fault_summaries(&self) -> Vec<String> {
        let line = self
            .faults
            .as_ref()
            .filter(|_| self.on_the_line)
            .zip(self.slaves.fault_stats())
            .map(|(faults, stats)| stats.summary(faults).to_string());
        let each = self.members.iter().filter_map(|member| {
            let stats = member.simulator.fault_stats()?;
            let summary = stats.summary(member.faults.as_ref()?);
            Some(if self.one_device {
                summary.to_string()
            } else {
                format!("{}: {summary}", member.name)
            })
        });
        line.into_iter().chain(each).collect()
    }
}
