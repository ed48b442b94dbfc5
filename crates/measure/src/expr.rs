//! The expression language: `20mm - top.distance_1 - bottom.distance_1`, read into a tree
//! whose every node knows where it was written.
//!
//! ```text
//! expr     := term (("+" | "-" | "−") term)*
//! term     := unary (("*" | "×" | "/" | "÷") unary)*
//! unary    := ("-" | "−" | "+") unary | primary
//! primary  := number unit? | device "." register | measurement
//!           | function "(" expr ("," expr)* ")" | "(" expr ")"
//! function := "abs" | "min" | "max" | "avg"
//! ```
//! Numbers are plain decimals (`20`, `0.02`) with their unit written right after them (`20mm`,
//! `0.02m`, `5µm`); names are letters, digits and `_`, starting with a letter or `_`.

use std::ops::Range;

use crate::number::Decimal;
use crate::unit::Unit;

/// The longest expression taken, in bytes.
pub const MAX_LENGTH: usize = 4_096;

/// The deepest tree taken (parentheses, calls, signs, and each operator of a chain such as
/// `a + b + c` counts one): trees are checked and evaluated by recursion, so their depth is
/// bounded when they are read.
pub const MAX_DEPTH: usize = 100;

/// Where in the expression's text something is: a byte range.
pub type Span = Range<usize>;

/// A problem with an expression, at its place in the text.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ExprError {
    /// Where (bytes of the expression's text).
    pub span: Span,
    /// What, in one line.
    pub message: String,
}

impl ExprError {
    pub(crate) fn new(span: Span, message: impl Into<String>) -> Self {
        Self {
            span,
            message: message.into(),
        }
    }
}

/// A function of the language.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Function {
    /// The magnitude of one argument.
    Abs,
    /// The least of its arguments.
    Min,
    /// The greatest of its arguments.
    Max,
    /// The mean of its arguments (a division: rounded to the result's resolution).
    Avg,
}

impl Function {
    fn named(name: &str) -> Option<Self> {
        Some(match name {
            "abs" => Self::Abs,
            "min" => Self::Min,
            "max" => Self::Max,
            "avg" => Self::Avg,
            _ => return None,
        })
    }

    /// Its name as written.
    pub fn name(self) -> &'static str {
        match self {
            Self::Abs => "abs",
            Self::Min => "min",
            Self::Max => "max",
            Self::Avg => "avg",
        }
    }
}

/// An arithmetic operator.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Operator {
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
}

/// An expression as written.
#[derive(Clone, Debug, PartialEq)]
pub enum Node {
    /// A constant, in the unit written after it.
    Number {
        /// Its digits.
        value: Decimal,
        /// Its unit, if one was written.
        unit: Option<Unit>,
        /// Where.
        span: Span,
    },
    /// A register of a device: `top.distance_1`.
    Input {
        /// The device's name in the bus file.
        device: String,
        /// The register's name.
        register: String,
        /// Where.
        span: Span,
    },
    /// Another measurement's value.
    Measurement {
        /// Its name.
        name: String,
        /// Where.
        span: Span,
    },
    /// `-x`.
    Negate(Box<Node>, Span),
    /// `a op b`.
    Binary {
        /// Which.
        operator: Operator,
        /// Left side.
        left: Box<Node>,
        /// Right side.
        right: Box<Node>,
        /// Where (the whole of it).
        span: Span,
    },
    /// `f(a, b, …)`.
    Call {
        /// Which.
        function: Function,
        /// Its arguments.
        arguments: Vec<Node>,
        /// Where (the whole call).
        span: Span,
    },
}

