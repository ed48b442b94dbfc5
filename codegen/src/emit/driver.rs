//! The typed driver of a family: `PSeries<T>` with one async getter per readable register,
//! one `set_…` per writable one, a method per command and per group, and the `Decode` /
//! `Encode` impls that connect the generated value types to `optobus-driver`.
//!
//! Every method is a thin, documented wrapper naming its register's entry in `DEVICE` and the
//! Rust type of its value; reading, validating and writing happen once, in `optobus-driver`.

use std::collections::HashSet;

use proc_macro2::{Ident, Literal, Span, TokenStream};
use quote::{format_ident, quote};

use super::{camel, doc_text, TypeNames};
use crate::model::{Kind, Model, Register, Scalar, Table};

/// The driver runtime's unit type for a spec unit; other units read as plain `Fixed`.
fn unit_type(unit: &str) -> Option<&'static str> {
    Some(match unit {
        "mm" => "Millimetres",
        "us" => "Microseconds",
        "%" => "Percent",
        "degC" => "DegreesCelsius",
        "uV" => "Microvolts",
        "Hz" => "Hertz",
        _ => return None,
    })
}

/// An identifier for a spec name, raw if it is a Rust keyword.
fn ident(name: &str) -> Ident {
    if syn::parse_str::<Ident>(name).is_ok() {
        Ident::new(name, Span::call_site())
    } else {
        Ident::new_raw(name, Span::call_site())
    }
}

