//! Build-time probes for the optional dependencies of synthgen's tests.
//!
//! A test that needs something the workspace does not build (headless Chromium, python3 with
//! scipy, the bpy venv, `../shared/data`) is marked
//! `#[cfg_attr(not(has_chromium), ignore = "needs chromium …")]`, and the crate's build script
//! calls [`emit`]: what is present sets its `cfg`, what is absent leaves the test ignored, so
//! `cargo test` lists it as ignored with the reason instead of counting a skip as a pass.
//! `SYNTHGEN_REQUIRE_<NAME>=1` (or `SYNTHGEN_REQUIRE_ALL=1`, as CI sets) sets the `cfg`
//! without looking: the test then runs and a missing dependency fails it.
//!
//! ```no_run
//! // build.rs
//! use synthgen_probe::Check;
//! synthgen_probe::emit(&[Check::SharedData, Check::PythonModules("scipy", &["scipy.io", "numpy"])]);
//! ```

use std::path::{Path, PathBuf};
use std::process::Command;

/// One optional dependency, probed when the crate is built.
#[derive(Debug, Clone, Copy)]
pub enum Check {
    /// `../shared/data` beside the checkout: `cfg(has_shared_data)`, `SYNTHGEN_REQUIRE_SHARED`.
    SharedData,
    /// A python3 on PATH: `cfg(has_python3)`, `SYNTHGEN_REQUIRE_PYTHON3`.
    Python3,
    /// python3 that imports every module: `cfg(has_<name>)`, `SYNTHGEN_REQUIRE_<NAME>`.
    PythonModules(&'static str, &'static [&'static str]),
    /// Every program on PATH (each given as alternatives): `cfg(has_<name>)`,
    /// `SYNTHGEN_REQUIRE_<NAME>`.
    Programs(&'static str, &'static [&'static [&'static str]]),
    /// The bpy venv of the Blender backend (`SYNTHGEN_BLENDER_VENV`, else
    /// `$XDG_CACHE_HOME/synthgen/blender-venv`): `cfg(has_bpy)`, `SYNTHGEN_REQUIRE_BLENDER`.
    Bpy,
    /// Mounting a tmpfs (CAP_SYS_ADMIN: root, and a sandbox that allows it): `cfg(has_tmpfs)`,
    /// `SYNTHGEN_REQUIRE_TMPFS`.
    Tmpfs,
}

impl Check {
    /// The name in `cfg(has_<name>)`.
    pub fn name(&self) -> &'static str {
        match self {
            Check::SharedData => "shared_data",
            Check::Python3 => "python3",
            Check::PythonModules(name, _) | Check::Programs(name, _) => name,
            Check::Bpy => "bpy",
            Check::Tmpfs => "tmpfs",
        }
    }

    /// The environment variable that makes the check required (set in CI).
    pub fn require_var(&self) -> String {
        match self {
            Check::SharedData => "SYNTHGEN_REQUIRE_SHARED".into(),
            Check::Bpy => "SYNTHGEN_REQUIRE_BLENDER".into(),
            _ => format!("SYNTHGEN_REQUIRE_{}", self.name().to_uppercase()),
        }
    }
}

/// What a probe found.
#[derive(Debug, PartialEq, Eq)]
pub enum Found {
    /// Present; the files whose change or removal should probe again.
    Yes(Vec<PathBuf>),
    /// Absent.
    No,
}

/// Probes each check and prints the build-script lines: `cargo::rustc-check-cfg` for every
/// check, `cargo::rustc-cfg=has_<name>` for those present or required, and what to watch.
/// `manifest_dir` is the crate's `CARGO_MANIFEST_DIR`.
pub fn emit(checks: &[Check]) {
    let manifest_dir = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    println!("cargo::rerun-if-changed=build.rs");
    println!("cargo::rerun-if-env-changed=SYNTHGEN_REQUIRE_ALL");
    for var in ["SYNTHGEN_BLENDER_VENV", "XDG_CACHE_HOME"] {
        println!("cargo::rerun-if-env-changed={var}");
    }
    let all = required("SYNTHGEN_REQUIRE_ALL");
    for check in checks {
        let name = check.name();
        let var = check.require_var();
        println!("cargo::rustc-check-cfg=cfg(has_{name})");
        println!("cargo::rerun-if-env-changed={var}");
        if all || required(&var) {
            println!("cargo::rustc-cfg=has_{name}");
            continue;
        }
        // Only files that exist are watched: cargo rebuilds on every run for a missing one.
        // An absent dependency is probed again when build.rs changes (the ignore reason says so).
        if let Found::Yes(watch) = probe(check, &manifest_dir) {
            println!("cargo::rustc-cfg=has_{name}");
            for path in watch {
                println!("cargo::rerun-if-changed={}", path.display());
            }
        }
    }
}

fn required(var: &str) -> bool {
    std::env::var(var).is_ok_and(|v| v == "1")
}

