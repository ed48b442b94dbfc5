//! The bus file's `measurements:`: values computed from the registers the polls read (the gap
//! between two opposed heads), checked with the rest of the file, each problem at its line and
//! column inside the expression.

use std::time::Duration;

use optobus_device::DeviceInfo;
use optobus_inspect::did_you_mean;
use optobus_measure::{
    check, quantity, Definition, InputInfo, Limits, Plan, Problem, Settings, Unit, Window,
};
use optobus_spec::source::{Node, Span, Value};

use super::reading::{parse_duration, FileReader};
use super::DeviceConfig;

pub(super) const MEASUREMENT_KEYS: &[&str] =
    &["name", "expr", "unit", "limits", "stats", "max_skew"];
pub(super) const LIMIT_KEYS: &[&str] = &["ll", "lo", "hi", "hh", "hysteresis"];

/// The most values a count window of statistics may hold.
const MAX_STATS: usize = optobus_measure::stats::MAX_WINDOW;

/// `max_skew` when no input has a period (all polled `fastest`).
const FASTEST_SKEW: Duration = Duration::from_millis(100);

/// A file's measurements, checked: their formulas in an order where each comes after those it
/// uses, and how each is judged and summed up (in the same order).
#[derive(Clone, Debug, Default)]
pub struct Measurements {
    /// The formulas and the registers they read.
    pub plan: Plan,
    /// Limits, statistics and skew of each formula.
    pub settings: Vec<Settings>,
}

impl Measurements {
    /// No measurement.
    pub fn is_empty(&self) -> bool {
        self.plan.formulas.is_empty()
    }
}

/// One measurement as read, before the set is checked.
struct Read<'n> {
    name: String,
    expr: &'n Node,
    expr_text: String,
    unit: Option<(&'n Node, String)>,
    limits: Option<&'n Node>,
    stats: Option<Window>,
    max_skew: Option<Duration>,
    span: Span,
}

