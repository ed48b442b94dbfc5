//! Exact decimals: `mantissa × 10^exponent`, added, subtracted and multiplied without rounding;
//! divided to a stated resolution, rounding half to even.

use std::cmp::Ordering;
use std::fmt;

use optobus_codec::value::{Fixed, Scale};

/// An exact decimal number, `mantissa × 10^exponent`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Decimal {
    mantissa: i128,
    exponent: i32,
}

/// Why a computation has no exact result: its numbers outgrew 128 bits, or it divided by
/// zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ArithmeticError {
    /// A result's digits do not fit 128 bits.
    Overflow,
    /// A division by zero.
    DivisionByZero,
}

impl fmt::Display for ArithmeticError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Overflow => "the result has more digits than 128 bits hold",
            Self::DivisionByZero => "a division by zero",
        })
    }
}

impl std::error::Error for ArithmeticError {}

type Result<T> = std::result::Result<T, ArithmeticError>;

fn pow10(exponent: u32) -> Result<i128> {
    10i128
        .checked_pow(exponent)
        .ok_or(ArithmeticError::Overflow)
}

impl Decimal {
    /// Zero.
    pub const ZERO: Self = Self {
        mantissa: 0,
        exponent: 0,
    };

    /// `mantissa × 10^exponent`.
    pub const fn new(mantissa: i128, exponent: i32) -> Self {
        Self { mantissa, exponent }
    }

    /// The digits.
    pub const fn mantissa(self) -> i128 {
        self.mantissa
    }

    /// The power of ten of the last digit.
    pub const fn exponent(self) -> i32 {
        self.exponent
    }

    /// A register's exact value, multiplied by `10^shift` (its unit's power of ten in the base
    /// unit). `None` for a step that is no finite decimal (a ratio whose denominator has a
    /// factor other than 2 and 5).
    pub fn from_fixed(value: Fixed, shift: i32) -> Option<Self> {
        let raw = i128::from(value.raw());
        match value.scale() {
            Scale::Decimal { exponent } => Some(Self::new(raw, i32::from(exponent) + shift)),
            Scale::Ratio {
                numerator,
                denominator,
            } => {
                // n/d = n × (10^k / d) / 10^k, exact when d divides 10^k.
                let denominator = i128::from(denominator.get());
                let (mut twos, mut fives, mut rest) = (0u32, 0u32, denominator);
                while rest % 2 == 0 {
                    rest /= 2;
                    twos += 1;
                }
                while rest % 5 == 0 {
                    rest /= 5;
                    fives += 1;
                }
                if rest != 1 {
                    return None;
                }
                let digits = twos.max(fives);
                let factor = pow10(digits).ok()? / denominator;
                let mantissa = raw
                    .checked_mul(i128::from(numerator))?
                    .checked_mul(factor)?;
                Some(Self::new(mantissa, shift - i32::try_from(digits).ok()?))
            }
        }
    }

    /// This number with its last digit at `10^exponent`, exactly; fails if that would drop
    /// digits that are not zero, or overflow.
    fn at_exponent(self, exponent: i32) -> Result<i128> {
        match self.exponent.cmp(&exponent) {
            Ordering::Equal => Ok(self.mantissa),
            Ordering::Greater => {
                let shift = u32::try_from(self.exponent - exponent)
                    .map_err(|_| ArithmeticError::Overflow)?;
                self.mantissa
                    .checked_mul(pow10(shift)?)
                    .ok_or(ArithmeticError::Overflow)
            }
            Ordering::Less => Err(ArithmeticError::Overflow),
        }
    }

    /// Both numbers with their last digit at the finer of the two exponents.
    fn aligned(self, other: Self) -> Result<(i128, i128, i32)> {
        let exponent = self.exponent.min(other.exponent);
        Ok((
            self.at_exponent(exponent)?,
            other.at_exponent(exponent)?,
            exponent,
        ))
    }

