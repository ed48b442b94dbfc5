//! Exact quantities: a register's fixed-point value tagged with its unit.
//!
//! A ×1e6 mm distance of 3584190 reads as `Millimetres` holding exactly 3.584190; convert to
//! `f64` only when you choose to. Setters take the same types and refuse values that are not
//! a whole number of the register's steps, so nothing is rounded behind your back.

use std::fmt;
use std::str::FromStr;

use optobus_codec::value::{Fixed, ParseFixedError, Scale};
use optobus_device::RegisterInfo;

use crate::convert::{Decode, Encode};
use crate::error::Error;

/// Multiplies a value by `10^shift` exactly (a change of unit prefix).
fn shift(value: Fixed, shift: i8) -> Fixed {
    match value.scale() {
        Scale::Decimal { exponent } => match exponent.checked_add(shift) {
            Some(exponent) => Fixed::new(value.raw(), Scale::Decimal { exponent }),
            None => value,
        },
        Scale::Ratio {
            numerator,
            denominator,
        } if shift >= 0 => 10u32
            .checked_pow(u32::from(shift.unsigned_abs()))
            .and_then(|p| numerator.checked_mul(p))
            .map_or(value, |numerator| {
                Fixed::new(
                    value.raw(),
                    Scale::Ratio {
                        numerator,
                        denominator,
                    },
                )
            }),
        Scale::Ratio { .. } => value,
    }
}

macro_rules! unit {
    ($(#[$doc:meta])* $name:ident, $symbol:literal, $accessor:ident $(, $other:ident = $shift:literal)*) => {
        $(#[$doc])*
        #[derive(Clone, Copy, PartialEq, Eq, Hash)]
        pub struct $name(Fixed);

        /// `Millimetres(3.584190)`: the exact value, not its raw steps.
        impl fmt::Debug for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{}({})", stringify!($name), self.0)
            }
        }

        /// `{"value": "3.584190", "unit": "mm"}`: exact text, never a rounded float.
        #[cfg(feature = "serde")]
        impl serde::Serialize for $name {
            fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                serde::Serialize::serialize(&crate::shapes::Quantity { value: self.0, unit: Self::SYMBOL.into() }, serializer)
            }
        }

        /// The shape it serialises to; refused unless the unit is this one.
        #[cfg(feature = "serde")]
        impl<'de> serde::Deserialize<'de> for $name {
            fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                <crate::shapes::Quantity<'_> as serde::Deserialize>::deserialize(deserializer)?.expect(Self::SYMBOL).map(Self)
            }
        }

        impl $name {
            /// The unit's symbol.
            pub const SYMBOL: &'static str = $symbol;

            /// Wraps an exact value given in this unit.
            pub const fn new(value: Fixed) -> Self {
                Self(value)
            }

            #[doc = concat!("The exact value in ", stringify!($accessor), ".")]
            pub const fn $accessor(self) -> Fixed {
                self.0
            }

            $(
                #[doc = concat!("The exact value in ", stringify!($other), ".")]
                pub fn $other(self) -> Fixed {
                    shift(self.0, $shift)
                }
            )*

            /// The value rounded to the nearest `f64`, in this unit.
            pub fn to_f64(self) -> f64 {
                self.0.to_f64()
            }
        }

        impl From<Fixed> for $name {
            fn from(value: Fixed) -> Self {
                Self(value)
            }
        }

        impl From<i32> for $name {
            fn from(value: i32) -> Self {
                Self(Fixed::from(value))
            }
        }

        impl FromStr for $name {
            type Err = ParseFixedError;

            /// Reads an exact decimal number in this unit (`"1.25"`).
            fn from_str(text: &str) -> Result<Self, Self::Err> {
                text.parse().map(Self)
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{} {}", self.0, Self::SYMBOL)
            }
        }

        impl Decode for $name {
            fn decode(register: &RegisterInfo, words: &[u16]) -> Self {
                Self(Fixed::decode(register, words))
            }
        }

        impl Encode for $name {
            fn encode(&self, register: &'static RegisterInfo) -> Result<Vec<u16>, Error> {
                self.0.encode(register)
            }
        }
    };
}

unit!(
    /// A length in millimetres.
    Millimetres, "mm", millimetres, micrometres = 3, nanometres = 6
);
unit!(
    /// A duration in microseconds.
    Microseconds, "us", microseconds, nanoseconds = 3
);
unit!(
    /// A share in percent.
    Percent, "%", percent
);
unit!(
    /// A temperature in degrees Celsius.
    DegreesCelsius, "°C", degrees_celsius
);
unit!(
    /// A voltage in microvolts.
    Microvolts, "uV", microvolts, nanovolts = 3
);
unit!(
    /// A frequency in hertz.
    Hertz, "Hz", hertz
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefixes_shift_exactly() {
        let d = Millimetres::new(Fixed::new(3_584_190, Scale::Decimal { exponent: -6 }));
        assert_eq!(d.to_string(), "3.584190 mm");
        assert_eq!(d.micrometres().to_string(), "3584.190");
        assert_eq!(d.nanometres().to_string(), "3584190");
        let parsed: Millimetres = "-1.5".parse().unwrap();
        assert_eq!(parsed.micrometres().to_string(), "-1500");
        assert_eq!(format!("{d:?}"), "Millimetres(3.584190)");
    }

    #[cfg(feature = "serde")]
    #[test]
    fn quantities_serialise_as_exact_text_with_their_unit() {
        let d = Millimetres::new(Fixed::new(3_584_190, Scale::Decimal { exponent: -6 }));
        let json = serde_json::to_string(&d).unwrap();
        assert_eq!(json, r#"{"value":"3.584190","unit":"mm"}"#);
        assert_eq!(serde_json::from_str::<Millimetres>(&json).unwrap(), d);
        let wrong_unit = serde_json::from_str::<Millimetres>(r#"{"value":"3.5","unit":"us"}"#);
        let error = wrong_unit.unwrap_err().to_string();
        assert!(
            error.contains("a value in mm expected, got one in us"),
            "{error}"
        );
        let celsius: DegreesCelsius =
            serde_json::from_str(r#"{"value":"-12.5","unit":"°C"}"#).unwrap();
        assert_eq!(celsius.to_string(), "-12.5 °C");
    }
}
