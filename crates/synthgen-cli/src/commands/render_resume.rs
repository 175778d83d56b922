//! Shards and resume for `synthgen render`: which frames this process renders, the run plan
//! that lets `--resume` check it continues the same run, and the command line recorded in
//! the manifest.
//!
//! The run plan (`.synthgen-run.json`, hidden) is the manifest of the run before any frame
//! is rendered; it is written at the start and removed once `synthgen.json` is written, so
//! a folder holding one is unfinished.

use std::ops::Range;
use std::path::Path;

use anyhow::{Context, Result};
use synthgen_dataset::bop::DoneFrames;
use synthgen_dataset::io::atomic_write;
use synthgen_dataset::manifest::{Manifest, MANIFEST_FILE};

use crate::cli::{FormatArg, RenderArgs};
use crate::commands::render_sink::Sink;
use crate::commands::user_error;

/// File name of the run plan at the root of an unfinished output folder.
pub const RUN_PLAN: &str = ".synthgen-run.json";

/// `--shard` and `--resume` need the BOP writer's global numbering and journals.
pub fn check_supported(args: &RenderArgs) -> Result<()> {
    if args.format != FormatArg::Bop && (args.shard.is_some() || args.resume) {
        return Err(user_error(
            "--shard and --resume work with --format bop only",
            "render BOP and convert the merged dataset with `synthgen convert --to linemod`",
        ));
    }
    Ok(())
}

/// The frames this process renders: all of `--first-frame .. +--frames`, or its shard.
pub fn frame_range(args: &RenderArgs) -> Result<Range<u64>> {
    if args.first_frame.checked_add(args.frames).is_none() {
        return Err(user_error(
            "--first-frame + --frames is beyond the last frame index (2^64 - 1)",
            "use smaller frame numbers",
        ));
    }
    Ok(match args.shard {
        Some(s) => s.range(args.first_frame, args.frames),
        None => args.first_frame..args.first_frame + args.frames,
    })
}

/// The command line for the manifest: `--resume` does not change what is written, so it is
/// left out and a resumed dataset is byte-identical to an uninterrupted one.
pub fn command_line() -> Vec<String> {
    std::env::args().filter(|a| a != "--resume").collect()
}

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
            let text = std::fs::read_to_string(&path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            let m: Manifest = serde_json::from_str(&text)
                .with_context(|| format!("malformed {}", path.display()))?;
            return Ok(Some(m));
        }
    }
    Ok(None)
}

/// Starts the run: with `--resume`, checks the folder holds the same run and returns the
/// frames already done; writes the run plan.
pub fn begin(
    args: &RenderArgs,
    plan: &Manifest,
    sink: &Sink,
    range: Range<u64>,
) -> Result<DoneFrames> {
    let done = if args.resume {
        if let Some(previous) = read_plan(&args.out)? {
            let (a, b) = (run_identity(&previous), run_identity(plan));
            if let Some(key) = first_difference(&a, &b, "") {
                return Err(user_error(
                    format!(
                        "--resume: {} was written by a different run ({key} differs)",
                        args.out.display()
                    ),
                    "pass exactly the options of the interrupted run (its command line is in .synthgen-run.json), or use another --out",
                ));
            }
        }
        sink.resume()?
    } else {
        DoneFrames::new(range)
    };
    let mut text = serde_json::to_string_pretty(plan).context("cannot serialize the run plan")?;
    text.push('\n');
    atomic_write(&args.out.join(RUN_PLAN), text.as_bytes())?;
    Ok(done)
}

/// Ends the run once `synthgen.json` is written.
pub fn end(out: &Path) -> Result<()> {
    let path = out.join(RUN_PLAN);
    match std::fs::remove_file(&path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(e).with_context(|| format!("cannot remove {}", path.display())),
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
