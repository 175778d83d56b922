//! 2D detections as BOP's challenge exchanges them (the "default detections" of BOP 2023,
//! COCO's result format): a JSON list of `{"scene_id", "image_id", "category_id", "score",
//! "bbox": [x, y, width, height], "time"}`, the box in pixels with the object covering
//! `x..x + width` (COCO's convention; one pixel more than `scene_gt_info`'s `bbox_visib`,
//! whose last pixel is `x + w`), and, where the detector gives one, `"segmentation"`: the
//! visible mask as COCO RLE (`{"size": [h, w], "counts": ...}`, compressed or a list).
//!
//! `synthgen detect` writes them; `synthgen eval --detections` crops the RGB models' input
//! from them instead of the GT boxes ([`Detections::box_for`]).

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use synthgen_formats::coco::Rle;
use synthgen_formats::identity::{FramesKey, ObjectIdentity};
use synthgen_train::data::{CropBoxes, CropMasks};
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
    /// The visible mask, when the detector gives one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segmentation: Option<Rle>,
}

fn unknown_time() -> f64 {
    -1.0
}

/// A COCO box (`[x, y, width, height]`) as `scene_gt_info`'s `bbox_visib` reads (last pixel
/// `x + w`): what the pose models' crops are made from.
pub fn bop_box(bbox: [f64; 4]) -> [f64; 4] {
    let [x, y, w, h] = bbox;
    [x, y, (w - 1.0).max(0.0), (h - 1.0).max(0.0)]
}

impl Detection {
    /// The box as `scene_gt_info`'s `bbox_visib` reads (`[x, y, w, h]`, last pixel `x + w`).
    pub fn bop_box(&self) -> [f64; 4] {
        bop_box(self.bbox)
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
            segmentation: None,
        }
    }
}

/// `list` best score first (ties in file order).
fn best_first<'a>(list: impl Iterator<Item = &'a Detection>) -> Vec<&'a Detection> {
    let mut sorted: Vec<&Detection> = list.collect();
    sorted.sort_by(|a, b| b.score.total_cmp(&a.score));
    sorted
}

/// The boxes of `list` as the RGB models' crops and the refinement read them: per (scene,
/// image, object), best score first, as `bbox_visib` reads ([`Detection::bop_box`]). The
/// `rank`-th instance of an object in an image is cropped from its `rank`-th box (BOP's
/// localization task knows how many instances each image shows; which detection goes with
/// which instance does not matter, the estimates are matched to the GT when scored).
pub fn crop_boxes(list: &[Detection]) -> CropBoxes {
    let mut out = CropBoxes::new();
    for d in best_first(list.iter()) {
        out.entry((d.scene_id, d.image_id, d.category_id))
            .or_default()
            .push(d.bop_box());
    }
    out
}

/// The masks of `list` as the depth models read their points from them: per (scene, image,
/// object), best score first, the entries that have a mask ([`crop_boxes`]' order).
pub fn crop_masks(list: &[Detection]) -> CropMasks {
    let mut out = CropMasks::new();
    for d in best_first(list.iter()) {
        if let Some(m) = &d.segmentation {
            out.entry((d.scene_id, d.image_id, d.category_id))
                .or_default()
                .push(m.clone());
        }
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

/// Where a detections file came from, written beside it by `synthgen detector run`
/// ([`provenance_path`]): the frames it is of and what its ids stand for, so that joining it
/// to another dataset whose ids coincide is refused. Files of other detectors have none.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// "synthgen detector run" and the version.
    pub written_by: String,
    pub dataset: PathBuf,
    pub split: String,
    pub frames: FramesKey,
    /// The detector's classes (its `category_id`s) and what each is.
    pub objects: Vec<ObjectIdentity>,
    pub detector: PathBuf,
}

/// The provenance file of detections file `path`: `det.json` → `det.provenance.json`.
pub fn provenance_path(path: &Path) -> PathBuf {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!("{stem}.provenance.json"))
}

/// Writes `prov` beside the detections file `path` (atomically).
pub fn write_provenance(path: &Path, prov: &Provenance) -> Result<()> {
    let text =
        serde_json::to_string_pretty(prov).map_err(|e| Error::InvalidOption(e.to_string()))?;
    synthgen_train::train::write_atomic(&provenance_path(path), (text + "\n").as_bytes())
}

/// The provenance beside the detections file `path`, None when it has none.
pub fn read_provenance(path: &Path) -> Result<Option<Provenance>> {
    let p = provenance_path(path);
    if !p.is_file() {
        return Ok(None);
    }
    synthgen_train::train::read_json(&p, "detections provenance").map(Some)
}

/// What joining a detections file to a dataset's frames kept and left out.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct JoinReport {
    pub entries: usize,
    pub kept: usize,
    /// Entries of an image the split does not have.
    pub other_frames: usize,
    /// Entries of an object id the dataset has no instance of in that split.
    pub unknown_objects: usize,
    /// Entries whose box misses the image or is larger than twice it.
    pub off_image: usize,
    /// Entries whose mask is of another size than the images.
    pub mask_size: usize,
    /// A few of the skipped entries, "entry N: why".
    pub examples: Vec<String>,
}

impl JoinReport {
    pub fn skipped(&self) -> usize {
        self.other_frames + self.unknown_objects + self.off_image + self.mask_size
    }

