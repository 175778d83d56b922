//! Guards for commands that write a dataset: one writer per output folder at a time
//! ([`OutputLock`]), and never an output that is, contains or lies inside one of the inputs
//! ([`check_apart`]).

use std::fs::{File, OpenOptions, TryLockError};
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::create_dir_all;

/// The lock file in an output folder (hidden: dataset readers skip dot files).
pub const LOCK_FILE: &str = ".synthgen.lock";

/// An exclusive advisory lock (`flock`) on `DIR/.synthgen.lock`, held while a command writes
/// into DIR and released when it is dropped or the process ends in any way (even `kill -9`),
/// so a crashed run never leaves it stuck and `--resume` can take it again.
#[derive(Debug)]
pub struct OutputLock {
    _file: File,
    path: PathBuf,
}

impl OutputLock {
    /// Creates `dir` if needed and takes its lock; a second writer gets
    /// [`Error::Locked`] naming the folder and what holds it.
    pub fn acquire(dir: &Path) -> Result<OutputLock> {
        create_dir_all(dir)?;
        let path = dir.join(LOCK_FILE);
        // The file stays empty (two runs of one command give byte-identical folders) and is
        // never deleted (deleting a lock file races with a process opening it).
        let file = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| Error::io("open", &path, e))?;
        match file.try_lock() {
            Ok(()) => Ok(OutputLock { _file: file, path }),
            Err(TryLockError::WouldBlock) => Err(Error::Locked {
                lock: path,
                path: dir.to_path_buf(),
            }),
            Err(TryLockError::Error(e)) => Err(Error::io("lock", &path, e)),
        }
    }

    /// The lock file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

pub use synthgen_core::paths::resolve;

/// Whether `dir` holds nothing but its lock file (or does not exist).
/// The run plan an unfinished render leaves in its output (synthgen-pipeline's resume record).
pub const RUN_PLAN_FILE: &str = ".synthgen-run.json";

/// Whether `out` holds what synthgen wrote: a `synthgen.json` manifest that reads as one, or
/// an unfinished render's run plan. (Not the lock file: a refused command may leave one in a
/// folder it did not write.)
pub fn written_by_synthgen(out: &Path) -> bool {
    crate::manifest::read_manifest(out).is_ok() || out.join(RUN_PLAN_FILE).is_file()
}

/// What `--force` may replace: an absent or empty `out`, or one synthgen wrote
/// ([`written_by_synthgen`]). A folder holding other files is refused, so that `--force` never
/// mixes a new dataset into another one, nor deletes files synthgen did not write.
pub fn check_force(out: &Path) -> Result<()> {
    if is_empty(out) || written_by_synthgen(out) {
        Ok(())
    } else {
        Err(Error::ForeignOutput {
            path: out.to_path_buf(),
        })
    }
}

/// `--force`, with the output's lock held: what an earlier run wrote in `out` goes (the folder
/// was checked to be synthgen's, [`check_force`]), so that the new output is not mixed with it;
/// says so on `progress` when something was removed.
pub fn replace_output(out: &Path, progress: &dyn synthgen_core::Progress) -> Result<()> {
    let n = clear_output(out)?;
    if n > 0 {
        progress.info(&format!(
            "--force: removed the earlier output in {} ({n} entries)",
            out.display()
        ));
    }
    Ok(())
}

/// `--force`'s replacement, with the folder's lock held: removes everything in `out` but the
/// lock file, so that nothing of the old output is left among the new. Returns how many
/// entries were removed.
pub fn clear_output(out: &Path) -> Result<usize> {
    let Ok(entries) = std::fs::read_dir(out) else {
        return Ok(0);
    };
    let mut n = 0;
    for e in entries {
        let e = e.map_err(|e| Error::io("list directory", out, e))?;
        if e.file_name() == std::ffi::OsStr::new(LOCK_FILE) {
            continue;
        }
        let p = e.path();
        let is_dir = e.file_type().map(|t| t.is_dir()).unwrap_or(false);
        let r = if is_dir {
            std::fs::remove_dir_all(&p)
        } else {
            std::fs::remove_file(&p)
        };
        r.map_err(|e| Error::io("remove", &p, e))?;
        n += 1;
    }
    Ok(n)
}

pub fn is_empty(dir: &Path) -> bool {
    match std::fs::read_dir(dir) {
        Ok(entries) => entries
            .flatten()
            .all(|e| e.file_name() == std::ffi::OsStr::new(LOCK_FILE)),
        Err(_) => !dir.exists(),
    }
}

/// Refuses an output (a folder or a file) that is one of the inputs, lies inside one, or
/// contains one (which `--force` could wipe). `inputs` are (role, path), e.g. ("input", IN).
pub fn check_apart(output: &Path, inputs: &[(&str, &Path)]) -> Result<()> {
    match synthgen_core::paths::first_overlap(output, inputs) {
        None => Ok(()),
        Some((relation, role, input)) => Err(Error::InvalidRequest(format!(
            "the output {} {} the {role} {}: a command never writes into its inputs; choose another output",
            output.display(),
            relation.verb(),
            input.display()
        ))),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn a_second_lock_on_one_folder_is_refused_until_the_first_is_dropped() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path().join("out");
        let first = OutputLock::acquire(&out).unwrap();
        let e = OutputLock::acquire(&out).unwrap_err().to_string();
        assert!(
            e.contains("another synthgen process") && e.contains(LOCK_FILE),
            "{e}"
        );
        drop(first);
        OutputLock::acquire(&out).unwrap();
    }

    #[test]
    fn outputs_apart_from_inputs() {
        let d = tempfile::tempdir().unwrap();
        let inp = d.path().join("in");
        std::fs::create_dir_all(inp.join("sub")).unwrap();
        let check = |out: &Path| check_apart(out, &[("input", &inp)]);
        assert!(check(&inp)
            .unwrap_err()
            .to_string()
            .contains(" is the input "));
        assert!(check(&inp.join("sub/new"))
            .unwrap_err()
            .to_string()
            .contains("lies inside"));
        assert!(check(d.path())
            .unwrap_err()
            .to_string()
            .contains("contains"));
        assert!(check(&d.path().join("in/../in")).is_err());
        check(&d.path().join("other")).unwrap();
        check(&d.path().join("in2")).unwrap();
    }
}
