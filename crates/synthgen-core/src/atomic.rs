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

/// A folder written whole or not at all: its files go into a hidden temporary sibling
/// ([`StagedDir::path`]), which [`StagedDir::commit`] renames onto the target (an earlier
/// folder there is replaced only then). Dropped without a commit (an error, a panic), the
/// temporary folder is removed, so a failed run leaves the target as it was.
#[derive(Debug)]
pub struct StagedDir {
    staging: PathBuf,
    target: PathBuf,
    committed: bool,
}

impl StagedDir {
    /// Creates the temporary sibling of `target` (its parent is created if needed).
    pub fn new(target: &Path) -> std::io::Result<StagedDir> {
        if let Some(parent) = target.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)?;
        }
        let staging = temp_path(target);
        std::fs::create_dir(&staging)?;
        Ok(StagedDir {
            staging,
            target: target.to_path_buf(),
            committed: false,
        })
    }

    /// Where to write the folder's files.
    pub fn path(&self) -> &Path {
        &self.staging
    }

    /// Puts the written folder in place of the target, replacing what was there.
    pub fn commit(mut self) -> std::io::Result<()> {
        if self.target.exists() {
            let old = temp_path(&self.target);
            std::fs::rename(&self.target, &old)?;
            if let Err(e) = std::fs::rename(&self.staging, &self.target) {
                let _ = std::fs::rename(&old, &self.target);
                return Err(e);
            }
            let _ = std::fs::remove_dir_all(&old);
        } else {
            std::fs::rename(&self.staging, &self.target)?;
        }
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.staging);
        }
    }
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

    #[test]
    fn a_staged_folder_replaces_the_target_on_commit_and_vanishes_otherwise() {
        let dir = std::env::temp_dir().join(format!("synthgen-staged-{}", std::process::id()));
        let target = dir.join("out");
        std::fs::create_dir_all(&target).unwrap();
        std::fs::write(target.join("old.txt"), "old").unwrap();
        {
            let s = StagedDir::new(&target).unwrap();
            std::fs::write(s.path().join("new.txt"), "new").unwrap();
            // dropped: nothing changes
        }
        assert!(target.join("old.txt").is_file() && !target.join("new.txt").exists());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        let s = StagedDir::new(&target).unwrap();
        std::fs::write(s.path().join("new.txt"), "new").unwrap();
        s.commit().unwrap();
        assert!(!target.join("old.txt").exists() && target.join("new.txt").is_file());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
