//! The runtime description of a checked model: the same [`DeviceInfo`] a family crate's
//! generated `DEVICE` holds, built while the program runs, so that a tool can load a spec
//! file without compiling a crate for it.
//!
//! This is the one computation of a description: the emitter (`optobus-codegen`) calls
//! [`description`] too and only prints the value as Rust, so a compiled `DEVICE` and a
//! description built at run time agree by construction. The description is leaked to
//! `'static`: a tool describes a handful of specs once.

use std::cell::RefCell;

use optobus_device::{
    BufferInfo, CodeInfo, CommandInfo, DeviceInfo, ExceptionShape, FieldInfo, FrameShape,
    GroupInfo, RegisterInfo, RepeatCopy, ReservedInfo, RtuInfo, Scale, TcpInfo, ValueKind,
};

use crate::model::{
    Apply, ExceptionStyle, Field, Kind, LongWrites, Model, Register, Scalar, ScaleSpec, Table,
};

/// The runtime description of `model`, which must have passed every rule
/// ([`crate::check_source`] gives only such models).
pub fn describe(model: &Model) -> &'static DeviceInfo {
    description(model).device
}

/// A checked model's description and the code lists it shares between registers.
#[derive(Debug)]
pub struct Description {
    /// What [`describe`] returns.
    pub device: &'static DeviceInfo,
    /// The codes of each of the model's enums, in `Model::enums` order: the very slices the
    /// device's registers, fields and exception codes hold, so that a printer can name a list
    /// by its enum (compare with [`std::ptr::eq`]).
    pub enum_codes: Vec<&'static [CodeInfo]>,
    /// Each number the description had to clamp (or, for a sentinel, leave out) because it
    /// does not fit its runtime type, as a sentence. Empty for a checked model: the rules
    /// refuse every such number; the emitter writes each as `compile_error!`, should the
    /// checker ever miss one, rather than compile a clamped number.
    pub unfit: Vec<String>,
}

/// [`describe`], with the code list of each enum and the numbers that did not fit beside it:
/// what the emitter prints as the compiled `DEVICE`.
pub fn description(model: &Model) -> Description {
    let describer = Describer::new(model);
    let device = leak(describer.device());
    Description {
        device,
        enum_codes: describer.codes,
        unfit: describer.unfit.into_inner(),
    }
}

fn leak<T>(value: T) -> &'static T {
    Box::leak(Box::new(value))
}

fn leak_slice<T>(values: Vec<T>) -> &'static [T] {
    Box::leak(values.into_boxed_slice())
}

/// `describe` applied to each of `items`, leaked.
fn leak_each<T, U>(items: &[T], describe: impl FnMut(&T) -> U) -> &'static [U] {
    leak_slice(items.iter().map(describe).collect())
}

fn text(text: &str) -> &'static str {
    Box::leak(text.to_owned().into_boxed_str())
}

/// A doc comment's text as the generated code carries it (trimmed; empty when absent).
fn doc(doc: Option<&str>) -> &'static str {
    text(doc.map(str::trim).unwrap_or(""))
}

fn option_text(value: Option<&str>) -> Option<&'static str> {
    value.map(text)
}

struct Describer<'m> {
    model: &'m Model,
    /// The codes of each enum of the model, leaked once and shared by every user.
    codes: Vec<&'static [CodeInfo]>,
    /// Each number that did not fit its runtime type (see [`Description::unfit`]).
    unfit: RefCell<Vec<String>>,
}

impl<'m> Describer<'m> {
    fn new(model: &'m Model) -> Self {
        let unfit = RefCell::new(Vec::new());
        let codes = model
            .enums
            .iter()
            .map(|def| {
                leak_slice(
                    def.codes
                        .iter()
                        .map(|c| CodeInfo {
                            code: fit(&unfit, c.code, u32::MAX, "enum code"),
                            name: text(&c.name),
                            meaning: text(c.meaning.as_deref().unwrap_or("")),
                            doc: doc(c.doc.as_deref()),
                        })
                        .collect(),
                )
            })
            .collect();
        Self {
            model,
            codes,
            unfit,
        }
    }

    fn fit<T, V>(&self, value: V, fallback: T, what: &str) -> T
    where
        T: TryFrom<V>,
        V: Copy + std::fmt::Display,
    {
        fit(&self.unfit, value, fallback, what)
    }

