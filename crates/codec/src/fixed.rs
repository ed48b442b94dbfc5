//! Exact fixed-point numbers: a register's raw steps ([`Scale`]) and values counted in them
//! ([`Fixed`]), parsed from and printed as exact decimals.

use core::fmt;
use core::num::NonZeroU32;

/// The size of one raw step of a fixed-point register, exactly.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Scale {
    /// One step is `10^exponent` units (×1e6 mm readings: exponent −6).
    Decimal {
        /// Power of ten.
        exponent: i8,
    },
    /// One step is `numerator / denominator` units (a slope ×2^20: 1/1048576).
    Ratio {
        /// Numerator.
        numerator: u32,
        /// Denominator.
        denominator: NonZeroU32,
    },
}

impl Scale {
    /// One step is one unit.
    pub const ONE: Self = Self::Decimal { exponent: 0 };

    /// The decimal exponents with which every `i64` count of steps prints exactly: up to
    /// 10^19 steps times `i64::MAX` still fits the 128-bit numerator, and down to 10^-37 the
    /// printed digits' remainder times ten still fits 128 bits. Specs are held to it.
    pub const DECIMAL_EXPONENTS: core::ops::RangeInclusive<i8> = -37..=19;

    /// `numerator / denominator`; `None` when the denominator is zero.
    pub const fn ratio(numerator: u32, denominator: u32) -> Option<Self> {
        match NonZeroU32::new(denominator) {
            Some(denominator) => Some(Self::Ratio {
                numerator,
                denominator,
            }),
            None => None,
        }
    }

    /// The step as people read it: a decimal step as the number it is (`0.1`, `1000`), a
    /// ratio as `1/1048576`. (`Display` prints the spec's notation, `1e-1`.)
    pub const fn step(self) -> Step {
        Step(self)
    }

    /// The step as `(numerator, denominator)`, or `None` if it overflows 128 bits.
    fn as_fraction(self) -> Option<(i128, i128)> {
        match self {
            Self::Decimal { exponent } if exponent >= 0 => {
                Some((pow10(exponent.unsigned_abs())?, 1))
            }
            Self::Decimal { exponent } => Some((1, pow10(exponent.unsigned_abs())?)),
            Self::Ratio {
                numerator,
                denominator,
            } => Some((i128::from(numerator), i128::from(denominator.get()))),
        }
    }
}

impl fmt::Display for Scale {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Decimal { exponent } => write!(f, "1e{exponent}"),
            Self::Ratio {
                numerator,
                denominator,
            } => write!(f, "{numerator}/{denominator}"),
        }
    }
}

/// A [`Scale`] printed as the number one step is; see [`Scale::step`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Step(Scale);

impl fmt::Display for Step {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            decimal @ Scale::Decimal { .. } => Fixed::new(1, decimal).fmt(f),
            ratio @ Scale::Ratio { .. } => ratio.fmt(f),
        }
    }
}

/// Divides `a` and `b` by their greatest common divisor.
fn cancel(a: &mut i128, b: &mut i128) {
    let g = gcd(*a, *b);
    if g > 1 {
        *a /= g;
        *b /= g;
    }
}

fn gcd(mut a: i128, mut b: i128) -> i128 {
    while b != 0 {
        (a, b) = (b, a % b);
    }
    a.abs()
}

fn pow10(exponent: u8) -> Option<i128> {
    10i128.checked_pow(u32::from(exponent))
}

/// A fixed-point number kept exactly: an integer count of `scale` steps.
///
/// `Fixed::new(3_584_190, Scale::Decimal { exponent: -6 })` is exactly 3.584190 (whole
/// nanometres for a mm reading); it prints as `3.584190`, and converting to `f64` is the
/// caller's choice.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Fixed {
    raw: i64,
    scale: Scale,
}

/// Why text could not be read as an exact fixed-point value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum ParseFixedError {
    /// Not a decimal number (`[+-]digits[.digits]`).
    Malformed,
    /// More digits than can be held exactly.
    TooManyDigits,
    /// The value is not a whole number of steps (it would need rounding).
    NotRepresentable {
        /// The step size.
        scale: Scale,
    },
    /// The number of steps does not fit in 64 bits.
    OutOfRange,
}

