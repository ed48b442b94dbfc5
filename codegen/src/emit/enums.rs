//! A Rust enum per code table of the spec: one variant per code, `Unknown(raw)` for the rest.
//!
//! Only what differs per enum is emitted: the variants, the code table as data and the two
//! `const` matches between variants and codes. Reading, writing (with its checks), names and
//! `Display` come from `optobus_driver::{RawValue, CodeEnum}`.

use proc_macro2::{Ident, Span, TokenStream};
use quote::quote;

use super::names::Imports;
use super::{camel, doc_text, exact, lit};
use optobus_spec::model::{Code, EnumDef};

/// The variant of each code, in order.
pub(super) fn variant_idents(def: &EnumDef) -> Vec<Ident> {
    def.codes
        .iter()
        .map(|code| {
            let mut name = camel(&code.name);
            if name == "Unknown" {
                name.push_str("Code");
            }
            Ident::new(&name, Span::call_site())
        })
        .collect()
}

fn code_doc(code: &Code) -> String {
    let meaning = code
        .meaning
        .as_deref()
        .map(|m| format!(" Manual: “{m}”."))
        .unwrap_or_default();
    format!(
        "{} (code {}).{meaning}",
        doc_text(code.doc.as_deref()).trim_end_matches('.'),
        code.code
    )
}

fn code_value(code: &Code) -> TokenStream {
    exact::<u32, _>(code.code, "enum code")
}

/// The table of codes that ends the enum's documentation.
fn code_table(def: &EnumDef) -> Vec<String> {
    let rows = def.codes.iter().map(|c| {
        format!(
            "| {} | `{}` | {} |",
            c.code,
            c.name,
            c.meaning.as_deref().unwrap_or("").replace('|', "/")
        )
    });
    [
        "| code | name | manual |".to_owned(),
        "|---|---|---|".to_owned(),
    ]
    .into_iter()
    .chain(rows)
    .collect()
}

pub(super) fn enum_type(def: &EnumDef, ident: &Ident, imports: &Imports) -> TokenStream {
    let variants = variant_idents(def);
    let docs = def.codes.iter().map(code_doc);
    let raws: Vec<TokenStream> = def.codes.iter().map(code_value).collect();
    let names = def.codes.iter().map(|c| c.name.as_str());
    let meanings = def.codes.iter().map(|c| c.meaning.as_deref().unwrap_or(""));
    let code_docs = def.codes.iter().map(|c| doc_text(c.doc.as_deref()));
    let count = lit(def.codes.len() as u64);
    let doc = doc_text(def.doc.as_deref());
    let table = code_table(def);
    let raw_value = imports.trait_("optobus_driver::RawValue");
    let code_enum = imports.trait_("optobus_driver::CodeEnum");
    let code_info = imports.get("optobus_device::CodeInfo");
    let fmt = imports.get("core::fmt");
    let option = imports.prelude("core::option::Option");
    quote! {
        #[doc = #doc]
        ///
        #(#[doc = #table])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum #ident {
            #(
                #[doc = #docs]
                #variants,
            )*
            /// A raw value the manual does not define.
            Unknown(u32),
        }

        impl #ident {
            /// Every defined value, in the manual's order.
            pub const ALL: [Self; #count] = [#(Self::#variants),*];

            /// The value for a raw code; undefined codes give `Unknown(raw)`.
            pub const fn from_raw(raw: u32) -> Self {
                match raw {
                    #(#raws => Self::#variants,)*
                    other => Self::Unknown(other),
                }
            }

            /// The raw code.
            pub const fn raw(self) -> u32 {
                match self {
                    #(Self::#variants => #raws,)*
                    Self::Unknown(raw) => raw,
                }
            }
        }

        impl #raw_value for #ident {
            fn from_raw(raw: u32) -> Self {
                Self::from_raw(raw)
            }

            fn to_raw(self) -> #option<u32> {
                Some(self.raw())
            }
        }

        impl #code_enum for #ident {
            const CODES: &'static [#code_info] = &[
                #(#code_info {
                    code: #raws,
                    name: #names,
                    meaning: #meanings,
                    doc: #code_docs,
                }),*
            ];
        }

        impl #fmt::Display for #ident {
            fn fmt(&self, f: &mut #fmt::Formatter<'_>) -> #fmt::Result {
                self.write_name(f)
            }
        }

        /// `{"code": 0, "name": "…"}`, as `optobus --json` prints codes.
        #[cfg(feature = "serde")]
        impl serde::Serialize for #ident {
            fn serialize<S: serde::Serializer>(&self, serializer: S) -> ::core::result::Result<S::Ok, S::Error> {
                optobus_driver::code_serde::serialize(self, serializer)
            }
        }

        /// The code, or the name alone; a contradiction between them is refused.
        #[cfg(feature = "serde")]
        impl<'de> serde::Deserialize<'de> for #ident {
            fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> ::core::result::Result<Self, D::Error> {
                optobus_driver::code_serde::deserialize(deserializer)
            }
        }
    }
}
