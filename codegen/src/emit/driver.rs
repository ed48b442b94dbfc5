//! The typed driver of a family: `PSeries<T>` with one async getter per readable register,
//! one `set_…` per writable one, a method per command and per group, and the structs group
//! reads return.
//!
//! Every method is a thin, documented wrapper naming its register (`registers::DISTANCE_1`)
//! and the Rust type of its value; reading, validating, planning group reads and writing
//! happen once, in `optobus-driver`.

use std::collections::HashSet;

use optobus_codec::value::{Fixed, Scale};
use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};

use super::device::{address_text, command_path, copies_path, group_path, register_path};
use super::names::{Imports, TypeNames};
use super::{camel, doc_alias, doc_text, ident, type_ident};
use optobus_spec::model::{Kind, Model, Register, Scalar};

/// The driver runtime's unit type for a spec unit; other units read as plain `Fixed`.
fn unit_type(unit: &str) -> Option<&'static str> {
    Some(match unit {
        "mm" => "optobus_driver::units::Millimetres",
        "us" => "optobus_driver::units::Microseconds",
        "%" => "optobus_driver::units::Percent",
        "degC" => "optobus_driver::units::DegreesCelsius",
        "uV" => "optobus_driver::units::Microvolts",
        "Hz" => "optobus_driver::units::Hertz",
        _ => return None,
    })
}

