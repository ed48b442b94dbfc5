//! The device as data: a named constant per register (`registers::DISTANCE_1`), command and
//! group, and the static `DEVICE: optobus_device::DeviceInfo` table listing them.
//!
//! Generated methods and generic tools reach a register by its name, never by its position
//! in the table, so inserting a register into a spec changes only the lines that describe it.
//!
//! The values are not computed here: [`optobus_spec::description`] computes them (the same
//! call a tool makes at run time), and this file only prints each description type as Rust,
//! one small printer per type. So the compiled `DEVICE` and the run-time description agree
//! by construction. What the description does not hold (the constants' names, docs and
//! aliases, the address text, the repeat modules) comes from the model.

use std::collections::BTreeMap;

use optobus_device::{
    BufferInfo, CodeInfo, CommandInfo, DeviceInfo, FieldInfo, GroupInfo, RegisterInfo, RepeatCopy,
    ReservedInfo, RtuInfo, Scale, TcpInfo, ValueKind,
};
use proc_macro2::{Ident, Literal, TokenStream};
use quote::quote;

use super::names::{Imports, TypeNames};
use super::{const_ident, doc_alias, hex, ident, lit};
use optobus_spec::model::{Model, Register};

/// `registers::DISTANCE_1` for a register, from outside the `registers` module.
pub(super) fn register_path(name: &str) -> TokenStream {
    let name = const_ident(name);
    quote!(registers::#name)
}

/// `registers::channel::EXPOSURE_TIME`: every copy of a repeat member, in order.
pub(super) fn copies_path(repeat: &str, member: &str) -> TokenStream {
    let (repeat, member) = (ident(repeat), const_ident(member));
    quote!(registers::#repeat::#member)
}

/// `commands::ZERO_POSITION_1`.
pub(super) fn command_path(name: &str) -> TokenStream {
    let name = const_ident(name);
    quote!(commands::#name)
}

/// `groups::MEASUREMENTS`.
pub(super) fn group_path(name: &str) -> TokenStream {
    let name = const_ident(name);
    quote!(groups::#name)
}

/// `holding 0x0010 (16)` or `holding 0x0010–0x0011 (16–17)`: hex and decimal, so neither
/// reads as the other; 0-based, as on the wire.
pub(super) fn address_text(model: &Model, register: &Register) -> String {
    let first = register.address.0;
    let last = first + model.extent(register).saturating_sub(1);
    let table = register.table.as_str();
    if last == first {
        format!("{table} {first:#06X} ({first})")
    } else {
        format!("{table} {first:#06X}–{last:#06X} ({first}–{last})")
    }
}

/// The `registers`, `commands` and `groups` modules and the `DEVICE` table.
pub(super) fn device(model: &Model, names: &TypeNames, imports: &Imports) -> TokenStream {
    let description = optobus_spec::description(model);
    let printer = Printer {
        names,
        imports,
        enum_codes: &description.enum_codes,
    };
    let device = description.device;
    let registers = registers_module(model, device, &printer);
    let commands = commands_module(device, &printer);
    let groups = groups_module(device, &printer);
    let table = printer.device(device);
    // A number the checker should have refused stops the build, rather than compile clamped.
    let unfit = &description.unfit;
    quote! {
        #(compile_error!(#unfit);)*
        #registers
        #commands
        #groups
        #table
    }
}

fn registers_module(model: &Model, device: &DeviceInfo, printer: &Printer) -> TokenStream {
    let register_info = printer.imports.get("optobus_device::RegisterInfo");
    // The description lists the model's registers in the model's order.
    let constants = model
        .registers
        .iter()
        .zip(device.registers)
        .map(|(register, info)| {
            let ident = const_ident(info.name);
            let doc = format!(
                "`{}` ({}): {}",
                info.name,
                address_text(model, register),
                info.doc
            );
            let alias = doc_alias(Some(info.zh));
            let info = printer.register(info);
            quote! {
                #[doc = #doc]
                #alias
                pub const #ident: #register_info = #info;
            }
        });
    // Per repeat block, the copies of each member in order, to index with the block's type.
    let mut blocks: BTreeMap<usize, Vec<(&str, Vec<&Register>)>> = BTreeMap::new();
    for register in &model.registers {
        let Some(copy) = &register.repeat else {
            continue;
        };
        let members = blocks.entry(copy.repeat).or_default();
        match members.iter_mut().find(|(base, _)| *base == copy.base) {
            Some((_, copies)) => copies.push(register),
            None => members.push((copy.base.as_str(), vec![register])),
        }
    }
    let blocks = blocks.into_iter().map(|(repeat, members)| {
        let repeat = &model.repeats[repeat];
        let module = ident(&repeat.name);
        let module_doc = format!(
            "The copies of each `{}` member, in order: index with [`{}::index`].",
            repeat.name,
            super::camel(&repeat.name),
        );
        let arrays = members.into_iter().map(|(member, mut copies)| {
            copies.sort_by_key(|r| r.repeat.as_ref().map_or(0, |c| c.number));
            let ident = const_ident(member);
            let count = Literal::usize_unsuffixed(copies.len());
            let doc = format!("`{member}` of each {}.", repeat.name);
            let copies = copies.iter().map(|r| const_ident(&r.name));
            quote! {
                #[doc = #doc]
                pub const #ident: [&#register_info; #count] = [#(&#copies),*];
            }
        });
        quote! {
            #[doc = #module_doc]
            pub mod #module {
                use super::*;

                #(#arrays)*
            }
        }
    });
    let doc = format!(
        "Every register of `specs/{}.yaml`, by name: what the driver's methods read and write.",
        device.family
    );
    quote! {
        #[doc = #doc]
        pub mod registers {
            use super::*;

            #(#constants)*
            #(#blocks)*
        }
    }
}

fn commands_module(device: &DeviceInfo, printer: &Printer) -> TokenStream {
    let constants = device.commands.iter().map(|command| {
        let ident = const_ident(command.name);
        let doc = format!("`{}`: {}", command.name, command.doc);
        let info = printer.command(command);
        let command_info = printer.imports.get("optobus_device::CommandInfo");
        quote! {
            #[doc = #doc]
            pub const #ident: #command_info = #info;
        }
    });
    let doc = format!("Every command of `specs/{}.yaml`, by name.", device.family);
    // An empty module imports nothing: a spec may declare no command.
    let parent = (!device.commands.is_empty()).then(|| {
        quote!(
            use super::*;
        )
    });
    quote! {
        #[doc = #doc]
        pub mod commands {
            #parent

            #(#constants)*
        }
    }
}

fn groups_module(device: &DeviceInfo, printer: &Printer) -> TokenStream {
    let constants = device.groups.iter().map(|group| {
        let ident = const_ident(group.name);
        let doc = format!("`{}`: {}", group.name, group.doc);
        let info = printer.group(group);
        let group_info = printer.imports.get("optobus_device::GroupInfo");
        quote! {
            #[doc = #doc]
            pub const #ident: #group_info = #info;
        }
    });
    let doc = format!(
        "Every register group of `specs/{}.yaml`, by name.",
        device.family
    );
    let parent = (!device.groups.is_empty()).then(|| {
        quote!(
            use super::*;
        )
    });
    quote! {
        #[doc = #doc]
        pub mod groups {
            #parent

            #(#constants)*
        }
    }
}

/// Prints description values as the Rust expressions that build them: runtime types by the
/// names [`Imports`] gives, a shared code list by its enum's `CODES`.
struct Printer<'a> {
    names: &'a TypeNames,
    imports: &'a Imports,
    /// The code list of each enum, in `TypeNames::enums` order.
    enum_codes: &'a [&'static [CodeInfo]],
}

impl Printer<'_> {
    /// `Type::Variant` (or its full path) for a value of an `optobus_device` enum: the
    /// variant is its derived `Debug` name.
    fn variant(&self, ty: &'static str, value: impl std::fmt::Debug) -> TokenStream {
        let ty = self.imports.get(ty);
        let variant = Ident::new(&format!("{value:?}"), proc_macro2::Span::call_site());
        quote!(#ty::#variant)
    }

    /// `Enum::CODES` for an enum's code list, `&[]` for none.
    fn codes(&self, codes: &[CodeInfo]) -> TokenStream {
        // A checked enum has at least one code, so an empty list is no enum's.
        let owner = (!codes.is_empty())
            .then(|| self.enum_codes.iter().position(|c| std::ptr::eq(*c, codes)))
            .flatten();
        match owner.map(|index| &self.names.enums[index]) {
            Some(ty) => quote!(#ty::CODES),
            None => quote!(&[]),
        }
    }

    fn scale(&self, scale: Option<Scale>) -> TokenStream {
        let Some(scale) = scale else {
            return quote!(None);
        };
        let ty = self.imports.get("optobus_device::Scale");
        match scale {
            Scale::Decimal { exponent } => {
                let exponent = lit(exponent);
                quote!(Some(#ty::Decimal { exponent: #exponent }))
            }
            Scale::Ratio {
                numerator,
                denominator,
            } => {
                let (numerator, denominator) = (lit(numerator), lit(denominator.get()));
                quote!(#ty::ratio(#numerator, #denominator))
            }
        }
    }

    fn field(&self, field: &FieldInfo) -> TokenStream {
        let field_info = self.imports.get("optobus_device::FieldInfo");
        let name = field.name;
        let doc = field.doc;
        let (lsb, width) = (lit(field.lsb), lit(field.width));
        let scalar = self.variant("optobus_device::Scalar", field.scalar);
        let codes = self.codes(field.codes);
        let range = range(field.range);
        let scale = self.scale(field.scale);
        let unit = option_str(field.unit);
        let sentinel = sentinel(field.sentinel);
        quote! {
            #field_info {
                name: #name,
                doc: #doc,
                lsb: #lsb,
                width: #width,
                scalar: #scalar,
                codes: #codes,
                range: #range,
                scale: #scale,
                unit: #unit,
                sentinel: #sentinel,
            }
        }
    }

    fn fields(&self, fields: &[FieldInfo]) -> TokenStream {
        let fields = fields.iter().map(|field| self.field(field));
        quote!(&[#(#fields),*])
    }

    fn kind(&self, kind: &ValueKind) -> TokenStream {
        let ty = self.imports.get("optobus_device::ValueKind");
        match kind {
            ValueKind::Bool => quote!(#ty::Bool),
            ValueKind::Scalar(scalar) => {
                let scalar = self.variant("optobus_device::Scalar", scalar);
                quote!(#ty::Scalar(#scalar))
            }
            ValueKind::Enum => quote!(#ty::Enum),
            ValueKind::Packed(fields) => {
                let fields = self.fields(fields);
                quote!(#ty::Packed(#fields))
            }
            ValueKind::Record(fields) => {
                let fields = self.fields(fields);
                quote!(#ty::Record(#fields))
            }
            ValueKind::Ipv4 => quote!(#ty::Ipv4),
            ValueKind::Version(parts) => {
                let parts = parts.iter();
                quote!(#ty::Version(&[#(#parts),*]))
            }
        }
    }

    fn copy(&self, copy: Option<&RepeatCopy>) -> TokenStream {
        let Some(copy) = copy else {
            return quote!(None);
        };
        let ty = self.imports.get("optobus_device::RepeatCopy");
        let (repeat, member) = (copy.repeat, copy.member);
        let number = lit(copy.number);
        quote!(Some(#ty { repeat: #repeat, number: #number, member: #member }))
    }

    fn register(&self, register: &RegisterInfo) -> TokenStream {
        let (name, doc, zh, section) = (register.name, register.doc, register.zh, register.section);
        let table = self.variant("optobus_device::Table", register.table);
        let (address, words) = (lit(register.address), lit(register.words));
        let access = self.variant("optobus_device::Access", register.access);
        let kind = self.kind(&register.kind);
        let codes = self.codes(register.codes);
        let scale = self.scale(register.scale);
        let unit = option_str(register.unit);
        let range = range(register.range);
        let allowed_values = register.allowed_values.iter().map(|v| lit(*v));
        let sentinel = sentinel(register.sentinel);
        let word_order = self.variant("optobus_device::WordOrder", register.word_order);
        let write_order = self.variant("optobus_device::WriteOrder", register.write_order);
        let copy = self.copy(register.copy.as_ref());
        let read_side_effect = option_str(register.read_side_effect);
        let action = register.action;
        let role = match register.role {
            Some(role) => {
                let role = self.variant("optobus_device::Role", role);
                quote!(Some(#role))
            }
            None => quote!(None),
        };
        let register_info = self.imports.get("optobus_device::RegisterInfo");
        quote! {
            #register_info {
                name: #name,
                doc: #doc,
                zh: #zh,
                section: #section,
                table: #table,
                address: #address,
                words: #words,
                access: #access,
                kind: #kind,
                codes: #codes,
                scale: #scale,
                unit: #unit,
                range: #range,
                allowed_values: &[#(#allowed_values),*],
                sentinel: #sentinel,
                word_order: #word_order,
                write_order: #write_order,
                copy: #copy,
                read_side_effect: #read_side_effect,
                action: #action,
                role: #role,
            }
        }
    }

    fn command(&self, command: &CommandInfo) -> TokenStream {
        let command_info = self.imports.get("optobus_device::CommandInfo");
        let (name, doc, register) = (command.name, command.doc, command.register);
        let (value, busy_ms) = (lit(command.value), lit(command.busy_ms));
        let effect = self.variant("optobus_device::Effect", command.effect);
        let targets = command.targets;
        let done_when = match command.done_when {
            Some(completion) => {
                let ty = self.imports.get("optobus_device::Completion");
                let value = lit(completion.value);
                let within_ms = lit(completion.within_ms);
                quote!(Some(#ty { value: #value, within_ms: #within_ms }))
            }
            None => quote!(None),
        };
        quote! {
            #command_info {
                name: #name,
                doc: #doc,
                register: #register,
                value: #value,
                busy_ms: #busy_ms,
                effect: #effect,
                targets: &[#(#targets),*],
                done_when: #done_when,
            }
        }
    }

    fn group(&self, group: &GroupInfo) -> TokenStream {
        let group_info = self.imports.get("optobus_device::GroupInfo");
        let (name, doc, members) = (group.name, group.doc, group.registers);
        quote! {
            #group_info {
                name: #name,
                doc: #doc,
                registers: &[#(#members),*],
            }
        }
    }

    fn rtu(&self, rtu: Option<&RtuInfo>) -> TokenStream {
        let Some(rtu) = rtu else {
            return quote!(None);
        };
        let ty = self.imports.get("optobus_device::RtuInfo");
        let default_baud = lit(rtu.default_baud);
        let bauds = rtu.bauds.iter().map(|b| lit(*b));
        let parity = self.variant("optobus_device::Parity", rtu.parity);
        let (data_bits, stop_bits) = (lit(rtu.data_bits), lit(rtu.stop_bits));
        quote!(Some(#ty {
            default_baud: #default_baud,
            bauds: &[#(#bauds),*],
            parity: #parity,
            data_bits: #data_bits,
            stop_bits: #stop_bits,
        }))
    }

    fn tcp(&self, tcp: Option<&TcpInfo>) -> TokenStream {
        let Some(tcp) = tcp else {
            return quote!(None);
        };
        let ty = self.imports.get("optobus_device::TcpInfo");
        let port = lit(tcp.port);
        let ip = match tcp.default_ip {
            Some(octets) => {
                let octets = octets.map(lit);
                quote!(Some([#(#octets),*]))
            }
            None => quote!(None),
        };
        quote!(Some(#ty { port: #port, default_ip: #ip }))
    }

    fn reserved(&self, reserved: &ReservedInfo) -> TokenStream {
        // Imported only where used: a spec may declare no reserved range.
        let reserved_info = self.imports.get("optobus_device::ReservedInfo");
        let table = self.variant("optobus_device::Table", reserved.table);
        let (from, to) = (lit(reserved.from), lit(reserved.to));
        let readable = reserved.readable;
        quote!(#reserved_info { table: #table, from: #from, to: #to, readable: #readable })
    }

    /// `Some(&BufferInfo { … })` for a device with a data buffer, else `None`.
    fn buffer(&self, buffer: Option<&BufferInfo>) -> TokenStream {
        let Some(buffer) = buffer else {
            return quote!(None);
        };
        let ty = self.imports.get("optobus_device::BufferInfo");
        let BufferInfo {
            section,
            doc,
            count,
            lock,
            unlock,
            page,
            read_count,
            valid_count,
            values,
            ..
        } = *buffer;
        let most = lit(buffer.most);
        let source = option_str(buffer.source);
        let interval = option_str(buffer.interval);
        let ratio = option_str(buffer.ratio);
        quote!(Some(&#ty {
            section: #section,
            doc: #doc,
            source: #source,
            count: #count,
            most: #most,
            lock: #lock,
            unlock: #unlock,
            page: #page,
            read_count: #read_count,
            valid_count: #valid_count,
            values: #values,
            interval: #interval,
            ratio: #ratio,
        }))
    }

    /// The `DEVICE` static, its registers, commands and groups named by their constants.
    fn device(&self, device: &DeviceInfo) -> TokenStream {
        let (family, title, manual) = (device.family, device.title, device.manual);
        let aliases = device.aliases;
        let rtu = self.rtu(device.rtu.as_ref());
        let tcp = self.tcp(device.tcp.as_ref());
        let default_slave = lit(device.default_slave);
        let (min_slave, max_slave) = (lit(device.slaves.0), lit(device.slaves.1));
        let functions = device.functions.iter().map(|f| lit(*f));
        let max_read_words = lit(device.max_read_words);
        let power_up_ms = lit(device.power_up_ms);
        let holding = lit(device.holding_registers);
        let input = lit(device.input_registers);
        let addressing = self.variant("optobus_device::Addressing", device.addressing);
        let long_writes = self.variant("optobus_device::LongWrites", device.long_writes);
        let frame_shape = self.imports.get("optobus_device::FrameShape");
        let exception = self.variant(
            "optobus_device::ExceptionShape",
            device.frame_shape.exception,
        );
        let wide = device.frame_shape.four_byte_writes.iter().map(|a| lit(*a));
        let needs_save = device.needs_save_and_power_cycle;
        let exception_codes = self.codes(device.exception_codes);
        let continuous = match device.continuous_send {
            Some((register, code)) => {
                let code = lit(code);
                quote!(Some((#register, #code)))
            }
            None => quote!(None),
        };
        let registers = device.registers.iter().map(|r| register_path(r.name));
        let reserved = device.reserved.iter().map(|r| self.reserved(r));
        let commands = device.commands.iter().map(|c| command_path(c.name));
        let groups = device.groups.iter().map(|g| group_path(g.name));
        let buffer = self.buffer(device.buffer);
        let doc =
            format!("Everything `specs/{family}.yaml` says about the {title}, for generic tools.");
        let device_info = self.imports.get("optobus_device::DeviceInfo");
        quote! {
            #[doc = #doc]
            pub static DEVICE: #device_info = #device_info {
                family: #family,
                title: #title,
                aliases: &[#(#aliases),*],
                manual: #manual,
                rtu: #rtu,
                tcp: #tcp,
                default_slave: #default_slave,
                slaves: (#min_slave, #max_slave),
                functions: &[#(#functions),*],
                max_read_words: #max_read_words,
                power_up_ms: #power_up_ms,
                holding_registers: #holding,
                input_registers: #input,
                addressing: #addressing,
                long_writes: #long_writes,
                frame_shape: #frame_shape {
                    exception: #exception,
                    four_byte_writes: &[#(#wide),*],
                },
                needs_save_and_power_cycle: #needs_save,
                exception_codes: #exception_codes,
                continuous_send: #continuous,
                registers: &[#(#registers),*],
                reserved: &[#(#reserved),*],
                commands: &[#(#commands),*],
                groups: &[#(#groups),*],
                buffer: #buffer,
            };
        }
    }
}

fn option_str(text: Option<&str>) -> TokenStream {
    match text {
        Some(text) => quote!(Some(#text)),
        None => quote!(None),
    }
}

fn range(range: Option<(i64, i64)>) -> TokenStream {
    match range {
        Some((min, max)) => {
            let (min, max) = (lit(min), lit(max));
            quote!(Some((#min, #max)))
        }
        None => quote!(None),
    }
}

/// A sentinel in hexadecimal: an all-ones pattern reads as one.
fn sentinel(sentinel: Option<u32>) -> TokenStream {
    match sentinel {
        Some(sentinel) => {
            let sentinel = hex(sentinel);
            quote!(Some(#sentinel))
        }
        None => quote!(None),
    }
}
