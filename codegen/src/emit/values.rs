//! Value structs (packed bit fields, versions, records) and a type per repeat index.
//!
//! A packed struct implements `optobus_driver::RawValue` (reading and checked writing come
//! with it); versions and records are read-only views decoded from their words.

use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};

use super::names::{Imports, TypeNames};
use super::{doc_text, exact, hex, lit, type_ident};
use optobus_spec::model::{Field, Kind, Model, Register, Scalar};

/// The value structs of every register (once for all copies of a repeat member), then the
/// repeat index types.
pub(super) fn value_types(model: &Model, names: &TypeNames, imports: &Imports) -> TokenStream {
    let structs = model
        .registers
        .iter()
        .filter(|r| r.repeat.as_ref().is_none_or(|c| c.number == 1))
        .filter_map(|r| value_struct(r, names, imports));
    let repeats = model.repeats.iter().map(|repeat| {
        let ident = type_ident(&repeat.name);
        let doc = doc_text(repeat.doc.as_deref());
        let count_doc = format!("Number of {}s: {}.", repeat.name, repeat.count);
        let count = exact::<u8, _>(repeat.count, "repeat count");
        let option = imports.prelude("core::option::Option");
        quote! {
            #[doc = #doc]
            ///
            /// Numbered from 1, as in the manual.
            #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
            pub struct #ident(u8);

            impl #ident {
                #[doc = #count_doc]
                pub const COUNT: u8 = #count;

                /// The copy numbered `number` (1-based); `None` outside `1..=COUNT`.
                pub const fn new(number: u8) -> #option<Self> {
                    if number >= 1 && number <= Self::COUNT {
                        Some(Self(number))
                    } else {
                        None
                    }
                }

                /// The 1-based number.
                pub const fn number(self) -> u8 {
                    self.0
                }

                /// The 0-based position, for arrays holding one entry per copy.
                pub const fn index(self) -> usize {
                    self.0 as usize - 1
                }

                /// Every copy, in order.
                pub fn all() -> impl Iterator<Item = Self> {
                    (1..=Self::COUNT).map(Self)
                }
            }
        }
    });
    quote! {
        #(#structs)*
        #(#repeats)*
    }
}

