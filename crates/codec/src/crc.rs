//! CRC-16/MODBUS: reflected polynomial 0xA001, initial value 0xFFFF, no final XOR.
//!
//! The checksum is appended to an RTU frame low byte first. The lookup tables are derived from
//! the polynomial at compile time (the tables printed in two of the vendor manuals are corrupt),
//! and the hot loop consumes 16 bytes per step ("slice-by-16").

/// The reflected generator polynomial of CRC-16/MODBUS (0x8005 bit-reversed).
pub const POLYNOMIAL: u16 = 0xA001;

/// The register value before the first byte.
pub const INITIAL: u16 = 0xFFFF;

const SLICES: usize = 16;

/// `TABLES[0][b]` is the CRC of byte `b` from a zero register; `TABLES[k][b]` is the same
/// byte followed by `k` zero bytes, which lets one step fold 16 input bytes at once.
static TABLES: [[u16; 256]; SLICES] = build_tables();

/// Eight bit steps of the reflected register: the byte XORed into its low bits shifted out
/// through the polynomial.
const fn shift_byte(mut crc: u16) -> u16 {
    let mut bit = 0;
    while bit < 8 {
        crc = if crc & 1 != 0 {
            (crc >> 1) ^ POLYNOMIAL
        } else {
            crc >> 1
        };
        bit += 1;
    }
    crc
}

const fn build_tables() -> [[u16; 256]; SLICES] {
    let mut tables = [[0u16; 256]; SLICES];
    let mut byte = 0;
    while byte < 256 {
        tables[0][byte] = shift_byte(byte as u16);
        byte += 1;
    }
    let mut slice = 1;
    while slice < SLICES {
        let mut byte = 0;
        while byte < 256 {
            let previous = tables[slice - 1][byte];
            tables[slice][byte] = (previous >> 8) ^ tables[0][(previous & 0xFF) as usize];
            byte += 1;
        }
        slice += 1;
    }
    tables
}

/// The CRC-16/MODBUS of `data`.
///
/// ```
/// // The request "read 3 holding registers from 0 on slave 1" ends in 05 CB.
/// let crc = optobus_codec::crc::crc16(&[0x01, 0x03, 0x00, 0x00, 0x00, 0x03]);
/// assert_eq!(crc.to_le_bytes(), [0x05, 0xCB]);
/// ```
#[inline]
pub fn crc16(data: &[u8]) -> u16 {
    update(INITIAL, data)
}

/// Bit-at-a-time CRC-16/MODBUS: slow, obviously correct, and usable in `const` context.
pub const fn crc16_bitwise(data: &[u8]) -> u16 {
    let mut crc = INITIAL;
    let mut index = 0;
    while index < data.len() {
        crc = shift_byte(crc ^ data[index] as u16);
        index += 1;
    }
    crc
}

/// Continues a CRC computation: `update(update(INITIAL, a), b) == crc16(a ++ b)`.
#[inline]
pub fn update(mut crc: u16, data: &[u8]) -> u16 {
    let t = &TABLES;
    let (blocks, rest) = data.as_chunks::<SLICES>();
    for block in blocks {
        // The bytes that do not depend on the running CRC go first, so their lookups overlap
        // with the previous step's; the two that do depend on it come last.
        let [low, high] = (crc ^ u16::from_le_bytes([block[0], block[1]])).to_le_bytes();
        crc = t[0][usize::from(block[15])]
            ^ t[1][usize::from(block[14])]
            ^ t[2][usize::from(block[13])]
            ^ t[3][usize::from(block[12])]
            ^ t[4][usize::from(block[11])]
            ^ t[5][usize::from(block[10])]
            ^ t[6][usize::from(block[9])]
            ^ t[7][usize::from(block[8])]
            ^ t[8][usize::from(block[7])]
            ^ t[9][usize::from(block[6])]
            ^ t[10][usize::from(block[5])]
            ^ t[11][usize::from(block[4])]
            ^ t[12][usize::from(block[3])]
            ^ t[13][usize::from(block[2])]
            ^ t[14][usize::from(high)]
            ^ t[15][usize::from(low)];
    }
    let (quads, tail) = rest.as_chunks::<4>();
    for quad in quads {
        let [low, high] = (crc ^ u16::from_le_bytes([quad[0], quad[1]])).to_le_bytes();
        crc = t[0][usize::from(quad[3])]
            ^ t[1][usize::from(quad[2])]
            ^ t[2][usize::from(high)]
            ^ t[3][usize::from(low)];
    }
    for &byte in tail {
        crc = (crc >> 8) ^ t[0][usize::from((crc as u8) ^ byte)];
    }
    crc
}

/// An incremental CRC-16/MODBUS, for frames that arrive in pieces.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Crc16 {
    state: u16,
}

impl Crc16 {
    /// A computation over no bytes yet.
    pub const fn new() -> Self {
        Self { state: INITIAL }
    }

    /// Feeds more bytes.
    pub fn update(&mut self, data: &[u8]) {
        self.state = update(self.state, data);
    }

    /// The CRC of every byte fed so far.
    pub const fn finish(&self) -> u16 {
        self.state
    }
}

impl Default for Crc16 {
    fn default() -> Self {
        Self::new()
    }
}

/// True when the last two bytes of `frame` are the CRC (low byte first) of the bytes before.
pub fn is_valid_frame(frame: &[u8]) -> bool {
    match frame.split_last_chunk::<2>() {
        Some((body, crc)) if !body.is_empty() => crc16(body) == u16::from_le_bytes(*crc),
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value_of_the_catalogue() {
        // The CRC catalogue's check value for CRC-16/MODBUS over "123456789".
        assert_eq!(crc16(b"123456789"), 0x4B37);
        assert_eq!(crc16_bitwise(b"123456789"), 0x4B37);
    }

    #[test]
    fn empty_input_is_the_initial_value() {
        assert_eq!(crc16(&[]), INITIAL);
    }

    #[test]
    fn table_row_zero_matches_the_classic_table_start() {
        // First entries of the (correct) published reflected 0xA001 table.
        assert_eq!(&TABLES[0][..4], &[0x0000, 0xC0C1, 0xC181, 0x0140]);
        assert_eq!(TABLES[0][255], 0x4040);
    }

    #[test]
    fn split_updates_match_one_shot() {
        let data: [u8; 40] = core::array::from_fn(|i| (i * 37 + 11) as u8);
        for cut in 0..data.len() {
            let mut crc = Crc16::new();
            crc.update(&data[..cut]);
            crc.update(&data[cut..]);
            assert_eq!(crc.finish(), crc16_bitwise(&data), "cut at {cut}");
        }
    }

    #[test]
    fn frame_validity() {
        assert!(is_valid_frame(&[
            0x01, 0x03, 0x00, 0x00, 0x00, 0x03, 0x05, 0xCB
        ]));
        assert!(!is_valid_frame(&[
            0x01, 0x03, 0x00, 0x00, 0x00, 0x03, 0xCB, 0x05
        ]));
        assert!(!is_valid_frame(&[0x05, 0xCB]));
        assert!(!is_valid_frame(&[]));
    }
}
