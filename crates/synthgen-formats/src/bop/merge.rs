//! Combining BOP datasets written as shards of one run (`synthgen merge`).
//!
//! Shards number frames globally, so their files never share a name unless they are the
//! same file (`camera.json`, `models/`), which must then be byte-identical. A scene folder
//! split between shards has its `scene_camera.json`, `scene_gt.json` and
//! `scene_gt_info.json` united entry by entry and written in bop_toolkit's layout, which
//! gives the bytes one process would have written. Every other file is hard-linked (or
//! copied, across file systems or when asked), so merging costs no image copies.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde_json::Value;

use super::chunk::{SCENE_CAMERA, SCENE_GT, SCENE_GT_INFO};
use super::journal::JOURNAL_FILE;
use super::json::save_json_dict;
use crate::error::{Error, Result};
use crate::io::{atomic_write, create_dir_all, TEMP_SUFFIX};

/// How files reach the merged folder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct MergeOptions {
    /// Copy every file instead of hard-linking it.
    pub copy: bool,
}

/// What [`merge`] did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct MergeSummary {
    pub files_linked: u64,
    pub files_copied: u64,
    /// Scene JSON files united from several shards.
    pub json_merged: u64,
    /// Files present in several sources with the same bytes (`camera.json`, models).
    pub identical_shared: u64,
}

/// Files left at the root for the caller (the manifest is merged by the CLI).
const SKIPPED_AT_ROOT: [&str; 1] = ["synthgen.json"];

fn is_scene_json(rel: &Path) -> bool {
    let n = rel.components().count();
    let name = rel.file_name().and_then(|n| n.to_str()).unwrap_or("");
    n == 3 && [SCENE_CAMERA, SCENE_GT, SCENE_GT_INFO].contains(&name)
}

/// Files of `root`, relative and sorted; hidden entries are skipped, but a scene folder's
/// journal or a temporary file means the source is unfinished.
fn list_files(root: &Path) -> Result<Vec<PathBuf>> {
    let mut out = Vec::new();
    let mut stack = vec![PathBuf::new()];
    while let Some(rel) = stack.pop() {
        let dir = root.join(&rel);
        let entries = std::fs::read_dir(&dir).map_err(|e| Error::io("list directory", &dir, e))?;
        for entry in entries {
            let entry = entry.map_err(|e| Error::io("list directory", &dir, e))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let path = entry.path();
            if name == JOURNAL_FILE || name.ends_with(TEMP_SUFFIX) {
                return Err(Error::InvalidRequest(format!(
                    "{} is from an unfinished run (finish it with `synthgen render ... --resume`): {}",
                    if name == JOURNAL_FILE {
                        "a scene journal"
                    } else {
                        "a temporary file"
                    },
                    path.display()
                )));
            }
            if name.starts_with('.') {
                continue;
            }
            let ft = entry
                .file_type()
                .map_err(|e| Error::io("list directory", &path, e))?;
            let child = rel.join(&name);
            if ft.is_dir() {
                stack.push(child);
            } else if ft.is_file() {
                if rel.as_os_str().is_empty() && SKIPPED_AT_ROOT.contains(&name.as_str()) {
                    continue;
                }
                out.push(child);
            } else {
                return Err(Error::InvalidRequest(format!(
                    "not a plain file or folder (links are not followed): {}",
                    path.display()
                )));
            }
        }
    }
    out.sort();
    Ok(out)
}

fn place(src: &Path, dest: &Path, opts: &MergeOptions, sum: &mut MergeSummary) -> Result<()> {
    if let Some(parent) = dest.parent() {
        create_dir_all(parent)?;
    }
    if !opts.copy && std::fs::hard_link(src, dest).is_ok() {
        sum.files_linked += 1;
        return Ok(());
    }
    // Across file systems, or asked to copy: through a temporary file, so a full disk never
    // leaves a partial file under the final name.
    let bytes = crate::io::read(src)?;
    atomic_write(dest, &bytes)?;
    sum.files_copied += 1;
    Ok(())
}

fn read_id_map(path: &Path) -> Result<BTreeMap<u32, Value>> {
    let bytes = crate::io::read(path)?;
    let raw: BTreeMap<String, Value> =
        serde_json::from_slice(&bytes).map_err(|e| Error::json(path, e))?;
    let mut out = BTreeMap::new();
    for (k, v) in raw {
        let id: u32 = k
            .parse()
            .map_err(|_| Error::malformed(path, format!("key {k:?} is not an image id")))?;
        out.insert(id, v);
    }
    Ok(out)
}

