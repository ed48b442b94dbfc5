//! A register's words ⇄ its raw value.

use core::ops::Deref;

use optobus_codec::value::{join_u32, split_u32};

use crate::register::RegisterInfo;

/// The words of a one- or two-word raw value, in address order.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawWords {
    words: [u16; 2],
    len: usize,
}

impl Deref for RawWords {
    type Target = [u16];

    fn deref(&self) -> &[u16] {
        self.words.get(..self.len).unwrap_or(&self.words)
    }
}

impl RegisterInfo {
    /// The raw value a register holds in `words` (address order): one word, or two joined in
    /// the register's word order. Missing words read as 0; words after the second are ignored.
    pub fn raw(&self, words: &[u16]) -> u32 {
        let word = |i: usize| words.get(i).copied().unwrap_or(0);
        if self.words >= 2 {
            join_u32([word(0), word(1)], self.word_order)
        } else {
            u32::from(word(0))
        }
    }

    /// The words holding `raw`: one (the low half), or two in the register's word order.
    pub fn raw_words(&self, raw: u32) -> RawWords {
        if self.words >= 2 {
            RawWords {
                words: split_u32(raw, self.word_order),
                len: 2,
            }
        } else {
            RawWords {
                words: [raw as u16, 0],
                len: 1,
            }
        }
    }
}
