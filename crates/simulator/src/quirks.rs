//! How a device reports errors and treats undefined addresses: the behaviour that the spec
//! schema does not (yet) carry as data, derived from what it does carry.

use optobus_codec::{ExceptionCode, ExceptionShape};
use optobus_device::DeviceInfo;

/// What a read of an address without a readable register (a reserved range the manual does
/// not mark readable, a write-only or action register) answers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UnreadableReads {
    /// Zeros, as the spec schema says for reserved ranges (P series, CCS, CCF, rangefinder).
    Zeros,
    /// The illegal-address exception (LC-RS: table 2 code 0x0001 "寄存器地址错误").
    Refused,
}

/// What a data buffer page's read count shows. The P series manual (appendix 3 (3)) says the
/// count of values read since the lock reaches the total once all are read, and leaves open
/// whether a reply's count already includes that reply's own page; the driver accepts both.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BufferReadCount {
    /// The values handed out since the lock, this page included (the default).
    IncludingPage,
    /// The values handed out before this page.
    BeforePage,
}

/// Error codes, address rules and readings the manuals leave open, of one device.
///
/// [`Quirks::of`] derives them from a `DeviceInfo`:
///
/// - Standard exception frames (P series 3.4 table 3-12, CCS/CCF tables 3-9/3-10, the
///   rangefinder, which describes none): 01 illegal function, 02 illegal data address, 03
///   illegal data value; reserved addresses read as zeros.
/// - Counted-word exception frames (LC-RS 2.1.3, 2.1.6, 2.2 6) table 2): 0x0001 "register
///   address error" for undefined addresses, reserved addresses included, and for reads
///   over 8 registers; 0x0002 "register write value error" for invalid values. Table 2 has no
///   code for an unsupported function code; the device answers 0x0001 (Modbus' own
///   illegal-function number) in the counted-word frame.
///
/// The derivation from the frame shape stands in for spec data (see the crate docs); a test
/// can override any field with [`crate::Simulator::quirks`], for instance to act out a
/// device that reads the manual another way ([`Quirks::buffer_read_count`],
/// [`Quirks::readable_reserved`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Quirks {
    /// Code for a function code the device does not implement.
    pub illegal_function: ExceptionCode,
    /// Code for an undefined address, a read past the table or over the read limit, and a
    /// write to a read-only register.
    pub illegal_address: ExceptionCode,
    /// Code for an invalid value (out of range, undefined code); the register is unchanged.
    pub illegal_value: ExceptionCode,
    /// What reads of reserved and write-only addresses answer.
    pub unreadable: UnreadableReads,
    /// What a read crossing a reserved range the spec marks `readable` answers: zeros (the
    /// default, as the spec infers), or the illegal-address exception, as a device (or a
    /// gateway) that refuses the reserved addresses the manual is silent on would.
    pub readable_reserved: UnreadableReads,
    /// What the data buffer's read count counts.
    pub buffer_read_count: BufferReadCount,
    /// Whether a read sent to broadcast address 0 is answered from the device's own address
    /// (the rangefinder's 3.5 shows this; standard Modbus never answers a broadcast).
    pub answer_broadcast_reads: bool,
}

impl Quirks {
    /// Standard Modbus behaviour.
    pub const STANDARD: Self = Self {
        illegal_function: ExceptionCode::ILLEGAL_FUNCTION,
        illegal_address: ExceptionCode::ILLEGAL_DATA_ADDRESS,
        illegal_value: ExceptionCode::ILLEGAL_DATA_VALUE,
        unreadable: UnreadableReads::Zeros,
        readable_reserved: UnreadableReads::Zeros,
        buffer_read_count: BufferReadCount::IncludingPage,
        answer_broadcast_reads: false,
    };

    /// LC-RS behaviour (manual 2.1.3, 2.1.6, 2.2 6) table 2).
    pub const COUNTED_WORD: Self = Self {
        illegal_function: ExceptionCode(0x0001),
        illegal_address: ExceptionCode(0x0001),
        illegal_value: ExceptionCode(0x0002),
        unreadable: UnreadableReads::Refused,
        readable_reserved: UnreadableReads::Zeros,
        buffer_read_count: BufferReadCount::IncludingPage,
        answer_broadcast_reads: false,
    };

    /// The quirks of `device`, derived from its exception frame shape.
    pub fn of(device: &DeviceInfo) -> Self {
        match device.frame_shape.exception {
            ExceptionShape::Standard => Self::STANDARD,
            ExceptionShape::CountedWord => Self::COUNTED_WORD,
        }
    }
}
