//! A file's measurements checked and evaluated as a user writes them: real expressions,
//! register values as the drivers give them (exact fixed-point), results compared digit for
//! digit.

use optobus_codec::value::{Fixed, Scale};
use optobus_measure::{check, Definition, InputInfo, Invalid, Plan, Problem};
use proptest::prelude::*;

/// A P series head's distance: mm in steps of 1e-6 mm.
const MICRO_MM: Scale = Scale::Decimal { exponent: -6 };

/// The registers of a bus of two heads, `top` and `bottom`, each polling `distance_1`, with an
/// unpolled `distance_2` and a temperature.
fn registers(device: &str, register: &str) -> Result<InputInfo, String> {
    if device != "top" && device != "bottom" {
        return Err(format!("the bus has no device `{device}`"));
    }
    match register {
        "distance_1" => Ok(InputInfo {
            unit: Some("mm"),
            scale: Some(MICRO_MM),
        }),
        "temperature" => Ok(InputInfo {
            unit: Some("degC"),
            scale: Some(Scale::Decimal { exponent: -1 }),
        }),
        "distance_2" => Err(format!("no poll of `{device}` reads `distance_2`")),
        _ => Err(format!("`{device}` has no register `{register}`")),
    }
}

fn plan(definitions: &[(&str, &str, Option<&str>)]) -> Result<Plan, Vec<Problem>> {
    let definitions: Vec<Definition<'_>> = definitions
        .iter()
        .map(|(name, expr, unit)| Definition {
            name,
            expr,
            unit: *unit,
        })
        .collect();
    check(&definitions, registers)
}

fn mm(raw: i64) -> Option<Fixed> {
    Some(Fixed::new(raw, MICRO_MM))
}

/// The inputs in the plan's order, by name.
fn inputs(plan: &Plan, values: &[(&str, Option<Fixed>)]) -> Vec<Option<Fixed>> {
    plan.inputs
        .iter()
        .map(|input| {
            values
                .iter()
                .find(|(name, _)| *name == input.to_string())
                .and_then(|(_, value)| *value)
        })
        .collect()
}

#[test]
fn the_gap_between_two_opposed_heads_is_exact() {
    let plan = plan(&[(
        "gap",
        "20mm - top.distance_1 - bottom.distance_1",
        Some("mm"),
    )])
    .unwrap();
    let values = inputs(
        &plan,
        &[
            ("top.distance_1", mm(4_969_234)),
            ("bottom.distance_1", mm(4_969_136)),
        ],
    );
    let gap = plan.evaluate(&values)[0].clone().unwrap();
    assert_eq!(gap.to_string(), "10.061630");
    // The same in metres, from a constant in metres: the unit is the measurement's own.
    let plan = self::plan(&[(
        "gap",
        "0.02m − top.distance_1 − bottom.distance_1",
        Some("um"),
    )])
    .unwrap();
    let values = inputs(
        &plan,
        &[
            ("top.distance_1", mm(4_969_234)),
            ("bottom.distance_1", mm(4_969_136)),
        ],
    );
    assert_eq!(
        plan.evaluate(&values)[0].clone().unwrap().to_string(),
        "10061.630"
    );
}

#[test]
fn a_division_rounds_half_to_even_at_the_inputs_resolution() {
    let plan = plan(&[("middle", "avg(top.distance_1, bottom.distance_1)", None)]).unwrap();
    assert_eq!(plan.formulas[0].unit.name, "mm");
    let values = inputs(
        &plan,
        &[("top.distance_1", mm(1)), ("bottom.distance_1", mm(2))],
    );
    // 1.5e-6 mm to the nearest 1e-6, ties to even: 2e-6.
    assert_eq!(plan.evaluate(&values)[0].clone().unwrap().raw(), 2);
    let values = inputs(
        &plan,
        &[("top.distance_1", mm(2)), ("bottom.distance_1", mm(3))],
    );
    assert_eq!(plan.evaluate(&values)[0].clone().unwrap().raw(), 2);
}

