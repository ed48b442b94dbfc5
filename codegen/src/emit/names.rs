//! Names in the generated file: the Rust types it declares (made unique), and the runtime
//! items it imports.
//!
//! Every runtime item is reached through [`Imports`]: used once, it is imported by its last
//! name in the `use` block at the top of the file; when a generated type takes that name (the
//! LC-RS spec has its own `Parity` enum), it is written with its full path instead, so an
//! import never clashes with a generated name.

use std::cell::RefCell;
use std::collections::{BTreeMap, BTreeSet, HashSet};

use proc_macro2::{Ident, Span, TokenStream};
use quote::quote;

use super::{camel, type_ident};
use optobus_spec::model::{Kind, Model, Register};

/// Rust type names for enums, value structs, repeat indexes, group structs and the driver,
/// made unique.
pub(super) struct TypeNames {
    /// One per `Model::enums` entry.
    pub(super) enums: Vec<Ident>,
    /// One per `Model::groups` entry: the struct its `read_…` method returns.
    pub(super) groups: Vec<Ident>,
    /// The driver type (`PSeries`).
    pub(super) driver: Ident,
    /// Repeat indexes, enums and the driver: value structs take another name than these.
    before_structs: HashSet<String>,
    /// Every type name the file declares.
    taken: HashSet<String>,
}

impl TypeNames {
    pub(super) fn new(model: &Model) -> Self {
        let driver = type_ident(&model.family);
        let mut taken: HashSet<String> = model.repeats.iter().map(|r| camel(&r.name)).collect();
        taken.insert(driver.to_string());
        // Shared enums first: they keep their plain names.
        let mut order: Vec<usize> = (0..model.enums.len()).collect();
        order.sort_by_key(|&i| !model.enums[i].shared);
        let mut by_index = vec![None; model.enums.len()];
        for i in order {
            let mut name = camel(&model.enums[i].name);
            if taken.contains(&name) {
                name.push_str("Code");
            }
            taken.insert(name.clone());
            by_index[i] = Some(Ident::new(&name, Span::call_site()));
        }
        let mut names = Self {
            enums: by_index.into_iter().flatten().collect(),
            groups: Vec::new(),
            driver,
            before_structs: taken.clone(),
            taken,
        };
        let structs: Vec<String> = model
            .registers
            .iter()
            .filter(|r| r.repeat.as_ref().is_none_or(|c| c.number == 1))
            .filter(|r| matches!(r.kind, Kind::Packed(_) | Kind::Version(_) | Kind::Record(_)))
            .map(|r| names.struct_name(r).to_string())
            .collect();
        names.taken.extend(structs);
        for group in &model.groups {
            let mut name = camel(&group.name);
            while names.taken.contains(&name) {
                name.push_str("Values");
            }
            names.taken.insert(name.clone());
            names.groups.push(Ident::new(&name, Span::call_site()));
        }
        names
    }

    /// The struct of a packed, version or record register (one for all copies of a repeat
    /// member).
    pub(super) fn struct_name(&self, register: &Register) -> Ident {
        let base = register
            .repeat
            .as_ref()
            .map_or(register.name.as_str(), |c| c.base.as_str());
        let mut name = camel(base);
        if self.before_structs.contains(&name) {
            name.push_str("Value");
        }
        Ident::new(&name, Span::call_site())
    }
}

/// What a driver crate re-exports from the runtime beside its generated items: the error, the
/// transports and the helpers that open them, the unit and number types its methods take and
/// return, the core its `core()` hands out. The generated file is the crate root, so it says
/// so itself, and documents them in place (`#[doc(inline)]`): one crate's docs are enough to
/// use it.
const REEXPORTS: [&str; 9] = [
    "optobus_driver::rtu_config",
    "optobus_driver::serial_settings",
    "optobus_driver::transport",
    "optobus_driver::units",
    "optobus_driver::CodeEnum",
    "optobus_driver::Core",
    "optobus_driver::Error",
    "optobus_driver::Fixed",
    "optobus_driver::Transport",
];

/// The runtime items the generated code uses, for its `use` block.
pub(super) struct Imports {
    declared: HashSet<String>,
    /// (module path, name, imported anonymously as `_`).
    used: RefCell<BTreeSet<(&'static str, &'static str, bool)>>,
}

impl Imports {
    pub(super) fn new(names: &TypeNames) -> Self {
        Self {
            declared: names.taken.clone(),
            used: RefCell::new(BTreeSet::new()),
        }
    }

