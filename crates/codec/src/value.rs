//! Register value codecs: integers across words, packed bytes, bit fields, invalid-reading
//! sentinels and the order of split writes; exact fixed-point numbers ([`Fixed`], [`Scale`])
//! live in their own file and are re-exported here.

pub use crate::fixed::{Fixed, ParseFixedError, Scale, Step};

/// Which 16-bit word of a 32-bit value sits at the lower register address.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum WordOrder {
    /// High word at the lower address (every manual here; "big-endian word order").
    #[default]
    HighFirst,
    /// Low word at the lower address.
    LowFirst,
}

impl WordOrder {
    /// The offset (0 or 1) of the high word of a register pair from its first address.
    pub const fn high_offset(self) -> u16 {
        match self {
            Self::HighFirst => 0,
            Self::LowFirst => 1,
        }
    }
}

/// Joins two words, listed in address order, into a `u32`.
pub const fn join_u32(words: [u16; 2], order: WordOrder) -> u32 {
    let [first, second] = words;
    let (high, low) = match order {
        WordOrder::HighFirst => (first, second),
        WordOrder::LowFirst => (second, first),
    };
    ((high as u32) << 16) | low as u32
}

/// Splits a `u32` into two words in address order.
pub const fn split_u32(value: u32, order: WordOrder) -> [u16; 2] {
    let (high, low) = ((value >> 16) as u16, value as u16);
    match order {
        WordOrder::HighFirst => [high, low],
        WordOrder::LowFirst => [low, high],
    }
}

/// Joins two words, listed in address order, into an `i32` (two's complement).
pub const fn join_i32(words: [u16; 2], order: WordOrder) -> i32 {
    join_u32(words, order) as i32
}

/// Splits an `i32` into two words in address order.
pub const fn split_i32(value: i32, order: WordOrder) -> [u16; 2] {
    split_u32(value as u32, order)
}

/// A 16-bit register read as a signed value.
pub const fn word_to_i16(word: u16) -> i16 {
    word as i16
}

/// A signed value as the 16-bit register it is written as.
pub const fn i16_to_word(value: i16) -> u16 {
    value as u16
}

/// A register whose high and low bytes are separate fields.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct BytePair {
    /// Bits 15..8.
    pub high: u8,
    /// Bits 7..0.
    pub low: u8,
}

impl BytePair {
    /// Splits a register value.
    pub const fn from_word(word: u16) -> Self {
        let [high, low] = word.to_be_bytes();
        Self { high, low }
    }

    /// Joins the bytes into a register value.
    pub const fn to_word(self) -> u16 {
        u16::from_be_bytes([self.high, self.low])
    }
}

/// A run of bits inside a register value (for example the rangefinder's 8-bit parity above a
/// 24-bit baud rate).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct BitField {
    /// Position of the least significant bit.
    pub shift: u8,
    /// Number of bits, 1 to 32.
    pub width: u8,
}

impl BitField {
    const fn mask(self) -> u32 {
        if self.width >= 32 {
            u32::MAX
        } else {
            (1u32 << self.width) - 1
        }
    }

    /// The field's value in `word`.
    pub const fn get(self, word: u32) -> u32 {
        match word.checked_shr(self.shift as u32) {
            Some(shifted) => shifted & self.mask(),
            None => 0,
        }
    }

    /// `word` with the field set to `value`; `None` when `value` does not fit the field.
    pub const fn set(self, word: u32, value: u32) -> Option<u32> {
        let mask = self.mask();
        if value & !mask != 0 || self.shift >= 32 {
            return None;
        }
        let shift = self.shift as u32;
        Some((word & !(mask << shift)) | (value << shift))
    }
}

/// A raw value the device uses to mean "no valid reading".
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Sentinel(pub u32);

impl Sentinel {
    /// `None` when `raw` is the sentinel, else `Some(raw)`.
    pub const fn check(self, raw: u32) -> Option<u32> {
        if raw == self.0 {
            None
        } else {
            Some(raw)
        }
    }
}

/// The order in which the two halves of a 32-bit register pair are written with two FC06s.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum WriteOrder {
    /// High word first (the natural order).
    #[default]
    HighWordFirst,
    /// Low word first (the P series latches the pair when the high word arrives).
    LowWordFirst,
}

/// One FC06 of a split 32-bit write: `offset` is 0 or 1 from the pair's first address.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct WordWrite {
    /// Offset from the pair's first (lower) register address.
    pub offset: u16,
    /// The 16-bit value to write there.
    pub value: u16,
}

/// The two single-register writes that store `value` in a register pair laid out in
/// `word_order`, in the sequence `write_order` demands.
///
/// ```
/// use optobus_codec::value::{u32_writes, WordOrder, WordWrite, WriteOrder};
/// // P series slope 2.0 (×2^20 = 0x0020_0000) at registers 27 (high) and 28 (low):
/// // write register 28 first, then 27.
/// let writes = u32_writes(0x0020_0000, WordOrder::HighFirst, WriteOrder::LowWordFirst);
/// assert_eq!(writes, [WordWrite { offset: 1, value: 0x0000 }, WordWrite { offset: 0, value: 0x0020 }]);
/// ```
pub const fn u32_writes(
    value: u32,
    word_order: WordOrder,
    write_order: WriteOrder,
) -> [WordWrite; 2] {
    let words = split_u32(value, word_order);
    let high_offset = word_order.high_offset();
    let low_offset = 1 - high_offset;
    let high = WordWrite {
        offset: high_offset,
        value: words[high_offset as usize],
    };
    let low = WordWrite {
        offset: low_offset,
        value: words[low_offset as usize],
    };
    match write_order {
        WriteOrder::HighWordFirst => [high, low],
        WriteOrder::LowWordFirst => [low, high],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_and_bytes() {
        assert_eq!(join_i32([0x0036, 0xB0BE], WordOrder::HighFirst), 3_584_190);
        assert_eq!(join_u32([0xB0BE, 0x0036], WordOrder::LowFirst), 0x0036_B0BE);
        assert_eq!(split_i32(-1, WordOrder::HighFirst), [0xFFFF, 0xFFFF]);
        assert_eq!(BytePair::from_word(0x0103), BytePair { high: 1, low: 3 });
        assert_eq!(word_to_i16(0xFEFC), -260);
    }

    #[test]
    fn bit_fields() {
        let parity = BitField {
            shift: 24,
            width: 8,
        };
        let baud = BitField {
            shift: 0,
            width: 24,
        };
        let word = 0x0100_E100;
        assert_eq!((parity.get(word), baud.get(word)), (1, 57_600));
        assert_eq!(baud.set(word, 115_200), Some(0x0101_C200));
        assert_eq!(parity.set(0, 256), None);
    }

    #[test]
    fn sentinels() {
        assert_eq!(Sentinel(0x7FFF_FFFF).check(0x7FFF_FFFF), None);
        assert_eq!(Sentinel(0x8000_0000).check(5), Some(5));
    }
}
