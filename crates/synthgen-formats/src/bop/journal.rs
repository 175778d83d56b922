//! The per-scene-folder completion journal that makes `synthgen render --resume` possible.
//!
//! A frame's images are written (atomically) first; then one line with its annotations is
//! appended to `{scene_dir}/.synthgen-journal.jsonl`. A frame counts as done when its line is
//! in the journal or its image is in `scene_camera.json`. When the folder's JSON files are
//! written, the journal is deleted, so a finished dataset has no journals and the journal of
//! a folder never holds more than `chunk_size` lines.
//!
//! A process killed in the middle of an append leaves at most one torn last line; readers
//! drop it (and [`rewrite`] drops it from the file before new lines are appended).

use std::fs::OpenOptions;
use std::io::Write;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use synthgen_core::GtInfo;

use super::chunk::FrameRecord;
use super::types::{GtEntry, SceneCamera};
use crate::error::{Error, Result};
use crate::io::atomic_write;

/// File name of a scene folder's journal (hidden, so dataset readers skip it).
pub const JOURNAL_FILE: &str = ".synthgen-journal.jsonl";

/// `{scene_dir}/.synthgen-journal.jsonl`.
pub fn journal_path(scene_dir: &Path) -> PathBuf {
    scene_dir.join(JOURNAL_FILE)
}

/// One line of the journal. Floats go through serde_json with `float_roundtrip`, so a record
/// read back is bit-identical to the one written.
#[derive(Serialize, Deserialize)]
struct Line {
    frame_index: u64,
    scene_id: u32,
    im_id: u32,
    camera: SceneCamera,
    gt: Vec<GtEntry>,
    gt_info: Vec<GtInfo>,
    depth_out_of_range_px: u64,
}

fn line_of(r: &FrameRecord) -> Line {
    Line {
        frame_index: r.frame_index,
        scene_id: r.scene_id,
        im_id: r.im_id,
        camera: r.camera,
        gt: r.gt.clone(),
        gt_info: r.gt_info.clone(),
        depth_out_of_range_px: r.depth_out_of_range_px,
    }
}

fn record_of(l: Line) -> FrameRecord {
    FrameRecord {
        frame_index: l.frame_index,
        scene_id: l.scene_id,
        im_id: l.im_id,
        camera: l.camera,
        gt: l.gt,
        gt_info: l.gt_info,
        depth_out_of_range_px: l.depth_out_of_range_px,
    }
}

fn encode(r: &FrameRecord, path: &Path) -> Result<String> {
    let mut text = serde_json::to_string(&line_of(r)).map_err(|e| Error::json(path, e))?;
    text.push('\n');
    Ok(text)
}

/// Appends one record with a single `write` call (`O_APPEND`), optionally fsync'd.
pub fn append(scene_dir: &Path, record: &FrameRecord, fsync: bool) -> Result<()> {
    let path = journal_path(scene_dir);
    let text = encode(record, &path)?;
    let mut f = OpenOptions::new()
        .create(true)
        .append(true)
        .open(&path)
        .map_err(|e| Error::io("write", &path, e))?;
    f.write_all(text.as_bytes())
        .map_err(|e| Error::io("write", &path, e))?;
    if fsync {
        f.sync_data().map_err(|e| Error::io("write", &path, e))?;
    }
    Ok(())
}

/// The records of a scene folder's journal, in file order; none when there is no journal.
/// A torn or unparsable line ends the journal: it and anything after it are dropped.
pub fn read(scene_dir: &Path) -> Result<Vec<FrameRecord>> {
    Ok(read_checked(scene_dir)?.0)
}

/// [`read`], and whether the whole file was read (false when a torn tail was dropped).
pub fn read_checked(scene_dir: &Path) -> Result<(Vec<FrameRecord>, bool)> {
    let path = journal_path(scene_dir);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok((Vec::new(), true)),
        Err(e) => return Err(Error::io("read", &path, e)),
    };
    let mut out = Vec::new();
    for line in bytes.split_inclusive(|&b| b == b'\n') {
        let Some(body) = line.strip_suffix(b"\n") else {
            return Ok((out, false));
        };
        match serde_json::from_slice::<Line>(body) {
            Ok(l) => out.push(record_of(l)),
            Err(_) => return Ok((out, false)),
        }
    }
    Ok((out, true))
}

/// Replaces the journal with exactly `records` (atomically), dropping a torn tail.
pub fn rewrite(scene_dir: &Path, records: &[FrameRecord]) -> Result<()> {
    let path = journal_path(scene_dir);
    let mut text = String::new();
    for r in records {
        text.push_str(&encode(r, &path)?);
    }
    atomic_write(&path, text.as_bytes())
}

/// Deletes the journal (the folder's JSON now holds its records).
pub fn remove(scene_dir: &Path) -> Result<()> {
    let path = journal_path(scene_dir);
    match std::fs::remove_file(&path) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::io("remove", &path, e)),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn rec(i: u32, x: f64) -> FrameRecord {
        FrameRecord {
            frame_index: u64::from(i) + 10,
            scene_id: 1,
            im_id: i,
            camera: SceneCamera {
                cam_k: [x, 0.0, 1.0 / 3.0, 0.0, 572.4114, -0.0, 0.0, 0.0, 1.0],
                cam_r_w2c: None,
                cam_t_w2c: Some([1e-300, -2.5e16, 0.1 + 0.2]),
                depth_scale: 0.1,
            },
            gt: vec![GtEntry {
                cam_r_m2c: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                cam_t_m2c: [x, 2.0, 700.123456789],
                obj_id: 5,
            }],
            gt_info: vec![GtInfo {
                bbox_obj: [-3, 4, 5, 6],
                bbox_visib: [-1, -1, -1, -1],
                px_count_all: 9,
                px_count_valid: 8,
                px_count_visib: 0,
                visib_fract: 2.0 / 3.0,
            }],
            depth_out_of_range_px: 7,
        }
    }

    #[test]
    fn records_round_trip_bit_exactly() {
        let dir = tempfile::tempdir().unwrap();
        let a = rec(0, 0.123_456_789_012_345_67);
        let b = rec(1, -1.7976931348623157e308);
        append(dir.path(), &a, false).unwrap();
        append(dir.path(), &b, true).unwrap();
        let back = read(dir.path()).unwrap();
        assert_eq!(back, vec![a.clone(), b]);
        assert_eq!(
            back[0].camera.cam_k[5].to_bits(),
            a.camera.cam_k[5].to_bits()
        );
        remove(dir.path()).unwrap();
        assert!(read(dir.path()).unwrap().is_empty());
        remove(dir.path()).unwrap();
    }

    #[test]
    fn torn_last_line_is_dropped_and_rewritten_away() {
        let dir = tempfile::tempdir().unwrap();
        append(dir.path(), &rec(0, 1.0), false).unwrap();
        append(dir.path(), &rec(1, 2.0), false).unwrap();
        let p = journal_path(dir.path());
        let full = std::fs::read(&p).unwrap();
        // Every possible cut of the second line keeps exactly the first record.
        let first_len = full.iter().position(|&b| b == b'\n').unwrap() + 1;
        for cut in first_len..full.len() {
            std::fs::write(&p, &full[..cut]).unwrap();
            assert_eq!(read(dir.path()).unwrap().len(), 1, "cut at {cut}");
        }
        let kept = read(dir.path()).unwrap();
        rewrite(dir.path(), &kept).unwrap();
        append(dir.path(), &rec(2, 3.0), false).unwrap();
        let back = read(dir.path()).unwrap();
        assert_eq!(back.iter().map(|r| r.im_id).collect::<Vec<_>>(), vec![0, 2]);
    }
}
