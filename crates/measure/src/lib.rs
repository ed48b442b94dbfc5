//! Measurements across optobus devices: what people buy the sensors for (the thickness of a
//! strip between two opposed heads, a step, a flatness, a part in tolerance), computed from
//! the exact values of the registers they are made of.
//!
//! - [`expr`]: the expression language (`20mm - top.distance_1 - bottom.distance_1`), read
//!   with every node's place in the text.
//! - [`formula`]: a file's measurements checked as a set, once (names, units and dimensions,
//!   no measurement using itself), then evaluated for each set of inputs with exact decimals.
//! - [`judge`]: LL / LO / GO / HI / HH against limits with hysteresis, counted.
//! - [`stats`]: rolling count, mean, sd, min, max, range and Cp/Cpk over a window.
//! - [`live`]: all of them as readings come: a value once each input was read again, judged,
//!   summed up, or invalid with the reason (an input without a value, inputs too far apart).
//!
//! It knows nothing of lines or devices: the bus gives it the registers' units and values.
//!
//! ```
//! use optobus_codec::value::{Fixed, Scale};
//! use optobus_measure::{check, Definition, InputInfo};
//!
//! let mm = Scale::Decimal { exponent: -6 };
//! let gap = Definition {
//!     name: "gap",
//!     expr: "20mm - top.distance_1 - bottom.distance_1",
//!     unit: Some("mm"),
//! };
//! let plan = check(&[gap], |_device, _register| {
//!     Ok(InputInfo { unit: Some("mm"), scale: Some(mm) })
//! })
//! .unwrap();
//! let inputs = [Some(Fixed::new(4_969_234, mm)), Some(Fixed::new(4_969_136, mm))];
//! assert_eq!(plan.evaluate(&inputs)[0].clone().unwrap().to_string(), "10.061630");
//! ```

pub mod expr;
pub mod formula;
pub mod judge;
pub mod live;
pub mod number;
pub mod stats;
pub mod unit;

pub use expr::quantity;
pub use formula::{check, Definition, Formula, InputInfo, InputName, Invalid, Plan, Problem};
pub use judge::{Comparator, Judgement, Limits};
pub use live::{Live, Outcome, Reading, Settings};
pub use number::{ArithmeticError, Decimal};
pub use stats::{Rolling, Summary, Window};
pub use unit::{Dimension, Unit};
