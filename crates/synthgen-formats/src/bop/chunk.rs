//! Per-scene-folder accumulation of the annotation JSON files.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

use serde::Serialize;
use synthgen_core::GtInfo;

use super::json::{dumps, save_json_dict};
use super::reader::{read_scene_camera, read_scene_gt, read_scene_gt_info};
use super::types::{GtEntry, SceneCamera};
use crate::error::{Error, Result};
use crate::io::atomic_write_with;

/// What the writer produced for one image: its entries of the three scene JSON files.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameRecord {
    pub frame_index: u64,
    pub scene_id: u32,
    pub im_id: u32,
    pub camera: SceneCamera,
    /// One per object, in `FrameScene::objects` order (list index = gt id).
    pub gt: Vec<GtEntry>,
    pub gt_info: Vec<GtInfo>,
    /// Depth pixels too far for 16 bits at this `depth_scale`, written as 0.
    pub depth_out_of_range_px: u64,
}

/// `scene_camera.json`, `scene_gt.json` and `scene_gt_info.json` of one scene folder, built
/// from [`FrameRecord`]s arriving in any order and written sorted by image id.
#[derive(Debug, Clone, Default)]
pub struct ChunkAnnotations {
    pub scene_id: u32,
    camera: BTreeMap<u32, SceneCamera>,
    gt: BTreeMap<u32, Vec<GtEntry>>,
    gt_info: BTreeMap<u32, Vec<GtInfo>>,
    /// Image ids this run will deliver; the chunk is complete when all are present.
    expected: Range<u32>,
    present_expected: u32,
}

pub const SCENE_CAMERA: &str = "scene_camera.json";
pub const SCENE_GT: &str = "scene_gt.json";
pub const SCENE_GT_INFO: &str = "scene_gt_info.json";

impl ChunkAnnotations {
    pub fn new(scene_id: u32, expected: Range<u32>) -> ChunkAnnotations {
        ChunkAnnotations {
            scene_id,
            expected,
            ..Default::default()
        }
    }

    /// Adds the images already written in `scene_dir` (from an earlier run); records added
    /// afterwards replace those with the same image id. Does nothing if the folder has no
    /// `scene_camera.json`.
    pub fn load_existing(&mut self, scene_dir: &Path) -> Result<()> {
        let camera_path = scene_dir.join(SCENE_CAMERA);
        if !camera_path.exists() {
            return Ok(());
        }
        let camera = read_scene_camera(&camera_path)?;
        let gt = read_scene_gt(&scene_dir.join(SCENE_GT))?;
        let gt_info = read_scene_gt_info(&scene_dir.join(SCENE_GT_INFO))?;
        for (&im, cam) in &camera {
            let (Some(g), Some(i)) = (gt.get(&im), gt_info.get(&im)) else {
                return Err(Error::malformed(
                    &scene_dir.join(SCENE_GT),
                    format!("image {im} of {SCENE_CAMERA} has no ground truth"),
                ));
            };
            self.insert(im, *cam, g.clone(), i.clone());
        }
        Ok(())
    }

    fn insert(&mut self, im: u32, camera: SceneCamera, gt: Vec<GtEntry>, info: Vec<GtInfo>) {
        let new = self.camera.insert(im, camera).is_none();
        if new && self.expected.contains(&im) {
            self.present_expected += 1;
        }
        self.gt.insert(im, gt);
        self.gt_info.insert(im, info);
    }

    pub fn add(&mut self, record: FrameRecord) {
        self.insert(record.im_id, record.camera, record.gt, record.gt_info);
    }

    /// Number of images held.
    pub fn len(&self) -> usize {
        self.camera.len()
    }

    pub fn is_empty(&self) -> bool {
        self.camera.is_empty()
    }

    /// Whether every expected image is present.
    pub fn is_complete(&self) -> bool {
        self.present_expected as usize >= self.expected.len()
    }

    /// Writes the three JSON files into `scene_dir`, each atomically.
    pub fn write(&self, scene_dir: &Path, fsync: bool) -> Result<()> {
        // gt_info first and camera last: a reader that finds scene_camera.json finds the rest.
        write_map(&scene_dir.join(SCENE_GT_INFO), &self.gt_info, fsync)?;
        write_map(&scene_dir.join(SCENE_GT), &self.gt, fsync)?;
        write_map(&scene_dir.join(SCENE_CAMERA), &self.camera, fsync)
    }
}

/// Writes an image-id-keyed map in bop_toolkit's `save_json` layout.
pub fn write_map<T: Serialize>(path: &Path, map: &BTreeMap<u32, T>, fsync: bool) -> Result<()> {
    let text = bop_json_text(path, map)?;
    atomic_write_with(path, text.as_bytes(), fsync)
}

pub(crate) fn bop_json_text<T: Serialize>(path: &Path, map: &BTreeMap<u32, T>) -> Result<String> {
    let non_finite = |what: String| Error::NonFinite {
        what,
        path: path.to_path_buf(),
    };
    let mut entries = Vec::with_capacity(map.len());
    for (k, v) in map {
        let value = serde_json::to_value(v).map_err(|e| non_finite(format!("entry {k} ({e})")))?;
        entries.push((k, value));
    }
    save_json_dict(entries.iter().map(|(k, v)| (k, v))).map_err(|_| {
        // Only on this error path: find the entry to name.
        let bad = entries.iter().find(|(_, v)| dumps(v).is_err());
        non_finite(bad.map_or("an entry".into(), |(k, _)| format!("entry {k}")))
    })
}
