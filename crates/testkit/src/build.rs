//! For build scripts: which peer programs are installed, as cfgs the tests are built with.
//!
//! ```no_run
//! // build.rs of a crate whose tests start mosquitto
//! use optobus_testkit::build::{peers, MOSQUITTO};
//! fn main() {
//!     peers(&[MOSQUITTO]);
//! }
//! ```

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::REQUIRE_PEERS;

/// A program (or Python module) some tests talk to.
#[derive(Debug, Clone, Copy)]
pub struct Peer {
    /// The cfg set when it is installed (`peer_mosquitto`).
    pub cfg: &'static str,
    /// The program: a name searched in `PATH`, or an absolute path.
    pub program: &'static str,
    /// A module `program` (a Python) must import, if the peer is one.
    pub python_module: Option<&'static str>,
    /// What it is called in the reason, and where it comes from.
    pub name: &'static str,
    /// How to install it (Debian package, or pip).
    pub package: &'static str,
}

impl Peer {
    const fn program(cfg: &'static str, program: &'static str, package: &'static str) -> Self {
        Peer {
            cfg,
            program,
            python_module: None,
            name: program,
            package,
        }
    }

    /// Why its tests are ignored: the text their `ignore` attribute carries.
    pub fn reason(&self) -> String {
        format!("{} is not installed ({})", self.name, self.package)
    }

    /// Where it is installed, searched in `path` (the value of `PATH`); when it is not, the
    /// folders where installing it would change something, for cargo to watch.
    fn find(&self, path: &OsStr) -> Result<PathBuf, Vec<PathBuf>> {
        let program = find_program(self.program, path)?;
        let Some(module) = self.python_module else {
            return Ok(program);
        };
        // Where the module is; or where pip would put it, with exit code 1.
        let script = format!(
            "import importlib.util, site, sys\n\
             spec = importlib.util.find_spec({module:?})\n\
             if spec and spec.origin:\n    print(spec.origin); sys.exit(0)\n\
             print('\\n'.join(site.getsitepackages() + [site.getusersitepackages()]))\n\
             sys.exit(1)\n"
        );
        let Ok(output) = Command::new(&program).args(["-c", &script]).output() else {
            return Err(Vec::new());
        };
        let lines = String::from_utf8_lossy(&output.stdout);
        let mut paths = lines.lines().map(PathBuf::from);
        if output.status.success() {
            paths.next().ok_or_else(Vec::new)
        } else {
            Err(paths.filter(|dir| dir.is_dir()).collect())
        }
    }
}

/// mbpoll (libmodbus's command-line client).
pub const MBPOLL: Peer = Peer::program("peer_mbpoll", "mbpoll", "Debian package mbpoll");
/// socat, for pseudo-terminal pairs.
pub const SOCAT: Peer = Peer::program("peer_socat", "socat", "Debian package socat");
/// The mosquitto MQTT broker.
pub const MOSQUITTO: Peer =
    Peer::program("peer_mosquitto", "mosquitto", "Debian package mosquitto");
/// mosquitto's publishing client.
pub const MOSQUITTO_PUB: Peer = Peer::program(
    "peer_mosquitto_pub",
    "mosquitto_pub",
    "Debian package mosquitto-clients",
);
/// The openssl tool, for test certificates.
pub const OPENSSL: Peer = Peer::program("peer_openssl", "openssl", "Debian package openssl");
/// Prometheus's promtool.
pub const PROMTOOL: Peer = Peer::program("peer_promtool", "promtool", "Debian package prometheus");
/// Headless Chromium, where the console's browser test starts it.
pub const CHROMIUM: Peer = Peer::program(
    "peer_chromium",
    "/usr/bin/chromium",
    "Debian package chromium",
);
/// chromedriver, driving Chromium.
pub const CHROMEDRIVER: Peer = Peer::program(
    "peer_chromedriver",
    "chromedriver",
    "Debian package chromium-driver",
);
/// pymodbus, a Modbus client in Python 3.
pub const PYMODBUS: Peer = Peer {
    cfg: "peer_pymodbus",
    program: "python3",
    python_module: Some("pymodbus"),
    name: "pymodbus (python3)",
    package: "pip install pymodbus, or Debian package python3-pymodbus",
};

/// Jinja2, the template engine Home Assistant renders a discovery's `value_template` with.
pub const JINJA2: Peer = Peer {
    cfg: "peer_jinja2",
    program: "python3",
    python_module: Some("jinja2"),
    name: "Jinja2 (python3)",
    package: "pip install jinja2, or Debian package python3-jinja2",
};

/// `program`'s path: itself if it has a folder, else the first executable of that name in a
/// folder of `path`; else the folders to watch (those of `path`, or `program`'s own).
fn find_program(program: &str, path: &OsStr) -> Result<PathBuf, Vec<PathBuf>> {
    let program = Path::new(program);
    if program.components().count() > 1 {
        return if is_executable(program) {
            Ok(program.to_path_buf())
        } else {
            Err(program
                .parent()
                .map(Path::to_path_buf)
                .into_iter()
                .collect())
        };
    }
    let folders: Vec<PathBuf> = std::env::split_paths(path)
        .filter(|dir| dir.is_dir())
        .collect();
    folders
        .iter()
        .map(|dir| dir.join(program))
        .find(|candidate| is_executable(candidate))
        .ok_or(folders)
}

