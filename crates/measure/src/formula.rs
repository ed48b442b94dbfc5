//! Measurements checked as a set, once, when the file that defines them is read: every name
//! known, units of one dimension where they meet, no measurement using itself; then evaluated
//! for each set of inputs without any check left to do.

use std::collections::HashMap;
use std::fmt;

use optobus_codec::value::{Fixed, Scale};

use crate::expr::{self, ExprError, Function, Node, Operator, Span};
use crate::number::{ArithmeticError, Decimal};
use crate::unit::{Dimension, Unit};

/// A measurement as the file defines it.
#[derive(Clone, Debug)]
pub struct Definition<'a> {
    /// Its name.
    pub name: &'a str,
    /// Its expression.
    pub expr: &'a str,
    /// The unit of its value (`mm`); by default the unit of its first input of the result's
    /// dimension.
    pub unit: Option<&'a str>,
}

/// What the file knows of a device's register used as an input.
#[derive(Clone, Copy, Debug)]
pub struct InputInfo {
    /// Its unit, if it has one.
    pub unit: Option<&'static str>,
    /// Its step (a number without a step counts in whole units).
    pub scale: Option<Scale>,
}

/// A problem with one measurement, at its place in its expression (an empty span for the
/// measurement as a whole, e.g. its unit).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Problem {
    /// Which measurement (its index in the definitions).
    pub measurement: usize,
    /// Where in its expression, if the problem is in it; `None` for its `unit`.
    pub span: Option<Span>,
    /// What, in one line.
    pub message: String,
}

/// One register read for the measurements.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct InputName {
    /// The device's name.
    pub device: String,
    /// The register's name.
    pub register: String,
}

impl fmt::Display for InputName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}", self.device, self.register)
    }
}

/// A checked expression, in base units.
#[derive(Clone, Debug)]
enum Step {
    Constant(Decimal),
    /// An input's value times `10^power` (its unit in base units).
    Input {
        index: usize,
        power: i32,
    },
    /// An earlier measurement's value, in base units.
    Measurement(usize),
    Negate(Box<Step>),
    Binary(Operator, Box<Step>, Box<Step>),
    Call(Function, Vec<Step>),
}

/// A measurement ready to evaluate.
#[derive(Clone, Debug)]
pub struct Formula {
    /// Its name.
    pub name: String,
    /// The unit of its value.
    pub unit: Unit,
    /// The power of ten of its value's last digit after a division, in `unit`.
    pub resolution: i32,
    /// Which inputs it reads (indices into [`Plan::inputs`]), itself or through the
    /// measurements it uses.
    pub inputs: Vec<usize>,
    step: Step,
}

/// The measurements of a file, checked, in an order where each comes after those it uses.
#[derive(Clone, Debug, Default)]
pub struct Plan {
    /// Every register any measurement reads, once each.
    pub inputs: Vec<InputName>,
    /// The measurements, each after those it uses.
    pub formulas: Vec<Formula>,
    /// For each formula, the index of its definition.
    pub order: Vec<usize>,
}

/// Why a measurement has no value this time.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Invalid {
    /// An input has no valid value (the caller knows why: the device's sentinel, no reply).
    Input(usize),
    /// A measurement it uses is invalid.
    Measurement(usize),
    /// The arithmetic has no exact result.
    Arithmetic(ArithmeticError),
}

impl From<ArithmeticError> for Invalid {
    fn from(error: ArithmeticError) -> Self {
        Self::Arithmetic(error)
    }
}

/// A measurement's dimension and unit power while the set is checked.
#[derive(Clone, Copy)]
struct Checked {
    dimension: Dimension,
}