impl fmt::Display for ParseFixedError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Malformed => f.write_str("not a decimal number"),
            Self::TooManyDigits => f.write_str("too many digits"),
            Self::NotRepresentable { scale } => {
                write!(
                    f,
                    "not a whole multiple of the register's step {}",
                    scale.step()
                )
            }
            Self::OutOfRange => f.write_str("value out of range"),
        }
    }
}

impl core::error::Error for ParseFixedError {}

/// Digits of a decimal number: `magnitude / 10^decimals`, negated if `negative`.
struct DecimalText {
    negative: bool,
    magnitude: i128,
    decimals: u8,
}

fn parse_decimal(text: &str) -> Result<DecimalText, ParseFixedError> {
    let bytes = text.trim().as_bytes();
    let (negative, digits) = match bytes.split_first() {
        Some((b'-', rest)) => (true, rest),
        Some((b'+', rest)) => (false, rest),
        _ => (false, bytes),
    };
    let mut magnitude: i128 = 0;
    let mut decimals: u8 = 0;
    let mut seen_point = false;
    let mut seen_digit = false;
    for &byte in digits {
        match byte {
            b'0'..=b'9' => {
                seen_digit = true;
                magnitude = magnitude
                    .checked_mul(10)
                    .and_then(|m| m.checked_add(i128::from(byte - b'0')))
                    .filter(|m| *m < 10i128.pow(36))
                    .ok_or(ParseFixedError::TooManyDigits)?;
                if seen_point {
                    decimals = decimals
                        .checked_add(1)
                        .filter(|d| *d <= 36)
                        .ok_or(ParseFixedError::TooManyDigits)?;
                }
            }
            b'.' if !seen_point => seen_point = true,
            _ => return Err(ParseFixedError::Malformed),
        }
    }
    if !seen_digit {
        return Err(ParseFixedError::Malformed);
    }
    Ok(DecimalText {
        negative,
        magnitude,
        decimals,
    })
}

impl Fixed {
    /// `raw` steps of `scale`.
    pub const fn new(raw: i64, scale: Scale) -> Self {
        Self { raw, scale }
    }

    /// The integer the register holds.
    pub const fn raw(self) -> i64 {
        self.raw
    }

    /// The size of one step.
    pub const fn scale(self) -> Scale {
        self.scale
    }

    /// The value, rounded to the nearest `f64`.
    pub fn to_f64(self) -> f64 {
        let raw = self.raw as f64;
        match self.scale {
            Self::DECIMAL_ZERO => raw,
            Scale::Decimal { exponent } => {
                // Powers of ten up to 1e22 are exact in f64, so one multiplication or division
                // rounds once.
                let mut power = 1f64;
                for _ in 0..exponent.unsigned_abs() {
                    power *= 10.0;
                }
                if exponent > 0 {
                    raw * power
                } else {
                    raw / power
                }
            }
            Scale::Ratio {
                numerator,
                denominator,
            } => raw * f64::from(numerator) / f64::from(denominator.get()),
        }
    }

    const DECIMAL_ZERO: Scale = Scale::Decimal { exponent: 0 };

    /// Reads decimal text such as `-12.5` exactly; fails rather than round.
    ///
    /// ```
    /// use optobus_codec::value::{Fixed, Scale};
    /// let um = Scale::Decimal { exponent: -6 };
    /// assert_eq!(Fixed::parse("0.5", um).unwrap().raw(), 500_000);
    /// assert!(Fixed::parse("0.0000001", um).is_err());
    /// let slope = Scale::ratio(1, 1 << 20).unwrap();
    /// assert_eq!(Fixed::parse("2", slope).unwrap().raw(), 2 << 20);
    /// ```
    pub fn parse(text: &str, scale: Scale) -> Result<Self, ParseFixedError> {
        let text = parse_decimal(text)?;
        let (step_num, step_den) = scale.as_fraction().ok_or(ParseFixedError::OutOfRange)?;
        // value = magnitude / 10^decimals and raw = value * step_den / step_num. Cancel common
        // factors first, so that long exact inputs do not overflow on the way.
        let (mut value_num, mut value_den) = (
            text.magnitude,
            pow10(text.decimals).ok_or(ParseFixedError::TooManyDigits)?,
        );
        let (mut step_num, mut step_den) = (step_num, step_den);
        if step_num == 0 {
            return Err(ParseFixedError::NotRepresentable { scale });
        }
        cancel(&mut value_num, &mut value_den);
        cancel(&mut value_num, &mut step_num);
        cancel(&mut step_den, &mut value_den);
        let numerator = value_num
            .checked_mul(step_den)
            .ok_or(ParseFixedError::OutOfRange)?;
        let denominator = value_den
            .checked_mul(step_num)
            .ok_or(ParseFixedError::OutOfRange)?;
        if numerator % denominator != 0 {
            return Err(ParseFixedError::NotRepresentable { scale });
        }
        let magnitude = numerator / denominator;
        let signed = if text.negative { -magnitude } else { magnitude };
        let raw = i64::try_from(signed).map_err(|_| ParseFixedError::OutOfRange)?;
        Ok(Self { raw, scale })
    }
}