/// The Rust type a register's value has (before a sentinel makes it optional).
fn value_type(register: &Register, names: &TypeNames, imports: &Imports) -> TokenStream {
    match &register.kind {
        Kind::Bool => quote!(bool),
        Kind::Scalar(scalar) => {
            if let Some(unit) = register.unit.as_deref().and_then(unit_type) {
                imports.get(unit)
            } else if register.scale.is_some() {
                imports.get("optobus_driver::Fixed")
            } else {
                match scalar {
                    Scalar::U16 => quote!(u16),
                    Scalar::I16 => quote!(i16),
                    Scalar::U32 => quote!(u32),
                    Scalar::I32 => quote!(i32),
                }
            }
        }
        Kind::Enum(reference) => match reference.index {
            Some(index) => {
                let ty = &names.enums[index];
                quote!(#ty)
            }
            None => quote!(u32),
        },
        Kind::Packed(_) | Kind::Version(_) | Kind::Record(_) => {
            let ty = names.struct_name(register);
            quote!(#ty)
        }
        Kind::Ipv4 => imports.get("std::net::Ipv4Addr"),
    }
}

/// The type a read gives: optional when the register has an "invalid" sentinel.
fn read_type(register: &Register, names: &TypeNames, imports: &Imports) -> TokenStream {
    let ty = value_type(register, names, imports);
    if register.sentinel.is_some() {
        let option = imports.prelude("core::option::Option");
        quote!(#option<#ty>)
    } else {
        ty
    }
}

/// Version and record values are read-only views; every other kind can be written.
fn encodable(register: &Register) -> bool {
    !matches!(register.kind, Kind::Version(_) | Kind::Record(_))
}

/// A raw value in the register's units (its steps applied), as the driver takes it.
fn shown_raw(register: &Register, raw: i64) -> String {
    match register.scale.as_ref().and_then(|s| s.value.clone().ok()) {
        Some(scale) => optobus_codec::value::Fixed::new(raw, scale).to_string(),
        None => raw.to_string(),
    }
}

/// The register-manual table every accessor's documentation ends with.
fn register_doc(model: &Model, register: &Register, copies: Option<&[&Register]>) -> Vec<String> {
    let mut lines = vec![doc_text(register.doc.as_deref()), String::new()];
    lines.push("| | |".into());
    lines.push("|---|---|".into());
    let address = match copies {
        Some(copies) => copies
            .iter()
            .map(|r| address_text(model, r))
            .collect::<Vec<_>>()
            .join(", "),
        None => address_text(model, register),
    };
    lines.push(format!(
        "| address | {address} ({} word{}) |",
        register.words.0,
        if register.words.0 == 1 { "" } else { "s" }
    ));
    let access = match (register.readable(), register.access.writable()) {
        (true, true) => "read-write",
        (true, false) => "read-only",
        _ if register.action => {
            "written only (an action: the manual does not say what a read returns)"
        }
        _ => "write-only",
    };
    lines.push(format!("| access | {access} |"));
    lines.push(format!("| wire type | {} |", register.kind.name()));
    if let Some(scale) = &register.scale {
        // A decimal step as the number it is (`0.1`); a ratio as written (`1/1048576`).
        let step = match scale.value {
            Ok(decimal @ Scale::Decimal { .. }) => Fixed::new(1, decimal).to_string(),
            _ => scale.text.clone(),
        };
        lines.push(format!("| step | {step} |"));
    }
    if let Some(unit) = &register.unit {
        lines.push(format!("| unit | {unit} |"));
    }
    if let Some((min, max)) = register.range {
        let shown = |raw| shown_raw(register, raw);
        lines.push(format!("| range | {} ..= {} |", shown(min), shown(max)));
    }
    if let Some((values, _)) = &register.allowed_values {
        let shown: Vec<String> = values.iter().map(|v| shown_raw(register, *v)).collect();
        lines.push(format!("| allowed values | {} |", shown.join(", ")));
    }
    if let Kind::Enum(reference) = &register.kind {
        lines.push(format!("| codes | see [`{}`] |", camel(&reference.name)));
    }
    if let Some(sentinel) = register.sentinel {
        lines.push(format!("| invalid | raw {sentinel:#X} reads as `None` |"));
    }
    let section = register.section.as_deref().unwrap_or("");
    let zh = register
        .zh
        .as_deref()
        .map(|zh| format!(" ({zh})"))
        .unwrap_or_default();
    lines.push(format!("| manual | {section}{zh} |"));
    if register.write_order == Some(optobus_codec::value::WriteOrder::LowWordFirst) {
        lines.push(String::new());
        lines.push("Written as two registers, low word first, as the manual demands.".into());
    }
    if let Some(effect) = &register.read_side_effect {
        lines.push(String::new());
        lines.push(format!(
            "Reading it {effect}, so a failed read is never retried."
        ));
    }
    lines
}

/// How an accessor reaches its register: a named constant, or one copy of a repeat member.
enum Target<'m> {
    Single(&'m Register),
    Copies {
        index_type: Ident,
        repeat: &'m str,
        member: &'m str,
        copies: Vec<&'m Register>,
    },
}

/// The parameter that picks a copy of a repeat block, named after the block (`channel:
/// Channel`); `value` is the setters' own parameter, so such a block's becomes `value_copy`.
fn copy_param(repeat: &str) -> Ident {
    match repeat {
        "value" | "self" | "crate" | "super" => format_ident!("{repeat}_copy"),
        _ => ident(repeat),
    }
}

impl Target<'_> {
    /// `(parameter list, expression giving &'static RegisterInfo)`.
    fn access(&self) -> (TokenStream, TokenStream) {
        match self {
            Self::Single(register) => (quote!(), {
                let path = register_path(&register.name);
                quote!(&#path)
            }),
            Self::Copies {
                index_type,
                repeat,
                member,
                ..
            } => {
                let copies = copies_path(repeat, member);
                let param = copy_param(repeat);
                (
                    quote!(#param: #index_type,),
                    quote!(#copies[#param.index()]),
                )
            }
        }
    }

    fn register(&self) -> &Register {
        match self {
            Self::Single(register) => register,
            Self::Copies { copies, .. } => copies[0],
        }
    }
}

/// Registers (plain ones, and repeat members once for all copies) with the method name
/// their accessors take.
fn targets(model: &Model) -> Vec<(String, Target<'_>)> {
    let mut out = Vec::new();
    let mut seen_bases = HashSet::new();
    for register in &model.registers {
        match &register.repeat {
            None => out.push((register.name.clone(), Target::Single(register))),
            Some(copy) => {
                if !seen_bases.insert((copy.repeat, copy.base.clone())) {
                    continue;
                }
                let mut copies: Vec<&Register> = model
                    .registers
                    .iter()
                    .filter(|r| {
                        r.repeat
                            .as_ref()
                            .is_some_and(|c| c.repeat == copy.repeat && c.base == copy.base)
                    })
                    .collect();
                copies.sort_by_key(|r| r.repeat.as_ref().map_or(0, |c| c.number));
                let repeat = &model.repeats[copy.repeat].name;
                out.push((
                    copy.base.clone(),
                    Target::Copies {
                        index_type: type_ident(repeat),
                        repeat,
                        member: &copy.base,
                        copies,
                    },
                ));
            }
        }
    }
    out
}

/// A group member as a struct field: one register, or every copy of a repeat member.
struct Member<'m> {
    name: String,
    register: &'m Register,
    /// For a repeat member: its block and number of copies.
    copies: Option<(&'m str, usize)>,
}

/// The members of a group, and the repeat block's name when the group is read per copy
/// (every member a repeat block's member name: CCF's `read_measurements(channel)`).
fn group_members<'m>(model: &'m Model, names: &[String]) -> (Vec<Member<'m>>, Option<&'m str>) {
    let single = |name: &str| model.registers.iter().find(|r| r.name == name);
    let copies_of = |base: &str| -> Vec<&'m Register> {
        model
            .registers
            .iter()
            .filter(|r| r.repeat.as_ref().is_some_and(|c| c.base == base))
            .collect()
    };
    let per_copy_repeat = names
        .iter()
        .map(|name| {
            if single(name).is_some() {
                None
            } else {
                copies_of(name)
                    .first()
                    .and_then(|r| r.repeat.as_ref().map(|c| c.repeat))
            }
        })
        .collect::<Option<Vec<usize>>>()
        .filter(|repeats| repeats.windows(2).all(|w| w[0] == w[1]))
        .and_then(|repeats| repeats.first().copied());
    let members = names
        .iter()
        .filter_map(|name| {
            if let Some(register) = single(name) {
                return Some(Member {
                    name: name.clone(),
                    register,
                    copies: None,
                });
            }
            let copies = copies_of(name);
            let register = *copies.first()?;
            let repeat = register.repeat.as_ref()?.repeat;
            Some(Member {
                name: name.clone(),
                register,
                copies: Some((model.repeats[repeat].name.as_str(), copies.len())),
            })
        })
        .collect();
    let per_copy = per_copy_repeat.map(|repeat| model.repeats[repeat].name.as_str());
    (members, per_copy)
}

/// The driver type, its methods, and the structs its group reads return.
pub(super) fn driver(model: &Model, names: &TypeNames, imports: &Imports) -> TokenStream {
    let driver = &names.driver;
    let title = &model.title;
    let mut taken: HashSet<String> = [
        "new",
        "with_default_slave",
        "core",
        "into_transport",
        "slave",
        "wait_ready",
    ]
    .into_iter()
    .map(str::to_owned)
    .collect();
    // Commands keep the manual's names; a register accessor of the same name gets `_state`.
    taken.extend(model.commands.iter().map(|c| c.name.clone()));
    if model.buffer.is_some() {
        taken.extend(BUFFER_METHODS.map(str::to_owned));
    }
    let unit = quote!(());

    let mut methods = Vec::new();
    for (name, target) in targets(model) {
        let name = if taken.contains(&name) {
            format!("{name}_state")
        } else {
            name
        };
        let register = target.register();
        let copies = match &target {
            Target::Copies { copies, .. } => Some(copies.as_slice()),
            Target::Single(..) => None,
        };
        let doc = register_doc(model, register, copies);
        let alias = doc_alias(register.zh.as_deref());
        let (param, info) = target.access();
        if register.readable() {
            taken.insert(name.clone());
            let method = ident(&name);
            let result = imports.result(read_type(register, names, imports));
            methods.push(quote! {
                #(#[doc = #doc])*
                #alias
                pub async fn #method(&mut self, #param) -> #result {
                    self.core.read(#info).await
                }
            });
        }
        if register.access.writable() && encodable(register) {
            let setter = format!("set_{name}");
            taken.insert(setter.clone());
            let method = ident(&setter);
            let ty = value_type(register, names, imports);
            let first = format!("Writes `{name}` after checking the value; an invalid value is refused before anything is sent.");
            let alias = if register.readable() { quote!() } else { alias };
            let result = imports.result(unit.clone());
            methods.push(quote! {
                #[doc = #first]
                ///
                #(#[doc = #doc])*
                #alias
                pub async fn #method(&mut self, #param value: #ty) -> #result {
                    self.core.write(#info, &value).await
                }
            });
        }
    }

    let mut group_types = Vec::new();
    for (group, struct_ident) in model.groups.iter().zip(&names.groups) {
        let member_names: Vec<String> = group.registers.iter().map(|(n, _)| n.clone()).collect();
        let (members, per_copy) = group_members(model, &member_names);
        let fields: Vec<Ident> = members.iter().map(|m| ident(&m.name)).collect();
        let field_docs = members.iter().map(|m| doc_text(m.register.doc.as_deref()));
        // serde's own array impls stop at 32 elements; a buffer page holds more.
        let field_serde = members.iter().map(|m| match (m.copies, &per_copy) {
            (Some(_), None) => {
                quote!(#[cfg_attr(feature = "serde", serde(with = "optobus_driver::array_serde"))])
            }
            _ => quote!(),
        });
        let field_types = members.iter().map(|m| {
            let ty = read_type(m.register, names, imports);
            match (m.copies, &per_copy) {
                (Some((_, count)), None) => {
                    let count = Literal::usize_unsuffixed(count);
                    quote!([#ty; #count])
                }
                _ => ty,
            }
        });
        let values = members.iter().map(|m| match (m.copies, &per_copy) {
            (Some((repeat, _)), Some(_)) => {
                let copies = copies_path(repeat, &m.name);
                let param = copy_param(repeat);
                quote!(readings.get(#copies[#param.index()]))
            }
            (Some((repeat, _)), None) => {
                let copies = copies_path(repeat, &m.name);
                quote!(#copies.map(|register| readings.get(register)))
            }
            (None, _) => {
                let path = register_path(&m.name);
                quote!(readings.get(&#path))
            }
        });
        let method = format_ident!("read_{}", group.name);
        taken.insert(method.to_string());
        let doc = doc_text(group.doc.as_deref());
        let struct_doc = format!("The registers [`{driver}::{method}`] reads: {doc}");
        let method_doc = format!(
            "Reads `{}` in the fewest requests the device allows: {doc}",
            group.name
        );
        let group = group_path(&group.name);
        let (param, read) = match &per_copy {
            Some(repeat) => {
                let (param, index_type) = (copy_param(repeat), type_ident(repeat));
                (
                    quote!(#param: #index_type),
                    quote!(self.core.read_declared_group_copy(&#group, #param.number())),
                )
            }
            None => (quote!(), quote!(self.core.read_declared_group(&#group))),
        };
        let serde = super::serde_derives();
        group_types.push(quote! {
            #[doc = #struct_doc]
            #[derive(Clone, Debug, PartialEq)]
            #serde
            pub struct #struct_ident {
                #(
                    #[doc = #field_docs]
                    #field_serde
                    pub #fields: #field_types,
                )*
            }
        });
        let result = imports.result(quote!(#struct_ident));
        methods.push(quote! {
            #[doc = #method_doc]
            pub async fn #method(&mut self, #param) -> #result {
                let readings = #read.await?;
                Ok(#struct_ident { #(#fields: #values,)* })
            }
        });
    }

    let all_targets = targets(model);
    for command in &model.commands {
        let method = ident(&command.name);
        let Some((_, target)) = all_targets.iter().find(|(n, _)| *n == command.register) else {
            continue;
        };
        let (param, info) = target.access();
        let mut doc = vec![doc_text(command.doc.as_deref()), String::new()];
        doc.push(format!(
            "Writes {} to `{}`{}.",
            command.value,
            command.register,
            match command.busy_ms {
                Some(ms) if ms > 0 => format!(", then waits {ms} ms while the device is busy"),
                _ => String::new(),
            }
        ));
        if let Some(completion) = command.completion() {
            doc.push(String::new());
            doc.push(format!(
                "Done only once `{}` reads {} again (the device has finished), polled for at most {} ms from the write; otherwise the error is `CommandNotFinished`.",
                command.register, completion.value, completion.within_ms
            ));
        }
        if let Some(section) = &command.section {
            doc.push(String::new());
            doc.push(format!("Manual: {section}."));
        }
        let command = command_path(&command.name);
        let result = imports.result(unit.clone());
        methods.push(quote! {
            #(#[doc = #doc])*
            pub async fn #method(&mut self, #param) -> #result {
                self.core.run(&#command, #info).await
            }
        });
    }

    methods.extend(buffer_methods(model, names, imports));

    let struct_doc = format!(
        "Driver for the {title}: one async method per register, command and group of `specs/{}.yaml`.",
        model.family
    );
    let slave_doc = format!(
        "A driver for the device at `slave` (factory setting {}); 0 broadcasts (writes and commands only), 248 to 255 are refused.",
        model.device.default_slave
    );
    let ready_ms = Literal::u64_unsuffixed(u64::from(model.device.power_up_ms.unwrap_or(0)) + 1000);
    let ready_doc = format!(
        "Polls until the device answers, for up to {} ms (the manual's start-up time plus one second); gives the time it took.",
        u64::from(model.device.power_up_ms.unwrap_or(0)) + 1000
    );
    let core = imports.get("optobus_driver::Core");
    let transport = imports.get("optobus_driver::Transport");
    let duration = imports.get("core::time::Duration");
    let new_result = imports.result(quote!(Self));
    let ready_result = imports.result(duration.clone());
    quote! {
        #(#group_types)*

        #[doc = #struct_doc]
        ///
        /// Reads of enumerated registers never fail on codes the manual does not define (they
        /// give `Unknown(raw)`); every write is validated before a byte is sent.
        #[derive(Debug)]
        pub struct #driver<T> {
            core: #core<T>,
        }

        impl<T: #transport> #driver<T> {
            #[doc = #slave_doc]
            pub fn new(transport: T, slave: u8) -> #new_result {
                #core::new(transport, slave, &DEVICE).map(|core| Self { core })
            }

            /// A driver for the device at its factory slave address.
            pub fn with_default_slave(transport: T) -> Self {
                Self { core: #core::with_default_slave(transport, &DEVICE) }
            }

            /// The slave address requests go to.
            pub fn slave(&self) -> u8 {
                self.core.slave()
            }

            /// The generic core, for register access by name (tools) or another slave address.
            pub fn core(&mut self) -> &mut #core<T> {
                &mut self.core
            }

            /// Gives the transport back.
            pub fn into_transport(self) -> T {
                self.core.into_transport()
            }

            #[doc = #ready_doc]
            pub async fn wait_ready(&mut self) -> #ready_result {
                self.core.wait_ready(#duration::from_millis(#ready_ms)).await
            }

            #(#methods)*
        }
    }
}

/// The methods a spec with a `buffer:` section gets.
const BUFFER_METHODS: [&str; 2] = ["start_buffering", "download_buffer"];

/// `start_buffering` and `download_buffer`, typed from the buffer's registers, over the
/// runtime's one download procedure.
fn buffer_methods(model: &Model, names: &TypeNames, imports: &Imports) -> Vec<TokenStream> {
    let Some(buffer) = &model.buffer else {
        return Vec::new();
    };
    let (Some(count), Some(values)) = (
        model.register(&buffer.count.name),
        model.resolve(&buffer.values.name),
    ) else {
        return Vec::new();
    };
    let about = doc_text(buffer.doc.as_deref());
    let manual = buffer
        .section
        .as_ref()
        .map(|section| format!("Manual: {section}."));
    let source = buffer
        .source
        .as_ref()
        .and_then(|source| model.register(&source.name));
    let (source_param, source_arg, writes) = match source {
        Some(register) => {
            let ty = value_type(register, names, imports);
            (
                quote!(source: #ty,),
                quote!(Some(&source)),
                format!("`{}` and `{}`", register.name, count.name),
            )
        }
        None => (quote!(), quote!(None), format!("`{}`", count.name)),
    };
    let what = if source.is_some() {
        "values of `source`"
    } else {
        "values"
    };
    let start_doc = [
        format!("Starts buffering `count` {what}."),
        String::new(),
        about.clone(),
        String::new(),
        format!(
            "Writes {writes}, then runs `{}`; 0 turns buffering off. A count above {} (the most that may be read out) is refused with `Error::OutOfRange` before anything is sent.",
            buffer.unlock.name, buffer.most.0
        ),
    ];
    let download_doc = [
        "Reads the data buffer out, oldest value first.".to_owned(),
        String::new(),
        about,
        String::new(),
        format!(
            "Runs `{}`, reads `{}` until the count in `{}` (at most {}) is reached or a page holds no valid value, and runs `{}`, also when a read fails. `progress` is called after every page.",
            buffer.lock.name, buffer.page.name, count.name, buffer.most.0, buffer.unlock.name
        ),
        String::new(),
        format!(
            "A page read is never retried (reading it turns the page), and `{}` is checked against the values received: a lost page fails the download with `Error::OutOfStep` rather than return fewer values.",
            buffer.read_count.name
        ),
    ];
    let manual = manual.map(|m| vec![String::new(), m]).unwrap_or_default();
    let count_ty = value_type(count, names, imports);
    let value_ty = read_type(values, names, imports);
    let vec = imports.prelude("std::vec::Vec");
    let progress = imports.get("optobus_driver::DownloadProgress");
    let started = imports.result(quote!(()));
    let downloaded = imports.result(quote!(#vec<#value_ty>));
    vec![
        quote! {
            #(#[doc = #start_doc])*
            #(#[doc = #manual])*
            pub async fn start_buffering(&mut self, #source_param count: #count_ty) -> #started {
                self.core.start_buffering(#source_arg, u32::from(count)).await
            }
        },
        quote! {
            #(#[doc = #download_doc])*
            #(#[doc = #manual])*
            pub async fn download_buffer(
                &mut self,
                progress: impl FnMut(#progress),
            ) -> #downloaded {
                self.core.download_buffer(progress).await
            }
        },
    ]
}
