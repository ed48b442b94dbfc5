//! Bytes as people read them on a line: `01 03 00 1F`.

use core::fmt;

/// `Display`s bytes in hex, space separated (`01 03 00 1F`); nothing is written until it is
/// formatted, so a frame log that is switched off costs nothing.
#[derive(Clone, Copy, Debug)]
pub struct Hex<'a>(pub &'a [u8]);

impl fmt::Display for Hex<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, byte) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{byte:02X}")?;
        }
        Ok(())
    }
}
