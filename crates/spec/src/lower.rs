//! From the spec as written to the model: hoist inline enums, resolve enum references, read
//! scales from their exact text, and expand repeat blocks.

use optobus_codec::value::{WordOrder, WriteOrder};

use crate::diagnostic::Diagnostic;
use crate::model::{
    Address, Buffer, Code, Command, Device, Effect, EnumDef, EnumRef, Field, Group, Kind, Manual,
    Model, NameRef, Protocol, Register, Repeat, RepeatCopy, Reserved, Rtu, Scalar, ScaleSpec,
    Table, Tcp, WordCount,
};
use crate::rules::scale::parse_scale;
use crate::source::Path;
use std::collections::BTreeSet;

use foldhash::{HashMap, HashMapExt};

use crate::syntax::{CodeDecl, FieldDecl, OrderName, RegisterDecl, SpecFile, TypeName};

/// Lowers `spec`; problems that stop lowering an item are reported, the rest is left to rules.
pub(crate) fn lower(mut spec: SpecFile) -> (Model, Vec<Diagnostic>) {
    let mut lowering = Lowering {
        enums: Vec::new(),
        enum_index: [HashMap::new(), HashMap::new()],
        diagnostics: Vec::new(),
    };
    let root = Path::root();

    for (name, decl) in spec.enums.entries() {
        let path = root.key("enums").key(name.clone());
        let codes = lowering.codes(&decl.codes, &path.key("codes"));
        lowering.add_enum(EnumDef {
            name: name.clone(),
            doc: decl.doc.clone(),
            codes,
            shared: true,
            section: decl.section.clone(),
            path,
        });
    }

    // Taken, so that their text moves into the model rather than being copied.
    let decls = spec.registers.take();
    let mut registers = Vec::with_capacity(decls.len());
    for (i, decl) in decls {
        let path = root.key("registers").index(i);
        registers.push(lowering.register(decl, path));
    }

    let mut repeats = Vec::new();
    let mut unread: BTreeSet<String> = [
        &spec.enums.unread,
        &spec.registers.unread,
        &spec.commands.unread,
        &spec.groups.unread,
        &spec.repeats.unread,
    ]
    .into_iter()
    .flatten()
    .cloned()
    .collect();
    for (r, (index, block)) in spec.repeats.iter_mut().enumerate() {
        let block_path = root.key("repeats").index(index);
        // Copies are numbered by a byte; a larger count is not expanded (nor its copies checked).
        let copies = if block.count > u32::from(u8::MAX) {
            lowering.diagnostics.push(
                Diagnostic::at(
                    "repeat-stride",
                    &block_path.key("count"),
                    format!(
                        "repeat `{}` has {} copies; copies are numbered 1 to 255",
                        block.name, block.count
                    ),
                )
                .label("count too large"),
            );
            // References to its copies are not reported again.
            unread.insert(block.name.clone());
            0
        } else {
            block.count
        };
        unread.extend(block.registers.unread.iter().cloned());
        for number in 1..=copies {
            unread.extend(
                block
                    .registers
                    .unread
                    .iter()
                    .map(|name| format!("{}_{number}_{name}", block.name)),
            );
        }
        let members = block
            .registers
            .iter()
            .map(|(_, d)| d.name.clone())
            .collect();
        for (i, decl) in block.registers.take() {
            let path = block_path.key("registers").index(i);
            let stride = decl.stride.or(match decl.table {
                Table::Holding => block.stride.holding,
                Table::Input => block.stride.input,
            });
            if stride.is_none() {
                lowering.diagnostics.push(
                    Diagnostic::at(
                        "repeat-stride",
                        &path.key("table"),
                        format!(
                            "repeat `{}` has no stride for {} registers",
                            block.name,
                            decl.table.as_str()
                        ),
                    )
                    .label("no stride for this table")
                    .help("add it to the block's `stride:` or give this register a `stride:`"),
                );
            }
            // One enum for all copies of an inline-coded register.
            let (base, address) = (decl.name.clone(), decl.address);
            let template = lowering.register(decl, path);
            for number in 1..=copies {
                let mut copy = template.clone();
                copy.name = format!("{}_{}_{}", block.name, number, base);
                let offset = stride.unwrap_or(0).saturating_mul(number - 1);
                copy.address = Address(address.saturating_add(offset));
                copy.repeat = Some(RepeatCopy {
                    repeat: r,
                    number,
                    base: base.clone(),
                    stride,
                });
                registers.push(copy);
            }
        }
        repeats.push(Repeat {
            name: block.name.clone(),
            count: block.count,
            holding_stride: block.stride.holding,
            input_stride: block.stride.input,
            doc: block.doc.clone(),
            members,
            path: block_path,
        });
    }

    let reserved = spec
        .reserved
        .iter()
        .map(|(i, decl)| Reserved {
            table: decl.table,
            from: decl.from,
            to: decl.to,
            readable: decl.readable,
            path: root.key("reserved").index(i),
        })
        .collect();

    let commands = spec
        .commands
        .iter()
        .map(|(i, decl)| Command {
            name: decl.name.clone(),
            register: decl.register.clone(),
            value: decl.value,
            busy_ms: decl.busy_ms,
            done_when: decl.done_when,
            within_ms: decl.within_ms,
            effect: decl.effect.unwrap_or(Effect::None),
            targets: decl.targets.clone(),
            doc: decl.doc.clone(),
            section: decl.section.clone(),
            path: root.key("commands").index(i),
        })
        .collect();

    let groups = spec
        .groups
        .iter()
        .map(|(i, decl)| {
            let path = root.key("groups").index(i);
            Group {
                name: decl.name.clone(),
                registers: decl
                    .registers
                    .iter()
                    .enumerate()
                    .map(|(j, name)| (name.clone(), path.key("registers").index(j)))
                    .collect(),
                doc: decl.doc.clone(),
                path,
            }
        })
        .collect();

    let buffer = spec.buffer.as_ref().map(|decl| {
        let path = root.key("buffer");
        let name = |key: &'static str, name: &String| NameRef {
            name: name.clone(),
            path: path.key(key),
        };
        Buffer {
            section: decl.section.clone(),
            doc: decl.doc.clone(),
            source: decl.source.as_ref().map(|n| name("source", n)),
            count: name("count", &decl.count),
            most: (decl.most, path.key("most")),
            lock: name("lock", &decl.lock),
            unlock: name("unlock", &decl.unlock),
            page: name("page", &decl.page),
            read_count: name("read_count", &decl.read_count),
            valid_count: name("valid_count", &decl.valid_count),
            values: name("values", &decl.values),
            interval: decl.interval.as_ref().map(|n| name("interval", n)),
            ratio: decl.ratio.as_ref().map(|n| name("ratio", n)),
            path: path.clone(),
        }
    });

    let device = lowering.device(&spec);
    let protocol = Protocol {
        addressing: spec.protocol.addressing,
        long_writes: spec.protocol.long_writes,
        exception: spec.protocol.exception,
        apply: spec.protocol.apply,
        exception_codes: spec.protocol.exception_codes.as_ref().map(|name| EnumRef {
            name: name.clone(),
            index: lowering.find_enum(true, name),
            path: root.key("protocol").key("exception_codes"),
        }),
        continuous_send: spec.protocol.continuous_send.as_ref().map(|c| {
            (
                c.register.clone(),
                c.code,
                root.key("protocol").key("continuous_send").key("register"),
            )
        }),
    };

    let model = Model {
        family: spec.family,
        title: spec.title,
        aliases: spec.aliases,
        manual: Manual {
            file: spec.manual.file,
            version: spec.manual.version,
            date: spec.manual.date,
        },
        device,
        protocol,
        enums: lowering.enums,
        registers,
        reserved,
        commands,
        groups,
        repeats,
        buffer,
        unread,
    };
    (model, lowering.diagnostics)
}

