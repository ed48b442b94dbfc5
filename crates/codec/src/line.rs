//! Timing of a Modbus RTU serial line: how long a character takes and the silence that ends a
//! frame (Modbus over serial line V1.02, 2.5.1.1).
//!
//! A character is a start bit, the data bits, an optional parity bit and the stop bits. A frame
//! ends after 3.5 character times of silence (t3.5). The specification allows a fixed 1.75 ms
//! above 19200 baud to spare slow timers; optobus computes t3.5 from the actual format, so a
//! fast line is not slowed down, and leaves the fixed floor to devices that need it
//! ([`LineFormat::frame_gap`] is only the default of the client's setting).

use core::fmt;
use core::time::Duration;

/// Parity of a serial line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Parity {
    /// No parity bit.
    #[default]
    None,
    /// Odd parity.
    Odd,
    /// Even parity.
    Even,
}

impl Parity {
    /// `none`, `odd` or `even` (also `n`, `o`, `e`), in any case; `None` for anything else.
    pub fn from_name(name: &str) -> Option<Self> {
        const NAMES: [(&str, Parity); 6] = [
            ("none", Parity::None),
            ("n", Parity::None),
            ("odd", Parity::Odd),
            ("o", Parity::Odd),
            ("even", Parity::Even),
            ("e", Parity::Even),
        ];
        NAMES
            .iter()
            .find(|(known, _)| known.eq_ignore_ascii_case(name))
            .map(|&(_, parity)| parity)
    }

    /// Bits the parity adds to a character.
    pub const fn bits(self) -> u32 {
        match self {
            Self::None => 0,
            Self::Odd | Self::Even => 1,
        }
    }

    /// `none`, `odd` or `even`.
    pub const fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Odd => "odd",
            Self::Even => "even",
        }
    }
}

impl fmt::Display for Parity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Speed and character format of a serial line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LineFormat {
    /// Bits per second.
    pub baud: u32,
    /// Data bits per character: 5 to 8 (Modbus RTU uses 8).
    pub data_bits: u8,
    /// Parity bit.
    pub parity: Parity,
    /// Stop bits: 1 or 2.
    pub stop_bits: u8,
}

/// Why a [`LineFormat`] cannot describe a serial line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum LineFormatError {
    /// The baud rate is 0.
    ZeroBaud,
    /// Data bits other than 5 to 8.
    DataBits(u8),
    /// Stop bits other than 1 or 2.
    StopBits(u8),
}

/// `9600 baud 8E1`.
impl fmt::Display for LineFormat {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parity = self.parity.name().chars().next().unwrap_or('n');
        write!(
            f,
            "{} baud {}{}{}",
            self.baud,
            self.data_bits,
            parity.to_ascii_uppercase(),
            self.stop_bits
        )
    }
}

impl fmt::Display for LineFormatError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::ZeroBaud => f.write_str("a baud rate of 0 carries no data"),
            Self::DataBits(bits) => write!(f, "{bits} data bits (a line has 5 to 8)"),
            Self::StopBits(bits) => write!(f, "{bits} stop bits (a line has 1 or 2)"),
        }
    }
}

impl core::error::Error for LineFormatError {}

const NANOS_PER_SECOND: u64 = 1_000_000_000;

impl LineFormat {
    /// `baud` with 8 data bits, no parity and one stop bit (8N1).
    pub const fn new(baud: u32) -> Self {
        Self {
            baud,
            data_bits: 8,
            parity: Parity::None,
            stop_bits: 1,
        }
    }

    /// This format with each setting that is given in its place (a device's factory format
    /// with the rate, parity, data bits or stop bits a user gives).
    pub fn changed(
        self,
        baud: Option<u32>,
        parity: Option<Parity>,
        data_bits: Option<u8>,
        stop_bits: Option<u8>,
    ) -> Self {
        Self {
            baud: baud.unwrap_or(self.baud),
            parity: parity.unwrap_or(self.parity),
            data_bits: data_bits.unwrap_or(self.data_bits),
            stop_bits: stop_bits.unwrap_or(self.stop_bits),
        }
    }

