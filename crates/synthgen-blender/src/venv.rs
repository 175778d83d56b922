//! Where the bpy venv is: `--blender-venv`, else `SYNTHGEN_BLENDER_VENV`, else
//! `$XDG_CACHE_HOME/synthgen/blender-venv` (`~/.cache/synthgen/blender-venv`), the folder
//! `scripts/setup-blender.sh` creates.

use std::path::{Path, PathBuf};

use crate::Error;

/// The environment variable naming the venv.
pub const VENV_ENV: &str = "SYNTHGEN_BLENDER_VENV";

/// The Python minor version bpy 5.0.1 is built for (and that the `blender` feature links).
pub const PYTHON_VERSION: &str = "3.11";

/// The default venv folder.
pub fn default_venv() -> Option<PathBuf> {
    let cache = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
    Some(cache.join("synthgen").join("blender-venv"))
}

/// The venv to use: the flag, then the environment variable, then the default.
pub fn resolve_venv(flag: Option<&Path>) -> Option<PathBuf> {
    flag.map(Path::to_path_buf)
        .or_else(|| {
            std::env::var_os(VENV_ENV)
                .filter(|v| !v.is_empty())
                .map(PathBuf::from)
        })
        .or_else(default_venv)
}

/// The venv's `site-packages` folder that holds `bpy`, or why there is none.
pub fn bpy_site_packages(venv: &Path) -> Result<PathBuf, Error> {
    let not_found = |reason: String| Error::BpyNotFound {
        reason,
        venv: venv.to_path_buf(),
    };
    if !venv.is_dir() {
        return Err(not_found("no venv folder".into()));
    }
    let site = venv
        .join("lib")
        .join(format!("python{PYTHON_VERSION}"))
        .join("site-packages");
    if !site.is_dir() {
        let found: Vec<String> = std::fs::read_dir(venv.join("lib"))
            .map(|rd| {
                rd.filter_map(|e| e.ok())
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .filter(|n| n.starts_with("python"))
                    .collect()
            })
            .unwrap_or_default();
        return Err(not_found(if found.is_empty() {
            format!("the venv has no lib/python{PYTHON_VERSION}/site-packages")
        } else {
            format!(
                "the venv is for {} but bpy 5.0.1 needs python{PYTHON_VERSION}",
                found.join(", ")
            )
        }));
    }
    // The wheel's package is a compiled `bpy/__init__.so`.
    let bpy = site.join("bpy");
    if !["__init__.so", "__init__.py"]
        .iter()
        .any(|f| bpy.join(f).is_file())
    {
        return Err(not_found(format!("{} has no bpy package", site.display())));
    }
    Ok(site)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flag_wins_over_everything() {
        let p = Path::new("/some/venv");
        assert_eq!(resolve_venv(Some(p)).unwrap(), p);
    }

    #[test]
    fn missing_and_incomplete_venvs_say_why() {
        let dir = std::env::temp_dir().join(format!("sg-venv-test-{}", std::process::id()));
        let e = bpy_site_packages(&dir).unwrap_err().to_string();
        assert!(
            e.contains("no venv folder") && e.ends_with(&dir.display().to_string()),
            "{e}"
        );
        std::fs::create_dir_all(dir.join("lib/python3.12/site-packages")).unwrap();
        let e = bpy_site_packages(&dir).unwrap_err().to_string();
        assert!(
            e.contains("python3.12") && e.contains("needs python3.11"),
            "{e}"
        );
        let site = dir.join("lib/python3.11/site-packages");
        std::fs::create_dir_all(&site).unwrap();
        let e = bpy_site_packages(&dir).unwrap_err().to_string();
        assert!(e.contains("has no bpy package"), "{e}");
        std::fs::create_dir_all(site.join("bpy")).unwrap();
        std::fs::write(site.join("bpy/__init__.py"), "").unwrap();
        assert_eq!(bpy_site_packages(&dir).unwrap(), site);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
