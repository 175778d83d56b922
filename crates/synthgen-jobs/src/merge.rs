//! A merge as `synthgen merge` runs it: the shard folders of one `synthgen render --shard I/N`
//! run → one BOP dataset, byte-identical (except `synthgen.json`) to rendering all frames in
//! one process; the shards checked (finished, of one run), the merged manifest.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use synthgen_core::Progress;
use synthgen_formats::bop::merge::{merge, MergeOptions, MergeSummary};
use synthgen_formats::manifest::{read_manifest, write_manifest, Manifest};

use synthgen_formats::output::{check_apart, is_empty, OutputLock};
use synthgen_pipeline::RUN_PLAN;

use crate::{user_error, Log};

/// What to merge: `synthgen merge`'s arguments as data.
#[derive(Debug, Clone)]
pub struct MergeRequest {
    /// The shard folders.
    pub dirs: Vec<PathBuf>,
    pub out: PathBuf,
    /// Copy the files instead of hard-linking them.
    pub copy: bool,
    /// Replace an output synthgen wrote.
    pub force: bool,
    /// The command recorded in the merged manifest.
    pub command_line: Vec<String>,
}

/// Merges `req.dirs` into `req.out`; the summary goes to `progress`.
pub fn merge_shards(req: &MergeRequest, progress: &dyn Progress) -> Result<MergeSummary> {
    let printer = &Log::new(progress);
    let args = req;
    let mut manifests = Vec::new();
    for dir in &args.dirs {
        if !dir.is_dir() {
            return Err(user_error(
                format!("not a folder: {}", dir.display()),
                "pass the --out folders of the shard runs",
            ));
        }
        if dir.join(RUN_PLAN).exists() {
            return Err(user_error(
                format!("shard is unfinished: {}", dir.display()),
                "finish it: run its `synthgen render ... --shard I/N` command again with --resume",
            ));
        }
        let m = read_manifest(dir)
            .with_context(|| format!("cannot read the manifest of shard {}", dir.display()))?;
        manifests.push(m);
    }
    let merged = merged_manifest(&args.dirs, &manifests, &args.command_line)?;
    let shards: Vec<(&str, &Path)> = args.dirs.iter().map(|d| ("shard", d.as_path())).collect();
    check_apart(&args.out, &shards)?;
    check_out(&args.out, args.force)?;
    let _lock = OutputLock::acquire(&args.out)?;
    if args.force {
        synthgen_formats::output::replace_output(&args.out, printer)?;
    }
    let summary = merge(&args.dirs, &args.out, &MergeOptions { copy: args.copy })?;
    write_manifest(&args.out, &merged)?;
    printer.info(format!(
        "Merged {} shards ({} frames) into {}: {} files linked, {} copied, {} scene JSON files united.",
        args.dirs.len(),
        merged.frames,
        args.out.display(),
        summary.files_linked,
        summary.files_copied,
        summary.json_merged
    ));
    printer.hint(format!(
        "check it with `synthgen validate {}`",
        args.out.display()
    ));
    Ok(summary)
}

fn check_out(out: &Path, force: bool) -> Result<()> {
    if out.is_dir() && !is_empty(out) && !force {
        return Err(user_error(
            format!("output folder is not empty: {}", out.display()),
            "choose another --out, or pass --force to replace it",
        ));
    }
    if force {
        synthgen_formats::output::check_force(out)?;
    }
    Ok(())
}