    /// A sentinel that does not fit 32 bits is recorded, and left out of the description.
    fn sentinel(&self, sentinel: Option<u64>) -> Option<u32> {
        sentinel.and_then(|s| fitting(&self.unfit, s, "sentinel"))
    }

    fn codes(&self, index: Option<usize>) -> &'static [CodeInfo] {
        index
            .and_then(|i| self.codes.get(i).copied())
            .unwrap_or(&[])
    }

    fn device(&self) -> DeviceInfo {
        let model = self.model;
        let device = &model.device;
        let rtu = device.rtu.as_ref().map(|rtu| RtuInfo {
            default_baud: rtu.default_baud,
            bauds: leak_slice(rtu.bauds.clone()),
            parity: rtu.parity,
            data_bits: rtu.data_bits,
            stop_bits: rtu.stop_bits,
        });
        let tcp = device.tcp.as_ref().map(|tcp| TcpInfo {
            port: tcp.port,
            default_ip: tcp.default_ip.map(|ip| ip.octets()),
        });
        let wide = if model.protocol.long_writes == LongWrites::Wide {
            model
                .registers
                .iter()
                .filter(|r| r.table == Table::Holding && r.access.writable() && r.words.0 == 2)
                .filter_map(|r| u16::try_from(r.address.0).ok())
                .collect()
        } else {
            Vec::new()
        };
        let exception = match model.protocol.exception {
            ExceptionStyle::Standard => ExceptionShape::Standard,
            ExceptionStyle::CountedWord => ExceptionShape::CountedWord,
        };
        let continuous_send = model
            .protocol
            .continuous_send
            .as_ref()
            .map(|(register, code, _)| {
                let code = self.fit(*code, u32::MAX, "continuous-send code");
                (text(register), code)
            });
        let exception_codes = self.codes(
            model
                .protocol
                .exception_codes
                .as_ref()
                .and_then(|r| r.index),
        );
        DeviceInfo {
            family: text(&model.family),
            title: text(&model.title),
            aliases: leak_each(&model.aliases, |a| text(a)),
            manual: text(&model.manual.file),
            rtu,
            tcp,
            default_slave: device.default_slave,
            slaves: (device.min_slave, device.max_slave),
            functions: leak_slice(device.functions.clone()),
            max_read_words: device.max_read_words,
            power_up_ms: device.power_up_ms.unwrap_or(0),
            holding_registers: self.fit(device.holding_size, u16::MAX, "holding table size"),
            input_registers: self.fit(device.input_size, u16::MAX, "input table size"),
            addressing: model.protocol.addressing,
            long_writes: model.protocol.long_writes,
            frame_shape: FrameShape {
                exception,
                four_byte_writes: leak_slice(wide),
            },
            needs_save_and_power_cycle: model.protocol.apply == Apply::AfterSaveAndPowerCycle,
            exception_codes,
            continuous_send,
            registers: leak_each(&model.registers, |r| self.register(r)),
            reserved: leak_each(&model.reserved, |r| ReservedInfo {
                table: r.table,
                from: self.fit(r.from, u16::MAX, "reserved address"),
                to: self.fit(r.to, u16::MAX, "reserved address"),
                readable: r.readable,
            }),
            commands: leak_each(&model.commands, |c| CommandInfo {
                name: text(&c.name),
                doc: doc(c.doc.as_deref()),
                register: text(&c.register),
                value: self.fit(c.value, u32::MAX, "command value"),
                busy_ms: c.busy_ms.unwrap_or(0),
                effect: c.effect,
                targets: leak_each(&c.targets, |t| text(t)),
                done_when: c.completion(),
            }),
            groups: leak_each(&model.groups, |g| GroupInfo {
                name: text(&g.name),
                doc: doc(g.doc.as_deref()),
                registers: leak_each(&g.registers, |(n, _)| text(n)),
            }),
            buffer: model.buffer.as_ref().map(|b| {
                leak(BufferInfo {
                    section: text(b.section.as_deref().unwrap_or("")),
                    doc: doc(b.doc.as_deref()),
                    source: b.source.as_ref().map(|n| text(&n.name)),
                    count: text(&b.count.name),
                    most: b.most.0,
                    lock: text(&b.lock.name),
                    unlock: text(&b.unlock.name),
                    page: text(&b.page.name),
                    read_count: text(&b.read_count.name),
                    valid_count: text(&b.valid_count.name),
                    values: text(&b.values.name),
                    interval: b.interval.as_ref().map(|n| text(&n.name)),
                    ratio: b.ratio.as_ref().map(|n| text(&n.name)),
                })
            }),
        }
    }

    fn register(&self, register: &Register) -> RegisterInfo {
        let mut codes: &'static [CodeInfo] = &[];
        let kind = match &register.kind {
            Kind::Bool => ValueKind::Bool,
            Kind::Scalar(scalar) => ValueKind::Scalar(*scalar),
            Kind::Enum(reference) => {
                codes = self.codes(reference.index);
                ValueKind::Enum
            }
            Kind::Packed(fields) => ValueKind::Packed(self.fields(fields)),
            Kind::Record(fields) => ValueKind::Record(self.fields(fields)),
            Kind::Ipv4 => ValueKind::Ipv4,
            Kind::Version(parts) => {
                let part = |i: usize| text(parts.get(i).map_or("ignore", String::as_str));
                ValueKind::Version(leak([part(0), part(1), part(2), part(3)]))
            }
        };
        let copy = register.repeat.as_ref().map(|copy| RepeatCopy {
            repeat: text(&self.model.repeats[copy.repeat].name),
            number: self.fit(copy.number, u8::MAX, "copy number"),
            member: text(&copy.base),
        });
        RegisterInfo {
            name: text(&register.name),
            doc: doc(register.doc.as_deref()),
            zh: text(register.zh.as_deref().unwrap_or("")),
            section: text(register.section.as_deref().unwrap_or("")),
            table: register.table,
            address: self.fit(register.address.0, u16::MAX, "address"),
            words: self.fit(register.words.0, u16::MAX, "word count"),
            access: register.access,
            kind,
            codes,
            scale: scale(register.scale.as_ref()),
            unit: option_text(register.unit.as_deref()),
            range: register.range,
            sentinel: self.sentinel(register.sentinel),
            word_order: register.word_order,
            write_order: register.write_order.unwrap_or_default(),
            copy,
            read_side_effect: option_text(register.read_side_effect.as_deref()),
            allowed_values: leak_slice(
                register
                    .allowed_values
                    .as_ref()
                    .map(|(values, _)| values.clone())
                    .unwrap_or_default(),
            ),
            action: register.action,
            role: register.role,
        }
    }

    fn fields(&self, fields: &[Field]) -> &'static [FieldInfo] {
        leak_slice(
            fields
                .iter()
                .map(|field| {
                    let scalar = field.scalar.unwrap_or(Scalar::unsigned(1));
                    FieldInfo {
                        name: text(&field.name),
                        doc: doc(field.doc.as_deref()),
                        lsb: field.lsb.unwrap_or(0),
                        width: field
                            .width
                            .unwrap_or(if scalar.words() == 2 { 32 } else { 16 }),
                        scalar,
                        codes: self.codes(field.enum_ref.as_ref().and_then(|r| r.index)),
                        range: field.range,
                        scale: scale(field.scale.as_ref()),
                        unit: option_text(field.unit.as_deref()),
                        sentinel: self.sentinel(field.sentinel),
                    }
                })
                .collect(),
        )
    }
}

/// The exact step, when the spec's scale is well formed (a checked model's always is).
fn scale(scale: Option<&ScaleSpec>) -> Option<Scale> {
    scale.and_then(|s| s.value.as_ref().ok()).copied()
}

/// `value` as `T`; else `fallback`, with the value and `what` it is written in `unfit`.
fn fit<T, V>(unfit: &RefCell<Vec<String>>, value: V, fallback: T, what: &str) -> T
where
    T: TryFrom<V>,
    V: Copy + std::fmt::Display,
{
    fitting(unfit, value, what).unwrap_or(fallback)
}

/// `value` as `T`; else `None`, with the value and `what` it is written in `unfit`.
fn fitting<T, V>(unfit: &RefCell<Vec<String>>, value: V, what: &str) -> Option<T>
where
    T: TryFrom<V>,
    V: Copy + std::fmt::Display,
{
    let fits = T::try_from(value).ok();
    if fits.is_none() {
        unfit.borrow_mut().push(format!(
            "{what} {value} does not fit {}: the spec checker should have refused it",
            std::any::type_name::<T>()
        ));
    }
    fits
}