    /// Checks that the format describes a line that can carry data.
    pub const fn check(&self) -> Result<(), LineFormatError> {
        if self.baud == 0 {
            Err(LineFormatError::ZeroBaud)
        } else if self.data_bits < 5 || self.data_bits > 8 {
            Err(LineFormatError::DataBits(self.data_bits))
        } else if self.stop_bits < 1 || self.stop_bits > 2 {
            Err(LineFormatError::StopBits(self.stop_bits))
        } else {
            Ok(())
        }
    }

    /// Bits on the wire per character: start, data, parity and stop bits (10 for 8N1, 11 for
    /// 8E1).
    pub const fn character_bits(&self) -> u32 {
        1 + self.data_bits as u32 + self.parity.bits() + self.stop_bits as u32
    }

    /// Time of `half_bits` half bit times, rounded up to a nanosecond (a baud rate of 0
    /// counts as 1).
    const fn half_bit_times(&self, half_bits: u64) -> Duration {
        let baud = if self.baud == 0 { 1 } else { self.baud as u64 };
        let nanos = half_bits
            .saturating_mul(NANOS_PER_SECOND)
            .div_ceil(2 * baud);
        Duration::from_nanos(nanos)
    }

    /// Time one character takes on the wire.
    pub const fn character_time(&self) -> Duration {
        self.half_bit_times(2 * self.character_bits() as u64)
    }

    /// Time `bytes` characters take back to back.
    pub const fn transmit_time(&self, bytes: usize) -> Duration {
        self.half_bit_times((bytes as u64).saturating_mul(2 * self.character_bits() as u64))
    }

    /// t3.5: the silence of 3.5 character times that ends a frame.
    pub const fn frame_gap(&self) -> Duration {
        self.half_bit_times(7 * self.character_bits() as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn character_and_gap_times_follow_the_format() {
        let fast = LineFormat::new(115_200);
        assert_eq!(fast.character_bits(), 10);
        assert_eq!(fast.character_time(), Duration::from_nanos(86_806));
        // 35 bit times.
        assert_eq!(fast.frame_gap(), Duration::from_nanos(303_820));
        let even = LineFormat {
            parity: Parity::Even,
            ..LineFormat::new(9_600)
        };
        assert_eq!(even.character_bits(), 11);
        // 38.5 bit times.
        assert_eq!(even.frame_gap(), Duration::from_nanos(4_010_417));
        assert_eq!(even.transmit_time(8), Duration::from_nanos(9_166_667));
    }

    #[test]
    fn a_format_changed_takes_each_setting_given_and_keeps_the_others() {
        let factory = LineFormat {
            parity: Parity::Even,
            ..LineFormat::new(9_600)
        };
        assert_eq!(factory.changed(None, None, None, None), factory);
        let changed = factory.changed(Some(115_200), None, Some(7), Some(2));
        let expected = LineFormat {
            baud: 115_200,
            data_bits: 7,
            parity: Parity::Even,
            stop_bits: 2,
        };
        assert_eq!(changed, expected);
        let changed = factory.changed(None, Some(Parity::None), None, None);
        assert_eq!(changed, LineFormat::new(9_600));
    }

    #[test]
    fn bad_formats_are_refused_and_never_divide_by_zero() {
        let zero = LineFormat::new(0);
        assert_eq!(zero.check(), Err(LineFormatError::ZeroBaud));
        assert_eq!(zero.character_time(), Duration::from_secs(10));
        let seven = LineFormat {
            data_bits: 9,
            ..LineFormat::new(9_600)
        };
        assert_eq!(seven.check(), Err(LineFormatError::DataBits(9)));
        assert_eq!(LineFormat::new(19_200).check(), Ok(()));
    }
}