    /// `self + other`, exactly.
    pub fn checked_add(self, other: Self) -> Result<Self> {
        let (a, b, exponent) = self.aligned(other)?;
        let sum = a.checked_add(b).ok_or(ArithmeticError::Overflow)?;
        Ok(Self::new(sum, exponent).trimmed())
    }

    /// `self − other`, exactly.
    pub fn checked_sub(self, other: Self) -> Result<Self> {
        self.checked_add(other.checked_neg()?)
    }

    /// `−self`.
    pub fn checked_neg(self) -> Result<Self> {
        let mantissa = self
            .mantissa
            .checked_neg()
            .ok_or(ArithmeticError::Overflow)?;
        Ok(Self::new(mantissa, self.exponent))
    }

    /// `|self|`.
    pub fn checked_abs(self) -> Result<Self> {
        if self.mantissa < 0 {
            self.checked_neg()
        } else {
            Ok(self)
        }
    }

    /// `self × other`, exactly.
    pub fn checked_mul(self, other: Self) -> Result<Self> {
        let mantissa = self
            .mantissa
            .checked_mul(other.mantissa)
            .ok_or(ArithmeticError::Overflow)?;
        let exponent = self
            .exponent
            .checked_add(other.exponent)
            .ok_or(ArithmeticError::Overflow)?;
        Ok(Self::new(mantissa, exponent).trimmed())
    }

    /// `self ÷ other` with its last digit at `10^resolution`, rounded half to even.
    pub fn div_to(self, other: Self, resolution: i32) -> Result<Self> {
        if other.mantissa == 0 {
            return Err(ArithmeticError::DivisionByZero);
        }
        // q = a·10^ea / (b·10^eb) = (a·10^(ea−eb−r) / b) · 10^r.
        let shift = i64::from(self.exponent) - i64::from(other.exponent) - i64::from(resolution);
        let (numerator, denominator) = if shift >= 0 {
            let shift = u32::try_from(shift).map_err(|_| ArithmeticError::Overflow)?;
            let numerator = self
                .mantissa
                .checked_mul(pow10(shift)?)
                .ok_or(ArithmeticError::Overflow)?;
            (numerator, other.mantissa)
        } else {
            let shift = u32::try_from(-shift).map_err(|_| ArithmeticError::Overflow)?;
            let denominator = other
                .mantissa
                .checked_mul(pow10(shift)?)
                .ok_or(ArithmeticError::Overflow)?;
            (self.mantissa, denominator)
        };
        Ok(Self::new(divide_half_even(numerator, denominator), resolution).trimmed())
    }

    /// This number rounded half to even to its last digit at `10^resolution` (unchanged if it
    /// has no finer digits).
    pub fn round_to(self, resolution: i32) -> Result<Self> {
        if self.exponent >= resolution {
            return Ok(self);
        }
        let shift =
            u32::try_from(resolution - self.exponent).map_err(|_| ArithmeticError::Overflow)?;
        // Beyond 38 digits every i128 rounds to zero.
        let Ok(divisor) = pow10(shift) else {
            return Ok(Self::new(0, resolution));
        };
        Ok(Self::new(
            divide_half_even(self.mantissa, divisor),
            resolution,
        ))
    }

    /// Trailing zero digits moved into the exponent, so that long chains stay small.
    fn trimmed(self) -> Self {
        let Self {
            mut mantissa,
            mut exponent,
        } = self;
        if mantissa == 0 {
            return self;
        }
        while mantissa % 10 == 0 && exponent < i32::MAX {
            mantissa /= 10;
            exponent += 1;
        }
        Self::new(mantissa, exponent)
    }

    /// The value at `10^exponent` steps as a register value would be, or `None` when it needs
    /// finer steps or more than 64 bits.
    pub fn to_fixed(self, exponent: i32) -> Option<Fixed> {
        let exponent8 = i8::try_from(exponent).ok()?;
        let raw = i64::try_from(self.at_exponent(exponent).ok()?).ok()?;
        Some(Fixed::new(
            raw,
            Scale::Decimal {
                exponent: exponent8,
            },
        ))
    }

