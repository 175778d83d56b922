//! 2D detections as BOP's challenge exchanges them (the "default detections" of BOP 2023,
//! COCO's result format): a JSON list of `{"scene_id", "image_id", "category_id", "score",
//! "bbox": [x, y, width, height], "time"}`, the box in pixels with the object covering
//! `x..x + width` (COCO's convention; one pixel more than `scene_gt_info`'s `bbox_visib`,
//! whose last pixel is `x + w`). Other fields (a `segmentation`) are ignored.
//!
//! `synthgen detect` writes them; `synthgen eval --detections` crops the RGB models' input
//! from them instead of the GT boxes ([`Detections::box_for`]).

use std::collections::BTreeMap;
use std::path::Path;

use serde::{Deserialize, Serialize};

use synthgen_train::{Error, Result};

/// One detection.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    pub scene_id: u32,
    pub image_id: u32,
    /// The object id.
    pub category_id: u32,
    pub score: f64,
    /// `[x, y, width, height]`, pixels; the object covers `x..x + width`.
    pub bbox: [f64; 4],
    /// Seconds the detector took for the image (−1 unknown).
    #[serde(default = "unknown_time")]
    pub time: f64,
}

fn unknown_time() -> f64 {
    -1.0
}

impl Detection {
    /// The box as `scene_gt_info`'s `bbox_visib` reads (`[x, y, w, h]`, last pixel `x + w`).
    pub fn bop_box(&self) -> [f64; 4] {
        let [x, y, w, h] = self.bbox;
        [x, y, (w - 1.0).max(0.0), (h - 1.0).max(0.0)]
    }

    /// The detection of a GT box as `scene_gt_info` writes it (score 1).
    pub fn from_bop_box(scene_id: u32, image_id: u32, obj_id: u32, b: [i64; 4]) -> Detection {
        Detection {
            scene_id,
            image_id,
            category_id: obj_id,
            score: 1.0,
            bbox: [
                b[0] as f64,
                b[1] as f64,
                b[2] as f64 + 1.0,
                b[3] as f64 + 1.0,
            ],
            time: -1.0,
        }
    }
}

/// Detections by image and object, each list best first.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Detections {
    by_object: BTreeMap<(u32, u32, u32), Vec<Detection>>,
    pub count: usize,
}

impl Detections {
    pub fn new(list: Vec<Detection>) -> Detections {
        let count = list.len();
        let mut by_object: BTreeMap<(u32, u32, u32), Vec<Detection>> = BTreeMap::new();
        for d in list {
            by_object
                .entry((d.scene_id, d.image_id, d.category_id))
                .or_default()
                .push(d);
        }
        for v in by_object.values_mut() {
            v.sort_by(|a, b| b.score.total_cmp(&a.score));
        }
        Detections { by_object, count }
    }

    /// The `rank`-th best detection (0: the best) of `obj_id` in an image, if there are that
    /// many: the box the `rank`-th instance of the object in the image is cropped from (BOP's
    /// localization task knows how many instances each image shows; which detection goes
    /// with which instance does not matter, the estimates are matched to the GT when scored).
    pub fn box_for(
        &self,
        scene_id: u32,
        im_id: u32,
        obj_id: u32,
        rank: usize,
    ) -> Option<&Detection> {
        self.by_object.get(&(scene_id, im_id, obj_id))?.get(rank)
    }

    /// The detections of `obj_id` in an image, best first.
    pub fn of(&self, scene_id: u32, im_id: u32, obj_id: u32) -> &[Detection] {
        self.by_object
            .get(&(scene_id, im_id, obj_id))
            .map_or(&[], Vec::as_slice)
    }

    pub fn iter(&self) -> impl Iterator<Item = &Detection> {
        self.by_object.values().flatten()
    }
}

pub(crate) fn io(op: &'static str, path: &Path, source: std::io::Error) -> Error {
    Error::Io {
        op,
        source,
        path: path.to_path_buf(),
    }
}