/// Merges the BOP datasets `sources` into `out` (created if missing; files already there
/// with the same name must hold the same bytes). The manifest (`synthgen.json`) is left to
/// the caller.
pub fn merge(sources: &[PathBuf], out: &Path, opts: &MergeOptions) -> Result<MergeSummary> {
    let mut sum = MergeSummary::default();
    create_dir_all(out)?;
    // Scene JSON files by relative path, with the sources that have them.
    let mut scene_json: BTreeMap<PathBuf, Vec<PathBuf>> = BTreeMap::new();
    // Where each placed file came from, to name both sides of a conflict.
    let mut origin: BTreeMap<PathBuf, PathBuf> = BTreeMap::new();
    for root in sources {
        for rel in list_files(root)? {
            let src = root.join(&rel);
            if is_scene_json(&rel) {
                scene_json.entry(rel).or_default().push(src);
                continue;
            }
            let dest = out.join(&rel);
            if dest.exists() {
                let same = crate::io::read(&dest)? == crate::io::read(&src)?;
                if !same {
                    let other = origin.get(&rel).cloned().unwrap_or_else(|| dest.clone());
                    return Err(Error::InvalidRequest(format!(
                        "{} differs between {} and {}; were these shards rendered with the same options?",
                        rel.display(),
                        other.display(),
                        src.display()
                    )));
                }
                sum.identical_shared += 1;
                continue;
            }
            place(&src, &dest, opts, &mut sum)?;
            origin.insert(rel, src);
        }
    }
    for (rel, srcs) in scene_json {
        let dest = out.join(&rel);
        if let [only] = srcs.as_slice() {
            if !dest.exists() {
                place(only, &dest, opts, &mut sum)?;
                continue;
            }
        }
        let mut merged: BTreeMap<u32, Value> = if dest.exists() {
            read_id_map(&dest)?
        } else {
            BTreeMap::new()
        };
        let mut from: BTreeMap<u32, PathBuf> = BTreeMap::new();
        for src in &srcs {
            for (id, v) in read_id_map(src)? {
                match merged.get(&id) {
                    Some(old) if *old != v => {
                        return Err(Error::InvalidRequest(format!(
                            "image {id} of {} differs between {} and {}",
                            rel.display(),
                            from.get(&id).unwrap_or(&dest).display(),
                            src.display()
                        )));
                    }
                    _ => {
                        merged.insert(id, v);
                        from.insert(id, src.clone());
                    }
                }
            }
        }
        let text = save_json_dict(merged.iter())
            .map_err(|_| Error::malformed(&srcs[0], "a null value, which BOP files never hold"))?;
        if let Some(parent) = dest.parent() {
            create_dir_all(parent)?;
        }
        atomic_write(&dest, text.as_bytes())?;
        sum.json_merged += 1;
    }
    Ok(sum)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn write(root: &Path, rel: &str, text: &str) {
        let p = root.join(rel);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, text).unwrap();
    }

    #[test]
    fn split_scene_json_is_united_in_bop_layout() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b, out) = (
            dir.path().join("a"),
            dir.path().join("b"),
            dir.path().join("out"),
        );
        write(&a, "camera.json", "{}");
        write(&b, "camera.json", "{}");
        write(
            &a,
            "train_pbr/000000/scene_gt.json",
            "{\n  \"0\": [1.5],\n  \"1\": [1e-05]\n}",
        );
        write(
            &b,
            "train_pbr/000000/scene_gt.json",
            "{\n  \"2\": [0.30000000000000004]\n}",
        );
        write(&a, "train_pbr/000000/rgb/000000.png", "x");
        write(&b, "train_pbr/000000/rgb/000002.png", "y");
        write(&b, "train_pbr/000001/scene_gt.json", "{\n  \"0\": [2]\n}");
        let s = merge(&[a, b], &out, &MergeOptions::default()).unwrap();
        assert_eq!(
            std::fs::read_to_string(out.join("train_pbr/000000/scene_gt.json")).unwrap(),
            "{\n  \"0\": [1.5],\n  \"1\": [1e-05],\n  \"2\": [0.30000000000000004]\n}"
        );
        assert_eq!(s.json_merged, 1);
        assert_eq!(s.identical_shared, 1);
        assert_eq!(s.files_linked + s.files_copied, 4);
    }

    #[test]
    fn conflicting_files_and_unfinished_sources_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a"), dir.path().join("b"));
        write(&a, "camera.json", "{\"fx\": 1}");
        write(&b, "camera.json", "{\"fx\": 2}");
        let e = merge(
            &[a.clone(), b.clone()],
            &dir.path().join("o1"),
            &MergeOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("camera.json differs between"), "{e}");
        write(&b, "camera.json", "{\"fx\": 1}");
        write(&a, "s/000000/scene_gt.json", "{\n  \"0\": [1]\n}");
        write(&b, "s/000000/scene_gt.json", "{\n  \"0\": [2]\n}");
        let e = merge(
            &[a.clone(), b.clone()],
            &dir.path().join("o2"),
            &MergeOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("image 0 of s/000000/scene_gt.json differs"),
            "{e}"
        );
        write(&b, "s/000000/.synthgen-journal.jsonl", "");
        let e = merge(
            &[a, b],
            &dir.path().join("o3"),
            &MergeOptions { copy: true },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("unfinished run"), "{e}");
    }
}