    /// The value as the nearest `f64` (for statistics and charts).
    pub fn to_f64(self) -> f64 {
        self.mantissa as f64 * 10f64.powi(self.exponent)
    }

    /// The order of two numbers, exactly where their digits align in 128 bits.
    pub fn compare(self, other: Self) -> Ordering {
        match self.aligned(other) {
            Ok((a, b, _)) => a.cmp(&b),
            Err(_) => self.to_f64().total_cmp(&other.to_f64()),
        }
    }
}

impl PartialEq for Decimal {
    fn eq(&self, other: &Self) -> bool {
        self.compare(*other) == Ordering::Equal
    }
}

/// `numerator / denominator` rounded to the nearest integer, ties to even.
fn divide_half_even(numerator: i128, denominator: i128) -> i128 {
    let (quotient, remainder) = (numerator / denominator, numerator % denominator);
    if remainder == 0 {
        return quotient;
    }
    // |2·remainder| against |denominator|, without overflow.
    let twice = remainder.unsigned_abs().saturating_mul(2);
    let away = match twice.cmp(&denominator.unsigned_abs()) {
        Ordering::Greater => true,
        Ordering::Less => false,
        Ordering::Equal => quotient % 2 != 0,
    };
    if !away {
        return quotient;
    }
    if (numerator < 0) == (denominator < 0) {
        quotient + 1
    } else {
        quotient - 1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_and_products_are_exact() {
        let a = Decimal::new(3_584_190, -9); // 3.584190 mm in m
        let b = Decimal::new(2, -2); // 0.02 m
        assert_eq!(b.checked_sub(a).unwrap(), Decimal::new(16_415_810, -9));
        assert_eq!(
            a.checked_mul(Decimal::new(3, 0)).unwrap(),
            Decimal::new(10_752_570, -9)
        );
    }

    #[test]
    fn divisions_round_half_to_even_at_the_resolution() {
        let one = Decimal::new(1, 0);
        assert_eq!(
            one.div_to(Decimal::new(3, 0), -3).unwrap(),
            Decimal::new(333, -3)
        );
        assert_eq!(
            Decimal::new(5, -3).div_to(Decimal::new(2, 0), -3).unwrap(),
            Decimal::new(2, -3)
        );
        assert_eq!(
            Decimal::new(7, -3).div_to(Decimal::new(2, 0), -3).unwrap(),
            Decimal::new(4, -3)
        );
        assert_eq!(
            Decimal::new(-7, -3).div_to(Decimal::new(2, 0), -3).unwrap(),
            Decimal::new(-4, -3)
        );
        assert_eq!(
            one.div_to(Decimal::ZERO, -3),
            Err(ArithmeticError::DivisionByZero)
        );
    }

    #[test]
    fn binary_steps_are_exact_decimals() {
        let slope = Fixed::new(3, Scale::ratio(1, 1 << 20).unwrap());
        let exact = Decimal::from_fixed(slope, 0).unwrap();
        assert_eq!(exact.to_f64(), 3.0 / 1_048_576.0);
        assert!(Decimal::from_fixed(Fixed::new(1, Scale::ratio(1, 3).unwrap()), 0).is_none());
    }

    #[test]
    fn overflow_is_an_error_not_a_wrong_value() {
        let huge = Decimal::new(i128::MAX / 2, 0);
        assert_eq!(
            huge.checked_mul(Decimal::new(3, 0)),
            Err(ArithmeticError::Overflow)
        );
        assert_eq!(huge.checked_add(huge).map(|_| ()), Ok(()));
        assert_eq!(
            huge.checked_add(huge).unwrap().checked_add(huge),
            Err(ArithmeticError::Overflow)
        );
    }
}