/// Probes one check (no output).
pub fn probe(check: &Check, manifest_dir: &Path) -> Found {
    match check {
        Check::SharedData => {
            let data = manifest_dir.join("../../../shared/data");
            if data.is_dir() {
                Found::Yes(
                    vec![data.join("README.md")]
                        .into_iter()
                        .filter(|p| p.is_file())
                        .collect(),
                )
            } else {
                Found::No
            }
        }
        Check::Python3 => match find_program("python3") {
            Some(p) => Found::Yes(vec![p]),
            None => Found::No,
        },
        Check::PythonModules(_, modules) => python_modules(modules),
        Check::Programs(_, groups) => {
            let mut found = Vec::new();
            for alternatives in *groups {
                match alternatives.iter().find_map(|n| find_program(n)) {
                    Some(p) => found.push(p),
                    None => return Found::No,
                }
            }
            Found::Yes(found)
        }
        Check::Bpy => bpy(),
        Check::Tmpfs => tmpfs(),
    }
}

/// The first `name` on PATH that is an executable file.
pub fn find_program(name: &str) -> Option<PathBuf> {
    use std::os::unix::fs::PermissionsExt;
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(name))
        .find(|p| {
            p.metadata()
                .is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
        })
}

fn python_modules(modules: &[&str]) -> Found {
    let Some(python) = find_program("python3") else {
        return Found::No;
    };
    // Prints each module's file, so that its removal probes again.
    let script = format!(
        "import importlib\nfor m in {modules:?}:\n    print(getattr(importlib.import_module(m), '__file__', None) or '')"
    );
    match Command::new(&python).args(["-c", &script]).output() {
        Ok(o) if o.status.success() => {
            let mut watch = vec![python];
            watch.extend(
                String::from_utf8_lossy(&o.stdout)
                    .lines()
                    .map(PathBuf::from)
                    .filter(|p| p.is_file()),
            );
            Found::Yes(watch)
        }
        _ => Found::No,
    }
}

fn bpy() -> Found {
    let venv = std::env::var_os("SYNTHGEN_BLENDER_VENV")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("XDG_CACHE_HOME")
                .map(PathBuf::from)
                .filter(|p| p.is_absolute())
                .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
                .map(|c| c.join("synthgen").join("blender-venv"))
        });
    let Some(venv) = venv else { return Found::No };
    let bpy = venv.join("lib/python3.11/site-packages/bpy");
    ["__init__.so", "__init__.py"]
        .iter()
        .map(|f| bpy.join(f))
        .find(|p| p.is_file())
        .map_or(Found::No, |p| Found::Yes(vec![p]))
}

/// Mounting needs CAP_SYS_ADMIN (root outside a restricting sandbox): read from
/// /proc/self/status rather than mounting from a build script.
fn tmpfs() -> Found {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let cap_eff = status
        .lines()
        .find_map(|l| l.strip_prefix("CapEff:"))
        .and_then(|v| u64::from_str_radix(v.trim(), 16).ok())
        .unwrap_or(0);
    const CAP_SYS_ADMIN: u64 = 1 << 21;
    if cap_eff & CAP_SYS_ADMIN != 0 && find_program("mount").is_some() {
        Found::Yes(Vec::new())
    } else {
        Found::No
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_variables() {
        let c = Check::Programs(
            "chromium",
            &[&["chromium", "chromium-browser"], &["chromedriver"]],
        );
        assert_eq!(c.name(), "chromium");
        assert_eq!(c.require_var(), "SYNTHGEN_REQUIRE_CHROMIUM");
        assert_eq!(Check::SharedData.require_var(), "SYNTHGEN_REQUIRE_SHARED");
        assert_eq!(Check::Bpy.require_var(), "SYNTHGEN_REQUIRE_BLENDER");
        assert_eq!(
            Check::PythonModules("pyyaml", &["yaml"]).require_var(),
            "SYNTHGEN_REQUIRE_PYYAML"
        );
    }

    #[test]
    fn a_program_that_does_not_exist_is_absent() {
        let c = Check::Programs("nothing", &[&["synthgen-no-such-program-xyz"]]);
        assert_eq!(probe(&c, Path::new(".")), Found::No);
        // `sh` exists on every machine that can build this crate.
        let sh = Check::Programs("sh", &[&["synthgen-no-such-program-xyz", "sh"]]);
        assert!(matches!(probe(&sh, Path::new(".")), Found::Yes(p) if p.len() == 1));
    }

    #[test]
    fn a_module_that_does_not_exist_is_absent() {
        let c = Check::PythonModules("x", &["synthgen_no_such_module_xyz"]);
        assert_eq!(probe(&c, Path::new(".")), Found::No);
    }

    #[test]
    fn shared_data_is_looked_for_beside_the_checkout() {
        assert_eq!(
            probe(&Check::SharedData, Path::new("/nonexistent/a/b/c")),
            Found::No
        );
    }
}