struct Lowering {
    enums: Vec<EnumDef>,
    /// Where each enum of `enums` is by name, inline ones (`[0]`) apart from shared ones
    /// (`[1]`): the first of a name.
    enum_index: [HashMap<String, usize>; 2],
    diagnostics: Vec<Diagnostic>,
}

fn scalar_of(kind: TypeName) -> Option<Scalar> {
    match kind {
        TypeName::U16 => Some(Scalar::U16),
        TypeName::I16 => Some(Scalar::I16),
        TypeName::U32 => Some(Scalar::U32),
        TypeName::I32 => Some(Scalar::I32),
        _ => None,
    }
}

impl Lowering {
    /// Appends `def` and returns its index.
    fn add_enum(&mut self, def: EnumDef) -> usize {
        let index = self.enums.len();
        self.enum_index[usize::from(def.shared)]
            .entry(def.name.clone())
            .or_insert(index);
        self.enums.push(def);
        index
    }

    /// The index of the first shared (or inline) enum called `name`.
    fn find_enum(&self, shared: bool, name: &str) -> Option<usize> {
        self.enum_index[usize::from(shared)].get(name).copied()
    }

    fn codes(&self, decls: &[CodeDecl], path: &Path) -> Vec<Code> {
        decls
            .iter()
            .enumerate()
            .map(|(i, decl)| Code {
                code: decl.code,
                name: decl.name.clone(),
                meaning: decl.meaning.clone(),
                doc: decl.doc.clone(),
                path: path.index(i),
            })
            .collect()
    }

