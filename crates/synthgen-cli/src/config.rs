//! The project config `synthgen.toml`, looked up in the current folder and its parents.
//!
//! ```toml
//! [mix]
//! real = "data/real"    # paths relative to this file
//! synth = "data/synth"
//! out = "data/mix"
//! ```

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Deserialize;

pub const CONFIG_FILE: &str = "synthgen.toml";

#[derive(Debug, Default, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    #[serde(default)]
    pub mix: MixConfig,
}

#[derive(Debug, Default, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MixConfig {
    pub real: Option<PathBuf>,
    pub synth: Option<PathBuf>,
    pub out: Option<PathBuf>,
}

/// The nearest `synthgen.toml` from `start` upwards, if any.
pub fn find_config(start: &Path) -> Option<PathBuf> {
    start
        .ancestors()
        .map(|d| d.join(CONFIG_FILE))
        .find(|p| p.is_file())
}

/// Reads a config file; relative paths in it become relative to its folder.
pub fn read_config(path: &Path) -> Result<Config> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let mut c: Config = toml::from_str(&text).map_err(|e| {
        anyhow::Error::new(synthgen_core::UserError::new(
            format!(
                "malformed {CONFIG_FILE}: {}: {}",
                e.message(),
                path.display()
            ),
            "see `synthgen mix --help` for the format",
        ))
    })?;
    let base = path.parent().unwrap_or(Path::new("."));
    for p in [&mut c.mix.real, &mut c.mix.synth, &mut c.mix.out]
        .into_iter()
        .flatten()
    {
        if p.is_relative() {
            *p = base.join(&*p);
        }
    }
    Ok(c)
}

/// The config found from the current folder (empty when there is none), and its path.
pub fn load() -> Result<(Config, Option<PathBuf>)> {
    let cwd = std::env::current_dir().context("cannot read the current folder")?;
    match find_config(&cwd) {
        Some(p) => Ok((read_config(&p)?, Some(p))),
        None => Ok((Config::default(), None)),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn found_in_a_parent_and_paths_resolved() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(CONFIG_FILE),
            "[mix]\nreal = \"data/real\"\nsynth = \"/abs/synth\"\n",
        )
        .unwrap();
        let sub = dir.path().join("a/b");
        std::fs::create_dir_all(&sub).unwrap();
        let p = find_config(&sub).unwrap();
        let c = read_config(&p).unwrap();
        assert_eq!(c.mix.real.unwrap(), dir.path().join("data/real"));
        assert_eq!(c.mix.synth.unwrap(), PathBuf::from("/abs/synth"));
        assert_eq!(c.mix.out, None);
    }

    #[test]
    fn unknown_key_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join(CONFIG_FILE);
        std::fs::write(&p, "[mix]\nreall = \"x\"\n").unwrap();
        let e = read_config(&p).unwrap_err().to_string();
        assert!(e.starts_with("malformed synthgen.toml: "), "{e}");
        assert!(e.ends_with(&p.display().to_string()), "{e}");
    }
}
