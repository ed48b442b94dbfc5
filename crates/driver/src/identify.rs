//! Which model a device is, from each candidate spec's fingerprint: the device is read as each
//! candidate would be read, with read-only requests (FC03, FC04) and never a read whose read
//! changes the device, and each candidate is ruled out by what does not fit it.
//!
//! The evidence per candidate, all taken from its description (`DEVICE`), none from a family
//! name:
//!
//! - **Its registers**: every register a dump reads, in the fewest requests, framed as the
//!   candidate frames them (exception shape, serial format) at its slave. An exception to a
//!   register the candidate defines, or a reply that does not fit its framing (or none at
//!   all), rules it out.
//! - **Its table bounds**: the first address past each of its tables (address 0 of a table it
//!   lacks). The specs give each table's size (from the manual, or from its highest defined
//!   address where the manual gives none), and a device refuses reads past it: an answer
//!   there rules the candidate out, and so does silence or a reply of another framing.
//! - **Its settings**: the stored value of every read-write register that no command writes
//!   must be one the device accepts (the one value check, [`RegisterInfo::check`]): the
//!   manuals' devices refuse an invalid write and keep the old value, so they never hold one.
//!
//! No request touches an address where any candidate has a register whose read changes the
//! device (`read_side_effect`: the P series' buffer page): reading as one model must not turn
//! another model's buffer. Such registers are left out, a request that would bridge them is
//! split, and a past-the-table probe moves on to the next address clear of them.
//!
//! A candidate fits when something it defines answered and nothing ruled it out. A device of
//! a model that is not among the candidates must fit none of them: [`Verdict::None`], never a
//! wrong model.

use std::fmt;
use std::future::Future;

use optobus_device::{DeviceInfo, ExceptionShape, Invalid, RegisterInfo, Table, ValueKind};
use optobus_transport::{Error as WireError, ExceptionCode, ReadRequest, Transport};

use crate::plan::{plan_reads, ReadSpan};

/// Opens a link to the device framed as a candidate model expects it: its exception frame
/// shape, and on a serial line its factory format unless the user gave another.
pub trait ConnectAs {
    /// The link.
    type Link: Transport;
    /// Why no link could be opened (the port or address cannot be reached): identification
    /// stops.
    type Error;

    /// A link framed for `model`.
    fn connect_as(
        &mut self,
        model: &'static DeviceInfo,
    ) -> impl Future<Output = Result<Self::Link, Self::Error>>;
}

/// One thing learnt about one candidate.
#[derive(Clone, Debug, PartialEq)]
pub enum Finding {
    /// Registers the candidate defines answered with words.
    Answered {
        /// The request.
        span: ReadSpan,
    },
    /// A register the candidate defines answered an exception: the device lacks it.
    Refused {
        /// The request.
        span: ReadSpan,
        /// The device's code, named as the candidate names it.
        code: Exception,
    },
    /// No reply that fits the candidate's framing at its slave and line format: another
    /// framing, another slave or serial format, or silence.
    NoFit {
        /// The request.
        span: ReadSpan,
        /// What the client saw.
        error: String,
    },
    /// Stored settings hold values the candidate accepts.
    Plausible {
        /// How many settings were checked.
        settings: usize,
    },
    /// A setting holds a value the candidate never stores.
    Implausible {
        /// The register.
        register: &'static str,
        /// Its raw value.
        raw: u32,
        /// Why the candidate refuses it.
        why: Invalid,
    },
    /// The first address past the candidate's table (address 0 of a table it lacks) was
    /// refused, as the candidate refuses it.
    RefusedPastTable {
        /// The request.
        span: ReadSpan,
        /// The device's code, named as the candidate names it.
        code: Exception,
    },
    /// The first address past the candidate's table answered with words: the device has more.
    AnsweredPastTable {
        /// The request.
        span: ReadSpan,
    },
}

/// An exception code and its name in the candidate's manual, where the spec lists the codes
/// (LC-RS numbers its own), else the standard Modbus name.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Exception {
    /// The code.
    pub code: ExceptionCode,
    /// Its name in the candidate's spec.
    pub name: Option<&'static str>,
    /// The candidate sends 16-bit codes (LC-RS), shown as `0x0001`, not `01`.
    pub wide: bool,
}

