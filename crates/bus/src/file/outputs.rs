//! The `outputs` of a bus file: where a running bus sends what it reads, besides its events.
//! The bus runs none of them: it checks that `outputs` is a mapping of named sections and
//! hands the sections, located, to whoever reads them (each output's crate reads its own with
//! the file's [reading kit](super::reading), as the file is read, so that its problems are
//! reported with the rest of the file's).

use optobus_spec::source::{Node, Span};

use super::reading::{FileReader, Reader};

/// The sections of a bus file's `outputs`, as written, for the outputs' readers.
#[derive(Clone, Copy, Debug)]
pub struct Outputs<'n> {
    /// Each section's key and value, in file order.
    sections: &'n [(Node, Node)],
    /// The name of every device whose name reads, with where it is written.
    devices: &'n [(&'n str, Span)],
}

impl<'n> Outputs<'n> {
    /// The key and the value of section `name`, if the file gives it (the first, if twice).
    pub fn section(&self, name: &str) -> Option<(&'n Node, &'n Node)> {
        self.sections
            .iter()
            .find(|(key, _)| key.scalar() == Some(name))
            .map(|(key, value)| (key, value))
    }

    /// The name of every device whose name reads, with where it is written (an output that
    /// names devices checks its names against them, or the names against its own rules).
    pub fn devices(&self) -> &'n [(&'n str, Span)] {
        self.devices
    }
}

/// What reads the sections of `outputs` as a bus file is read
/// ([`BusFile::parse_with`](super::BusFile::parse_with)).
pub trait ReadOutputs {
    /// The sections it reads, in the order a message lists them: any other is reported.
    fn sections(&self) -> &[&str];

    /// Reads the sections of `outputs` (all empty when the file has none), each problem
    /// reported on `reader`.
    fn read(&mut self, outputs: &Outputs<'_>, reader: &mut Reader<'_>);
}

/// An output's settings, read from its section of `outputs` with the file's kit.
pub trait OutputSettings: Sized {
    /// The section's name (`mqtt`).
    const SECTION: &'static str;

    /// The settings the section gives, if the file has it; `None` (each problem reported on
    /// `reader`) if they do not read.
    fn read(outputs: &Outputs<'_>, reader: &mut Reader<'_>) -> Option<Self>;
}

/// One output's settings alone (for a program that runs one output, or its tests): the file
/// may have no other section.
impl<T: OutputSettings> ReadOutputs for Option<T> {
    fn sections(&self) -> &[&str] {
        const { &[T::SECTION] }
    }

    fn read(&mut self, outputs: &Outputs<'_>, reader: &mut Reader<'_>) {
        *self = T::read(outputs, reader);
    }
}

impl FileReader<'_> {
    /// `outputs:` (`None` where the file has none): its shape checked, its sections handed to
    /// `read` (every section name taken when there is no reader).
    pub(in crate::file) fn outputs(
        &mut self,
        node: Option<&Node>,
        devices: &[(&str, Span)],
        read: Option<&mut dyn ReadOutputs>,
    ) {
        let sections = match (node, &read) {
            (None, _) => &[][..],
            (Some(node), Some(read)) => self
                .mapping(node, "`outputs`", read.sections())
                .unwrap_or_default(),
            (Some(node), None) => match node.entries() {
                Some(entries) => entries,
                None => {
                    self.mapping(node, "`outputs`", &[]);
                    &[][..]
                }
            },
        };
        if let Some(read) = read {
            read.read(&Outputs { sections, devices }, &mut self.kit);
        }
    }
}