/// Reads a detections file; a malformed one is an error naming it and the entry.
pub fn read_detections(path: &Path) -> Result<Detections> {
    let text = std::fs::read_to_string(path).map_err(|e| io("read", path, e))?;
    let malformed = |message: String| Error::Malformed {
        what: "detections file",
        message,
        path: path.to_path_buf(),
    };
    let values: Vec<serde_json::Value> = serde_json::from_str(&text).map_err(|e| {
        malformed(format!(
            "{e} (expected a JSON list of {{\"scene_id\", \"image_id\", \"category_id\", \"score\", \"bbox\"}})"
        ))
    })?;
    let mut list = Vec::with_capacity(values.len());
    for (i, v) in values.into_iter().enumerate() {
        let d: Detection =
            serde_json::from_value(v).map_err(|e| malformed(format!("entry {i}: {e}")))?;
        let finite = d.score.is_finite() && d.bbox.iter().all(|v| v.is_finite());
        if !finite || d.bbox[2] <= 0.0 || d.bbox[3] <= 0.0 {
            return Err(malformed(format!(
                "entry {i}: the box {:?} (score {}) is not a box of positive size",
                d.bbox, d.score
            )));
        }
        list.push(d);
    }
    Ok(Detections::new(list))
}

/// Writes detections as a JSON list (atomically).
pub fn write_detections(path: &Path, list: &[Detection]) -> Result<()> {
    let text =
        serde_json::to_string_pretty(list).map_err(|e| Error::InvalidOption(e.to_string()))?;
    synthgen_core::atomic::write_atomic(path, (text + "\n").as_bytes(), false)
        .map_err(|(_, e)| io("write", path, e))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn detections_are_read_best_first_and_bad_entries_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("det.json");
        std::fs::write(
            &path,
            r#"[{"scene_id": 2, "image_id": 3, "category_id": 5, "score": 0.4, "bbox": [10, 20, 30, 40], "time": 0.1},
                {"scene_id": 2, "image_id": 3, "category_id": 5, "score": 0.9, "bbox": [11, 21, 31, 41], "segmentation": {"counts": "x"}}]"#,
        )
        .unwrap();
        let d = read_detections(&path).unwrap();
        assert_eq!(d.count, 2);
        assert_eq!(d.box_for(2, 3, 5, 0).unwrap().score, 0.9);
        assert_eq!(
            d.box_for(2, 3, 5, 1).unwrap().bbox,
            [10.0, 20.0, 30.0, 40.0]
        );
        assert!(d.box_for(2, 3, 5, 2).is_none());
        assert!(d.box_for(2, 3, 6, 0).is_none());
        // COCO's width is one more than bbox_visib's.
        assert_eq!(
            d.box_for(2, 3, 5, 1).unwrap().bop_box(),
            [10.0, 20.0, 29.0, 39.0]
        );
        let gt = Detection::from_bop_box(2, 3, 5, [10, 20, 29, 39]);
        assert_eq!(gt.bop_box(), [10.0, 20.0, 29.0, 39.0]);

        std::fs::write(&path, r#"[{"scene_id": 2, "image_id": 3, "category_id": 5, "score": 1, "bbox": [1, 2, 0, 4]}]"#).unwrap();
        let e = read_detections(&path).unwrap_err().to_string();
        assert!(e.contains("entry 0") && e.contains("det.json"), "{e}");
        std::fs::write(
            &path,
            r#"[{"scene_id": 2, "image_id": 3, "score": 1, "bbox": [1, 2, 3, 4]}]"#,
        )
        .unwrap();
        let e = read_detections(&path).unwrap_err().to_string();
        assert!(e.contains("category_id") && e.contains("det.json"), "{e}");
        std::fs::write(&path, "{}").unwrap();
        assert!(read_detections(&path)
            .unwrap_err()
            .to_string()
            .contains("JSON list"));
    }
}