/// Checks `definitions` against the registers `input` describes (an error message for a
/// device or register the file has not, or that no poll reads); every problem of every
/// measurement at once.
pub fn check(
    definitions: &[Definition<'_>],
    input: impl Fn(&str, &str) -> Result<InputInfo, String>,
) -> Result<Plan, Vec<Problem>> {
    let mut problems = Vec::new();
    let mut trees = Vec::new();
    for (index, definition) in definitions.iter().enumerate() {
        match expr::parse(definition.expr) {
            Ok(node) => trees.push(Some(node)),
            Err(ExprError { span, message }) => {
                problems.push(Problem {
                    measurement: index,
                    span: Some(span),
                    message,
                });
                trees.push(None);
            }
        }
    }
    let names: HashMap<&str, usize> = definitions
        .iter()
        .enumerate()
        .map(|(index, d)| (d.name, index))
        .collect();
    let order = order(&trees, &names, definitions, &mut problems);
    let mut plan = Plan::default();
    let mut checked: Vec<Option<(Checked, usize)>> = vec![None; definitions.len()];
    for index in order {
        let Some(tree) = &trees[index] else { continue };
        let mut context = Context {
            definition: index,
            names: &names,
            checked: &checked,
            input: &input,
            plan: &mut plan,
            problems: &mut problems,
            finest: None,
            inputs: Vec::new(),
            first_units: Vec::new(),
        };
        let Some((step, dimension)) = context.lower(tree) else {
            continue;
        };
        let (finest, inputs, first_units) = (context.finest, context.inputs, context.first_units);
        let Some(unit) = result_unit(
            &definitions[index],
            dimension,
            &first_units,
            index,
            &mut problems,
        ) else {
            continue;
        };
        let resolution = finest.map_or(0, |finest| finest - unit.power);
        checked[index] = Some((Checked { dimension }, plan.formulas.len()));
        plan.order.push(index);
        plan.formulas.push(Formula {
            name: definitions[index].name.to_owned(),
            unit,
            resolution,
            inputs,
            step,
        });
    }
    if problems.is_empty() {
        Ok(plan)
    } else {
        problems.sort_by_key(|p| (p.measurement, p.span.as_ref().map(|s| s.start)));
        Err(problems)
    }
}

/// The unit of a measurement's value: the one it names, or its first input's of the result's
/// dimension.
fn result_unit(
    definition: &Definition<'_>,
    dimension: Dimension,
    first_units: &[Unit],
    index: usize,
    problems: &mut Vec<Problem>,
) -> Option<Unit> {
    let mut problem = |message: String| {
        problems.push(Problem {
            measurement: index,
            span: None,
            message,
        });
        None
    };
    match definition.unit {
        Some(name) => match Unit::named(name) {
            Some(unit) if unit.dimension == dimension => Some(unit),
            Some(unit) => problem(format!(
                "`unit: {name}` is {}, but the expression gives {dimension}",
                unit.dimension
            )),
            None => problem(format!("`unit: {name}` is not a unit known here")),
        },
        None if dimension == Dimension::NONE => Some(Unit::none()),
        None => match first_units.iter().find(|u| u.dimension == dimension) {
            Some(unit) => Some(unit.clone()),
            None => problem(format!(
                "the expression gives {dimension}: name its unit with `unit:`"
            )),
        },
    }
}

/// The measurements in an order where each comes after those it uses; unknown names and
/// cycles are problems (a measurement in a cycle is left out).
fn order(
    trees: &[Option<Node>],
    names: &HashMap<&str, usize>,
    definitions: &[Definition<'_>],
    problems: &mut Vec<Problem>,
) -> Vec<usize> {
    let uses: Vec<Vec<(usize, Span)>> = trees
        .iter()
        .enumerate()
        .map(|(index, tree)| {
            let mut uses = Vec::new();
            if let Some(tree) = tree {
                measurements_used(tree, &mut |name, span| match names.get(name) {
                    Some(&used) => uses.push((used, span)),
                    None => problems.push(Problem {
                        measurement: index,
                        span: Some(span),
                        message: format!(
                            "`{name}` is no measurement of this file (a device's register is written `device.register`)"
                        ),
                    }),
                });
            }
            uses
        })
        .collect();
    // Depth-first, marking each measurement while its uses are visited: meeting a marked one
    // again is a cycle.
    #[derive(Clone, Copy, PartialEq)]
    enum Mark {
        New,
        Visiting,
        Done,
    }
    let mut marks = vec![Mark::New; trees.len()];
    let mut order = Vec::new();
    fn visit(
        index: usize,
        uses: &[Vec<(usize, Span)>],
        marks: &mut [Mark],
        order: &mut Vec<usize>,
        path: &mut Vec<usize>,
        cycles: &mut Vec<(usize, Span, Vec<usize>)>,
    ) {
        marks[index] = Mark::Visiting;
        path.push(index);
        for (used, span) in &uses[index] {
            match marks[*used] {
                Mark::New => visit(*used, uses, marks, order, path, cycles),
                Mark::Visiting => {
                    let from = path.iter().position(|p| p == used).unwrap_or(0);
                    cycles.push((index, span.clone(), path[from..].to_vec()));
                }
                Mark::Done => {}
            }
        }
        path.pop();
        marks[index] = Mark::Done;
        order.push(index);
    }
    let mut cycles = Vec::new();
    for index in 0..trees.len() {
        if marks[index] == Mark::New {
            visit(
                index,
                &uses,
                &mut marks,
                &mut order,
                &mut Vec::new(),
                &mut cycles,
            );
        }
    }
    let mut in_cycle = vec![false; trees.len()];
    for (index, span, cycle) in cycles {
        let path: Vec<&str> = cycle
            .iter()
            .chain(cycle.first())
            .map(|i| definitions[*i].name)
            .collect();
        for member in &cycle {
            in_cycle[*member] = true;
        }
        problems.push(Problem {
            measurement: index,
            span: Some(span),
            message: format!(
                "measurements use each other in a circle: {}",
                path.join(" → ")
            ),
        });
    }
    order.retain(|index| !in_cycle[*index]);
    order
}

fn measurements_used(node: &Node, found: &mut impl FnMut(&str, Span)) {
    match node {
        Node::Measurement { name, span } => found(name, span.clone()),
        Node::Number { .. } | Node::Input { .. } => {}
        Node::Negate(inner, _) => measurements_used(inner, found),
        Node::Binary { left, right, .. } => {
            measurements_used(left, found);
            measurements_used(right, found);
        }
        Node::Call { arguments, .. } => {
            for argument in arguments {
                measurements_used(argument, found);
            }
        }
    }
}

/// What checking one measurement needs and gathers.
struct Context<'a, F> {
    definition: usize,
    names: &'a HashMap<&'a str, usize>,
    checked: &'a [Option<(Checked, usize)>],
    input: &'a F,
    plan: &'a mut Plan,
    problems: &'a mut Vec<Problem>,
    /// The finest step of its inputs and constants, as a power of ten of base units.
    finest: Option<i32>,
    /// Its inputs, itself or through measurements it uses.
    inputs: Vec<usize>,
    /// The units of its inputs and constants, in the order written.
    first_units: Vec<Unit>,
}

impl<F: Fn(&str, &str) -> Result<InputInfo, String>> Context<'_, F> {
    fn problem(&mut self, span: Span, message: String) -> Option<(Step, Dimension)> {
        self.problems.push(Problem {
            measurement: self.definition,
            span: Some(span),
            message,
        });
        None
    }

    fn finer(&mut self, exponent: i32) {
        self.finest = Some(self.finest.map_or(exponent, |f| f.min(exponent)));
    }

    fn uses_input(&mut self, index: usize) {
        if !self.inputs.contains(&index) {
            self.inputs.push(index);
        }
    }

    /// The step of a checked node and its dimension; `None` after a problem (recorded).
    fn lower(&mut self, node: &Node) -> Option<(Step, Dimension)> {
        match node {
            Node::Number { value, unit, .. } => {
                let unit = unit.clone().unwrap_or_else(Unit::none);
                let power = unit.power;
                self.finer(value.exponent() + power);
                let dimension = unit.dimension;
                if !unit.name.is_empty() {
                    self.first_units.push(unit);
                }
                Some((
                    Step::Constant(Decimal::new(value.mantissa(), value.exponent() + power)),
                    dimension,
                ))
            }
            Node::Input {
                device,
                register,
                span,
            } => {
                let info = match (self.input)(device, register) {
                    Ok(info) => info,
                    Err(message) => return self.problem(span.clone(), message),
                };
                let unit = match info.unit {
                    None => Unit::none(),
                    Some(name) => match Unit::named(name) {
                        Some(unit) => unit,
                        None => {
                            return self.problem(
                                span.clone(),
                                format!("`{device}.{register}` is in `{name}`, a unit measurements cannot compute with"),
                            )
                        }
                    },
                };
                let step = info.scale.unwrap_or(Scale::ONE);
                let Some(one_step) = Decimal::from_fixed(Fixed::new(1, step), 0) else {
                    return self.problem(
                        span.clone(),
                        format!("`{device}.{register}` counts in steps of {} {}, which no decimal holds exactly", step.step(), unit.name),
                    );
                };
                self.finer(one_step.exponent() + unit.power);
                let name = InputName {
                    device: device.clone(),
                    register: register.clone(),
                };
                let index = match self.plan.inputs.iter().position(|i| *i == name) {
                    Some(index) => index,
                    None => {
                        self.plan.inputs.push(name);
                        self.plan.inputs.len() - 1
                    }
                };
                self.uses_input(index);
                let (power, dimension) = (unit.power, unit.dimension);
                if !unit.name.is_empty() {
                    self.first_units.push(unit);
                }
                Some((Step::Input { index, power }, dimension))
            }
            Node::Measurement { name, span } => {
                let Some((checked, formula)) =
                    self.names.get(name.as_str()).and_then(|&i| self.checked[i])
                else {
                    // Unknown or in a cycle: already a problem.
                    return None;
                };
                let _ = span;
                let used = &self.plan.formulas[formula];
                let (inputs, unit, resolution) =
                    (used.inputs.clone(), used.unit.clone(), used.resolution);
                for input in inputs {
                    self.uses_input(input);
                }
                self.finer(resolution + unit.power);
                self.first_units.push(unit);
                Some((Step::Measurement(formula), checked.dimension))
            }
            Node::Negate(inner, _) => {
                let (step, dimension) = self.lower(inner)?;
                Some((Step::Negate(Box::new(step)), dimension))
            }
            Node::Binary {
                operator,
                left,
                right,
                ..
            } => {
                let left_checked = self.lower(left);
                let right_checked = self.lower(right);
                let ((l, ld), (r, rd)) = (left_checked?, right_checked?);
                let dimension = match operator {
                    Operator::Add | Operator::Sub if ld != rd => {
                        let verb = if *operator == Operator::Add {
                            "added to"
                        } else {
                            "subtracted from"
                        };
                        return self.problem(
                            right.span().start..right.span().end,
                            format!(
                                "{} cannot be {verb} {}{}",
                                rd,
                                ld,
                                plain_hint(left, right, ld, rd)
                            ),
                        );
                    }
                    Operator::Add | Operator::Sub => ld,
                    Operator::Mul => ld.times(rd),
                    Operator::Div => ld.per(rd),
                };
                Some((Step::Binary(*operator, Box::new(l), Box::new(r)), dimension))
            }
            Node::Call {
                function,
                arguments,
                ..
            } => {
                let lowered: Vec<_> = arguments.iter().map(|a| self.lower(a)).collect();
                let lowered: Option<Vec<_>> = lowered.into_iter().collect();
                let lowered = lowered?;
                let dimension = lowered[0].1;
                if let Some(position) = lowered.iter().position(|(_, d)| *d != dimension) {
                    return self.problem(
                        arguments[position].span(),
                        format!("`{}` takes arguments of one dimension: this is {}, the first {dimension}", function.name(), lowered[position].1),
                    );
                }
                Some((
                    Step::Call(*function, lowered.into_iter().map(|(s, _)| s).collect()),
                    dimension,
                ))
            }
        }
    }
}