impl Node {
    /// Where it was written.
    pub fn span(&self) -> Span {
        match self {
            Self::Number { span, .. }
            | Self::Input { span, .. }
            | Self::Measurement { span, .. }
            | Self::Negate(_, span)
            | Self::Binary { span, .. }
            | Self::Call { span, .. } => span.clone(),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Token {
    Number(Decimal, Option<Unit>),
    Name(String),
    Dot,
    Open,
    Close,
    Comma,
    Operator(Operator),
}

/// Reads `text` into tokens with their places.
fn tokens(text: &str) -> Result<Vec<(Token, Span)>, ExprError> {
    let mut tokens = Vec::new();
    let mut chars = text.char_indices().peekable();
    while let Some(&(start, c)) = chars.peek() {
        let single = |token| (token, start..start + c.len_utf8());
        match c {
            _ if c.is_whitespace() => {
                chars.next();
            }
            '0'..='9' => {
                let mut end = start;
                while let Some(&(i, d)) = chars.peek() {
                    if !(d.is_ascii_digit() || d == '.') {
                        break;
                    }
                    end = i + d.len_utf8();
                    chars.next();
                }
                let digits = &text[start..end];
                let unit_start = end;
                while let Some(&(i, u)) = chars.peek() {
                    if !(u.is_alphabetic() || matches!(u, 'µ' | 'μ' | '°' | '℃' | '%')) {
                        break;
                    }
                    end = i + u.len_utf8();
                    chars.next();
                }
                let unit_text = &text[unit_start..end];
                if unit_text.starts_with(['e', 'E'])
                    && chars
                        .peek()
                        .is_some_and(|(_, n)| n.is_ascii_digit() || *n == '-' || *n == '+')
                {
                    return Err(ExprError::new(
                        start..end + 1,
                        format!("`{digits}{unit_text}…`: write numbers as plain decimals (`10`, `0.001`), not with an exponent"),
                    ));
                }
                let value = decimal(digits).ok_or_else(|| {
                    ExprError::new(
                        start..unit_start,
                        format!("`{digits}` is not a decimal number"),
                    )
                })?;
                let unit = match unit_text {
                    "" => None,
                    _ => Some(Unit::named(unit_text).ok_or_else(|| {
                        ExprError::new(
                            unit_start..end,
                            format!("`{unit_text}` is not a unit known here (mm, µm, m, us, ms, s, Hz, uV, %, degC)"),
                        )
                    })?),
                };
                tokens.push((Token::Number(value, unit), start..end));
            }
            _ if c.is_alphabetic() || c == '_' => {
                let mut end = start;
                while let Some(&(i, d)) = chars.peek() {
                    if !(d.is_alphanumeric() || d == '_') {
                        break;
                    }
                    end = i + d.len_utf8();
                    chars.next();
                }
                tokens.push((Token::Name(text[start..end].to_owned()), start..end));
            }
            _ => {
                let token = match c {
                    '.' => Token::Dot,
                    '(' => Token::Open,
                    ')' => Token::Close,
                    ',' => Token::Comma,
                    '+' => Token::Operator(Operator::Add),
                    '-' | '−' => Token::Operator(Operator::Sub),
                    '*' | '×' => Token::Operator(Operator::Mul),
                    '/' | '÷' => Token::Operator(Operator::Div),
                    _ => {
                        return Err(ExprError::new(
                            start..start + c.len_utf8(),
                            format!("`{c}` has no meaning here"),
                        ))
                    }
                };
                tokens.push(single(token));
                chars.next();
            }
        }
    }
    Ok(tokens)
}

/// `12`, `0.020`: exactly.
fn decimal(digits: &str) -> Option<Decimal> {
    let (whole, fraction) = digits.split_once('.').unwrap_or((digits, ""));
    if whole.is_empty() || fraction.contains('.') || digits.len() > 36 {
        return None;
    }
    let mantissa: i128 = format!("{whole}{fraction}").parse().ok()?;
    let exponent = -i32::try_from(fraction.len()).ok()?;
    Some(Decimal::new(mantissa, exponent))
}

/// Reads an expression.
pub fn parse(text: &str) -> Result<Node, ExprError> {
    if text.len() > MAX_LENGTH {
        return Err(ExprError::new(
            0..text.len(),
            format!("an expression is at most {MAX_LENGTH} bytes long"),
        ));
    }
    let tokens = tokens(text)?;
    if tokens.is_empty() {
        return Err(ExprError::new(0..text.len(), "the expression is empty"));
    }
    let mut parser = Parser {
        tokens: &tokens,
        at: 0,
        end: text.len(),
        depth: 0,
    };
    let node = parser.sum()?;
    match parser.peek() {
        None => Ok(node),
        Some((_, span)) => Err(ExprError::new(
            span.clone(),
            "an operator (+ - * /) or the end was expected here",
        )),
    }
}

struct Parser<'t> {
    tokens: &'t [(Token, Span)],
    at: usize,
    end: usize,
    depth: usize,
}

impl Parser<'_> {
    fn peek(&self) -> Option<&(Token, Span)> {
        self.tokens.get(self.at)
    }

    fn next(&mut self) -> Option<&(Token, Span)> {
        let token = self.tokens.get(self.at);
        self.at += 1;
        token
    }

    /// The place after the last token, for "expected … here" at the end.
    fn end_span(&self) -> Span {
        self.end..self.end
    }

    fn deeper(&mut self, span: &Span) -> Result<(), ExprError> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(ExprError::new(
                span.clone(),
                format!("nested more than {MAX_DEPTH} deep"),
            ));
        }
        Ok(())
    }

    fn binary(
        &mut self,
        operators: [Operator; 2],
        operand: fn(&mut Self) -> Result<Node, ExprError>,
    ) -> Result<Node, ExprError> {
        let mut left = operand(self)?;
        let depth = self.depth;
        while let Some((Token::Operator(operator), span)) = self.peek() {
            let (operator, span) = (*operator, span.clone());
            if !operators.contains(&operator) {
                break;
            }
            self.at += 1;
            self.deeper(&span)?;
            let right = operand(self)?;
            let span = left.span().start..right.span().end;
            left = Node::Binary {
                operator,
                left: Box::new(left),
                right: Box::new(right),
                span,
            };
        }
        self.depth = depth;
        Ok(left)
    }

    fn sum(&mut self) -> Result<Node, ExprError> {
        self.binary([Operator::Add, Operator::Sub], Self::term)
    }

    fn term(&mut self) -> Result<Node, ExprError> {
        self.binary([Operator::Mul, Operator::Div], Self::unary)
    }

    fn unary(&mut self) -> Result<Node, ExprError> {
        match self.peek().cloned() {
            Some((Token::Operator(sign @ (Operator::Sub | Operator::Add)), span)) => {
                self.at += 1;
                self.deeper(&span)?;
                let operand = self.unary()?;
                self.depth -= 1;
                let whole = span.start..operand.span().end;
                Ok(match sign {
                    Operator::Sub => Node::Negate(Box::new(operand), whole),
                    _ => operand,
                })
            }
            _ => self.primary(),
        }
    }

    fn primary(&mut self) -> Result<Node, ExprError> {
        let Some((token, span)) = self.next().cloned() else {
            return Err(ExprError::new(
                self.end_span(),
                "a number, a device's register or a measurement was expected here",
            ));
        };
        match token {
            Token::Number(value, unit) => Ok(Node::Number { value, unit, span }),
            Token::Open => {
                self.deeper(&span)?;
                let inner = self.sum()?;
                self.depth -= 1;
                self.close(&span)?;
                Ok(inner)
            }
            Token::Name(name) => match self.peek() {
                Some((Token::Dot, _)) => {
                    self.at += 1;
                    match self.next().cloned() {
                        Some((Token::Name(register), end)) => Ok(Node::Input {
                            device: name,
                            register,
                            span: span.start..end.end,
                        }),
                        other => Err(ExprError::new(
                            other.map_or_else(|| self.end_span(), |(_, s)| s),
                            format!("a register of `{name}` was expected after `{name}.`"),
                        )),
                    }
                }
                Some((Token::Open, _)) => self.call(&name, span),
                _ => Ok(Node::Measurement { name, span }),
            },
            _ => Err(ExprError::new(
                span,
                "a number, a device's register or a measurement was expected here",
            )),
        }
    }

    fn close(&mut self, open: &Span) -> Result<Span, ExprError> {
        match self.next().cloned() {
            Some((Token::Close, span)) => Ok(span),
            Some((_, span)) => Err(ExprError::new(span, "`)` was expected here")),
            None => Err(ExprError::new(open.clone(), "this `(` is never closed")),
        }
    }

    fn call(&mut self, name: &str, span: Span) -> Result<Node, ExprError> {
        let function = Function::named(name).ok_or_else(|| {
            ExprError::new(
                span.clone(),
                format!("`{name}` is not a function (abs, min, max, avg)"),
            )
        })?;
        let open = self
            .next()
            .map(|(_, s)| s.clone())
            .unwrap_or_else(|| span.clone());
        self.deeper(&span)?;
        let mut arguments = vec![self.sum()?];
        while let Some((Token::Comma, _)) = self.peek() {
            self.at += 1;
            arguments.push(self.sum()?);
        }
        self.depth -= 1;
        let close = self.close(&open)?;
        let whole = span.start..close.end;
        match (function, arguments.len()) {
            (Function::Abs, 1) | (Function::Min | Function::Max | Function::Avg, 1..) => {
                Ok(Node::Call {
                    function,
                    arguments,
                    span: whole,
                })
            }
            (_, count) => Err(ExprError::new(
                whole,
                format!("`abs` takes one argument, not {count}"),
            )),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn precedence_and_places() {
        let node = parse("20mm - top.distance_1 - bottom.distance_1").unwrap();
        let Node::Binary {
            operator,
            left,
            right,
            span,
        } = node
        else {
            panic!()
        };
        assert_eq!((operator, span), (Operator::Sub, 0..41));
        assert!(
            matches!(*right, Node::Input { ref device, ref register, ref span } if device == "bottom" && register == "distance_1" && *span == (24..41))
        );
        assert!(matches!(
            *left,
            Node::Binary {
                operator: Operator::Sub,
                ..
            }
        ));
        let node = parse("a.x + b.y * 2").unwrap();
        assert!(
            matches!(node, Node::Binary { operator: Operator::Add, ref right, .. } if matches!(**right, Node::Binary { operator: Operator::Mul, .. }))
        );
    }

    #[test]
    fn functions_signs_and_the_typographic_minus() {
        assert!(
            matches!(parse("avg(a.x, b.x, c.x)").unwrap(), Node::Call { function: Function::Avg, ref arguments, .. } if arguments.len() == 3)
        );
        assert!(matches!(parse("−gap").unwrap(), Node::Negate(..)));
        assert!(matches!(
            parse("0.02m − a.b").unwrap(),
            Node::Binary {
                operator: Operator::Sub,
                ..
            }
        ));
    }

    #[test]
    fn mistakes_are_located() {
        let error = parse("20mm - top.").unwrap_err();
        assert_eq!(error.span, 11..11);
        let error = parse("1e1 + a.b").unwrap_err();
        assert!(
            error.message.contains("plain decimals"),
            "{}",
            error.message
        );
        let error = parse("20 furlong").unwrap_err();
        assert!(error.message.contains("an operator"), "{}", error.message);
        let error = parse("20fur").unwrap_err();
        assert_eq!(error.span, 2..5);
        let error = parse("sqrt(a.b)").unwrap_err();
        assert!(error.message.contains("not a function"));
        let error = parse("abs(a.b, c.d)").unwrap_err();
        assert!(error.message.contains("one argument"));
        let error = parse("(a.b + 1").unwrap_err();
        assert_eq!(error.span, 0..1);
        let deep = format!("{}a.b{}", "(".repeat(101), ")".repeat(101));
        assert!(parse(&deep).unwrap_err().message.contains("nested"));
        let long = vec!["a.b"; 102].join(" + ");
        assert!(parse(&long).unwrap_err().message.contains("nested"));
        assert!(parse("").is_err());
        assert!(parse("a.b $ c.d")
            .unwrap_err()
            .message
            .contains("no meaning"));
    }
}

/// A quantity as a file writes a limit (`9.9mm`, `-0.5`, `10 um`… written as one number with
/// its unit right after it), in `unit`, exactly; a number without a unit is in `unit`.
pub fn quantity(text: &str, unit: &Unit) -> Result<Decimal, String> {
    let node = parse(text.trim()).map_err(|e| e.message)?;
    let (negative, node) = match node {
        Node::Negate(inner, _) => (true, *inner),
        node => (false, node),
    };
    let Node::Number {
        value, unit: given, ..
    } = node
    else {
        return Err(format!("`{text}` is not a number with its unit (`9.9mm`)"));
    };
    let value = match given {
        None => value,
        Some(given) if given.dimension == unit.dimension => Decimal::new(
            value.mantissa(),
            value.exponent() + given.power - unit.power,
        ),
        Some(given) => {
            return Err(format!(
                "`{text}` is {}, the measurement is {}",
                given.dimension, unit.dimension
            ))
        }
    };
    if negative {
        value.checked_neg().map_err(|e| e.to_string())
    } else {
        Ok(value)
    }
}

#[cfg(test)]
mod quantity_tests {
    use super::*;

    #[test]
    fn limits_are_read_in_the_measurements_unit() {
        let mm = Unit::named("mm").unwrap();
        assert_eq!(quantity("9.9mm", &mm).unwrap(), Decimal::new(99, -1));
        assert_eq!(quantity("10100um", &mm).unwrap(), Decimal::new(101, -1));
        assert_eq!(quantity("-0.001", &mm).unwrap(), Decimal::new(-1, -3));
        assert!(quantity("5s", &mm)
            .unwrap_err()
            .contains("is s, the measurement is m"));
        assert!(quantity("top.distance_1", &mm).is_err());
    }
}
