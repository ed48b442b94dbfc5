//! Reading a file within a limit: every file of the project (specs, bus files, recordings)
//! is read through [`open_limited`], so that no input can grow the process without bound.

use std::fmt;
use std::io::{self, Read};

/// The most bytes a YAML file read by this crate (a spec, and the bus files to come) may
/// hold: 16 MiB. The largest spec in `specs/` has 42 kB; a generated spec of 100,000
/// registers has 15 MB. The densest file (16 MiB of one-character scalars) makes a tree of
/// under a gigabyte; a spec is checked in some twenty times its size.
pub const YAML_LIMIT: u64 = 16 * 1024 * 1024;

/// Why a file could not be read within its limit.
#[derive(Debug)]
pub enum ReadError {
    /// The system refused (no such file, no permission, …).
    Io(io::Error),
    /// A device, directory or socket: only regular files (and pipes, on Unix) are read.
    NotAFile,
    /// More bytes than the limit.
    TooLarge {
        /// The limit, in bytes.
        limit: u64,
    },
    /// Bytes that are not UTF-8 text.
    NotText {
        /// Where the first bad byte is.
        offset: usize,
    },
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Io(error) => write!(f, "{error}"),
            Self::NotAFile => f.write_str("not a regular file (a device, directory or socket)"),
            Self::TooLarge { limit } => {
                write!(f, "larger than the limit of {}", size_text(*limit))
            }
            Self::NotText { offset } => write!(f, "not UTF-8 text (byte {offset})"),
        }
    }
}

impl std::error::Error for ReadError {}

/// A byte count as people read it: `16 MiB`, `512 KiB`, `100 bytes`.
pub fn size_text(bytes: u64) -> String {
    const UNITS: [(u64, &str); 3] = [(1 << 30, "GiB"), (1 << 20, "MiB"), (1 << 10, "KiB")];
    UNITS
        .iter()
        .find(|(unit, _)| bytes >= *unit && bytes.is_multiple_of(*unit))
        .map_or_else(
            || format!("{bytes} bytes"),
            |(unit, name)| format!("{} {name}", bytes / unit),
        )
}

/// A file opened by [`open_limited`]: reading past its limit fails with
/// [`io::ErrorKind::FileTooLarge`].
#[derive(Debug)]
pub struct Limited {
    file: io::Take<std::fs::File>,
    limit: u64,
    read: u64,
}

impl Read for Limited {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let count = self.file.read(buf)?;
        self.read += count as u64;
        if self.read > self.limit {
            return Err(io::Error::new(
                io::ErrorKind::FileTooLarge,
                ReadError::TooLarge { limit: self.limit },
            ));
        }
        Ok(count)
    }
}

/// Opens `path` to read at most `limit` bytes. A regular file larger than that is refused at
/// once; a pipe is read up to one byte past the limit; devices (`/dev/zero`), directories and
/// sockets are refused.
pub fn open_limited(path: &std::path::Path, limit: u64) -> Result<Limited, ReadError> {
    let file = std::fs::File::open(path).map_err(ReadError::Io)?;
    let kind = file.metadata().map_err(ReadError::Io)?;
    #[cfg(unix)]
    let pipe = std::os::unix::fs::FileTypeExt::is_fifo(&kind.file_type());
    #[cfg(not(unix))]
    let pipe = false;
    if !kind.is_file() && !pipe {
        return Err(ReadError::NotAFile);
    }
    if kind.len() > limit {
        return Err(ReadError::TooLarge { limit });
    }
    Ok(Limited {
        file: file.take(limit.saturating_add(1)),
        limit,
        read: 0,
    })
}

/// The bytes of `path`, at most `limit` of them (see [`open_limited`]).
pub fn read_limited(path: &std::path::Path, limit: u64) -> Result<Vec<u8>, ReadError> {
    let mut file = open_limited(path, limit)?;
    let mut bytes = Vec::new();
    match file.read_to_end(&mut bytes) {
        Ok(_) => Ok(bytes),
        Err(error) if error.kind() == io::ErrorKind::FileTooLarge => {
            Err(ReadError::TooLarge { limit })
        }
        Err(error) => Err(ReadError::Io(error)),
    }
}

/// The text of a YAML file: at most [`YAML_LIMIT`] bytes of UTF-8.
pub fn read_yaml(path: &std::path::Path) -> Result<String, ReadError> {
    String::from_utf8(read_limited(path, YAML_LIMIT)?).map_err(|error| ReadError::NotText {
        offset: error.utf8_error().valid_up_to(),
    })
}