impl Exception {
    fn of(model: &DeviceInfo, code: ExceptionCode) -> Self {
        let name = model
            .exception_codes
            .iter()
            .find(|c| c.code == u32::from(code.0))
            .map(|c| c.name);
        let wide = model.frame_shape.exception == ExceptionShape::CountedWord;
        Self { code, name, wide }
    }
}

impl fmt::Display for Exception {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name {
            Some(name) if self.wide => write!(f, "{:#06X} ({name})", self.code.0),
            Some(name) => write!(f, "{:02X} ({name})", self.code.0),
            None => self.code.fmt(f),
        }
    }
}

impl Finding {
    /// Whether the finding shows beyond doubt that the device is not the candidate: an
    /// exception to a register it defines, or an answer past its table. (A missing or
    /// misfit reply may be noise; a setting out of range may be a manual's error.)
    pub fn excludes(&self) -> bool {
        matches!(self, Self::Refused { .. } | Self::AnsweredPastTable { .. })
    }

    /// Whether the finding rules the candidate out.
    pub fn rules_out(&self) -> bool {
        matches!(
            self,
            Self::Refused { .. }
                | Self::NoFit { .. }
                | Self::Implausible { .. }
                | Self::AnsweredPastTable { .. }
        )
    }
}

/// `holding 0x0000 (0) ×10`: a request as people read it.
struct Request<'a>(&'a ReadSpan);

impl fmt::Display for Request<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ReadSpan {
            table,
            address,
            count,
        } = self.0;
        write!(f, "{} {address:#06X} ({address})", table.as_str())?;
        if *count > 1 {
            write!(f, " ×{count}")?;
        }
        Ok(())
    }
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Answered { span } => write!(f, "{} answered", Request(span)),
            Self::Refused { span, code } => write!(
                f,
                "{} holds registers of the model, yet answered exception {code}",
                Request(span)
            ),
            Self::NoFit { span, error } => {
                write!(f, "{}: no reply that fits: {error}", Request(span))
            }
            Self::Plausible { settings } => {
                write!(f, "{settings} settings hold values the model accepts")
            }
            Self::Implausible { register, raw, why } => {
                write!(
                    f,
                    "`{register}` holds {raw}, which the model refuses: {why}"
                )
            }
            Self::RefusedPastTable { span, code } if span.address == 0 => write!(
                f,
                "the model has no {} registers, and {} was refused ({code})",
                span.table.as_str(),
                Request(span)
            ),
            Self::RefusedPastTable { span, code } => write!(
                f,
                "{} lies past the table and was refused ({code})",
                Request(span)
            ),
            Self::AnsweredPastTable { span } if span.address == 0 => write!(
                f,
                "the model has no {} registers, yet {} answered",
                span.table.as_str(),
                Request(span)
            ),
            Self::AnsweredPastTable { span } => {
                write!(f, "{} lies past the table, yet answered", Request(span))
            }
        }
    }
}

/// What was learnt about one candidate.
#[derive(Clone, Debug, PartialEq)]
pub struct Evidence {
    /// The candidate.
    pub model: &'static DeviceInfo,
    /// The slave address it was asked at.
    pub slave: u8,
    /// What was learnt, in the order it was asked; probing stops at an exception, a reply
    /// that does not fit or an answer past the table.
    pub findings: Vec<Finding>,
}

impl Evidence {
    /// Whether the candidate fits: something it defines answered, and nothing ruled it out.
    pub fn fits(&self) -> bool {
        self.findings
            .iter()
            .any(|f| matches!(f, Finding::Answered { .. }))
            && !self.findings.iter().any(Finding::rules_out)
    }
}

/// The evidence for every candidate, in the order they were given.
#[derive(Clone, Debug, PartialEq)]
pub struct Identification {
    /// One entry per candidate.
    pub candidates: Vec<Evidence>,
}

