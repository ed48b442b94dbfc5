//! A pseudo-terminal speaking RTU, so that tools that open serial ports (mbpoll, a driver's
//! serial transport) can talk to the simulator.

use std::ffi::OsStr;
use std::io;
use std::os::unix::ffi::OsStrExt;
use std::path::{Path, PathBuf};

use rustix::termios::{tcgetattr, tcsetattr, ttyname, OptionalActions};
use tokio::task::JoinHandle;

use crate::line::Line;
use crate::rtu::Slaves;
use crate::sim::Simulator;

/// A pseudo-terminal served on a spawned task; dropping it stops serving.
pub struct Pty {
    path: PathBuf,
    task: JoinHandle<io::Result<()>>,
    /// Kept open so that the master side does not see a hang-up between clients.
    _terminal: pty_process::Pts,
}

impl Pty {
    /// The terminal device other programs open (e.g. `/dev/pts/3`).
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl std::fmt::Debug for Pty {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pty").field("path", &self.path).finish()
    }
}

impl Drop for Pty {
    fn drop(&mut self) {
        self.task.abort();
    }
}

impl Slaves {
    /// Serves the line on a new pseudo-terminal in raw mode; needs a tokio runtime.
    pub fn serve_pty(&self) -> io::Result<Pty> {
        self.open_pty(None)
    }

    /// Serves the line on a new pseudo-terminal in raw mode, timed as `line` (see
    /// [`Slaves::serve_line`]); needs a tokio runtime. The pty itself adds no timing of its own
    /// beyond the kernel's latency, so bytes reach the client no earlier than `line` says.
    pub fn serve_pty_line(&self, line: Line) -> io::Result<Pty> {
        self.open_pty(Some(line))
    }

    fn open_pty(&self, line: Option<Line>) -> io::Result<Pty> {
        let (master, terminal) = pty_process::open().map_err(io::Error::other)?;
        // Raw mode: no echo, no line editing, no CR/LF translation of binary frames.
        let mut termios = tcgetattr(&terminal)?;
        termios.make_raw();
        tcsetattr(&terminal, OptionalActions::Now, &termios)?;
        let name = ttyname(&terminal, Vec::new())?;
        let path = PathBuf::from(OsStr::from_bytes(name.as_bytes()));
        let slaves = self.clone();
        let task = tokio::spawn(async move {
            match line {
                Some(line) => slaves.serve_line(master, &line).await,
                None => slaves.serve(master).await,
            }
        });
        Ok(Pty {
            path,
            task,
            _terminal: terminal,
        })
    }
}

impl Simulator {
    /// Serves this device on a new pseudo-terminal; see [`Slaves::serve_pty`].
    pub fn serve_pty(&self) -> io::Result<Pty> {
        Slaves::new([self.clone()]).serve_pty()
    }

    /// Serves this device on a new pseudo-terminal timed as `line`; see
    /// [`Slaves::serve_pty_line`].
    pub fn serve_pty_line(&self, line: Line) -> io::Result<Pty> {
        Slaves::new([self.clone()]).serve_pty_line(line)
    }
}
