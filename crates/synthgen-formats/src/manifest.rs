//! `synthgen.json`: how a dataset was made, so it can be made again.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::bop::reader::read_json;
use crate::error::{Error, Result};
use crate::io::atomic_write_with;

/// File name of the manifest at a dataset's root.
pub const MANIFEST_FILE: &str = "synthgen.json";

/// Provenance of a dataset.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub synthgen_version: String,
    /// The full command line, program name first.
    pub command_line: Vec<String>,
    pub seed: u64,
    /// Seconds since the Unix epoch; left out for byte-reproducible output.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub created_unix: Option<u64>,
    /// The scene spec used, as JSON (null when the command samples no scenes).
    #[serde(default)]
    pub scene_spec: serde_json::Value,
    /// Renderer backend (`cpu`, `blender`), empty when nothing was rendered.
    #[serde(default)]
    pub backend: String,
    /// Frames written.
    pub frames: u64,
    /// Command-specific details (mix counts, per-frame provenance file, ...).
    #[serde(default)]
    pub extra: serde_json::Value,
}

impl Manifest {
    /// A manifest for the current synthgen version with empty spec and extra.
    pub fn new(command_line: Vec<String>, seed: u64) -> Manifest {
        Manifest {
            synthgen_version: synthgen_core::VERSION.to_string(),
            command_line,
            seed,
            created_unix: None,
            scene_spec: serde_json::Value::Null,
            backend: String::new(),
            frames: 0,
            extra: serde_json::Value::Null,
        }
    }

    /// Sets `created_unix` to now.
    pub fn stamped_now(mut self) -> Manifest {
        self.created_unix = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .ok()
            .map(|d| d.as_secs());
        self
    }
}

/// Writes `root/synthgen.json` atomically (pretty JSON, trailing newline).
pub fn write_manifest(root: &Path, manifest: &Manifest) -> Result<PathBuf> {
    let path = root.join(MANIFEST_FILE);
    let mut text = serde_json::to_string_pretty(manifest).map_err(|e| Error::json(&path, e))?;
    text.push('\n');
    atomic_write_with(&path, text.as_bytes(), true)?;
    Ok(path)
}

/// Reads `root/synthgen.json`.
pub fn read_manifest(root: &Path) -> Result<Manifest> {
    read_json(&root.join(MANIFEST_FILE))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn manifest_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let mut m = Manifest::new(vec!["synthgen".into(), "render".into()], u64::MAX).stamped_now();
        m.scene_spec = serde_json::json!({"camera": {"preset": "linemod"}});
        m.backend = "cpu".into();
        m.frames = 5;
        m.extra = serde_json::json!({"note": "é"});
        let p = write_manifest(dir.path(), &m).unwrap();
        assert_eq!(p, dir.path().join("synthgen.json"));
        assert_eq!(read_manifest(dir.path()).unwrap(), m);
        assert!(m.created_unix.unwrap() > 1_600_000_000);
    }

    #[test]
    fn missing_and_malformed_manifest() {
        let dir = tempfile::tempdir().unwrap();
        let e = read_manifest(dir.path()).unwrap_err();
        assert!(e.to_string().starts_with("missing file: "), "{e}");
        std::fs::write(dir.path().join(MANIFEST_FILE), "{\"seed\": 1,\n}").unwrap();
        let e = read_manifest(dir.path()).unwrap_err().to_string();
        assert!(e.starts_with("malformed synthgen.json: "), "{e}");
        assert!(e.contains("line 2"), "{e}");
    }
}
