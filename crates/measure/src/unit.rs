//! Units and their dimensions: what may be added to what, and what a product or a quotient is.

use std::fmt;

use optobus_inspect::base_unit;

/// The base units a dimension is counted in: metre, second, volt, ampere, degree Celsius.
const BASES: [&str; 5] = ["m", "s", "V", "A", "degC"];

/// A dimension: the power of each base unit (a length is m¹, a speed m¹·s⁻¹, a ratio none).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Dimension([i8; BASES.len()]);

impl Dimension {
    /// No dimension: a plain number or a ratio (`%`).
    pub const NONE: Self = Self([0; BASES.len()]);

    /// The dimension of a base unit as `base_unit` names it (`m`, `s`, `Hz`, `""`).
    fn of_base(base: &str) -> Option<Self> {
        if base.is_empty() {
            return Some(Self::NONE);
        }
        if base == "Hz" {
            return Some(Self::NONE.per(Self::of_base("s")?));
        }
        let index = BASES.iter().position(|b| *b == base)?;
        let mut powers = [0; BASES.len()];
        powers[index] = 1;
        Some(Self(powers))
    }

    /// The dimension of a product.
    pub fn times(self, other: Self) -> Self {
        Self(std::array::from_fn(|i| {
            self.0[i].saturating_add(other.0[i])
        }))
    }

    /// The dimension of a quotient.
    pub fn per(self, other: Self) -> Self {
        Self(std::array::from_fn(|i| {
            self.0[i].saturating_sub(other.0[i])
        }))
    }
}

impl fmt::Display for Dimension {
    /// `m`, `m²`, `m/s`, `1/s`, and `a plain number` for none.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if *self == Self::NONE {
            return f.write_str("a plain number");
        }
        let part = |sign: i8| {
            BASES
                .iter()
                .zip(self.0)
                .filter(|(_, power)| power.signum() == sign)
                .map(|(base, power)| match power.unsigned_abs() {
                    1 => (*base).to_owned(),
                    2 => format!("{base}²"),
                    3 => format!("{base}³"),
                    n => format!("{base}^{n}"),
                })
                .collect::<Vec<_>>()
                .join("·")
        };
        let (above, below) = (part(1), part(-1));
        match (above.is_empty(), below.is_empty()) {
            (_, true) => f.write_str(&above),
            (true, false) => write!(f, "1/{below}"),
            (false, false) => write!(f, "{above}/{below}"),
        }
    }
}

/// A unit: its name as the spec or the user wrote it, its power of ten of the base units, and
/// its dimension (`mm` is 10⁻³ m, `us` 10⁻⁶ s, `%` 10⁻² of a plain number).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Unit {
    /// As written (`mm`, `µm`, `degC`).
    pub name: String,
    /// `10^power` base units make one of it.
    pub power: i32,
    /// What it measures.
    pub dimension: Dimension,
}

impl Unit {
    /// The unit named `name` (a spec's unit, or an SI prefix of one: `mm`, `um`, `µm`, `m`,
    /// `us`, `ms`, `s`, `Hz`, `uV`, `%`, `degC`, `°C`); `None` for a name not known.
    pub fn named(name: &str) -> Option<Self> {
        let (power, base) = base_unit(name)?;
        Some(Self {
            name: name.to_owned(),
            power: i32::from(power),
            dimension: Dimension::of_base(base)?,
        })
    }

    /// A plain number.
    pub fn none() -> Self {
        Self {
            name: String::new(),
            power: 0,
            dimension: Dimension::NONE,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prefixes_share_a_dimension_and_differ_in_power() {
        let mm = Unit::named("mm").unwrap();
        let m = Unit::named("m").unwrap();
        let um = Unit::named("µm").unwrap();
        assert_eq!((mm.power, m.power, um.power), (-3, 0, -6));
        assert_eq!(mm.dimension, m.dimension);
        assert_ne!(mm.dimension, Unit::named("us").unwrap().dimension);
        assert_eq!(Unit::named("%").unwrap().dimension, Dimension::NONE);
        assert_eq!(
            Unit::named("°C").unwrap().dimension,
            Unit::named("degC").unwrap().dimension
        );
        assert!(Unit::named("furlong").is_none());
    }

    #[test]
    fn dimensions_print_as_people_write_them() {
        let m = Unit::named("m").unwrap().dimension;
        let s = Unit::named("s").unwrap().dimension;
        assert_eq!(m.to_string(), "m");
        assert_eq!(m.times(m).to_string(), "m²");
        assert_eq!(m.per(s).to_string(), "m/s");
        assert_eq!(Unit::named("Hz").unwrap().dimension.to_string(), "1/s");
        assert_eq!(Dimension::NONE.to_string(), "a plain number");
    }
}