impl FileReader<'_> {
    /// The `measurements` list, checked against the devices as read (`None` where a device did
    /// not read whole: its problems are reported already, and its inputs are not checked
    /// again).
    pub(super) fn measurements(
        &mut self,
        node: &Node,
        devices: &[(
            Option<String>,
            Option<&DeviceConfig>,
            Option<&'static DeviceInfo>,
        )],
    ) -> Option<Measurements> {
        let items = self.list(node, "`measurements`")?;
        let mut read = Vec::new();
        let mut ok = true;
        for item in items {
            match self.measurement(item) {
                Some(measurement) => read.push(measurement),
                None => ok = false,
            }
        }
        for (index, measurement) in read.iter().enumerate() {
            if read[..index].iter().any(|m| m.name == measurement.name) {
                self.error(
                    measurement.span,
                    format!("two measurements are named `{}`", measurement.name),
                    "give each measurement a name of its own",
                );
                ok = false;
            }
        }
        let definitions: Vec<Definition<'_>> = read
            .iter()
            .map(|m| Definition {
                name: &m.name,
                expr: &m.expr_text,
                unit: m.unit.as_ref().map(|(_, unit)| unit.as_str()),
            })
            .collect();
        let plan = match check(&definitions, |device, register| {
            input(devices, device, register)
        }) {
            Ok(plan) => plan,
            Err(problems) => {
                for problem in problems {
                    self.problem(&read[problem.measurement], problem);
                }
                // The limits are still checked where the unit is named.
                for measurement in &read {
                    let unit = measurement.unit.as_ref().and_then(|(_, u)| Unit::named(u));
                    if let (Some(node), Some(unit)) = (measurement.limits, unit) {
                        self.limits(node, &unit);
                    }
                }
                return None;
            }
        };
        let mut settings = Vec::new();
        for &index in &plan.order {
            let measurement = &read[index];
            let formula = &plan.formulas[settings.len()];
            let limits = match measurement.limits {
                Some(node) => Some(self.limits(node, &formula.unit)?),
                None => None,
            };
            let max_skew = measurement
                .max_skew
                .unwrap_or_else(|| slowest_period(&plan, formula.inputs.as_slice(), devices));
            settings.push(Settings {
                limits,
                stats: measurement.stats,
                max_skew,
            });
        }
        ok.then_some(Measurements { plan, settings })
    }

    fn measurement<'n>(&mut self, node: &'n Node) -> Option<Read<'n>> {
        let pairs = self.mapping(node, "a measurement", MEASUREMENT_KEYS)?;
        let get = |key: &str| {
            pairs
                .iter()
                .find(|(k, _)| k.scalar() == Some(key))
                .map(|(_, v)| v)
        };
        let name = match get("name") {
            Some(v) => self.text(v, "a measurement's `name`").map(str::to_owned),
            None => {
                self.error(
                    node.span,
                    "a measurement needs a `name`",
                    "its values carry it",
                );
                None
            }
        };
        let expr = match get("expr") {
            Some(v) => self.text(v, "`expr`").map(|text| (v, text.to_owned())),
            None => {
                self.error(
                    node.span,
                    "a measurement needs an `expr`",
                    "e.g. `expr: 20mm - top.distance_1 - bottom.distance_1`",
                );
                None
            }
        };
        let unit = match get("unit") {
            Some(v) => Some(self.text(v, "`unit`").map(|t| (v, t.to_owned()))?),
            None => None,
        };
        let stats = match get("stats") {
            Some(v) => Some(self.window(v)?),
            None => None,
        };
        let max_skew = match get("max_skew") {
            Some(v) => Some(self.duration(v, "`max_skew`", Duration::ZERO)?),
            None => None,
        };
        let (expr, expr_text) = expr?;
        Some(Read {
            name: name?,
            expr,
            expr_text,
            unit,
            limits: get("limits"),
            stats,
            max_skew,
            span: get("name").map_or(node.span, |n| n.span),
        })
    }

    /// `stats`: a count of values or a duration.
    fn window(&mut self, node: &Node) -> Option<Window> {
        let text = self.text(node, "`stats`")?;
        if text.bytes().all(|b| b.is_ascii_digit()) {
            let count = self.number::<usize>(node, "`stats`", (2, MAX_STATS as u64))?;
            return Some(Window::Count(count));
        }
        match parse_duration(text) {
            Ok(_) => self
                .duration(node, "`stats`", Duration::from_nanos(1))
                .map(Window::Duration),
            Err(_) => {
                self.error(
                    node.span,
                    format!("`stats` `{text}` is neither a count of values nor a duration"),
                    "e.g. `stats: 200` (the latest 200 values) or `stats: 10s`",
                );
                None
            }
        }
    }

    /// `limits`: `ll`, `lo`, `hi`, `hh` and `hysteresis`, each a quantity in `unit`.
    fn limits(&mut self, node: &Node, unit: &Unit) -> Option<Limits> {
        let pairs = self.mapping(node, "`limits`", LIMIT_KEYS)?;
        let mut limits = Limits::default();
        let mut ok = true;
        for (key, value) in pairs {
            let Some(name) = key.scalar() else { continue };
            let Some(text) = self.text(value, "a limit") else {
                ok = false;
                continue;
            };
            let quantity = match quantity(text, unit) {
                Ok(quantity) => quantity,
                Err(why) => {
                    self.error(value.span, format!("`{name}`: {why}"), "e.g. `lo: 9.9mm`");
                    ok = false;
                    continue;
                }
            };
            match name {
                "ll" => limits.ll = Some(quantity),
                "lo" => limits.lo = Some(quantity),
                "hi" => limits.hi = Some(quantity),
                "hh" => limits.hh = Some(quantity),
                "hysteresis" => limits.hysteresis = quantity,
                _ => {}
            }
        }
        if let Err(why) = limits.check() {
            self.error(node.span, why.to_string(), "ll ≤ lo ≤ hi ≤ hh");
            ok = false;
        }
        ok.then_some(limits)
    }

    /// A problem of the set, at its place: inside the expression where it has one.
    fn problem(&mut self, measurement: &Read<'_>, problem: Problem) {
        if problem.message.is_empty() {
            // An input of a device that did not read: reported already.
            return;
        }
        let (span, help) = match problem.span {
            Some(range) => (
                inside(measurement.expr, &measurement.expr_text, range),
                "`optobus bus schema` shows what an expression takes",
            ),
            None => (
                measurement
                    .unit
                    .as_ref()
                    .map_or(measurement.span, |(n, _)| n.span),
                "a unit of the result's dimension: mm, um, m, us, s, %, degC …",
            ),
        };
        self.error(span, problem.message, help);
    }
}