/// "write 20mm" when a plain number meets a quantity.
fn plain_hint(left: &Node, right: &Node, ld: Dimension, rd: Dimension) -> String {
    let plain = |node: &Node, other: Dimension| match node {
        Node::Number {
            unit: None, value, ..
        } if other != Dimension::NONE => Some(format!(
            " (a number without a unit is a plain number: write its unit after it, as `{}mm`)",
            Decimal::new(value.mantissa(), value.exponent()).to_f64()
        )),
        _ => None,
    };
    plain(left, rd)
        .or_else(|| plain(right, ld))
        .unwrap_or_default()
}

impl Plan {
    /// Evaluates every measurement from `inputs` (one per [`Plan::inputs`], `None` where it
    /// has no valid value): each formula's value in its unit, or why it has none.
    pub fn evaluate(&self, inputs: &[Option<Fixed>]) -> Vec<Result<Fixed, Invalid>> {
        let mut results: Vec<Result<Decimal, Invalid>> = Vec::with_capacity(self.formulas.len());
        let mut values = Vec::with_capacity(self.formulas.len());
        for formula in &self.formulas {
            let base_resolution = formula.resolution + formula.unit.power;
            let value = evaluate(&formula.step, inputs, &results, base_resolution);
            values.push(value.clone().and_then(|v| formula.in_unit(v)));
            results.push(value);
        }
        values
    }
}

