//! Writing a file so that no reader (or a resumed run) ever sees half of it: a temporary
//! sibling, then a rename. The one implementation every crate uses, so that a crash-left
//! temporary file always has the same recognisable name and `--resume` can sweep it.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

/// Suffix of the temporary files [`write_atomic`] creates next to their targets.
pub const TEMP_SUFFIX: &str = ".synthgen-tmp";

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Whether `name` is one of our temporary files (left behind only by a crash).
pub fn is_temp_file(name: &str) -> bool {
    name.starts_with('.') && name.ends_with(TEMP_SUFFIX)
}

/// The temporary sibling of `path`: hidden, unique per process and call (so parallel
/// writers of the same target never share one), ending in [`TEMP_SUFFIX`].
pub fn temp_path(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let n = TEMP_COUNTER.fetch_add(1, Ordering::Relaxed);
    path.with_file_name(format!(".{name}.{}.{n}{TEMP_SUFFIX}", std::process::id()))
}

/// Which step of [`write_atomic`] failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// Creating or writing the temporary file.
    Write,
    /// Renaming it over the target.
    Rename,
}

/// Writes `bytes` to a temporary sibling of `path` (synced to disk first when `fsync`),
/// then renames it over `path`. On failure the temporary file is removed.
pub fn write_atomic(path: &Path, bytes: &[u8], fsync: bool) -> Result<(), (Step, std::io::Error)> {
    let tmp = temp_path(path);
    let written = (|| {
        let mut f = File::create(&tmp)?;
        f.write_all(bytes)?;
        if fsync {
            f.sync_all()?;
        }
        Ok(())
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err((Step::Write, e));
    }
    if let Err(e) = std::fs::rename(&tmp, path) {
        let _ = std::fs::remove_file(&tmp);
        return Err((Step::Rename, e));
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn temp_names_are_recognised_and_unique() {
        let p = Path::new("/x/models/obj_000001.ply");
        let (a, b) = (temp_path(p), temp_path(p));
        assert_ne!(a, b);
        assert_eq!(a.parent(), p.parent());
        assert!(is_temp_file(&a.file_name().unwrap().to_string_lossy()));
        assert!(!is_temp_file("obj_000001.ply"));
    }

    #[test]
    fn failed_rename_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("synthgen-atomic-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("target_is_a_dir")).unwrap();
        let e = write_atomic(&dir.join("target_is_a_dir"), b"x", false).unwrap_err();
        assert_eq!(e.0, Step::Rename);
        let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
        assert_eq!(left.len(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