/// The place of `range` (bytes of `text`) inside the scalar `node`, where the scalar is on one
/// line as written (plain or quoted); else the whole scalar.
fn inside(node: &Node, text: &str, range: std::ops::Range<usize>) -> Span {
    let chars = text.chars().count();
    let quote = match &node.value {
        Value::Scalar { plain: true, .. } if node.span.width == chars => 0,
        Value::Scalar { plain: false, .. } if node.span.width == chars + 2 => 1,
        _ => return node.span,
    };
    let start = text.get(..range.start).map_or(0, |t| t.chars().count());
    let width = text
        .get(range.clone())
        .map_or(1, |t| t.chars().count())
        .max(1);
    Span {
        line: node.span.line,
        column: node.span.column + quote + start,
        width,
    }
}

/// What the file says of `device.register`: its unit and step, if a poll of the device reads
/// it; else why not.
fn input(
    devices: &[(
        Option<String>,
        Option<&DeviceConfig>,
        Option<&'static DeviceInfo>,
    )],
    device: &str,
    register: &str,
) -> Result<InputInfo, String> {
    let Some((_, config, info)) = devices
        .iter()
        .find(|(name, _, _)| name.as_deref() == Some(device))
    else {
        let names = devices.iter().filter_map(|(name, _, _)| name.as_deref());
        let near = did_you_mean(device, names)
            .map(|n| format!(" ({n})"))
            .unwrap_or_default();
        return Err(format!("the bus has no device `{device}`{near}"));
    };
    let (Some(config), Some(info)) = (config, info) else {
        return Err(String::new());
    };
    let Some(found) = info.register(register) else {
        let names = info.registers.iter().map(|r| r.name);
        let near = did_you_mean(register, names)
            .map(|n| format!(" ({n})"))
            .unwrap_or_default();
        return Err(format!(
            "`{}` has no register `{register}`{near}",
            info.model_name()
        ));
    };
    if !config
        .polls
        .iter()
        .any(|p| p.registers.iter().any(|r| r.name == found.name))
    {
        return Err(format!(
            "no poll of `{device}` reads `{register}`: add it to one of its polls"
        ));
    }
    Ok(InputInfo {
        unit: found.unit,
        scale: found.scale,
    })
}

/// The longest period among the polls that read a formula's inputs: by default, inputs may be
/// that far apart.
fn slowest_period(
    plan: &Plan,
    inputs: &[usize],
    devices: &[(
        Option<String>,
        Option<&DeviceConfig>,
        Option<&'static DeviceInfo>,
    )],
) -> Duration {
    inputs
        .iter()
        .filter_map(|&index| {
            let input = &plan.inputs[index];
            let (_, config, _) = devices
                .iter()
                .find(|(name, _, _)| name.as_deref() == Some(input.device.as_str()))?;
            (*config)?
                .polls
                .iter()
                .filter(|p| p.registers.iter().any(|r| r.name == input.register))
                .filter_map(|p| p.every)
                .min()
        })
        .max()
        .unwrap_or(FASTEST_SKEW)
}
