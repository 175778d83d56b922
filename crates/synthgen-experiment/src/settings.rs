//! An experiment's settings file and the fingerprints of the datasets it read: what lets a
//! re-run with the same options on the same data resume, and refuses (or with `force` starts
//! over) anything else. Shared by every experiment.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use synthgen_formats::io::atomic_write;

use crate::user_error;

/// What an experiment read, beside its settings: `inputs.json`.
const INPUTS_FILE: &str = "inputs.json";

/// One dataset an experiment reads, and what it held.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct Input {
    /// The flag that named it (`--test`, `--real`, ...).
    role: String,
    path: PathBuf,
    fingerprint: synthgen_formats::fingerprint::Fingerprint,
}

fn fingerprint_inputs(inputs: &[(&str, &Path)]) -> Result<Vec<Input>> {
    let mut out: Vec<Input> = Vec::new();
    for &(role, path) in inputs {
        if out.iter().any(|i| i.path == path) {
            continue;
        }
        out.push(Input {
            role: role.to_string(),
            path: path.to_path_buf(),
            fingerprint: synthgen_formats::fingerprint::fingerprint(path)?,
        });
    }
    Ok(out)
}

/// The first input whose files changed since `out`'s experiment recorded them, as a message;
/// None when they are the same (or an experiment from before inputs were recorded).
fn changed_input(out: &Path, now: &[Input]) -> Option<String> {
    let text = std::fs::read_to_string(out.join(INPUTS_FILE)).ok()?;
    let then: Vec<Input> = serde_json::from_str(&text).ok()?;
    now.iter().find_map(|n| {
        let t = then.iter().find(|t| t.role == n.role)?;
        (t.fingerprint != n.fingerprint).then(|| {
            let (tf, nf) = (&t.fingerprint, &n.fingerprint);
            let what = if (tf.files, tf.bytes) == (nf.files, nf.bytes) {
                format!(
                    "the same {} files and {} bytes, but their names or modification times differ: files rewritten, or the folder copied without keeping times",
                    nf.files, nf.bytes
                )
            } else {
                format!(
                    "then {} files, {} bytes; now {} files, {} bytes",
                    tf.files, tf.bytes, nf.files, nf.bytes
                )
            };
            format!(
                "the {} dataset {} changed since this experiment's finished steps read it ({what}): their results are not this data's",
                n.role,
                n.path.display(),
            )
        })
    })
}

fn write_inputs(out: &Path, inputs: &[Input]) -> Result<()> {
    let text = serde_json::to_string_pretty(inputs)? + "\n";
    atomic_write(&out.join(INPUTS_FILE), text.as_bytes())?;
    Ok(())
}

/// Writes an experiment's settings `file` in `out` and the fingerprints of the datasets it
/// reads (`inputs`: flag and folder; `inputs.json`), or checks both against those already
/// there: the same settings on the same data resume; other settings, or data that changed
/// (frames deleted, another dataset under the same path), are refused unless `force`, which
/// removes the old run's `stale` folders and files first. With `refuse_foreign`, a non-empty
/// `out` without a settings file is refused too (unless `force`).
pub(crate) fn check_settings_file<S>(
    out: &Path,
    file: &str,
    settings: &S,
    inputs: &[(&str, &Path)],
    force: bool,
    stale: &[&str],
    refuse_foreign: bool,
) -> Result<()>
where
    S: Serialize + serde::de::DeserializeOwned + PartialEq,
{
    let path = out.join(file);
    let now = fingerprint_inputs(inputs)?;
    if let Ok(text) = std::fs::read_to_string(&path) {
        let same = serde_json::from_str::<S>(&text).is_ok_and(|s| &s == settings);
        let changed = if same { changed_input(out, &now) } else { None };
        if same && changed.is_none() {
            // (An experiment from before inputs were recorded gets its record now.)
            return write_inputs(out, &now);
        }
        if !force {
            return Err(match changed {
                Some(msg) => user_error(
                    msg,
                    "restore the dataset, pass --force to redo every step on the data as it is now, or choose another --out",
                ),
                None => user_error(
                    format!(
                        "{} holds an experiment with other settings ({file} differs)",
                        out.display()
                    ),
                    "pass the same options to resume it, choose another --out, or add --force to start over",
                ),
            });
        }
        let _ = std::fs::remove_file(out.join(INPUTS_FILE));
        for name in stale {
            let p = out.join(name);
            if p.is_dir() {
                std::fs::remove_dir_all(&p)
                    .with_context(|| format!("cannot remove {}", p.display()))?;
            } else if p.is_file() {
                std::fs::remove_file(&p)
                    .with_context(|| format!("cannot remove {}", p.display()))?;
            }
        }
    } else if refuse_foreign && out.is_dir() && !synthgen_formats::output::is_empty(out) && !force {
        return Err(user_error(
            format!("output folder is not empty: {}", out.display()),
            "choose another --out, or pass --force",
        ));
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let text = serde_json::to_string_pretty(settings)? + "\n";
    atomic_write(&path, text.as_bytes())?;
    write_inputs(out, &now)
}

/// `dir` made absolute (it may not exist yet).
pub(crate) fn absolute(dir: &Path) -> PathBuf {
    std::path::absolute(dir).unwrap_or_else(|_| dir.to_path_buf())
}

/// The completion record of a row, in `rows/NAME/` (every experiment's rows).
pub const ROW_FILE: &str = "row.json";

pub fn row_dir(out: &Path, name: &str) -> PathBuf {
    out.join("rows").join(name)
}

/// `rows/NAME/row.json` as `T`, if it reads (an experiment's completion record of a row).
pub fn read_row_file<T: serde::de::DeserializeOwned>(out: &Path, name: &str) -> Option<T> {
    let text = std::fs::read_to_string(row_dir(out, name).join(ROW_FILE)).ok()?;
    serde_json::from_str(&text).ok()
}