impl Fixed {
    /// The same value in steps of `scale`; fails rather than round, or when the count of
    /// steps does not fit 64 bits.
    ///
    /// ```
    /// use optobus_codec::value::{Fixed, Scale};
    /// let mm: Fixed = "1.25".parse().unwrap();
    /// let micro = Scale::Decimal { exponent: -6 };
    /// assert_eq!(mm.to_scale(micro).unwrap().raw(), 1_250_000);
    /// assert!(mm.to_scale(Scale::Decimal { exponent: -1 }).is_err());
    /// ```
    pub fn to_scale(self, scale: Scale) -> Result<Self, ParseFixedError> {
        if self.scale == scale {
            return Ok(self);
        }
        let (from_num, from_den) = self
            .scale
            .as_fraction()
            .ok_or(ParseFixedError::OutOfRange)?;
        let (to_num, to_den) = scale.as_fraction().ok_or(ParseFixedError::OutOfRange)?;
        if to_num == 0 {
            return Err(ParseFixedError::NotRepresentable { scale });
        }
        // raw' = raw * from_num * to_den / (from_den * to_num), cancelled step by step.
        let (mut value_num, mut value_den) = (i128::from(self.raw), 1i128);
        let (mut from_num, mut from_den, mut to_num, mut to_den) =
            (from_num, from_den, to_num, to_den);
        cancel(&mut from_num, &mut from_den);
        cancel(&mut to_num, &mut to_den);
        cancel(&mut from_num, &mut to_num);
        cancel(&mut to_den, &mut from_den);
        cancel(&mut value_num, &mut from_den);
        cancel(&mut value_num, &mut to_num);
        let numerator = value_num
            .checked_mul(from_num)
            .and_then(|n| n.checked_mul(to_den))
            .ok_or(ParseFixedError::OutOfRange)?;
        value_den = value_den
            .checked_mul(from_den)
            .and_then(|d| d.checked_mul(to_num))
            .ok_or(ParseFixedError::OutOfRange)?;
        if numerator % value_den != 0 {
            return Err(ParseFixedError::NotRepresentable { scale });
        }
        let raw = i64::try_from(numerator / value_den).map_err(|_| ParseFixedError::OutOfRange)?;
        Ok(Self { raw, scale })
    }
}

/// Reads decimal text exactly, in steps of its last digit (`"1.250"` is 1250 × 1e-3).
impl core::str::FromStr for Fixed {
    type Err = ParseFixedError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let parsed = parse_decimal(text)?;
        let magnitude = i64::try_from(parsed.magnitude).map_err(|_| ParseFixedError::OutOfRange)?;
        let exponent =
            -i8::try_from(parsed.decimals).map_err(|_| ParseFixedError::TooManyDigits)?;
        Ok(Self {
            raw: if parsed.negative {
                -magnitude
            } else {
                magnitude
            },
            scale: Scale::Decimal { exponent },
        })
    }
}

/// A whole number of units.
impl From<i32> for Fixed {
    fn from(value: i32) -> Self {
        Self::new(i64::from(value), Scale::ONE)
    }
}