fn is_executable(path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        path.metadata()
            .is_ok_and(|meta| meta.is_file() && meta.permissions().mode() & 0o111 != 0)
    }
    #[cfg(not(unix))]
    {
        path.is_file()
    }
}

/// The build script lines for `peers` with `PATH` = `path`: for each, the declared cfg, and
/// the cfg set when it is found; what cargo watches to run the script again (`PATH`, the
/// peer found, or the folders it would be installed in); and under [`REQUIRE_PEERS`]
/// (`required`), an error for each missing peer.
pub fn directives(peers: &[Peer], path: &OsStr, required: bool) -> Vec<String> {
    let mut lines = vec![
        "cargo::rerun-if-env-changed=PATH".to_owned(),
        format!("cargo::rerun-if-env-changed={REQUIRE_PEERS}"),
    ];
    for peer in peers {
        lines.push(format!("cargo::rustc-check-cfg=cfg({})", peer.cfg));
        match peer.find(path) {
            Ok(found) => {
                lines.push(format!("cargo::rerun-if-changed={}", found.display()));
                lines.push(format!("cargo::rustc-cfg={}", peer.cfg));
            }
            Err(watched) => {
                for folder in watched {
                    lines.push(format!("cargo::rerun-if-changed={}", folder.display()));
                }
                // No warning otherwise: `cargo install` builds this script too, and the
                // ignored tests say why themselves.
                if required {
                    lines.push(format!(
                        "cargo::error={}, and {REQUIRE_PEERS} is set: the tests that need it \
                         must run",
                        peer.reason()
                    ));
                }
            }
        }
    }
    lines
}

/// Called from a build script: sets `peer_<name>` for each of `peers` installed (see
/// [`directives`]), reading `PATH` and [`REQUIRE_PEERS`].
pub fn peers(peers: &[Peer]) {
    let path = std::env::var_os("PATH").unwrap_or_default();
    let required = std::env::var_os(REQUIRE_PEERS).is_some();
    for line in directives(peers, &path, required) {
        println!("{line}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A folder holding an executable `name`.
    fn folder_with(name: &str) -> PathBuf {
        let dir =
            std::env::temp_dir().join(format!("optobus-testkit-{}-{name}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let program = dir.join(name);
        std::fs::write(&program, "#!/bin/sh\n").unwrap();
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            std::fs::set_permissions(&program, std::fs::Permissions::from_mode(0o755)).unwrap();
        }
        dir
    }

    const FAKE: Peer = Peer::program("peer_fake", "optobus-fake-peer", "Debian package fake");

    #[test]
    fn a_peer_missing_from_path_makes_its_tests_ignored_with_the_reason() {
        let with = folder_with("optobus-fake-peer");
        let without = std::env::temp_dir();
        let found = directives(&[FAKE], with.as_os_str(), false);
        assert!(
            found.contains(&"cargo::rustc-cfg=peer_fake".to_owned()),
            "{found:?}"
        );
        assert!(found.contains(&"cargo::rustc-check-cfg=cfg(peer_fake)".to_owned()));
        let program = with.join("optobus-fake-peer");
        assert!(found.contains(&format!("cargo::rerun-if-changed={}", program.display())));
        let missing = directives(&[FAKE], without.as_os_str(), false);
        assert!(
            !missing
                .iter()
                .any(|line| line.starts_with("cargo::rustc-cfg")),
            "{missing:?}"
        );
        assert!(missing.contains(&"cargo::rustc-check-cfg=cfg(peer_fake)".to_owned()));
        assert!(missing.contains(&format!("cargo::rerun-if-changed={}", without.display())));
        assert!(!missing.iter().any(|line| line.starts_with("cargo::error")));
        assert!(missing.contains(&"cargo::rerun-if-env-changed=PATH".to_owned()));
        std::fs::remove_dir_all(with).unwrap();
    }

    #[test]
    fn a_peer_missing_under_require_interop_fails_the_build() {
        let missing = directives(&[FAKE], std::env::temp_dir().as_os_str(), true);
        assert!(missing.contains(
            &"cargo::error=optobus-fake-peer is not installed (Debian package fake), and \
              OPTOBUS_REQUIRE_INTEROP is set: the tests that need it must run"
                .to_owned()
        ));
        assert!(!missing
            .iter()
            .any(|line| line.starts_with("cargo::rustc-cfg")));
    }

    #[test]
    fn a_python_module_is_found_only_where_python_imports_it() {
        let path = std::env::var_os("PATH").unwrap_or_default();
        let absent = Peer {
            python_module: Some("optobus_no_such_module"),
            ..PYMODBUS
        };
        let Ok(_) = find_program("python3", &path) else {
            return assert!(absent.find(&path).is_err());
        };
        // Not found, with the folders pip installs into to watch.
        assert!(absent.find(&path).is_err_and(|watched| !watched.is_empty()));
        let standard = Peer {
            python_module: Some("json"),
            ..PYMODBUS
        };
        let found = standard.find(&path).expect("python3 imports json");
        assert!(found.ends_with("json/__init__.py"), "{found:?}");
    }
}