    /// Resolves `enum: name` or hoists `codes:` into an enum called `inline_name`.
    fn enum_ref(
        &mut self,
        enum_name: Option<&String>,
        codes: Option<&Vec<CodeDecl>>,
        inline_name: &str,
        doc: Option<&String>,
        path: &Path,
    ) -> Option<EnumRef> {
        if let Some(codes) = codes {
            let codes = self.codes(codes, &path.key("codes"));
            let index = match self.find_enum(false, inline_name) {
                Some(existing) => existing,
                None => self.add_enum(EnumDef {
                    name: inline_name.to_owned(),
                    doc: doc.cloned(),
                    codes,
                    shared: false,
                    section: None,
                    path: path.key("codes"),
                }),
            };
            return Some(EnumRef {
                name: inline_name.to_owned(),
                index: Some(index),
                path: path.key("codes"),
            });
        }
        enum_name.map(|name| EnumRef {
            name: name.clone(),
            index: self.find_enum(true, name),
            path: path.key("enum"),
        })
    }

    fn scale(&self, text: Option<&String>, path: &Path) -> Option<ScaleSpec> {
        let text = text?.clone();
        Some(ScaleSpec {
            value: parse_scale(&text),
            text,
            path: path.key("scale"),
        })
    }

    fn field(&mut self, decl: &FieldDecl, owner: &str, path: &Path) -> Field {
        let enum_ref = self.enum_ref(
            decl.enum_name.as_ref(),
            decl.codes.as_ref(),
            &format!("{owner}_{}", decl.name),
            decl.doc.as_ref(),
            path,
        );
        Field {
            name: decl.name.clone(),
            lsb: decl.lsb,
            width: decl.width,
            scalar: decl.kind.and_then(scalar_of),
            enum_ref,
            range: decl.range,
            scale: self.scale(decl.scale.as_ref(), path),
            unit: decl.unit.clone(),
            sentinel: decl.sentinel,
            doc: decl.doc.clone(),
            path: path.clone(),
        }
    }

    fn fields(&mut self, decl: &RegisterDecl, path: &Path) -> Vec<Field> {
        decl.fields
            .iter()
            .flatten()
            .enumerate()
            .map(|(i, field)| self.field(field, &decl.name, &path.key("fields").index(i)))
            .collect()
    }