/// `(type, read from the raw bits, raw bits to write)` of a packed field.
fn field_type(field: &Field, names: &TypeNames) -> (TokenStream, TokenStream, TokenStream) {
    let name = format_ident!("{}", field.name);
    let width = u32::from(field.width.unwrap_or(16));
    let mask = hex(if width >= 32 {
        u32::MAX
    } else {
        (1u32 << width) - 1
    });
    let bits = match field.lsb.unwrap_or(0) {
        0 => quote!(raw & #mask),
        lsb => {
            let lsb = lit(lsb);
            quote!((raw >> #lsb) & #mask)
        }
    };
    match field.enum_ref.as_ref().and_then(|r| r.index) {
        Some(index) => {
            let ty = names.enums[index].clone();
            (
                quote!(#ty),
                quote!(#ty::from_raw(#bits)),
                quote!(self.#name.raw()),
            )
        }
        None => (quote!(u32), bits, quote!(self.#name)),
    }
}

fn value_struct(register: &Register, names: &TypeNames, imports: &Imports) -> Option<TokenStream> {
    let ident = names.struct_name(register);
    let doc = format!(
        "Value of `{}`: {}",
        register
            .repeat
            .as_ref()
            .map_or(register.name.as_str(), |c| c.base.as_str()),
        doc_text(register.doc.as_deref())
    );
    match &register.kind {
        Kind::Packed(fields) => Some(packed_struct(&ident, &doc, fields, names, imports)),
        Kind::Version(parts) => Some(version_struct(&ident, &doc, parts, imports)),
        Kind::Record(fields) => Some(record_struct(&ident, &doc, fields, imports)),
        _ => None,
    }
}

fn packed_struct(
    ident: &Ident,
    doc: &str,
    fields: &[Field],
    names: &TypeNames,
    imports: &Imports,
) -> TokenStream {
    let field_names: Vec<Ident> = fields.iter().map(|f| format_ident!("{}", f.name)).collect();
    let docs = fields.iter().map(|f| {
        format!(
            "{} (bits {}..{}).",
            doc_text(f.doc.as_deref()).trim_end_matches('.'),
            f.lsb.unwrap_or(0),
            f.lsb.unwrap_or(0) + f.width.unwrap_or(0)
        )
    });
    let parts: Vec<_> = fields.iter().map(|f| field_type(f, names)).collect();
    let types = parts.iter().map(|p| p.0.clone());
    let decodes = parts.iter().map(|p| &p.1);
    let encodes = parts.iter().map(|p| &p.2);
    let lsbs = fields.iter().map(|f| lit(f.lsb.unwrap_or(0)));
    let widths = fields.iter().map(|f| lit(f.width.unwrap_or(16)));
    let bit_field = imports.get("optobus_codec::value::BitField");
    let raw_value = imports.trait_("optobus_driver::RawValue");
    let option = imports.prelude("core::option::Option");
    let declaration = plain_struct(
        quote!(#[doc = #doc]),
        ident,
        Order::Unordered,
        &field_names,
        docs,
        types,
    );
    quote! {
        #declaration

        impl #ident {
            /// Splits the register's raw value into its fields.
            pub const fn from_raw(raw: u32) -> Self {
                Self { #(#field_names: #decodes,)* }
            }

            /// Joins the fields; `None` when a field's raw value does not fit its bits.
            pub const fn to_raw(self) -> #option<u32> {
                let raw = 0;
                #(
                    let Some(raw) = #bit_field { shift: #lsbs, width: #widths }.set(raw, #encodes) else {
                        return None;
                    };
                )*
                Some(raw)
            }
        }

        impl #raw_value for #ident {
            fn from_raw(raw: u32) -> Self {
                Self::from_raw(raw)
            }

            fn to_raw(self) -> #option<u32> {
                self.to_raw()
            }
        }
    }
}

/// Whether a value struct derives `PartialOrd` and `Ord`.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Order {
    Ordered,
    Unordered,
}

/// The declaration every value struct starts with: `doc`, the derives of a small `Copy` value,
/// and a documented public field per name.
fn plain_struct(
    doc: TokenStream,
    ident: &Ident,
    order: Order,
    names: &[impl quote::ToTokens],
    docs: impl IntoIterator<Item = String>,
    types: impl IntoIterator<Item = TokenStream>,
) -> TokenStream {
    let docs = docs.into_iter();
    let types = types.into_iter();
    let ord = match order {
        Order::Ordered => quote!(, PartialOrd, Ord),
        Order::Unordered => quote!(),
    };
    let serde = super::serde_derives();
    quote! {
        #doc
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash #ord)]
        #serde
        pub struct #ident {
            #(
                #[doc = #docs]
                pub #names: #types,
            )*
        }
    }
}

fn version_struct(ident: &Ident, doc: &str, parts: &[String], imports: &Imports) -> TokenStream {
    let named: Vec<(usize, Ident)> = parts
        .iter()
        .enumerate()
        .filter(|(_, p)| p.as_str() != "ignore")
        .map(|(i, p)| (i, format_ident!("{}", p)))
        .collect();
    let fields: Vec<&Ident> = named.iter().map(|(_, n)| n).collect();
    let indexes: Vec<Literal> = named.iter().map(|(i, _)| lit(*i as u64)).collect();
    let field_docs = named
        .iter()
        .map(|(i, n)| format!("The {n} version number (byte {i})."));
    let format = vec!["{}"; fields.len()].join(".");
    let fmt = imports.get("core::fmt");
    let decode = imports.get("optobus_driver::Decode");
    let register_info = imports.get("optobus_device::RegisterInfo");
    let word_array = imports.get("optobus_driver::word_array");
    // Versions compare field by field, major first.
    let declaration = plain_struct(
        quote!(#[doc = #doc]),
        ident,
        Order::Ordered,
        &fields,
        field_docs,
        fields.iter().map(|_| quote!(u8)),
    );
    quote! {
        #declaration

        impl #ident {
            /// Reads the version from its two words.
            pub const fn from_words(words: [u16; 2]) -> Self {
                let bytes = [
                    (words[0] >> 8) as u8,
                    words[0] as u8,
                    (words[1] >> 8) as u8,
                    words[1] as u8,
                ];
                Self { #(#fields: bytes[#indexes],)* }
            }
        }

        impl #decode for #ident {
            fn decode(_register: &#register_info, words: &[u16]) -> Self {
                Self::from_words(#word_array(words))
            }
        }

        impl #fmt::Display for #ident {
            fn fmt(&self, f: &mut #fmt::Formatter<'_>) -> #fmt::Result {
                write!(f, #format, #(self.#fields),*)
            }
        }
    }
}

fn record_struct(ident: &Ident, doc: &str, fields: &[Field], imports: &Imports) -> TokenStream {
    let field_names: Vec<Ident> = fields.iter().map(|f| format_ident!("{}", f.name)).collect();
    let mut offset = 0usize;
    let mut types = Vec::new();
    let mut reads = Vec::new();
    let mut docs = Vec::new();
    for field in fields {
        let scalar = field.scalar.unwrap_or(Scalar::U16);
        let unit = field
            .unit
            .as_deref()
            .map(|u| format!(" Unit: {u}."))
            .unwrap_or_default();
        let scale = field
            .scale
            .as_ref()
            .map(|s| format!(" Raw steps of {}.", s.text))
            .unwrap_or_default();
        let invalid = field
            .sentinel
            .map(|s| format!(" {s:#X} means invalid."))
            .unwrap_or_default();
        docs.push(format!(
            "{}{scale}{unit}{invalid}",
            doc_text(field.doc.as_deref())
        ));
        let (at, next) = (lit(offset as u64), lit(offset as u64 + 1));
        let (ty, read) = match scalar {
            Scalar::U16 => (quote!(u16), quote!(words[#at])),
            Scalar::I16 => (quote!(i16), quote!(words[#at] as i16)),
            Scalar::U32 => (
                quote!(u32),
                quote!(((words[#at] as u32) << 16) | words[#next] as u32),
            ),
            Scalar::I32 => (
                quote!(i32),
                quote!((((words[#at] as u32) << 16) | words[#next] as u32) as i32),
            ),
        };
        offset += scalar.words() as usize;
        types.push(ty);
        reads.push(read);
    }
    let words = lit(offset as u64);
    let decode = imports.get("optobus_driver::Decode");
    let register_info = imports.get("optobus_device::RegisterInfo");
    let word_array = imports.get("optobus_driver::word_array");
    let doc = quote! {
        #[doc = #doc]
        ///
        /// Raw register values; the driver applies scales and sentinels.
    };
    let declaration = plain_struct(doc, ident, Order::Unordered, &field_names, docs, types);
    quote! {
        #declaration

        impl #ident {
            /// Number of words the record takes.
            pub const WORDS: usize = #words;

            /// Reads the record from its words.
            pub const fn from_words(words: &[u16; #words]) -> Self {
                Self { #(#field_names: #reads,)* }
            }
        }

        impl #decode for #ident {
            fn decode(_register: &#register_info, words: &[u16]) -> Self {
                Self::from_words(&#word_array(words))
            }
        }
    }
}