impl Formula {
    /// A value in base units as a value in this formula's unit.
    fn in_unit(&self, value: Decimal) -> Result<Fixed, Invalid> {
        let value = Decimal::new(value.mantissa(), value.exponent() - self.unit.power);
        let exponent = value.exponent().min(self.resolution);
        value
            .to_fixed(exponent)
            .ok_or(Invalid::Arithmetic(ArithmeticError::Overflow))
    }
}

fn evaluate(
    step: &Step,
    inputs: &[Option<Fixed>],
    earlier: &[Result<Decimal, Invalid>],
    resolution: i32,
) -> Result<Decimal, Invalid> {
    let value = |step| evaluate(step, inputs, earlier, resolution);
    Ok(match step {
        Step::Constant(value) => *value,
        Step::Input { index, power } => {
            let fixed = inputs
                .get(*index)
                .copied()
                .flatten()
                .ok_or(Invalid::Input(*index))?;
            Decimal::from_fixed(fixed, *power).ok_or(Invalid::Input(*index))?
        }
        Step::Measurement(index) => earlier
            .get(*index)
            .cloned()
            .unwrap_or(Err(Invalid::Measurement(*index)))
            .map_err(|_| Invalid::Measurement(*index))?,
        Step::Negate(inner) => value(inner)?.checked_neg()?,
        Step::Binary(operator, left, right) => {
            let (left, right) = (value(left)?, value(right)?);
            match operator {
                Operator::Add => left.checked_add(right)?,
                Operator::Sub => left.checked_sub(right)?,
                Operator::Mul => left.checked_mul(right)?,
                Operator::Div => left.div_to(right, resolution)?,
            }
        }
        Step::Call(function, arguments) => {
            let mut values = arguments.iter().map(value);
            let first = values.next().unwrap_or(Ok(Decimal::ZERO))?;
            match function {
                Function::Abs => first.checked_abs()?,
                Function::Min => values.try_fold(first, |a, b| {
                    let b = b?;
                    Ok::<_, Invalid>(if b.compare(a).is_lt() { b } else { a })
                })?,
                Function::Max => values.try_fold(first, |a, b| {
                    let b = b?;
                    Ok::<_, Invalid>(if b.compare(a).is_gt() { b } else { a })
                })?,
                Function::Avg => {
                    let sum =
                        values.try_fold(first, |a, b| Ok::<_, Invalid>(a.checked_add(b?)?))?;
                    let count = i128::try_from(arguments.len()).unwrap_or(1);
                    sum.div_to(Decimal::new(count, 0), resolution)?
                }
            }
        }
    })
}