    /// The item at `path` (`"optobus_device::RegisterInfo"`): its last name, imported once,
    /// or its full path where a generated type has that name.
    pub(super) fn get(&self, path: &'static str) -> TokenStream {
        let (module, name) = split(path);
        if self.declared.contains(name) {
            return path_tokens(path);
        }
        self.used.borrow_mut().insert((module, name, false));
        path_tokens(name)
    }

    /// A trait at `path`: like [`Imports::get`], and in scope for its methods and constants
    /// either way (imported as `_` where a generated type has its name).
    pub(super) fn trait_(&self, path: &'static str) -> TokenStream {
        let (module, name) = split(path);
        if self.declared.contains(name) {
            self.used.borrow_mut().insert((module, name, true));
            return path_tokens(path);
        }
        self.get(path)
    }

    /// A name of the standard prelude (`Option`, `Result`): as is, or by `path` where a
    /// generated type shadows it.
    pub(super) fn prelude(&self, path: &'static str) -> TokenStream {
        let (_, name) = split(path);
        if self.declared.contains(name) {
            path_tokens(path)
        } else {
            path_tokens(name)
        }
    }

    /// `Result<ok, Error>`, the return type of every driver method.
    pub(super) fn result(&self, ok: TokenStream) -> TokenStream {
        let result = self.prelude("core::result::Result");
        let error = self.get("optobus_driver::Error");
        quote!(#result<#ok, #error>)
    }

    /// The `use` block: the standard library first, then the optobus crates, one `use` per
    /// module, ordered as rustfmt orders them; last the crate's public re-exports of the
    /// runtime ([`REEXPORTS`], but for names the file declares itself), which also bring those
    /// items into scope.
    pub(super) fn use_block(&self) -> String {
        let reexports: Vec<(&str, &str)> = REEXPORTS
            .into_iter()
            .map(split)
            .filter(|(_, name)| !self.declared.contains(*name))
            .collect();
        let mut modules: BTreeMap<&str, Vec<String>> = BTreeMap::new();
        for &(module, name, anonymous) in self.used.borrow().iter() {
            if !anonymous && reexports.contains(&(module, name)) {
                continue;
            }
            let item = if anonymous {
                format!("{name} as _")
            } else {
                name.to_owned()
            };
            modules.entry(module).or_default().push(item);
        }
        let mut std = Vec::new();
        let mut ours = Vec::new();
        for (module, mut items) in modules {
            sort_items(&mut items);
            let line = use_line("use", module, &items);
            if module.starts_with("core") || module.starts_with("std") {
                std.push(line);
            } else {
                ours.push(line);
            }
        }
        std.sort();
        ours.sort();
        let mut public: BTreeMap<&str, Vec<String>> = BTreeMap::new();
        for (module, name) in reexports {
            public.entry(module).or_default().push(name.to_owned());
        }
        let public = public
            .into_iter()
            .map(|(module, mut items)| {
                sort_items(&mut items);
                use_line("#[doc(inline)]\npub use", module, &items)
            })
            .collect();
        [std, ours, public]
            .into_iter()
            .filter(|lines| !lines.is_empty())
            .map(|lines| {
                let text = lines.join("\n");
                // Long lines wrapped as rustfmt would.
                #[cfg(feature = "pretty")]
                let text = syn::parse_file(&text).map_or(text, |file| prettyplease::unparse(&file));
                text
            })
            .collect::<Vec<_>>()
            .join("\n")
    }
}

/// Functions and modules before types, as rustfmt sorts them.
fn sort_items(items: &mut [String]) {
    items.sort_by_key(|item| (item.starts_with(char::is_uppercase), item.clone()));
}

/// `use module::item;` or `use module::{a, B};` (`keyword` is `use` or `pub use`).
fn use_line(keyword: &str, module: &str, items: &[String]) -> String {
    match items {
        [item] => format!("{keyword} {module}::{item};"),
        _ => format!("{keyword} {module}::{{{}}};", items.join(", ")),
    }
}

/// `(module path, last name)` of `a::b::C`.
fn split(path: &'static str) -> (&'static str, &'static str) {
    path.rsplit_once("::").unwrap_or(("", path))
}

fn path_tokens(path: &str) -> TokenStream {
    let segments = path.split("::").map(|s| Ident::new(s, Span::call_site()));
    quote!(#(#segments)::*)
}
