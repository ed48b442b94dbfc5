//! The `Decode` and `Encode` traits: typed values to and from register words.

use std::fmt;
use std::net::Ipv4Addr;

use optobus_codec::value::{Fixed, Scale};
use optobus_device::{CodeInfo, RegisterInfo, ValueKind};

use crate::error::Error;

/// A value read from a register's words.
///
/// Decoding never fails: undefined enum codes become `Unknown(raw)`, and a register with a
/// sentinel is read as `Option<_>` (`None` for "invalid").
pub trait Decode: Sized {
    /// The value `register` holds in `words` (its words in address order).
    fn decode(register: &RegisterInfo, words: &[u16]) -> Self;
}

/// A value that can be written to a register, validated first.
pub trait Encode {
    /// The register's words in address order, or why the value cannot be written.
    fn encode(&self, register: &'static RegisterInfo) -> Result<Vec<u16>, Error>;
}

/// The register's bits: one word, or two joined in the register's word order.
pub fn raw_bits(register: &RegisterInfo, words: &[u16]) -> u32 {
    register.raw(words)
}

/// The first `N` of a register's words, zeros where fewer were read (version and record
/// values decode from a fixed number of words).
pub fn word_array<const N: usize>(words: &[u16]) -> [u16; N] {
    let mut all = [0; N];
    for (slot, word) in all.iter_mut().zip(words) {
        *slot = *word;
    }
    all
}

/// The register's integer value, sign-extended by its wire type.
fn integer(register: &RegisterInfo, words: &[u16]) -> i64 {
    register.scalar().extend(raw_bits(register, words))
}

/// The words of `bits` for `register`.
pub(crate) fn bits_to_words(register: &RegisterInfo, bits: u32) -> Vec<u16> {
    register.raw_words(bits).to_vec()
}

/// Checks `value` against the register's range, wire type and codes
/// ([`RegisterInfo::check_integer`]), and gives its words.
pub fn encode_integer(register: &'static RegisterInfo, value: i64) -> Result<Vec<u16>, Error> {
    let bits = register
        .check_integer(value)
        .map_err(|why| Error::invalid(register, why))?;
    Ok(bits_to_words(register, bits))
}

/// Checks that `code` is one the register defines, and gives its words.
pub fn encode_code(register: &'static RegisterInfo, code: u32) -> Result<Vec<u16>, Error> {
    encode_integer(register, i64::from(code))
}

/// Checks packed `bits` ([`RegisterInfo::check`]: each field's codes and range, no bit
/// outside the fields), and gives the words; `None` is a field too wide for its bits.
pub fn encode_packed(
    register: &'static RegisterInfo,
    bits: Option<u32>,
) -> Result<Vec<u16>, Error> {
    let bits = bits.ok_or(Error::FieldTooWide {
        register: register.name,
    })?;
    register
        .check(bits)
        .map_err(|why| Error::invalid(register, why))?;
    Ok(bits_to_words(register, bits))
}

/// A generated value kept in a register's raw bits: a code enum (`Unknown(raw)` for codes the
/// manual does not define) or a packed struct of bit fields.
///
/// [`Decode`] and [`Encode`] come with it, written once here: a read never fails; a write is
/// refused unless every code is one the register (or its packed field) defines and every
/// field fits its bits and range.
pub trait RawValue: Copy + PartialEq + 'static {
    /// The value of the register's raw bits.
    fn from_raw(raw: u32) -> Self;

    /// The raw bits; `None` when a packed field does not fit its bits.
    fn to_raw(self) -> Option<u32>;
}

impl<V: RawValue> Decode for V {
    fn decode(register: &RegisterInfo, words: &[u16]) -> Self {
        V::from_raw(raw_bits(register, words))
    }
}

