//! File output that never leaves a half-written file under its final name.

use std::path::Path;

use crate::error::{Error, Result};

pub use synthgen_core::atomic::{is_temp_file, TEMP_SUFFIX};
use synthgen_core::atomic::{write_atomic, Step};

/// Writes `bytes` to `path` atomically: a temporary file in the same folder, then a rename.
/// Readers see the old file or the new one, never a partial one.
pub fn atomic_write(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_write_with(path, bytes, false)
}

/// [`atomic_write`], with `fsync` forcing the data to disk before the rename (slower; for
/// files that must survive a power cut, such as the annotation JSON of a finished chunk).
pub fn atomic_write_with(path: &Path, bytes: &[u8], fsync: bool) -> Result<()> {
    write_atomic(path, bytes, fsync).map_err(|(step, e)| {
        let op = match step {
            Step::Write => "write",
            Step::Rename => "rename",
        };
        Error::io(op, path, e)
    })
}

/// Checks that `name` (a split or folder name taken from a command line or a file) is one
/// plain path component, so joining it to a dataset root cannot leave the root: no `/` or
/// `\\`, not `.`/`..`, no leading dot, no NUL, not empty.
pub fn check_plain_name(name: &str, what: &str, root: &Path) -> Result<()> {
    let escapes = name.is_empty()
        || name.starts_with('.')
        || name.contains(['/', '\\', '\0'])
        || (cfg!(windows) && name.contains(':'));
    let plain = !escapes;
    if plain {
        Ok(())
    } else {
        Err(Error::InvalidRequest(format!(
            "{what} {name:?} is not a plain folder name (it could point outside the dataset): {}",
            root.display()
        )))
    }
}

/// `std::fs::create_dir_all` with the path in the error.
pub fn create_dir_all(path: &Path) -> Result<()> {
    std::fs::create_dir_all(path).map_err(|e| Error::io("create directory", path, e))
}

/// `std::fs::read` with the path in the error (a missing file is [`Error::MissingFile`]).
pub fn read(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|e| Error::io("read", path, e))
}

/// Removes temporary files a crashed run left in `dir` (not recursive); returns how many.
pub fn remove_stale_temp_files(dir: &Path) -> Result<usize> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(Error::io("list directory", dir, e)),
    };
    let mut n = 0;
    for entry in entries {
        let entry = entry.map_err(|e| Error::io("list directory", dir, e))?;
        if is_temp_file(&entry.file_name().to_string_lossy()) {
            let p = entry.path();
            std::fs::remove_file(&p).map_err(|e| Error::io("remove", &p, e))?;
            n += 1;
        }
    }
    Ok(n)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn names(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn atomic_write_leaves_no_temp_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.json");
        atomic_write(&p, b"one").unwrap();
        atomic_write_with(&p, b"two", true).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two");
        assert_eq!(names(dir.path()), ["a.json"]);
    }

    #[test]
    fn failed_write_names_path_and_cleans_up() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("missing_dir").join("a.json");
        let e = atomic_write(&p, b"x").unwrap_err();
        assert!(e.to_string().ends_with(&p.display().to_string()), "{e}");
        assert!(e.to_string().starts_with("cannot write: "), "{e}");
        assert!(names(dir.path()).is_empty());
    }

    #[test]
    fn parallel_writes_to_one_target() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.bin");
        std::thread::scope(|s| {
            for i in 0..8u8 {
                let p = &p;
                s.spawn(move || atomic_write(p, &[i; 1000]).unwrap());
            }
        });
        let b = std::fs::read(&p).unwrap();
        assert_eq!(b.len(), 1000);
        assert!(b.iter().all(|&v| v == b[0]));
        assert_eq!(names(dir.path()), ["x.bin"]);
    }

    #[test]
    fn names_that_escape_the_root_are_refused() {
        let root = Path::new("/data/ds");
        for bad in [
            "..",
            "../../etc",
            "a/b",
            "a\\b",
            ".hidden",
            "",
            "/abs",
            "x\0y",
        ] {
            let e = check_plain_name(bad, "split", root)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("not a plain folder name") && e.ends_with("/data/ds"),
                "{e}"
            );
        }
        check_plain_name("train_pbr", "split", root).unwrap();
    }

    #[test]
    fn stale_temp_files_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join(format!(".a.png.1.2{TEMP_SUFFIX}")), b"").unwrap();
        std::fs::write(dir.path().join("a.png"), b"").unwrap();
        assert_eq!(remove_stale_temp_files(dir.path()).unwrap(), 1);
        assert_eq!(names(dir.path()), ["a.png"]);
    }
}
