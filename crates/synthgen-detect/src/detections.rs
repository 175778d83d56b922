//! 2D detections as BOP's challenge exchanges them (the "default detections" of BOP 2023,
//! COCO's result format): a JSON list of `{"scene_id", "image_id", "category_id", "score",
//! "bbox": [x, y, width, height], "time"}`, the box in pixels with the object covering
//! `x..x + width` (COCO's convention; one pixel more than `scene_gt_info`'s `bbox_visib`,
//! whose last pixel is `x + w`). Other fields (a `segmentation`) are ignored.
//!
//! `synthgen detect` writes them; `synthgen eval --detections` crops the RGB models' input
//! from them instead of the GT boxes ([`Detections::box_for`]).

use std::path::Path;

use serde::{Deserialize, Serialize};

use synthgen_train::data::CropBoxes;
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

/// The boxes of `list` as the RGB models' crops and the refinement read them: per (scene,
/// image, object), best score first, as `bbox_visib` reads ([`Detection::bop_box`]). The
/// `rank`-th instance of an object in an image is cropped from its `rank`-th box (BOP's
/// localization task knows how many instances each image shows; which detection goes with
/// which instance does not matter, the estimates are matched to the GT when scored).
pub fn crop_boxes(list: &[Detection]) -> CropBoxes {
    let mut sorted: Vec<&Detection> = list.iter().collect();
    sorted.sort_by(|a, b| b.score.total_cmp(&a.score));
    let mut out = CropBoxes::new();
    for d in sorted {
        out.entry((d.scene_id, d.image_id, d.category_id))
            .or_default()
            .push(d.bop_box());
    }
    out
}

/// Reads a detections file; a malformed one is an error naming it and the entry.
pub fn read_detections(path: &Path) -> Result<Vec<Detection>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io("read", path, e))?;
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
    Ok(list)
}

/// Writes detections as a JSON list (atomically).
pub fn write_detections(path: &Path, list: &[Detection]) -> Result<()> {
    let text =
        serde_json::to_string_pretty(list).map_err(|e| Error::InvalidOption(e.to_string()))?;
    synthgen_train::train::write_atomic(path, (text + "\n").as_bytes())
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
        assert_eq!(d.len(), 2);
        let boxes = crop_boxes(&d);
        // Best first (score 0.9, then 0.4), and COCO's width is one more than bbox_visib's.
        assert_eq!(
            boxes[&(2, 3, 5)],
            vec![[11.0, 21.0, 30.0, 40.0], [10.0, 20.0, 29.0, 39.0]]
        );
        assert!(!boxes.contains_key(&(2, 3, 6)));
        assert_eq!(d[0].bop_box(), [10.0, 20.0, 29.0, 39.0]);
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