/// Prints the exact value: a decimal scale with exactly its number of decimals
/// (`3.584190`), a ratio scale with the shortest exact decimal (`0.00000095367431640625`).
impl fmt::Display for Fixed {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let Some((step_num, step_den)) = self.scale.as_fraction() else {
            return write!(f, "{}×{}", self.raw, self.scale);
        };
        let Some(value_num) = i128::from(self.raw).checked_mul(step_num) else {
            return write!(f, "{}×{}", self.raw, self.scale);
        };
        let negative = value_num < 0;
        let magnitude = value_num.unsigned_abs();
        let den = step_den.unsigned_abs();
        let (whole, mut remainder) = (magnitude / den, magnitude % den);
        let fixed_decimals = match self.scale {
            Scale::Decimal { exponent } if exponent < 0 => Some(exponent.unsigned_abs()),
            Scale::Decimal { .. } => Some(0),
            Scale::Ratio { .. } => None,
        };
        if negative && (whole != 0 || remainder != 0) {
            f.write_str("-")?;
        }
        write!(f, "{whole}")?;
        let mut written = 0u8;
        let limit = fixed_decimals.unwrap_or(u8::MAX);
        while written < limit && (remainder != 0 || fixed_decimals.is_some()) {
            if written == 0 {
                f.write_str(".")?;
            }
            if written == 60 {
                // A ratio whose decimal expansion does not end: say so rather than loop.
                return f.write_str("…");
            }
            // Cannot overflow within `DECIMAL_EXPONENTS`; beyond them, stop rather than wrap.
            let Some(shifted) = remainder.checked_mul(10) else {
                return f.write_str("…");
            };
            remainder = shifted;
            write!(f, "{}", remainder / den)?;
            remainder %= den;
            written += 1;
        }
        Ok(())
    }
}

/// Exact decimal text, as `Display` writes it: `"3.584190"`, never a rounded float.
#[cfg(feature = "serde")]
impl serde::Serialize for Fixed {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

/// Exact decimal text, in steps of its last digit (as [`FromStr`](core::str::FromStr)).
#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for Fixed {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Text;

