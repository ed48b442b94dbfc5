//! The device as data: a named constant per register (`registers::DISTANCE_1`), command and
//! group, and the static `DEVICE: optobus_device::DeviceInfo` table listing them.
//!
//! Generated methods and generic tools reach a register by its name, never by its position
//! in the table, so inserting a register into a spec changes only the lines that describe it.

use std::collections::BTreeMap;

use optobus_codec::value::Scale;
use proc_macro2::{Ident, Literal, TokenStream};
use quote::quote;

use super::names::{Imports, TypeNames};
use super::{const_ident, doc_alias, doc_text, exact, hex, ident, lit};
use optobus_spec::model::{
    Apply, ExceptionStyle, Field, Kind, LongWrites, Model, Register, Scalar, ScaleSpec, Table,
};

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
    let registers = registers_module(model, names, imports);
    let commands = commands_module(model, imports);
    let groups = groups_module(model, imports);
    let table = device_info(model, names, imports);
    quote! {
        #registers
        #commands
        #groups
        #table
    }
}

fn registers_module(model: &Model, names: &TypeNames, imports: &Imports) -> TokenStream {
    let constants = model.registers.iter().map(|register| {
        let ident = const_ident(&register.name);
        let doc = format!(
            "`{}` ({}): {}",
            register.name,
            address_text(model, register),
            doc_text(register.doc.as_deref())
        );
        let alias = doc_alias(register.zh.as_deref());
        let info = register_info(model, register, names, imports);
        let register_info = imports.get("optobus_device::RegisterInfo");
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
        let register_info = imports.get("optobus_device::RegisterInfo");
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
        model.family
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

fn commands_module(model: &Model, imports: &Imports) -> TokenStream {
    let constants = model.commands.iter().map(|c| {
        let command_info = imports.get("optobus_device::CommandInfo");
        let ident = const_ident(&c.name);
        let name = &c.name;
        let doc = doc_text(c.doc.as_deref());
        let const_doc = format!("`{name}`: {doc}");
        let register = &c.register;
        let value = exact::<u32, _>(c.value, "command value");
        let busy_ms = lit(c.busy_ms.unwrap_or(0));
        let effect = variant(imports, "optobus_device::Effect", c.effect);
        let targets = &c.targets;
        let done_when = match c.completion() {
            Some(completion) => {
                let type_ = imports.get("optobus_device::Completion");
                let value = lit(completion.value);
                let within_ms = lit(completion.within_ms);
                quote!(Some(#type_ { value: #value, within_ms: #within_ms }))
            }
            None => quote!(None),
        };
        quote! {
            #[doc = #const_doc]
            pub const #ident: #command_info = #command_info {
                name: #name,
                doc: #doc,
                register: #register,
                value: #value,
                busy_ms: #busy_ms,
                effect: #effect,
                targets: &[#(#targets),*],
                done_when: #done_when,
            };
        }
    });
    let doc = format!("Every command of `specs/{}.yaml`, by name.", model.family);
    // An empty module imports nothing: a spec may declare no command.
    let parent = (!model.commands.is_empty()).then(|| {
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

fn groups_module(model: &Model, imports: &Imports) -> TokenStream {
    let constants = model.groups.iter().map(|g| {
        let group_info = imports.get("optobus_device::GroupInfo");
        let ident = const_ident(&g.name);
        let name = &g.name;
        let doc = doc_text(g.doc.as_deref());
        let const_doc = format!("`{name}`: {doc}");
        let members = g.registers.iter().map(|(n, _)| n);
        quote! {
            #[doc = #const_doc]
            pub const #ident: #group_info = #group_info {
                name: #name,
                doc: #doc,
                registers: &[#(#members),*],
            };
        }
    });
    let doc = format!(
        "Every register group of `specs/{}.yaml`, by name.",
        model.family
    );
    let parent = (!model.groups.is_empty()).then(|| {
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

/// `Type::Variant` (or its full path) for a value of an `optobus_device` enum the model
/// shares with the runtime: the variant is its derived `Debug` name.
fn variant(imports: &Imports, ty: &'static str, value: impl std::fmt::Debug) -> TokenStream {
    let ty = imports.get(ty);
    let variant = Ident::new(&format!("{value:?}"), proc_macro2::Span::call_site());
    quote!(#ty::#variant)
}

fn scale_tokens(scale: Option<&ScaleSpec>, imports: &Imports) -> TokenStream {
    let Some(scale) = scale.and_then(|s| s.value.as_ref().ok()) else {
        return quote!(None);
    };
    let ty = imports.get("optobus_device::Scale");
    match scale {
        Scale::Decimal { exponent } => {
            let exponent = lit(*exponent);
            quote!(Some(#ty::Decimal { exponent: #exponent }))
        }
        Scale::Ratio {
            numerator,
            denominator,
        } => {
            let (numerator, denominator) = (lit(*numerator), lit(denominator.get()));
            quote!(#ty::ratio(#numerator, #denominator))
        }
    }
}

fn option_str(text: Option<&str>) -> TokenStream {
    match text {
        Some(text) => quote!(Some(#text)),
        None => quote!(None),
    }
}

fn range_tokens(range: Option<(i64, i64)>) -> TokenStream {
    match range {
        Some((min, max)) => {
            let (min, max) = (lit(min), lit(max));
            quote!(Some((#min, #max)))
        }
        None => quote!(None),
    }
}

fn sentinel_tokens(sentinel: Option<u64>) -> TokenStream {
    match sentinel.map(u32::try_from) {
        Some(Ok(s)) => {
            let s = hex(s);
            quote!(Some(#s))
        }
        Some(Err(_)) => exact::<u32, _>(sentinel.unwrap_or_default(), "sentinel"),
        None => quote!(None),
    }
}

fn codes_tokens(reference: Option<usize>, names: &TypeNames) -> TokenStream {
    match reference {
        Some(index) => {
            let ty = &names.enums[index];
            quote!(#ty::CODES)
        }
        None => quote!(&[]),
    }
}

fn fields_tokens(fields: &[Field], names: &TypeNames, imports: &Imports) -> TokenStream {
    let fields = fields.iter().map(|field| {
        let field_info = imports.get("optobus_device::FieldInfo");
        let name = &field.name;
        let doc = doc_text(field.doc.as_deref());
        let scalar = field.scalar.unwrap_or(Scalar::unsigned(1));
        let lsb = lit(field.lsb.unwrap_or(0));
        let width = lit(field
            .width
            .unwrap_or(if scalar.words() == 2 { 32 } else { 16 }));
        let scalar = variant(imports, "optobus_device::Scalar", scalar);
        let codes = codes_tokens(field.enum_ref.as_ref().and_then(|r| r.index), names);
        let range = range_tokens(field.range);
        let scale = scale_tokens(field.scale.as_ref(), imports);
        let unit = option_str(field.unit.as_deref());
        let sentinel = sentinel_tokens(field.sentinel);
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
    });
    quote!(&[#(#fields),*])
}

fn register_info(
    model: &Model,
    register: &Register,
    names: &TypeNames,
    imports: &Imports,
) -> TokenStream {
    let name = &register.name;
    let doc = doc_text(register.doc.as_deref());
    let zh = register.zh.as_deref().unwrap_or("");
    let section = register.section.as_deref().unwrap_or("");
    let table = variant(imports, "optobus_device::Table", register.table);
    let address = exact::<u16, _>(register.address.0, "address");
    let words = exact::<u16, _>(register.words.0, "word count");
    let access = variant(imports, "optobus_device::Access", register.access);
    let value_kind = || imports.get("optobus_device::ValueKind");
    let mut codes = quote!(&[]);
    let kind = match &register.kind {
        Kind::Bool => {
            let ty = value_kind();
            quote!(#ty::Bool)
        }
        Kind::Scalar(scalar) => {
            let ty = value_kind();
            let scalar = variant(imports, "optobus_device::Scalar", *scalar);
            quote!(#ty::Scalar(#scalar))
        }
        Kind::Enum(reference) => {
            codes = codes_tokens(reference.index, names);
            let ty = value_kind();
            quote!(#ty::Enum)
        }
        Kind::Packed(fields) => {
            let ty = value_kind();
            let fields = fields_tokens(fields, names, imports);
            quote!(#ty::Packed(#fields))
        }
        Kind::Record(fields) => {
            let ty = value_kind();
            let fields = fields_tokens(fields, names, imports);
            quote!(#ty::Record(#fields))
        }
        Kind::Ipv4 => {
            let ty = value_kind();
            quote!(#ty::Ipv4)
        }
        Kind::Version(parts) => {
            let ty = value_kind();
            let parts = (0..4).map(|i| parts.get(i).map_or("ignore", String::as_str));
            quote!(#ty::Version(&[#(#parts),*]))
        }
    };
    let scale = scale_tokens(register.scale.as_ref(), imports);
    let unit = option_str(register.unit.as_deref());
    let range = range_tokens(register.range);
    let allowed_values = register
        .allowed_values
        .iter()
        .flat_map(|(values, _)| values.iter().map(|v| lit(*v)));
    let action = register.action;
    let sentinel = sentinel_tokens(register.sentinel);
    let word_order = variant(imports, "optobus_device::WordOrder", register.word_order);
    let write_order = variant(
        imports,
        "optobus_device::WriteOrder",
        register.write_order.unwrap_or_default(),
    );
    let read_side_effect = option_str(register.read_side_effect.as_deref());
    let role = match register.role {
        Some(role) => {
            let role = variant(imports, "optobus_device::Role", role);
            quote!(Some(#role))
        }
        None => quote!(None),
    };
    let copy = match &register.repeat {
        Some(copy) => {
            let ty = imports.get("optobus_device::RepeatCopy");
            let repeat = &model.repeats[copy.repeat].name;
            let number = exact::<u8, _>(copy.number, "copy number");
            let member = &copy.base;
            quote!(Some(#ty { repeat: #repeat, number: #number, member: #member }))
        }
        None => quote!(None),
    };
    let register_info = imports.get("optobus_device::RegisterInfo");
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

fn device_info(model: &Model, names: &TypeNames, imports: &Imports) -> TokenStream {
    let device = &model.device;
    let family = &model.family;
    let title = &model.title;
    let manual = &model.manual.file;
    let rtu = match &device.rtu {
        Some(rtu) => {
            let ty = imports.get("optobus_device::RtuInfo");
            let default_baud = lit(rtu.default_baud);
            let bauds = rtu.bauds.iter().map(|b| lit(*b));
            let parity = variant(imports, "optobus_device::Parity", rtu.parity);
            let (data_bits, stop_bits) = (lit(rtu.data_bits), lit(rtu.stop_bits));
            quote!(Some(#ty {
                default_baud: #default_baud,
                bauds: &[#(#bauds),*],
                parity: #parity,
                data_bits: #data_bits,
                stop_bits: #stop_bits,
            }))
        }
        None => quote!(None),
    };
    let tcp = match &device.tcp {
        Some(tcp) => {
            let ty = imports.get("optobus_device::TcpInfo");
            let port = lit(tcp.port);
            let ip = match tcp.default_ip {
                Some(ip) => {
                    let octets = ip.octets().map(lit);
                    quote!(Some([#(#octets),*]))
                }
                None => quote!(None),
            };
            quote!(Some(#ty { port: #port, default_ip: #ip }))
        }
        None => quote!(None),
    };
    let (default_slave, min_slave, max_slave) = (
        lit(device.default_slave),
        lit(device.min_slave),
        lit(device.max_slave),
    );
    let functions = device.functions.iter().map(|f| lit(*f));
    let max_read_words = lit(device.max_read_words);
    let power_up_ms = lit(device.power_up_ms.unwrap_or(0));
    let holding = exact::<u16, _>(device.holding_size, "holding table size");
    let input = exact::<u16, _>(device.input_size, "input table size");
    let addressing = variant(
        imports,
        "optobus_device::Addressing",
        model.protocol.addressing,
    );
    let long_writes = variant(
        imports,
        "optobus_device::LongWrites",
        model.protocol.long_writes,
    );
    let exception = variant(
        imports,
        "optobus_device::ExceptionShape",
        match model.protocol.exception {
            ExceptionStyle::Standard => optobus_codec::ExceptionShape::Standard,
            ExceptionStyle::CountedWord => optobus_codec::ExceptionShape::CountedWord,
        },
    );
    let frame_shape = imports.get("optobus_device::FrameShape");
    let wide: Vec<TokenStream> = if model.protocol.long_writes == LongWrites::Wide {
        model
            .registers
            .iter()
            .filter(|r| r.table == Table::Holding && r.access.writable() && r.words.0 == 2)
            .map(|r| exact::<u16, _>(r.address.0, "address"))
            .collect()
    } else {
        Vec::new()
    };
    let needs_save = model.protocol.apply == Apply::AfterSaveAndPowerCycle;
    let continuous = match &model.protocol.continuous_send {
        Some((register, code, _)) => {
            let code = exact::<u32, _>(*code, "continuous-send code");
            quote!(Some((#register, #code)))
        }
        None => quote!(None),
    };
    let exception_codes = codes_tokens(
        model
            .protocol
            .exception_codes
            .as_ref()
            .and_then(|r| r.index),
        names,
    );
    let aliases = &model.aliases;
    let registers = model.registers.iter().map(|r| register_path(&r.name));
    let reserved = model.reserved.iter().map(|r| {
        // Imported only where used: a spec may declare no reserved range.
        let reserved_info = imports.get("optobus_device::ReservedInfo");
        let table = variant(imports, "optobus_device::Table", r.table);
        let from = exact::<u16, _>(r.from, "reserved address");
        let to = exact::<u16, _>(r.to, "reserved address");
        let readable = r.readable;
        quote!(#reserved_info { table: #table, from: #from, to: #to, readable: #readable })
    });
    let commands = model.commands.iter().map(|c| command_path(&c.name));
    let groups = model.groups.iter().map(|g| group_path(&g.name));
    let buffer = buffer_tokens(model, imports);
    let doc =
        format!("Everything `specs/{family}.yaml` says about the {title}, for generic tools.");
    let device_info = imports.get("optobus_device::DeviceInfo");
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

/// `Some(&BufferInfo { … })` for a spec with a data buffer, else `None`.
fn buffer_tokens(model: &Model, imports: &Imports) -> TokenStream {
    let Some(buffer) = &model.buffer else {
        return quote!(None);
    };
    let ty = imports.get("optobus_device::BufferInfo");
    let section = buffer.section.as_deref().unwrap_or("");
    let doc = doc_text(buffer.doc.as_deref());
    let source = option_str(buffer.source.as_ref().map(|n| n.name.as_str()));
    let most = lit(buffer.most.0);
    let interval = option_str(buffer.interval.as_ref().map(|n| n.name.as_str()));
    let ratio = option_str(buffer.ratio.as_ref().map(|n| n.name.as_str()));
    let [count, lock, unlock, page, read_count, valid_count, values] = [
        &buffer.count,
        &buffer.lock,
        &buffer.unlock,
        &buffer.page,
        &buffer.read_count,
        &buffer.valid_count,
        &buffer.values,
    ]
    .map(|n| n.name.as_str());
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
