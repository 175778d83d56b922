//! Resume: the run plan that lets a resumed write check it continues the same run.
//!
//! The run plan (`.synthgen-run.json`, hidden) is the manifest of the run before any frame
//! is rendered; it is written at the start and removed once `synthgen.json` is written, so
//! a folder holding one is unfinished.

use std::ops::Range;
use std::path::Path;

use synthgen_formats::bop::DoneFrames;
use synthgen_formats::io::atomic_write;
use synthgen_formats::manifest::{Manifest, MANIFEST_FILE};

use crate::error::{Error, Result};
use crate::sink::Sink;

/// File name of the run plan at the root of an unfinished output folder.
pub use synthgen_formats::output::RUN_PLAN_FILE as RUN_PLAN;

/// The parts of a manifest two runs must share to write the same dataset.
fn run_identity(m: &Manifest) -> serde_json::Value {
    let mut extra = m.extra.clone();
    if let Some(o) = extra.as_object_mut() {
        o.remove("failed_frames");
        o.remove("physics_fallback_frames");
    }
    serde_json::json!({
        "synthgen_version": m.synthgen_version,
        "seed": m.seed,
        "scene_spec": m.scene_spec,
        "backend": m.backend,
        "extra": extra,
    })
}

/// The first key (dotted path) where two JSON values differ.
fn first_difference(a: &serde_json::Value, b: &serde_json::Value, at: &str) -> Option<String> {
    match (a, b) {
        (serde_json::Value::Object(x), serde_json::Value::Object(y)) => {
            let mut keys: Vec<&String> = x.keys().chain(y.keys()).collect();
            keys.sort();
            keys.dedup();
            keys.into_iter().find_map(|k| {
                let path = if at.is_empty() {
                    k.clone()
                } else {
                    format!("{at}.{k}")
                };
                match (x.get(k), y.get(k)) {
                    (Some(p), Some(q)) => first_difference(p, q, &path),
                    _ => Some(path),
                }
            })
        }
        _ if a == b => None,
        _ => Some(if at.is_empty() {
            "(root)".into()
        } else {
            at.into()
        }),
    }
}

fn read_plan(out: &Path) -> Result<Option<Manifest>> {
    for name in [RUN_PLAN, MANIFEST_FILE] {
        let path = out.join(name);
        if path.exists() {
            let text = std::fs::read_to_string(&path).map_err(|e| Error::Read {
                path: path.clone(),
                source: e,
            })?;
            let m: Manifest =
                serde_json::from_str(&text).map_err(|e| Error::Malformed { path, source: e })?;
            return Ok(Some(m));
        }
    }
    Ok(None)
}

/// Starts the run: when resuming, checks the folder holds the same run and returns the
/// frames already done; writes the run plan.
pub(crate) fn begin(
    out: &Path,
    resume: bool,
    plan: &Manifest,
    sink: &Sink,
    range: Range<u64>,
) -> Result<DoneFrames> {
    let done = if resume {
        if let Some(previous) = read_plan(out)? {
            let (a, b) = (run_identity(&previous), run_identity(plan));
            if let Some(key) = first_difference(&a, &b, "") {
                return Err(Error::invalid(
                    format!(
                        "--resume: {} was written by a different run ({key} differs)",
                        out.display()
                    ),
                    "pass exactly the options of the interrupted run (its command line is in .synthgen-run.json), or use another --out",
                ));
            }
        }
        sink.resume()?
    } else {
        DoneFrames::new(range)
    };
    let mut text = serde_json::to_string_pretty(plan).map_err(|e| Error::Serialize {
        what: "the run plan",
        source: e,
    })?;
    text.push('\n');
    atomic_write(&out.join(RUN_PLAN), text.as_bytes())?;
    Ok(done)
}

/// Ends the run once `synthgen.json` is written.
pub(crate) fn end(out: &Path) -> Result<()> {
    let path = out.join(RUN_PLAN);
    match std::fs::remove_file(&path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::Remove { path, source: e }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn differences_are_named() {
        let a = serde_json::json!({"seed": 1, "extra": {"frame_range": [0, 5], "x": 1}});
        let b = serde_json::json!({"seed": 1, "extra": {"frame_range": [0, 6], "x": 1}});
        assert_eq!(
            first_difference(&a, &b, "").as_deref(),
            Some("extra.frame_range")
        );
        assert_eq!(first_difference(&a, &a, ""), None);
    }
}