impl<V: RawValue> Encode for V {
    fn encode(&self, register: &'static RegisterInfo) -> Result<Vec<u16>, Error> {
        if let ValueKind::Packed(_) = register.kind {
            return encode_packed(register, self.to_raw());
        }
        let code = self.to_raw().unwrap_or(u32::MAX);
        // `Unknown(0)` where 0 is a named code is not a value a read gives: refused too.
        if V::from_raw(code) != *self {
            return Err(Error::UndefinedCode {
                register: register.name,
                field: None,
                code,
            });
        }
        encode_code(register, code)
    }
}

/// A generated enum of codes: the [`RawValue`] of an enumerated register or field, with its
/// codes as data.
pub trait CodeEnum: RawValue {
    /// Every defined code, in the manual's order.
    const CODES: &'static [CodeInfo];

    /// The code as defined in the spec; `None` for `Unknown` values.
    fn info(self) -> Option<&'static CodeInfo> {
        let raw = self.to_raw()?;
        Self::CODES
            .iter()
            .find(|code| code.code == raw)
            .filter(|_| Self::from_raw(raw) == self)
    }

    /// The snake_case name of a defined code.
    fn name(self) -> Option<&'static str> {
        self.info().map(|code| code.name)
    }

    /// Writes the code's name, or `unknown (raw)`: the `Display` of every code enum.
    fn write_name(self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.name(), self.to_raw()) {
            (Some(name), _) => f.write_str(name),
            (None, Some(raw)) => write!(f, "unknown ({raw})"),
            (None, None) => f.write_str("unknown"),
        }
    }
}

impl<V: Decode> Decode for Option<V> {
    /// `None` when the register holds its "invalid" sentinel.
    fn decode(register: &RegisterInfo, words: &[u16]) -> Self {
        match register.sentinel {
            Some(sentinel) if raw_bits(register, words) == sentinel => None,
            _ => Some(V::decode(register, words)),
        }
    }
}

impl Decode for bool {
    fn decode(register: &RegisterInfo, words: &[u16]) -> Self {
        raw_bits(register, words) != 0
    }
}

impl Encode for bool {
    fn encode(&self, register: &'static RegisterInfo) -> Result<Vec<u16>, Error> {
        Ok(bits_to_words(register, u32::from(*self)))
    }
}

macro_rules! integers {
    ($($ty:ty),*) => {$(
        impl Decode for $ty {
            fn decode(register: &RegisterInfo, words: &[u16]) -> Self {
                // The generator picks the type from the register's wire type, so this fits.
                integer(register, words) as $ty
            }
        }

        impl Encode for $ty {
            fn encode(&self, register: &'static RegisterInfo) -> Result<Vec<u16>, Error> {
                encode_integer(register, i64::from(*self))
            }
        }
    )*};
}

integers!(u16, i16, u32, i32);

impl Decode for Fixed {
    fn decode(register: &RegisterInfo, words: &[u16]) -> Self {
        Fixed::new(
            integer(register, words),
            register.scale.unwrap_or(Scale::ONE),
        )
    }
}

impl Encode for Fixed {
    fn encode(&self, register: &'static RegisterInfo) -> Result<Vec<u16>, Error> {
        let scale = register.scale.unwrap_or(Scale::ONE);
        let steps = self.to_scale(scale).map_err(|_| Error::NotRepresentable {
            register: register.name,
            value: *self,
            scale,
            unit: register.unit,
        })?;
        encode_integer(register, steps.raw())
    }
}

impl Decode for Ipv4Addr {
    /// Four words, one octet each.
    fn decode(_register: &RegisterInfo, words: &[u16]) -> Self {
        let octet = |i: usize| words.get(i).map_or(0, |w| *w as u8);
        Ipv4Addr::new(octet(0), octet(1), octet(2), octet(3))
    }
}

impl Encode for Ipv4Addr {
    fn encode(&self, _register: &'static RegisterInfo) -> Result<Vec<u16>, Error> {
        Ok(self.octets().iter().map(|&o| u16::from(o)).collect())
    }
}