    /// Lowers `decl`, declared at `at`: its text moves into the register.
    fn register(&mut self, mut decl: RegisterDecl, at: Path) -> Register {
        let (name, path) = (decl.name.as_str(), &at);
        let kind = match decl.kind {
            TypeName::Bool => Kind::Bool,
            TypeName::U16 | TypeName::I16 | TypeName::U32 | TypeName::I32 => {
                Kind::Scalar(scalar_of(decl.kind).unwrap_or(Scalar::U16))
            }
            TypeName::Enum => {
                match self.enum_ref(
                    decl.enum_name.as_ref(),
                    decl.codes.as_ref(),
                    name,
                    decl.doc.as_ref(),
                    path,
                ) {
                    Some(reference) => Kind::Enum(reference),
                    None => {
                        self.diagnostics.push(
                            Diagnostic::at(
                                "enum-reference",
                                &path.key("type"),
                                format!("enum register `{name}` names no codes"),
                            )
                            .label("declared `enum` here")
                            .help("add `enum: <shared enum>` or inline `codes:`"),
                        );
                        Kind::Scalar(Scalar::U16)
                    }
                }
            }
            TypeName::Packed => Kind::Packed(self.fields(&decl, path)),
            TypeName::Record => Kind::Record(self.fields(&decl, path)),
            TypeName::Ipv4 => Kind::Ipv4,
            TypeName::Version => Kind::Version(decl.parts.take().unwrap_or_default()),
        };
        let default_words = match &kind {
            Kind::Bool | Kind::Enum(_) | Kind::Packed(_) => 1,
            Kind::Scalar(scalar) => scalar.words(),
            Kind::Ipv4 => 4,
            Kind::Version(_) => 2,
            Kind::Record(fields) => fields
                .iter()
                .map(|f| f.scalar.map_or(1, Scalar::words))
                .sum(),
        };
        let scale = self.scale(decl.scale.as_ref(), path);
        let allowed_values =
            (decl.allowed_values.take()).map(|values| (values, path.key("allowed_values")));
        Register {
            name: decl.name,
            table: decl.table,
            address: Address(decl.address),
            access: decl.access,
            words: WordCount(decl.words.unwrap_or(default_words)),
            declared_words: decl.words,
            kind,
            doc: decl.doc,
            zh: decl.zh,
            section: decl.section,
            note: decl.note,
            scale,
            unit: decl.unit,
            range: decl.range,
            allowed_values,
            sentinel: decl.sentinel,
            word_order: match decl.word_order {
                Some(OrderName::LowFirst) => WordOrder::LowFirst,
                _ => WordOrder::HighFirst,
            },
            write_order: decl.write_order.map(|order| match order {
                OrderName::HighFirst => WriteOrder::HighWordFirst,
                OrderName::LowFirst => WriteOrder::LowWordFirst,
            }),
            alias_of: decl.alias_of,
            read_side_effect: decl.read_side_effect,
            action: decl.action,
            role: decl.role,
            repeat: None,
            path: at,
        }
    }

    fn device(&mut self, spec: &SpecFile) -> Device {
        let decl = &spec.device;
        let tcp = decl.transports.tcp.as_ref().map(|tcp| {
            let default_ip = tcp.default_ip.as_ref().and_then(|ip| match ip.parse() {
                Ok(ip) => Some(ip),
                Err(_) => {
                    self.diagnostics.push(
                        Diagnostic::at(
                            "device",
                            &Path::root()
                                .key("device")
                                .key("transports")
                                .key("tcp")
                                .key("default_ip"),
                            format!("`{ip}` is not an IPv4 address"),
                        )
                        .label("expected four octets such as 192.168.0.10"),
                    );
                    None
                }
            });
            Tcp {
                port: tcp.port,
                default_ip,
            }
        });
        Device {
            rtu: decl.transports.rtu.as_ref().map(|rtu| Rtu {
                default_baud: rtu.default_baud,
                bauds: rtu.bauds.clone(),
                parity: rtu.parity,
                data_bits: rtu.data_bits,
                stop_bits: rtu.stop_bits,
            }),
            tcp,
            default_slave: decl.slave.default,
            min_slave: decl.slave.min,
            max_slave: decl.slave.max,
            functions: decl.functions.clone(),
            max_read_words: decl.max_read_words,
            power_up_ms: decl.power_up_ms,
            holding_size: decl.tables.holding,
            input_size: decl.tables.input,
        }
    }
}
