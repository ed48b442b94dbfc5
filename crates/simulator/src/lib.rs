//! Virtual optobus devices, driven by a family's generated `DEVICE` description.
//!
//! One engine serves every family: the register model is the family's
//! `&'static DeviceInfo`, and device quirks come from its data (frame shape, addressing,
//! long writes, commands and their effects, reserved ranges, sentinels). Nothing here is
//! written per family.
//!
//! ```no_run
//! # async fn demo(device: &'static optobus_device::DeviceInfo) -> std::io::Result<()> {
//! use optobus_simulator::{Slaves, Simulator};
//! let sim = Simulator::new(device).slave(5);
//! let (stream, _server) = sim.duplex(); // an RTU line in memory
//! let server = sim.serve_tcp("127.0.0.1:0").await?; // Modbus TCP
//! let pty = sim.serve_pty()?; // a terminal mbpoll can open: pty.path()
//! let slaves = Slaves::new([sim.clone(), Simulator::new(device).slave(6)]); // two slaves, one line
//! sim.set_silent(true); // stops answering
//! # Ok(()) }
//! ```
//!
//! # A serial line's timing
//!
//! [`Line`] makes an in-memory RTU connection take as long as an RS-485 line of a
//! `LineFormat`: one character time per byte on one half-duplex wire, the device answering
//! t3.5 after a request's last byte plus its turnaround, reply bytes reaching the client as
//! their characters complete, and a request that starts less than t3.5 after a reply held
//! until then (and counted). Bytes keep to their times within tens of microseconds on an
//! idle machine, so timing benchmarks of clients mean something. See [`mod@line`].
//!
//! ```no_run
//! # async fn demo(device: &'static optobus_device::DeviceInfo) {
//! use optobus_codec::LineFormat;
//! use optobus_simulator::{Line, Simulator};
//! let line = Line::new(LineFormat::new(19_200)).turnaround(std::time::Duration::from_millis(2));
//! let stats = line.stats();
//! let (stream, _server) = Simulator::new(device).duplex_line(line); // the client's end
//! // ... after the exchanges:
//! assert_eq!(stats.gap_violations(), 0, "the client waited t3.5 between frames");
//! # }
//! ```
//!
//! # Faults
//!
//! [`Faults`] injects seeded, reproducible faults into the device's replies, over RTU (with
//! or without a [`Line`], which then times the faulty bytes) and Modbus TCP: a flipped bit,
//! a truncated frame, garbage in front, a valid reply from another slave, a frame in pieces,
//! no reply, a late reply, a closed connection. [`FaultStats`] counts them and says which
//! reply got which. The bytes of each kind are in [`faults`].
//!
//! ```no_run
//! # async fn demo(device: &'static optobus_device::DeviceInfo) -> Result<(), Box<dyn std::error::Error>> {
//! use optobus_simulator::{FaultKind, Faults, Simulator};
//! let faults: Faults = "corrupt=0.05,split=0.05,delay=0.01,seed=7".parse()?;
//! let sim = Simulator::new(device).faults(faults.client_timeout(std::time::Duration::from_millis(200)));
//! let (stream, _server) = sim.duplex(); // or sim.serve_tcp(..), sim.duplex_line(..)
//! // ... after the exchanges:
//! let stats = sim.fault_stats().ok_or("no faults")?;
//! println!("{} of {} replies corrupted", stats.count(FaultKind::Corrupt), stats.replies());
//! # Ok(()) }
//! ```
//!
//! # Behaviour on the wire
//!
//! - **Framing**: RTU with CRC (requests split across reads, back-to-back frames, garbage
//!   skipped, bad CRCs ignored; see [`Slaves`]), Modbus TCP with MBAP (transaction and unit id
//!   echoed), both through `optobus-codec` with the device's `FrameShape` (LC-RS's 7-byte
//!   counted-word exceptions, the rangefinder's 10-byte FC06 echo).
//! - **Addresses**: frames for other slaves are ignored; broadcast (slave 0) writes are
//!   carried out and never answered, broadcast reads are not answered unless
//!   [`Quirks::answer_broadcast_reads`] (the rangefinder's 3.5 shows an answer).
//! - **Exceptions** ([`Quirks`]): illegal function for function codes not in
//!   `DeviceInfo::functions`; illegal address for undefined addresses, reads past the table,
//!   reads of 0 or more than `max_read_words` words (LC-RS 2.2 4): 1 to 8), and writes to
//!   read-only registers (the manuals' 02 "address outside the device's range" is the nearest
//!   code: the address holds nothing writable); illegal value for out-of-range values,
//!   values outside a register's `allowed_values`, undefined enum codes and packed fields with
//!   undefined codes or stray bits, and the register keeps its value (P series/CCS/CCF 4.1.1
//!   note 2).
//! - **Reserved ranges marked `readable`** (inferred: the manual counts them in the table it
//!   allows reading, P series, CCS, CCF 4.1.1 note 1 and 4.2.2 note, and is silent on reading
//!   them) read as zeros on every device, unless [`Quirks::readable_reserved`] refuses them
//!   with the illegal-address exception.
//! - **Other reserved addresses, write-only and action registers** read as zeros, except on
//!   LC-RS, whose table 2 code 0x0001 "register address error" refuses them (the golden frame
//!   lc-2.1.3).
//! - **Field addressing** (rangefinder): one address per field; a read names one field and
//!   asks for exactly its width (a 32-bit field: 2 words, high word first; the 0019H record:
//!   6 words). Every read in the manual does so (1.2, 3.1-3.38; 3.6's printed count 1 is an
//!   erratum), so reads spanning several fields, or with another count, are refused (02).
//!   A reserved field reads as one zero word.
//! - **32-bit writes**: of a split write (two FC06, P series 4.1.2 note 4: low word first,
//!   latched when the high word arrives) the half that comes first in the register's
//!   `write_order` is acknowledged and held; the second completes the value, which is
//!   validated whole and stored, or refused (03) leaving the register unchanged. Until then
//!   reads show the old value. A second half without a first pairs with the stored first
//!   half. Wide writes (rangefinder) carry the value in one 4-byte FC06, echoed whole.
//! - **Slave address changes** apply to the next request on devices that apply settings
//!   immediately (the reply to the write itself comes from the old address). With
//!   `needs_save_and_power_cycle` (LC-RS 2.2 3): "所有寄存器修改后必须发送保存配置指令且重新上电
//!   设备才生效") a write is acknowledged and reads return the new value at once (the manual
//!   says nothing about read-back, and the device keeps the value to save it), but it takes
//!   effect, e.g. the address the device answers to, only after save and
//!   [`Simulator::power_cycle`]; unsaved changes are lost by the power cycle.
//! - **Commands and effects**: see [`effects`] and [`buffer`].
//! - **Measurements**: see [`signal`]; tokio's clock drives them, so paused test time works.
//! - **Defaults**: see [`defaults`].
//!
//! Not modelled: LC-RS continuous-send mode (its stream format is not described), baud rate
//! and parity changes (a stream has no line speed; a [`Line`] has one fixed format), enable flags of statistics and encoder
//! counters (they always run), the time code and sample number the P series attaches to its
//! measurements (no register shows them), the P series' down-sampling of its sampled readings
//! (mode and ratio do not change them, 4.1.2 note 1; the ratio does set the buffering rate,
//! see [`buffer`]), and
//! power-up silence at creation (only after [`Simulator::power_cycle`]).
#![forbid(unsafe_code)]

pub mod buffer;
pub mod defaults;
pub mod effects;
pub mod faults;
mod layout;
pub mod line;
mod model;
mod names;
mod quirks;
mod rtu;
mod served;
pub mod signal;
mod sim;
mod tcp;

#[cfg(unix)]
mod pty;

pub use faults::{FaultKind, FaultStats, FaultSummary, Faults, FaultsError};
pub use line::{Line, LineStats};
pub use model::Reply;
#[cfg(unix)]
pub use pty::Pty;
pub use quirks::{BufferReadCount, Quirks, UnreadableReads};
pub use rtu::Slaves;
pub use served::{Member, Protocol, ServedLine};
pub use sim::{Exchange, PokeError, RegisterState, Simulator};
pub use tcp::TcpServer;