#[test]
fn measurements_use_measurements_and_an_invalid_input_invalidates_both() {
    let plan = plan(&[
        (
            "flat",
            "max(top.distance_1, bottom.distance_1) - min(top.distance_1, bottom.distance_1)",
            None,
        ),
        ("double", "2 * flat", None),
    ])
    .unwrap();
    let values = inputs(
        &plan,
        &[("top.distance_1", mm(5)), ("bottom.distance_1", mm(-3))],
    );
    let results = plan.evaluate(&values);
    assert_eq!(results[0].clone().unwrap().raw(), 8);
    assert_eq!(results[1].clone().unwrap().raw(), 16);
    let values = inputs(
        &plan,
        &[("top.distance_1", None), ("bottom.distance_1", mm(-3))],
    );
    let results = plan.evaluate(&values);
    let top = plan.inputs.iter().position(|i| i.device == "top").unwrap();
    assert_eq!(results[0], Err(Invalid::Input(top)));
    assert_eq!(results[1], Err(Invalid::Measurement(0)));
}

#[test]
fn every_mistake_is_refused_at_its_place_all_at_once() {
    let problems = plan(&[
        ("a", "20s - top.distance_1", None),
        ("b", "top.distanse_1 + right.distance_1", None),
        ("c", "top.distance_2", None),
        ("d", "top.distance_1", Some("s")),
        ("e", "f + 1mm", None),
        ("f", "e - 1mm", None),
        ("g", "20 - top.distance_1", None),
        ("h", "top.temperature + top.distance_1", None),
    ])
    .unwrap_err();
    let found: Vec<(usize, Option<std::ops::Range<usize>>, &str)> = problems
        .iter()
        .map(|p| (p.measurement, p.span.clone(), p.message.as_str()))
        .collect();
    let at = |measurement: usize| {
        found
            .iter()
            .filter(move |(m, _, _)| *m == measurement)
            .map(|(_, span, message)| (span.clone(), *message))
            .collect::<Vec<_>>()
    };
    assert_eq!(at(0), [(Some(6..20), "m cannot be subtracted from s")]);
    assert_eq!(
        at(1),
        [
            (Some(0..14), "`top` has no register `distanse_1`"),
            (Some(17..33), "the bus has no device `right`"),
        ]
    );
    assert_eq!(
        at(2),
        [(Some(0..14), "no poll of `top` reads `distance_2`")]
    );
    assert_eq!(
        at(3),
        [(None, "`unit: s` is s, but the expression gives m")]
    );
    // The circle is told once, where it closes.
    assert_eq!(
        found.iter().filter(|(m, _, _)| *m == 4 || *m == 5).count(),
        1
    );
    assert!(found
        .iter()
        .any(|(_, _, message)| message.contains("in a circle: e → f → e")
            || message.contains("in a circle: f → e → f")));
    assert!(
        at(6)[0].1.contains("write its unit after it"),
        "{:?}",
        at(6)
    );
    assert_eq!(at(7), [(Some(18..32), "m cannot be added to degC")]);
}

proptest! {
    /// A value equals the exact arithmetic of its inputs: sums, differences and products with
    /// constants, digit for digit.
    #[test]
    fn a_value_is_the_exact_arithmetic_of_its_inputs(
        top in -1_000_000_000_000i64..1_000_000_000_000,
        bottom in -1_000_000_000_000i64..1_000_000_000_000,
        factor in -1000i64..1000,
    ) {
        let plan = plan(&[
            ("gap", "20mm - top.distance_1 - bottom.distance_1", Some("mm")),
            ("scaled", "gap * 0.001 * FACTOR + top.distance_1".replace("FACTOR", &factor.abs().to_string()).leak(), Some("mm")),
        ]).unwrap();
        let values = inputs(&plan, &[("top.distance_1", mm(top)), ("bottom.distance_1", mm(bottom))]);
        let results = plan.evaluate(&values);
        let gap = i128::from(20_000_000 - top - bottom);
        let gap_result = results[0].clone().unwrap();
        prop_assert_eq!(i128::from(gap_result.raw()), gap);
        prop_assert_eq!(gap_result.scale(), MICRO_MM);
        // gap·0.001·|factor| in steps of 1e-9 mm, plus top.
        let scaled = gap * i128::from(factor.abs()) + i128::from(top) * 1000;
        let scaled_result = results[1].clone().unwrap();
        let exponent = match scaled_result.scale() { Scale::Decimal { exponent } => exponent, _ => unreachable!() };
        let in_nano = i128::from(scaled_result.raw()) * 10i128.pow(u32::try_from(i32::from(exponent) + 9).unwrap());
        prop_assert_eq!(in_nano, scaled);
    }
}