/// Which model the device is.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// Exactly one candidate fits.
    One(&'static DeviceInfo),
    /// No candidate fits.
    None,
    /// Several candidates fit: they cannot be told apart by what the device answers.
    Several(Vec<&'static DeviceInfo>),
}

/// Which model a device is, in words: `p-series`, `no model fits`, `several models fit: ccs,
/// ccf`.
impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::One(model) => write!(f, "{}", model.model_name()),
            Self::None => f.write_str("no model fits"),
            Self::Several(models) => {
                let names: Vec<String> =
                    models.iter().map(|m| m.model_name().to_string()).collect();
                write!(f, "several models fit: {}", names.join(", "))
            }
        }
    }
}

impl Identification {
    /// The candidates that fit.
    pub fn fitting(&self) -> Vec<&'static DeviceInfo> {
        self.candidates
            .iter()
            .filter(|e| e.fits())
            .map(|e| e.model)
            .collect()
    }

    /// The model that fits, or that none or several do.
    pub fn verdict(&self) -> Verdict {
        match self.fitting().as_slice() {
            [] => Verdict::None,
            [one] => Verdict::One(one),
            several => Verdict::Several(several.to_vec()),
        }
    }
}

/// Asks the device, as each of `candidates` would be asked, at `slave` or each candidate's
/// factory slave, and gives the evidence, in the order of `candidates`. Only read-only
/// requests are sent (FC03, FC04), and none to an address where a candidate has a register
/// whose read changes the device, until the device is shown not to be that candidate: give
/// every model you know as a candidate.
pub async fn identify<C: ConnectAs>(
    connect: &mut C,
    candidates: &[&'static DeviceInfo],
    slave: Option<u8>,
) -> Result<Identification, C::Error> {
    // Candidates with such registers first, so that their addresses are freed as soon as the
    // device has shown it is none of them.
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    order.sort_by_key(|&i| Avoid::of(candidates[i]).0.is_empty());
    let mut excluded: Vec<&'static str> = Vec::new();
    let mut found: Vec<Option<Evidence>> = vec![None; candidates.len()];
    for i in order {
        let model = candidates[i];
        let avoid = Avoid(
            candidates
                .iter()
                .filter(|m| !excluded.contains(&m.family))
                .flat_map(|m| Avoid::of(m).0)
                .collect(),
        );
        let slave = slave.unwrap_or(model.default_slave);
        let mut link = connect.connect_as(model).await?;
        let findings = probe(&mut link, model, slave, &avoid).await;
        if findings.iter().any(Finding::excludes) {
            excluded.push(model.family);
        }
        found[i] = Some(Evidence {
            model,
            slave,
            findings,
        });
    }
    Ok(Identification {
        candidates: found.into_iter().flatten().collect(),
    })
}

/// The addresses no request may touch: where a candidate has a register whose read changes
/// the device (table, first address, end).
struct Avoid(Vec<(Table, u32, u32)>);

impl Avoid {
    /// The registers of `model` whose read changes the device.
    fn of(model: &DeviceInfo) -> Self {
        let registers = model.registers.iter().filter(|r| !r.read_is_repeatable());
        Self(
            registers
                .map(|r| {
                    let start = u32::from(r.address);
                    (r.table, start, start + u32::from(r.words))
                })
                .collect(),
        )
    }

    /// Whether `count` words from `address` of `table` touch such an address.
    fn touches(&self, table: Table, address: u16, count: u16) -> bool {
        let (start, end) = (u32::from(address), u32::from(address) + u32::from(count));
        self.0
            .iter()
            .any(|&(t, from, to)| t == table && from < end && start < to)
    }

    /// The first address at or after `address` of `table` that touches none.
    fn clear_from(&self, table: Table, address: u16) -> Option<u16> {
        (address..=u16::MAX).find(|&a| !self.touches(table, a, 1))
    }
}

/// What `read` answers, as a finding: `answered` for words, `refused` for an exception.
async fn ask<T: Transport>(
    link: &mut T,
    slave: u8,
    span: ReadSpan,
) -> Result<Vec<u16>, Result<ExceptionCode, Finding>> {
    let read = ReadRequest::new(span.table.read_function(), span.address, span.count);
    match link.read_words(slave, read).await {
        Ok(words) => Ok(words),
        Err(WireError::Exception { code, .. }) => Err(Ok(code)),
        Err(error) => Err(Err(Finding::NoFit {
            span,
            error: error.to_string(),
        })),
    }
}

/// The findings about `model`, up to the first that rules it out.
async fn probe<T: Transport>(
    link: &mut T,
    model: &'static DeviceInfo,
    slave: u8,
    avoid: &Avoid,
) -> Vec<Finding> {
    let mut findings = Vec::new();
    let registers: Vec<&RegisterInfo> = model
        .dump_registers()
        .filter(|r| !avoid.touches(r.table, r.address, r.words))
        .collect();
    let mut spans = Vec::new();
    for span in plan_reads(model, &registers) {
        if !avoid.touches(span.table, span.address, span.count) {
            spans.push(span);
            continue;
        }
        // The span bridges an address to avoid: its registers one by one.
        spans.extend(
            registers
                .iter()
                .filter(|r| span.offset_of(r, model.addressing).is_some())
                .map(|r| ReadSpan {
                    table: r.table,
                    address: r.address,
                    count: r.words,
                }),
        );
    }
    let mut settings = 0;
    for span in spans {
        let words = match ask(link, slave, span).await {
            Ok(words) => words,
            Err(Ok(code)) => {
                let code = Exception::of(model, code);
                findings.push(Finding::Refused { span, code });
                return findings;
            }
            Err(Err(no_fit)) => {
                findings.push(no_fit);
                return findings;
            }
        };
        findings.push(Finding::Answered { span });
        for register in registers.iter().filter(|r| is_setting(model, r)) {
            let Some(offset) = span.offset_of(register, model.addressing) else {
                continue;
            };
            let raw = register.raw(words.get(offset..).unwrap_or_default());
            match register.check(raw) {
                Ok(()) => settings += 1,
                // The first is evidence enough; the probe goes on for a finding that excludes.
                Err(why)
                    if !findings
                        .iter()
                        .any(|f| matches!(f, Finding::Implausible { .. })) =>
                {
                    findings.push(Finding::Implausible {
                        register: register.name,
                        raw,
                        why,
                    });
                }
                Err(_) => {}
            }
        }
    }
    if settings > 0 {
        findings.push(Finding::Plausible { settings });
    }
    for table in [Table::Holding, Table::Input] {
        let Some(address) = avoid.clear_from(table, model.table_size(table)) else {
            continue;
        };
        let span = ReadSpan {
            table,
            address,
            count: 1,
        };
        match ask(link, slave, span).await {
            Ok(_) => {
                findings.push(Finding::AnsweredPastTable { span });
                return findings;
            }
            Err(Ok(code)) => {
                let code = Exception::of(model, code);
                findings.push(Finding::RefusedPastTable { span, code });
            }
            Err(Err(no_fit)) => {
                findings.push(no_fit);
                return findings;
            }
        }
    }
    findings
}

/// A register whose stored value the device has checked: read-write, one or two words of a
/// checkable kind, and not the register of a command (which reads back what the command
/// left, not a setting).
fn is_setting(model: &DeviceInfo, register: &RegisterInfo) -> bool {
    let checkable = matches!(
        register.kind,
        ValueKind::Bool | ValueKind::Scalar(_) | ValueKind::Enum | ValueKind::Packed(_)
    );
    let commanded = model
        .commands
        .iter()
        .any(|c| c.register == register.name || register.member_name() == Some(c.register));
    register.access.writable()
        && register.readable()
        && register.words <= 2
        && checkable
        && !commanded
}

#[cfg(test)]
mod tests {
    use super::Verdict;

    #[test]
    fn a_verdict_says_which_model_in_the_names_users_type() {
        let (p_series, rangefinder) = (&optobus_p_series::DEVICE, &optobus_rangefinder::DEVICE);
        assert_eq!(Verdict::One(p_series).to_string(), "p-series");
        assert_eq!(Verdict::None.to_string(), "no model fits");
        assert_eq!(
            Verdict::Several(vec![p_series, rangefinder]).to_string(),
            "several models fit: p-series, rangefinder"
        );
    }
}
