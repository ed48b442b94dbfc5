//! `scale`: a scale is exact and non-zero: a power of ten (`1e-6`, `0.1`) or a ratio of
//! integers (`1/1048576`).

use optobus_codec::value::Scale;

use crate::diagnostic::Diagnostic;
use crate::model::{Kind, Model, RegisterNames, ScaleSpec};

/// Rule name.
pub const RULE: &str = "scale";

/// Reads a scale written in a spec; a power of ten must lie in [`Scale::DECIMAL_EXPONENTS`], the
/// steps with which every raw value prints exactly.
pub fn parse_scale(text: &str) -> Result<Scale, String> {
    match read_scale(text)? {
        Scale::Decimal { exponent } if !Scale::DECIMAL_EXPONENTS.contains(&exponent) => {
            Err(format!(
                "1e{exponent} is beyond the steps a value prints exactly (1e{} to 1e{})",
                Scale::DECIMAL_EXPONENTS.start(),
                Scale::DECIMAL_EXPONENTS.end()
            ))
        }
        scale => Ok(scale),
    }
}

fn read_scale(text: &str) -> Result<Scale, String> {
    let text = text.trim();
    if let Some((numerator, denominator)) = text.split_once('/') {
        let numerator: u32 = numerator
            .trim()
            .parse()
            .map_err(|_| format!("numerator `{}` is not a whole number", numerator.trim()))?;
        let denominator: u32 = denominator
            .trim()
            .parse()
            .map_err(|_| format!("denominator `{}` is not a whole number", denominator.trim()))?;
        if numerator == 0 {
            return Err("a scale of zero would make every reading 0".into());
        }
        return Scale::ratio(numerator, denominator).ok_or_else(|| "division by zero".into());
    }
    if let Some((mantissa, exponent)) = text.split_once(['e', 'E']) {
        let exponent: i8 = exponent
            .parse()
            .map_err(|_| format!("exponent `{exponent}` is not a small integer"))?;
        return match mantissa {
            "1" | "1.0" => Ok(Scale::Decimal { exponent }),
            "0" | "0.0" => Err("a scale of zero would make every reading 0".into()),
            _ => Err(format!(
                "mantissa `{mantissa}` must be 1 (write other steps as a ratio)"
            )),
        };
    }
    // A plain power of ten: 1, 10, 0.1, 0.001.
    match text {
        "1" => return Ok(Scale::ONE),
        "0" => return Err("a scale of zero would make every reading 0".into()),
        _ => {}
    }
    if let Some(decimals) = text.strip_prefix("0.") {
        if let Some(zeros) = decimals.strip_suffix('1') {
            if zeros.chars().all(|c| c == '0') {
                return i8::try_from(zeros.len() + 1)
                    .map(|decimals| Scale::Decimal {
                        exponent: -decimals,
                    })
                    .map_err(|_| format!("`{text}` has too many decimals"));
            }
        }
    }
    if let Some(zeros) = text.strip_prefix('1') {
        if !zeros.is_empty() && zeros.chars().all(|c| c == '0') {
            return i8::try_from(zeros.len())
                .map(|exponent| Scale::Decimal { exponent })
                .map_err(|_| format!("`{text}` has too many digits"));
        }
    }
    Err(format!("`{text}` is not an exact scale"))
}

fn report(owner: &str, scale: &ScaleSpec, out: &mut Vec<Diagnostic>) {
    if let Err(problem) = &scale.value {
        out.push(
            Diagnostic::at(
                RULE,
                &scale.path,
                format!("bad scale for `{owner}`: {problem}"),
            )
            .label("malformed scale")
            .help("write a power of ten (`1e-6`, `0.1`) or a ratio (`1/1048576`)"),
        );
    }
}

/// Checks scales.
pub fn check(model: &Model, _: &RegisterNames<'_>, out: &mut Vec<Diagnostic>) {
    for register in super::declared(model) {
        if let Some(scale) = &register.scale {
            report(&register.name, scale, out);
        }
        if let Kind::Packed(fields) | Kind::Record(fields) = &register.kind {
            for field in fields {
                if let Some(scale) = &field.scale {
                    report(&format!("{}.{}", register.name, field.name), scale, out);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_forms() {
        assert_eq!(parse_scale("1e-6"), Ok(Scale::Decimal { exponent: -6 }));
        assert_eq!(parse_scale("0.1"), Ok(Scale::Decimal { exponent: -1 }));
        assert_eq!(parse_scale("0.001"), Ok(Scale::Decimal { exponent: -3 }));
        assert_eq!(parse_scale("100"), Ok(Scale::Decimal { exponent: 2 }));
        assert_eq!(
            parse_scale("1/1048576"),
            Scale::ratio(1, 1 << 20).ok_or(String::new())
        );
        assert!(parse_scale("0.5").is_err());
        assert!(parse_scale("0").is_err());
        assert!(parse_scale("1/0").is_err());
        assert!(parse_scale("2e-3").is_err());
        assert!(parse_scale("abc").is_err());
        assert_eq!(parse_scale("1e-37"), Ok(Scale::Decimal { exponent: -37 }));
        assert!(parse_scale("1e-38").is_err());
        assert!(parse_scale("1e127").is_err());
        assert!(parse_scale("1e20").is_err());
        assert!(parse_scale(&format!("0.{}1", "0".repeat(300))).is_err());
        assert!(parse_scale(&format!("1{}", "0".repeat(300))).is_err());
    }
}