/// The Rust type a register's value has (before a sentinel makes it optional).
fn value_type(register: &Register, names: &TypeNames) -> TokenStream {
    match &register.kind {
        Kind::Bool => quote!(bool),
        Kind::Scalar(scalar) => {
            if let Some(unit) = register.unit.as_deref().and_then(unit_type) {
                let unit = format_ident!("{unit}");
                quote!(::optobus_driver::units::#unit)
            } else if register.scale.is_some() {
                quote!(::optobus_driver::Fixed)
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
        Kind::Ipv4 => quote!(::std::net::Ipv4Addr),
    }
}

/// The type a read gives: optional when the register has an "invalid" sentinel.
fn read_type(register: &Register, names: &TypeNames) -> TokenStream {
    let ty = value_type(register, names);
    if register.sentinel.is_some() {
        quote!(::core::option::Option<#ty>)
    } else {
        ty
    }
}

/// Version and record values are read-only views; every other kind can be written.
fn encodable(register: &Register) -> bool {
    !matches!(register.kind, Kind::Version(_) | Kind::Record(_))
}

/// `0012` or `0012–0013`, as the manuals print addresses.
fn address_text(model: &Model, register: &Register) -> String {
    let first = register.address.0;
    let last = first + model.extent(register).saturating_sub(1);
    let table = match register.table {
        Table::Holding => "holding",
        Table::Input => "input",
    };
    if last == first {
        format!("{table} {first:04}")
    } else {
        format!("{table} {first:04}–{last:04}")
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
    let access = match (register.access.readable(), register.access.writable()) {
        (true, true) => "read-write",
        (true, false) => "read-only",
        _ => "write-only",
    };
    lines.push(format!("| access | {access} |"));
    lines.push(format!("| wire type | {} |", register.kind.name()));
    if let Some(scale) = &register.scale {
        lines.push(format!("| step | {} |", scale.text));
    }
    if let Some(unit) = &register.unit {
        lines.push(format!("| unit | {unit} |"));
    }
    if let Some((min, max)) = register.range {
        let shown = |raw: i64| match register.scale.as_ref().and_then(|s| s.value.clone().ok()) {
            Some(scale) => optobus_codec::value::Fixed::new(raw, scale).to_string(),
            None => raw.to_string(),
        };
        lines.push(format!("| range | {} ..= {} |", shown(min), shown(max)));
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

/// A register's entry in `DEVICE.registers`.
fn entry(index: usize) -> TokenStream {
    let index = Literal::usize_unsuffixed(index);
    quote!(&DEVICE.registers[#index])
}

/// How an accessor reaches its register: a fixed entry, or one of a repeat block's copies.
enum Target<'m> {
    Single(usize, &'m Register),
    Copies {
        index_type: Ident,
        indexes: Vec<usize>,
        first: &'m Register,
        copies: Vec<&'m Register>,
    },
}

impl Target<'_> {
    /// `(parameter list, expression giving &'static RegisterInfo)`.
    fn access(&self, param: &Ident) -> (TokenStream, TokenStream) {
        match self {
            Self::Single(index, _) => (quote!(), entry(*index)),
            Self::Copies {
                index_type,
                indexes,
                ..
            } => {
                let indexes = indexes.iter().map(|i| Literal::usize_unsuffixed(*i));
                (
                    quote!(#param: #index_type,),
                    quote!({
                        const COPIES: &[usize] = &[#(#indexes),*];
                        &DEVICE.registers[COPIES[usize::from(#param.number()) - 1]]
                    }),
                )
            }
        }
    }

    fn register(&self) -> &Register {
        match self {
            Self::Single(_, register) => register,
            Self::Copies { first, .. } => first,
        }
    }
}

/// Registers (plain ones, and repeat members once for all copies) with the method name
/// their accessors take.
fn targets<'m>(model: &'m Model) -> Vec<(String, Target<'m>)> {
    let mut out = Vec::new();
    let mut seen_bases = HashSet::new();
    for (index, register) in model.registers.iter().enumerate() {
        match &register.repeat {
            None => out.push((register.name.clone(), Target::Single(index, register))),
            Some(copy) => {
                let key = (copy.repeat, copy.base.clone());
                if !seen_bases.insert(key) {
                    continue;
                }
                let mut copies: Vec<(u32, usize, &Register)> = model
                    .registers
                    .iter()
                    .enumerate()
                    .filter(|(_, r)| {
                        r.repeat
                            .as_ref()
                            .is_some_and(|c| c.repeat == copy.repeat && c.base == copy.base)
                    })
                    .map(|(i, r)| (r.repeat.as_ref().map_or(0, |c| c.number), i, r))
                    .collect();
                copies.sort_by_key(|c| c.0);
                out.push((
                    copy.base.clone(),
                    Target::Copies {
                        index_type: super::type_ident(&model.repeats[copy.repeat].name),
                        indexes: copies.iter().map(|c| c.1).collect(),
                        first: register,
                        copies: copies.iter().map(|c| c.2).collect(),
                    },
                ));
            }
        }
    }
    out
}

/// `Decode` and `Encode` for the generated value types.
pub(super) fn value_impls(model: &Model, names: &TypeNames) -> TokenStream {
    let enums = names.enums.iter().map(|ty| {
        quote! {
            impl ::optobus_driver::Decode for #ty {
                fn decode(register: &::optobus_device::RegisterInfo, words: &[u16]) -> Self {
                    Self::from_raw(::optobus_driver::raw_bits(register, words))
                }
            }

            impl ::optobus_driver::Encode for #ty {
                /// Refuses `Unknown` codes and codes the register does not define.
                fn encode(
                    &self,
                    register: &'static ::optobus_device::RegisterInfo,
                ) -> ::core::result::Result<::std::vec::Vec<u16>, ::optobus_driver::Error> {
                    if let Self::Unknown(code) = self {
                        return Err(::optobus_driver::Error::UndefinedCode {
                            register: register.name,
                            field: None,
                            code: *code,
                        });
                    }
                    ::optobus_driver::encode_code(register, self.raw())
                }
            }
        }
    });
    let structs = model
        .registers
        .iter()
        .filter(|r| r.repeat.as_ref().is_none_or(|c| c.number == 1))
        .filter_map(|register| {
            let ty = names.struct_name(register);
            match &register.kind {
                Kind::Packed(_) => Some(quote! {
                    impl ::optobus_driver::Decode for #ty {
                        fn decode(register: &::optobus_device::RegisterInfo, words: &[u16]) -> Self {
                            Self::from_raw(::optobus_driver::raw_bits(register, words))
                        }
                    }

                    impl ::optobus_driver::Encode for #ty {
                        /// Refuses fields that do not fit their bits or hold undefined codes.
                        fn encode(
                            &self,
                            register: &'static ::optobus_device::RegisterInfo,
                        ) -> ::core::result::Result<::std::vec::Vec<u16>, ::optobus_driver::Error> {
                            ::optobus_driver::encode_packed(register, self.to_raw())
                        }
                    }
                }),
                Kind::Version(_) => Some(quote! {
                    impl ::optobus_driver::Decode for #ty {
                        fn decode(_register: &::optobus_device::RegisterInfo, words: &[u16]) -> Self {
                            let word = |i: usize| words.get(i).copied().unwrap_or(0);
                            Self::from_words([word(0), word(1)])
                        }
                    }
                }),
                Kind::Record(_) => Some(quote! {
                    impl ::optobus_driver::Decode for #ty {
                        fn decode(_register: &::optobus_device::RegisterInfo, words: &[u16]) -> Self {
                            let mut all = [0u16; Self::WORDS];
                            for (slot, word) in all.iter_mut().zip(words) {
                                *slot = *word;
                            }
                            Self::from_words(&all)
                        }
                    }
                }),
                _ => None,
            }
        });
    quote! { #(#enums)* #(#structs)* }
}

/// A group member as a struct field: one register, or every copy of a repeat member.
struct Member<'m> {
    name: String,
    register: &'m Register,
    /// Entries in `DEVICE.registers` (one, or each copy in order).
    indexes: Vec<usize>,
    array: bool,
}

/// The members of a group, and the repeat index type when the group is read per copy (every
/// member a repeat block's member name: CCF's `read_measurements(channel)`).
fn group_members<'m>(
    model: &'m Model,
    names: &[String],
) -> (Vec<Member<'m>>, Option<(Ident, usize)>) {
    let index_of = |name: &str| model.registers.iter().position(|r| r.name == name);
    let copies_of = |base: &str| -> Vec<(usize, &'m Register)> {
        let mut copies: Vec<(usize, &Register)> = model
            .registers
            .iter()
            .enumerate()
            .filter(|(_, r)| r.repeat.as_ref().is_some_and(|c| c.base == base))
            .collect();
        copies.sort_by_key(|(_, r)| r.repeat.as_ref().map_or(0, |c| c.number));
        copies
    };
    let per_copy_repeat = names
        .iter()
        .map(|name| {
            if index_of(name).is_some() {
                None
            } else {
                copies_of(name)
                    .first()
                    .and_then(|(_, r)| r.repeat.as_ref().map(|c| c.repeat))
            }
        })
        .collect::<Option<Vec<usize>>>()
        .filter(|repeats| repeats.windows(2).all(|w| w[0] == w[1]))
        .and_then(|repeats| repeats.first().copied());
    let members = names
        .iter()
        .filter_map(|name| {
            if let Some(index) = index_of(name) {
                return Some(Member {
                    name: name.clone(),
                    register: &model.registers[index],
                    indexes: vec![index],
                    array: false,
                });
            }
            let copies = copies_of(name);
            let register = copies.first()?.1;
            Some(Member {
                name: name.clone(),
                register,
                indexes: copies.iter().map(|c| c.0).collect(),
                array: per_copy_repeat.is_none(),
            })
        })
        .collect();
    let per_copy = per_copy_repeat.map(|repeat| {
        let count = usize::try_from(model.repeats[repeat].count).unwrap_or(0);
        (super::type_ident(&model.repeats[repeat].name), count)
    });
    (members, per_copy)
}

/// The driver type and its methods.
pub(super) fn driver(model: &Model, names: &TypeNames) -> TokenStream {
    let driver = format_ident!("{}", camel(&model.family));
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
    let copy_param = format_ident!("copy");

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
        let (param, info) = target.access(&copy_param);
        if register.access.readable() {
            taken.insert(name.clone());
            let method = ident(&name);
            let ty = read_type(register, names);
            methods.push(quote! {
                #(#[doc = #doc])*
                pub async fn #method(&mut self, #param) -> ::core::result::Result<#ty, ::optobus_driver::Error> {
                    self.core.read(#info).await
                }
            });
        }
        if register.access.writable() && encodable(register) {
            let setter = format!("set_{name}");
            taken.insert(setter.clone());
            let method = ident(&setter);
            let ty = value_type(register, names);
            let first = format!("Writes `{name}` after checking the value; an invalid value is refused before anything is sent.");
            methods.push(quote! {
                #[doc = #first]
                ///
                #(#[doc = #doc])*
                pub async fn #method(&mut self, #param value: #ty) -> ::core::result::Result<(), ::optobus_driver::Error> {
                    self.core.write(#info, &value).await
                }
            });
        }
    }

    let mut group_types = Vec::new();
    for group in &model.groups {
        let member_names: Vec<String> = group.registers.iter().map(|(n, _)| n.clone()).collect();
        let (members, per_copy) = group_members(model, &member_names);
        let mut struct_name = camel(&group.name);
        while names.taken.contains(&struct_name) {
            struct_name.push_str("Values");
        }
        let struct_ident = format_ident!("{struct_name}");
        let fields: Vec<Ident> = members.iter().map(|m| ident(&m.name)).collect();
        let field_docs = members.iter().map(|m| doc_text(m.register.doc.as_deref()));
        let field_types: Vec<TokenStream> = members
            .iter()
            .map(|m| {
                let ty = read_type(m.register, names);
                if m.array {
                    let len = Literal::usize_unsuffixed(m.indexes.len());
                    quote!([#ty; #len])
                } else {
                    ty
                }
            })
            .collect();
        // The registers to read, in member order, and how each field picks its values.
        let mut entries = Vec::new();
        let mut values = Vec::new();
        for member in &members {
            let start = Literal::usize_unsuffixed(entries.len());
            match (&per_copy, member.array) {
                (Some(_), _) => {
                    let indexes = member.indexes.iter().map(|i| Literal::usize_unsuffixed(*i));
                    entries.push(quote!({
                        const COPIES: &[usize] = &[#(#indexes),*];
                        &DEVICE.registers[COPIES[usize::from(#copy_param.number()) - 1]]
                    }));
                    values.push(quote!(readings.get(registers[#start])));
                }
                (None, true) => {
                    entries.extend(member.indexes.iter().map(|i| entry(*i)));
                    values.push(
                        quote!(::core::array::from_fn(|i| readings.get(registers[#start + i]))),
                    );
                }
                (None, false) => {
                    entries.push(entry(member.indexes[0]));
                    values.push(quote!(readings.get(registers[#start])));
                }
            }
        }
        let count = Literal::usize_unsuffixed(entries.len());
        let method = format_ident!("read_{}", group.name);
        taken.insert(method.to_string());
        let doc = doc_text(group.doc.as_deref());
        let struct_doc = format!("The registers [`{driver}::{method}`] reads: {doc}");
        let method_doc = format!(
            "Reads `{}` in the fewest requests the device allows: {doc}",
            group.name
        );
        let (param, plan) = match &per_copy {
            Some((index_type, copies)) => {
                let copies = Literal::usize_unsuffixed(*copies);
                (
                    quote!(#copy_param: #index_type),
                    quote! {
                        static PLANS: [::std::sync::OnceLock<::std::vec::Vec<::optobus_driver::ReadSpan>>; #copies] =
                            [const { ::std::sync::OnceLock::new() }; #copies];
                        let plan = &PLANS[usize::from(#copy_param.number()) - 1];
                    },
                )
            }
            None => (
                quote!(),
                quote! {
                    static PLAN: ::std::sync::OnceLock<::std::vec::Vec<::optobus_driver::ReadSpan>> =
                        ::std::sync::OnceLock::new();
                    let plan = &PLAN;
                },
            ),
        };
        group_types.push(quote! {
            #[doc = #struct_doc]
            #[derive(Clone, Debug, PartialEq)]
            pub struct #struct_ident {
                #(
                    #[doc = #field_docs]
                    pub #fields: #field_types,
                )*
            }
        });
        methods.push(quote! {
            #[doc = #method_doc]
            pub async fn #method(&mut self, #param) -> ::core::result::Result<#struct_ident, ::optobus_driver::Error> {
                let registers: [&'static ::optobus_device::RegisterInfo; #count] = [#(#entries),*];
                // The requests are planned on the first call and kept.
                #plan
                let readings = self.core.read_group_with(plan, &registers).await?;
                Ok(#struct_ident { #(#fields: #values,)* })
            }
        });
    }

    for (index, command) in model.commands.iter().enumerate() {
        let method = ident(&command.name);
        let index = Literal::usize_unsuffixed(index);
        let target = targets(model)
            .into_iter()
            .find(|(n, _)| *n == command.register)
            .map(|(_, t)| t);
        let Some(target) = target else { continue };
        let (param, info) = target.access(&copy_param);
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
        if let Some(section) = &command.section {
            doc.push(String::new());
            doc.push(format!("Manual: {section}."));
        }
        methods.push(quote! {
            #(#[doc = #doc])*
            pub async fn #method(&mut self, #param) -> ::core::result::Result<(), ::optobus_driver::Error> {
                self.core.run(&DEVICE.commands[#index], #info).await
            }
        });
    }

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
        model.device.power_up_ms.unwrap_or(0) + 1000
    );
    quote! {
        #(#group_types)*

        #[doc = #struct_doc]
        ///
        /// Reads of enumerated registers never fail on codes the manual does not define (they
        /// give `Unknown(raw)`); every write is validated before a byte is sent.
        #[derive(Debug)]
        pub struct #driver<T> {
            core: ::optobus_driver::Core<T>,
        }

        impl<T: ::optobus_driver::Transport> #driver<T> {
            #[doc = #slave_doc]
            pub fn new(transport: T, slave: u8) -> ::core::result::Result<Self, ::optobus_driver::Error> {
                ::optobus_driver::Core::new(transport, slave, &DEVICE).map(|core| Self { core })
            }

            /// A driver for the device at its factory slave address.
            pub fn with_default_slave(transport: T) -> Self {
                Self { core: ::optobus_driver::Core::with_default_slave(transport, &DEVICE) }
            }

            /// The slave address requests go to.
            pub fn slave(&self) -> u8 {
                self.core.slave()
            }

            /// The generic core, for register access by name (tools) or another slave address.
            pub fn core(&mut self) -> &mut ::optobus_driver::Core<T> {
                &mut self.core
            }

            /// Gives the transport back.
            pub fn into_transport(self) -> T {
                self.core.into_transport()
            }

            #[doc = #ready_doc]
            pub async fn wait_ready(&mut self) -> ::core::result::Result<::core::time::Duration, ::optobus_driver::Error> {
                self.core.wait_ready(::core::time::Duration::from_millis(#ready_ms)).await
            }

            #(#methods)*
        }
    }
}
