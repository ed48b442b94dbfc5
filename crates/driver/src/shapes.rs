//! The shapes readings take in serde formats (feature `serde`), each defined once: the typed
//! drivers' units and code enums serialise through them, and so do the generic values of
//! `optobus-inspect`, which the `optobus` tool prints with `--json`.

use std::borrow::Cow;

use optobus_codec::value::Fixed;
use serde::{Deserialize, Serialize};

/// A quantity: exact decimal text and the unit's symbol, `{"value": "3.584190", "unit": "mm"}`;
/// never a rounded float.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quantity<'a> {
    /// The exact value.
    pub value: Fixed,
    /// The unit's symbol.
    #[serde(borrow)]
    pub unit: Cow<'a, str>,
}

impl Quantity<'_> {
    /// The value, if it is given in `symbol`: a value in another unit is refused rather than
    /// taken as this one.
    pub fn expect<E: serde::de::Error>(self, symbol: &str) -> Result<Fixed, E> {
        if self.unit == symbol {
            Ok(self.value)
        } else {
            Err(E::custom(format_args!(
                "a value in {symbol} expected, got one in {}",
                self.unit
            )))
        }
    }
}

/// A code and its name, `{"code": 0, "name": "distance"}`; `"name": null` for a code the
/// manual does not define. Read back, either part alone is enough.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Code<'a> {
    /// The code as on the wire.
    pub code: Option<u32>,
    /// Its name in the spec.
    #[serde(borrow, default)]
    pub name: Option<Cow<'a, str>>,
}