/// The shard manifests' common run with the shard details removed: what a single process
/// rendering every frame writes, except `command_line` (this merge's) and
/// `extra.merged_from` (each shard's folder and command line).
fn merged_manifest(dirs: &[PathBuf], ms: &[Manifest], command_line: &[String]) -> Result<Manifest> {
    let shard_of = |m: &Manifest, dir: &Path| -> Result<(u64, u64)> {
        let s = &m.extra["shard"];
        match (s["index"].as_u64(), s["count"].as_u64()) {
            (Some(i), Some(n)) => Ok((i, n)),
            _ => Err(user_error(
                format!(
                    "not a shard (its synthgen.json has no extra.shard): {}",
                    dir.display()
                ),
                "merge the output folders of `synthgen render --shard I/N` runs",
            )),
        }
    };
    let common = |m: &Manifest| {
        let mut extra = m.extra.clone();
        if let Some(o) = extra.as_object_mut() {
            for k in ["shard", "frame_range", "failed_frames"] {
                o.remove(k);
            }
        }
        (
            m.synthgen_version.clone(),
            m.seed,
            m.scene_spec.clone(),
            m.backend.clone(),
            extra,
        )
    };
    let (_, n) = shard_of(&ms[0], &dirs[0])?;
    let mut by_index: Vec<Option<usize>> =
        vec![None; usize::try_from(n).unwrap_or(usize::MAX).min(1 << 20)];
    for (k, (m, dir)) in ms.iter().zip(dirs).enumerate() {
        let (i, nk) = shard_of(m, dir)?;
        if nk != n || common(m) != common(&ms[0]) {
            return Err(user_error(
                format!(
                    "{} and {} are not shards of the same run (seed, spec, options or shard count differ)",
                    dirs[0].display(),
                    dir.display()
                ),
                "merge only the shards of one `synthgen render --shard I/N` command",
            ));
        }
        match by_index.get_mut(i as usize) {
            Some(slot @ None) => *slot = Some(k),
            Some(Some(j)) => {
                return Err(user_error(
                    format!(
                        "shard {i}/{n} given twice: {} and {}",
                        dirs[*j].display(),
                        dir.display()
                    ),
                    "pass each shard folder once",
                ))
            }
            None => {
                return Err(user_error(
                    format!("shard {i}/{n} out of range: {}", dir.display()),
                    "check the shard folders",
                ))
            }
        }
    }
    let missing: Vec<String> = by_index
        .iter()
        .enumerate()
        .filter(|(_, s)| s.is_none())
        .map(|(i, _)| format!("{i}/{n}"))
        .collect();
    if !missing.is_empty() {
        return Err(user_error(
            format!("missing shards: {}", missing.join(", ")),
            "render them (`synthgen render ... --shard I/N`) and pass every shard folder",
        ));
    }
    // In shard order: frame ranges must tile the run.
    let order: Vec<usize> = by_index.into_iter().flatten().collect();
    let range = |m: &Manifest| {
        (
            m.extra["frame_range"][0].as_u64(),
            m.extra["frame_range"][1].as_u64(),
        )
    };
    let mut merged = ms[order[0]].clone();
    let (Some(start), _) = range(&merged) else {
        return Err(user_error(
            format!("no extra.frame_range in {}", dirs[order[0]].display()),
            "re-render the shard with this synthgen version",
        ));
    };
    let mut end = start;
    let mut failed: Vec<u64> = Vec::new();
    let mut frames = 0;
    for &k in &order {
        let (a, b) = range(&ms[k]);
        if a != Some(end) || b.is_none() {
            return Err(user_error(
                format!(
                    "frame ranges of the shards do not tile the run at {}",
                    dirs[k].display()
                ),
                "merge only the shards of one run",
            ));
        }
        end = b.unwrap_or(end);
        frames += ms[k].frames;
        failed.extend(
            ms[k].extra["failed_frames"]
                .as_array()
                .into_iter()
                .flatten()
                .filter_map(|v| v.as_u64()),
        );
    }
    failed.sort_unstable();
    merged.command_line = command_line.to_vec();
    merged.frames = frames;
    if let Some(o) = merged.extra.as_object_mut() {
        o.remove("shard");
        o.insert("frame_range".into(), serde_json::json!([start, end]));
        o.insert("failed_frames".into(), failed.into());
        o.insert(
            "merged_from".into(),
            order
                .iter()
                .map(|&k| serde_json::json!({"dir": dirs[k], "command_line": ms[k].command_line}))
                .collect::<Vec<_>>()
                .into(),
        );
    }
    Ok(merged)
}
