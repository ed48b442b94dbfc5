//! A register's stored words: its raw value in the register's words (device facts in
//! `optobus-device`), padded to the register's width.

use optobus_device::RegisterInfo;

/// The stored words of a register holding `raw` (words after the second are zero).
pub(crate) fn split(register: &RegisterInfo, raw: u32) -> Vec<u16> {
    let mut words = register.raw_words(raw).to_vec();
    words.resize(usize::from(register.words).max(words.len()), 0);
    words
}