    /// "12 of 40 entries skipped: 10 of images not in the split, 2 boxes off the image (entry 3: ...)".
    pub fn describe(&self) -> String {
        let mut parts = Vec::new();
        for (n, what) in [
            (self.other_frames, "of images the split does not have"),
            (
                self.unknown_objects,
                "of objects the split has no instance of",
            ),
            (
                self.off_image,
                "with a box off the image or larger than twice it",
            ),
            (
                self.mask_size,
                "with a mask of another size than the images",
            ),
        ] {
            if n > 0 {
                parts.push(format!("{n} {what}"));
            }
        }
        format!(
            "{} of {} detections skipped: {}{}",
            self.skipped(),
            self.entries,
            parts.join(", "),
            if self.examples.is_empty() {
                String::new()
            } else {
                format!(" ({})", self.examples.join("; "))
            }
        )
    }
}

/// The detections of `list` that belong to the frames `frames` ((scene, image) → the object
/// ids with GT there, or None where the frame's objects are not known) of images
/// `image_size` big: per entry, its image must be one of the frames, its object one the
/// frame shows (when known), its box must overlap the image and be at most twice its size
/// (a box 1e308 wide is not a detection). The others are counted, a few named.
pub fn join_detections(
    list: &[Detection],
    frames: &BTreeMap<(u32, u32), Option<BTreeSet<u32>>>,
    image_size: [u32; 2],
) -> (Vec<Detection>, JoinReport) {
    let (w, h) = (f64::from(image_size[0]), f64::from(image_size[1]));
    let mut report = JoinReport {
        entries: list.len(),
        ..JoinReport::default()
    };
    let mut kept = Vec::with_capacity(list.len());
    for (i, d) in list.iter().enumerate() {
        let [x, y, bw, bh] = d.bbox;
        let why = match frames.get(&(d.scene_id, d.image_id)) {
            None => {
                report.other_frames += 1;
                format!(
                    "entry {i}: scene {} image {} is not in the split",
                    d.scene_id, d.image_id
                )
            }
            Some(Some(objs)) if !objs.contains(&d.category_id) => {
                report.unknown_objects += 1;
                format!(
                    "entry {i}: object {} is not in scene {} image {}",
                    d.category_id, d.scene_id, d.image_id
                )
            }
            _ if x + bw <= 0.0
                || y + bh <= 0.0
                || x >= w
                || y >= h
                || bw > 2.0 * w
                || bh > 2.0 * h =>
            {
                report.off_image += 1;
                format!(
                    "entry {i}: the box {:?} does not fit the {}x{} image",
                    d.bbox, image_size[0], image_size[1]
                )
            }
            _ if d
                .segmentation
                .as_ref()
                .is_some_and(|m| [m.width, m.height] != image_size) =>
            {
                report.mask_size += 1;
                format!(
                    "entry {i}: the mask is not {}x{}, the images' size",
                    image_size[0], image_size[1]
                )
            }
            _ => {
                kept.push(d.clone());
                continue;
            }
        };
        if report.examples.len() < 3 {
            report.examples.push(why);
        }
    }
    report.kept = kept.len();
    (kept, report)
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
                {"scene_id": 2, "image_id": 3, "category_id": 5, "score": 0.9, "bbox": [11, 21, 31, 41], "segmentation": {"size": [2, 3], "counts": [1, 2, 3]}}]"#,
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

        assert_eq!(d[1].segmentation.as_ref().map(|m| m.area()), Some(2));
        assert_eq!(d[0].segmentation, None);
        // A mask whose runs do not fill its size is named with its entry.
        std::fs::write(&path, r#"[{"scene_id": 2, "image_id": 3, "category_id": 5, "score": 1, "bbox": [1, 2, 3, 4], "segmentation": {"size": [2, 3], "counts": [1, 2]}}]"#).unwrap();
        let e = read_detections(&path).unwrap_err().to_string();
        assert!(e.contains("entry 0") && e.contains("cover 3 pixels"), "{e}");
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

    #[test]
    fn joining_keeps_what_fits_the_frames_and_counts_the_rest() {
        let d = |scene, im, obj, bbox| Detection {
            scene_id: scene,
            image_id: im,
            category_id: obj,
            score: 0.5,
            bbox,
            time: -1.0,
            segmentation: None,
        };
        let list = vec![
            d(2, 3, 5, [10.0, 20.0, 30.0, 40.0]),
            d(2, 4, 5, [10.0, 20.0, 30.0, 40.0]), // no such image
            d(2, 3, 9, [10.0, 20.0, 30.0, 40.0]), // no object 9 there
            d(2, 3, 5, [700.0, 20.0, 30.0, 40.0]), // right of the image
            d(2, 3, 5, [0.0, 0.0, 1e308, 40.0]),  // absurdly wide
            d(7, 0, 1, [0.0, 0.0, 5.0, 5.0]),     // objects unknown: kept
        ];
        let mut frames = BTreeMap::new();
        frames.insert((2, 3), Some(BTreeSet::from([5])));
        frames.insert((7, 0), None);
        let (kept, r) = join_detections(&list, &frames, [640, 480]);
        assert_eq!(kept.len(), 2);
        assert_eq!(
            (
                r.entries,
                r.kept,
                r.other_frames,
                r.unknown_objects,
                r.off_image
            ),
            (6, 2, 1, 1, 2)
        );
        let text = r.describe();
        assert!(text.starts_with("4 of 6 detections skipped"), "{text}");
        assert!(
            text.contains("entry 1: scene 2 image 4 is not in the split"),
            "{text}"
        );
    }

    #[test]
    fn the_provenance_sits_beside_its_file() {
        assert_eq!(
            provenance_path(Path::new("runs/det_lmo.json")),
            PathBuf::from("runs/det_lmo.provenance.json")
        );
    }
}