        impl serde::de::Visitor<'_> for Text {
            type Value = Fixed;

            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("an exact decimal number as text, e.g. \"3.584190\"")
            }

            fn visit_str<E: serde::de::Error>(self, text: &str) -> Result<Fixed, E> {
                text.parse().map_err(E::custom)
            }
        }

        deserializer.deserialize_str(Text)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    const MICRO: Scale = Scale::Decimal { exponent: -6 };
    const TENTH: Scale = Scale::Decimal { exponent: -1 };

    #[test]
    fn a_step_prints_as_the_number_it_is() {
        assert_eq!(TENTH.step().to_string(), "0.1");
        assert_eq!(MICRO.step().to_string(), "0.000001");
        assert_eq!(Scale::Decimal { exponent: 3 }.step().to_string(), "1000");
        let slope = Scale::ratio(1, 1_048_576).unwrap();
        assert_eq!(slope.step().to_string(), "1/1048576");
        // The spec's notation stays what Display prints.
        assert_eq!(TENTH.to_string(), "1e-1");
    }

    #[cfg(feature = "serde")]
    #[test]
    fn serialises_as_exact_text_and_back() {
        let value = Fixed::new(3_584_190, MICRO);
        let json = serde_json::to_string(&value).unwrap();
        assert_eq!(json, "\"3.584190\"");
        assert_eq!(serde_json::from_str::<Fixed>(&json).unwrap(), value);
        assert!(serde_json::from_str::<Fixed>("\"3.5.1\"").is_err());
        assert!(serde_json::from_str::<Fixed>("3.5").is_err());
    }

    #[test]
    fn prints_exact_decimals() {
        assert_eq!(Fixed::new(3_584_190, MICRO).to_string(), "3.584190");
        assert_eq!(Fixed::new(-5, TENTH).to_string(), "-0.5");
        assert_eq!(Fixed::new(0, TENTH).to_string(), "0.0");
        assert_eq!(
            Fixed::new(12, Scale::Decimal { exponent: 2 }).to_string(),
            "1200"
        );
        let slope = Scale::ratio(1, 1 << 20).unwrap();
        assert_eq!(Fixed::new(2 << 20, slope).to_string(), "2");
        assert_eq!(Fixed::new(1, slope).to_string(), "0.00000095367431640625");
        let third = Scale::ratio(1, 3).unwrap();
        assert!(Fixed::new(1, third).to_string().ends_with('…'));
    }

    #[test]
    fn parses_exactly() {
        assert_eq!(Fixed::parse("3.584190", MICRO).unwrap().raw(), 3_584_190);
        assert_eq!(Fixed::parse("-26", TENTH).unwrap().raw(), -260);
        assert_eq!(Fixed::parse("+0.5", TENTH).unwrap().raw(), 5);
        assert_eq!(
            Fixed::parse("0.05", TENTH),
            Err(ParseFixedError::NotRepresentable { scale: TENTH })
        );
        assert_eq!(
            Fixed::parse("1.2.3", TENTH),
            Err(ParseFixedError::Malformed)
        );
        assert_eq!(Fixed::parse("", TENTH), Err(ParseFixedError::Malformed));
        assert_eq!(Fixed::parse("-", TENTH), Err(ParseFixedError::Malformed));
        assert_eq!(
            Fixed::parse("99999999999999999999", TENTH),
            Err(ParseFixedError::OutOfRange)
        );
        assert_eq!(
            Fixed::parse("1", Scale::Decimal { exponent: 120 }),
            Err(ParseFixedError::OutOfRange)
        );
    }

    #[test]
    fn rescales_exactly() {
        let text: Fixed = "-3.5".parse().unwrap();
        assert_eq!(text.to_scale(MICRO).unwrap().raw(), -3_500_000);
        assert_eq!(text.to_scale(TENTH).unwrap().raw(), -35);
        assert!(text.to_scale(Scale::ONE).is_err());
        let slope = Scale::ratio(1, 1 << 20).unwrap();
        assert_eq!(Fixed::from(2).to_scale(slope).unwrap().raw(), 2 << 20);
        assert_eq!(Fixed::new(1 << 19, slope).to_scale(TENTH).unwrap().raw(), 5);
        assert_eq!(
            Fixed::new(i64::MAX, Scale::ONE).to_scale(MICRO),
            Err(ParseFixedError::OutOfRange)
        );
        assert_eq!("12".parse::<Fixed>().unwrap(), Fixed::new(12, Scale::ONE));
        assert!("1e3".parse::<Fixed>().is_err());
    }

    /// `raw × 10^exponent` written out from `raw`'s own digits.
    fn digits(raw: i64, exponent: i8) -> std::string::String {
        use std::format;
        let digits = raw.unsigned_abs().to_string();
        let sign = if raw < 0 { "-" } else { "" };
        let decimals = usize::from(exponent.unsigned_abs());
        if exponent >= 0 {
            let zeros = if raw == 0 { 0 } else { decimals };
            format!("{sign}{digits}{}", "0".repeat(zeros))
        } else {
            let padded = format!("{digits:0>width$}", width = decimals + 1);
            let (whole, fraction) = padded.split_at(padded.len() - decimals);
            format!("{sign}{whole}.{fraction}")
        }
    }

    /// Every decimal scale specs may use prints every `i64` count exactly, digit for digit,
    /// and nothing overflows.
    #[test]
    fn every_accepted_decimal_scale_prints_every_count() {
        use proptest::prelude::*;
        let mut runner = proptest::test_runner::TestRunner::default();
        let exponents = *Scale::DECIMAL_EXPONENTS.start()..=*Scale::DECIMAL_EXPONENTS.end();
        let raws = prop_oneof![
            Just(i64::MIN),
            Just(i64::MAX),
            Just(0i64),
            Just(-1i64),
            any::<i64>(),
            any::<u32>().prop_map(i64::from),
            any::<i32>().prop_map(i64::from),
        ];
        runner
            .run(&(exponents, raws), |(exponent, raw)| {
                let scale = Scale::Decimal { exponent };
                let text = Fixed::new(raw, scale).to_string();
                prop_assert_eq!(text, digits(raw, exponent));
                Ok(())
            })
            .unwrap();
        // Ratios: a u32 over a u32 never overflows; a terminating one reads back.
        runner
            .run(
                &(1u32.., 0u32..=31, any::<i64>()),
                |(numerator, shift, raw)| {
                    let scale = Scale::ratio(numerator, 1 << shift).unwrap();
                    let text = Fixed::new(raw, scale).to_string();
                    prop_assert!(!text.contains('×'), "{text}");
                    Ok(())
                },
            )
            .unwrap();
    }

    #[test]
    fn scales_beyond_the_bounds_print_without_overflow() {
        for exponent in [-128, -38, 20, 38, 127] {
            for raw in [i64::MIN, -1, 1, i64::MAX] {
                let _ = Fixed::new(raw, Scale::Decimal { exponent }).to_string();
            }
        }
    }

    #[test]
    fn converts_to_float() {
        assert_eq!(Fixed::new(3_584_190, MICRO).to_f64(), 3.58419);
        assert_eq!(Fixed::new(-260, TENTH).to_f64(), -26.0);
    }
}
