//! `synthgen detector eval`: a BOP detections file (boxes, and masks as COCO RLE where it has
//! them: ours, CNOS's, SAM-6D's, GDRNPP's) scored against a dataset's GT as bop_toolkit's
//! `scripts/eval_bop22_coco.py` scores it (`synthgen_detect::coco_eval`).
//!
//! The GT is what bop_toolkit's `calc_gt_coco.py` writes: per image of the split (by default
//! those of the dataset's `test_targets_bop19.json`, as the script reads), per GT instance
//! with a visible pixel, its visible mask as the segmentation, its visible pixels as the
//! area, and as the box the bounds of its full silhouette (amodal, the default) or of its
//! visible mask (modal). Masks come from the dataset (`mask_visib/`, `mask/`, YCB-Video's
//! `label.png`); where it has none they are rendered from the GT poses and models as
//! `synthgen annotate` computes them (against the frame's depth where it has one, else the
//! other GT objects only), and the output says so.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::Serialize;
use serde_json::json;
use synthgen_core::annotate::DEFAULT_VISIB_DELTA_M;
use synthgen_core::Progress;
use synthgen_detect::coco_eval::{
    evaluate, CocoScores, DtInstance, GtInstance, IouType, STAT_NAMES,
};
use synthgen_detect::detections::read_detections;
use synthgen_formats::annotate::annotate_frame;
use synthgen_formats::coco::Rle;
use synthgen_formats::layout::open_source;
use synthgen_formats::output::check_apart;
use synthgen_formats::source::SourceFrame;
use synthgen_render::ObjectRenderer;
use synthgen_train::eval::pick_split;

use crate::models::{frame_obj_ids, object_renderer};
use crate::{user_error, Log};

/// Which box of a GT instance the detections' boxes are compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BboxType {
    /// The full silhouette's bounds, occluded parts included (bop_toolkit's default).
    #[default]
    Amodal,
    /// The visible mask's bounds.
    Modal,
}

/// BOP's estimation targets file, read by default when the dataset has it.
pub const TARGETS_FILE: &str = "test_targets_bop19.json";

/// A detections file scored against a dataset: `synthgen detector eval`'s arguments.
#[derive(Debug, Clone, Default)]
pub struct DetectionEvalRequest {
    pub data: PathBuf,
    pub split: Option<String>,
    pub detections: PathBuf,
    /// The images to score (a BOP targets file); default: the dataset's
    /// [`TARGETS_FILE`] when it has one, else every frame of the split.
    pub targets: Option<PathBuf>,
    /// Every frame of the split, targets file or not.
    pub all_frames: bool,
    pub bbox_type: BboxType,
    /// Write the scores as JSON here.
    pub out: Option<PathBuf>,
    /// Write the COCO GT scored against here (pycocotools' `COCO(...)` reads it).
    pub gt_out: Option<PathBuf>,
    /// Draw this many scored images (spread over them) into this folder: the GT's visible
    /// masks and boxes against each object's best detection ([`draw_frames`]).
    pub draw: Option<(PathBuf, usize)>,
    pub jobs: Option<usize>,
}

/// One set of scores (`bbox` or `segm`): bop_toolkit's twelve numbers and each object's.
#[derive(Debug, Clone, Serialize)]
pub struct ScoreSet {
    /// `AP`, `AP50`, ... as bop_toolkit's `scores_bop22_coco_*.json` names them.
    pub stats: BTreeMap<String, f64>,
    /// Per object id: `AP`, `AP50`, `AP75`, `AR100`, `n_gt`.
    pub objects: BTreeMap<u32, BTreeMap<String, f64>>,
}

impl ScoreSet {
    fn of(s: &CocoScores) -> ScoreSet {
        ScoreSet {
            stats: STAT_NAMES
                .iter()
                .zip(s.stats)
                .map(|(n, v)| (n.to_string(), v))
                .collect(),
            objects: s
                .objects
                .iter()
                .map(|(&obj, o)| {
                    (
                        obj,
                        BTreeMap::from([
                            ("AP".to_string(), o.ap),
                            ("AP50".to_string(), o.ap50),
                            ("AP75".to_string(), o.ap75),
                            ("AR100".to_string(), o.ar100),
                            ("n_gt".to_string(), o.n_gt as f64),
                        ]),
                    )
                })
                .collect(),
        }
    }

    pub fn stat(&self, name: &str) -> f64 {
        self.stats.get(name).copied().unwrap_or(-1.0)
    }
}

/// What `detector eval` scored and how.
#[derive(Debug, Clone, Serialize)]
pub struct DetectionScores {
    pub detections: PathBuf,
    pub dataset: PathBuf,
    pub split: String,
    pub bbox_type: BboxType,
    /// The targets file that chose the images, if one did.
    pub targets: Option<PathBuf>,
    pub n_images: usize,
    pub n_gt: usize,
    /// Images whose GT masks were rendered from the poses (the dataset has none there).
    pub images_with_rendered_masks: usize,
    /// Entries in the file; scored (of the images); of other images (left out, as
    /// bop_toolkit leaves them); of objects with no GT in these images (in no mean).
    pub entries: usize,
    pub scored: usize,
    pub other_images: usize,
    pub objects_without_gt: usize,
    /// Scored entries without a mask (left out of `segm`, as bop_toolkit leaves them).
    pub without_mask: usize,
    /// Scored entries whose box lies wholly off the image (false positives, as bop_toolkit
    /// scores them; counted so that they are not a silent score).
    pub off_image: usize,
    pub bbox: ScoreSet,
    /// None when no entry has a mask.
    pub segm: Option<ScoreSet>,
}

impl DetectionScores {
    /// The block `experiment sim2real` writes as `report.json["detection"]`.
    pub fn report_block(&self) -> serde_json::Value {
        let segm = |k: &str| self.segm.as_ref().map(|s| s.stat(k));
        let mut objects = serde_json::Map::new();
        for (obj, b) in &self.bbox.objects {
            let s = self.segm.as_ref().and_then(|s| s.objects.get(obj));
            objects.insert(
                obj.to_string(),
                json!({
                    "n_gt": b.get("n_gt"),
                    "bbox_ap": b.get("AP"),
                    "bbox_ap50": b.get("AP50"),
                    "segm_ap": s.and_then(|s| s.get("AP")),
                    "segm_ap50": s.and_then(|s| s.get("AP50")),
                }),
            );
        }
        json!({
            "n_gt": self.n_gt,
            "bbox_type": self.bbox_type,
            "bbox_ap": self.bbox.stat("AP"),
            "bbox_ap50": self.bbox.stat("AP50"),
            "segm_ap": segm("AP"),
            "segm_ap50": segm("AP50"),
            "objects": objects,
        })
    }

    /// The scores as markdown tables (what the CLI prints).
    pub fn table(&self) -> String {
        let fmt = |v: f64| {
            if v < 0.0 {
                "–".to_string()
            } else {
                format!("{v:.3}")
            }
        };
        let mut s = String::from("| score | bbox | segm |\n|---|---:|---:|\n");
        for name in STAT_NAMES {
            s += &format!(
                "| {name} | {} | {} |\n",
                fmt(self.bbox.stat(name)),
                self.segm
                    .as_ref()
                    .map_or_else(|| "no masks".to_string(), |m| fmt(m.stat(name)))
            );
        }
        s += "\n| object | GT | bbox AP | bbox AP50 | segm AP | segm AP50 |\n|---:|---:|---:|---:|---:|---:|\n";
        for (obj, b) in &self.bbox.objects {
            let m = self.segm.as_ref().and_then(|m| m.objects.get(obj));
            let get = |set: Option<&BTreeMap<String, f64>>, k: &str| {
                set.and_then(|x| x.get(k))
                    .map_or("–".to_string(), |&v| fmt(v))
            };
            s += &format!(
                "| {obj} | {} | {} | {} | {} | {} |\n",
                b.get("n_gt").copied().unwrap_or(0.0),
                get(Some(b), "AP"),
                get(Some(b), "AP50"),
                get(m, "AP"),
                get(m, "AP50"),
            );
        }
        s
    }
}

/// The COCO GT of some frames, as bop_toolkit's `calc_gt_coco.py` builds it.
#[derive(Debug, Clone, Default)]
pub struct CocoGt {
    /// (scene, image) per image index.
    pub images: Vec<(u32, u32)>,
    pub width: u32,
    pub height: u32,
    pub instances: Vec<GtInstance>,
    /// Per instance: its visible fraction (bop_toolkit writes `"ignore"` below 0.1).
    pub visib_fract: Vec<f64>,
    pub images_with_rendered_masks: usize,
}

impl CocoGt {
    /// The GT as a COCO annotation file (`COCO(...)` reads it; ids from 1).
    pub fn to_json(&self) -> serde_json::Value {
        let mut cats: Vec<u32> = self.instances.iter().map(|g| g.category).collect();
        cats.sort_unstable();
        cats.dedup();
        json!({
            "images": self.images.iter().enumerate().map(|(i, (scene, im))| json!({
                "id": i, "scene_id": scene, "im_id": im,
                "width": self.width, "height": self.height,
            })).collect::<Vec<_>>(),
            "annotations": self.instances.iter().zip(&self.visib_fract).enumerate().map(|(j, (g, v))| json!({
                "id": j + 1, "image_id": g.image, "category_id": g.category, "iscrowd": 0,
                "area": g.area, "bbox": g.bbox,
                "segmentation": g.segmentation.as_ref().map(|r| json!({"size": [r.height, r.width], "counts": r.counts})),
                "ignore": *v < 0.1, "width": self.width, "height": self.height,
            })).collect::<Vec<_>>(),
            "categories": cats.iter().map(|c| json!({"id": c, "name": c.to_string()})).collect::<Vec<_>>(),
        })
    }
}

/// COCO's box of a mask: `[x, y, width, height]`, the last column `x + width - 1`.
fn mask_box(mask: &[u8], width: u32) -> Option<[f64; 4]> {
    let b = synthgen_core::annotate::mask_bbox(mask, width);
    (b[2] >= 0 && b[3] >= 0).then(|| {
        [
            f64::from(b[0]),
            f64::from(b[1]),
            f64::from(b[2] + 1),
            f64::from(b[3] + 1),
        ]
    })
}

/// The frames' GT as COCO instances. A frame where the dataset lacks a needed mask gets it
/// rendered by `renderer` (None: an error naming the frame).
pub fn coco_gt(
    frames: &[SourceFrame],
    size: (u32, u32),
    bbox_type: BboxType,
    renderer: Option<&ObjectRenderer>,
) -> Result<CocoGt> {
    let (w, h) = size;
    // Per frame: its instances with their visible fractions, and whether it was rendered.
    type FrameGt = (Vec<(GtInstance, f64)>, bool);
    let per_frame: Result<Vec<FrameGt>> = frames
        .par_iter()
        .enumerate()
        .map(|(image, f)| {
            let rendered = if lacks_masks(f, bbox_type) {
                let r = renderer.with_context(|| {
                    format!(
                        "{}/{:06} image {} has no masks and no models to render them from",
                        f.location.split, f.location.scene_id, f.location.im_id
                    )
                })?;
                Some(annotate_frame(r, f, w, h, DEFAULT_VISIB_DELTA_M)?)
            } else {
                None
            };
            let read = |m: Option<&synthgen_formats::source::MaskRef>,
                        computed: Option<&Vec<u8>>|
             -> Result<Option<Vec<u8>>> {
                match (m, computed) {
                    (Some(m), _) => Ok(Some(m.read_sized(w, h)?.data)),
                    (None, Some(c)) => Ok(Some(c.clone())),
                    (None, None) => Ok(None),
                }
            };
            let mut out = Vec::new();
            for (i, g) in f.gt.iter().enumerate() {
                let ann = rendered.as_ref().and_then(|r| r.objects.get(i));
                let Some(visib) = read(
                    f.masks_visib.get(i).and_then(Option::as_ref),
                    ann.map(|a| &a.mask_visib),
                )?
                else {
                    continue;
                };
                let area = visib.iter().filter(|&&v| v != 0).count();
                if area == 0 {
                    continue;
                }
                let full = read(
                    f.masks.get(i).and_then(Option::as_ref),
                    ann.map(|a| &a.mask),
                )?;
                let full_area = full.as_ref().map(|m| m.iter().filter(|&&v| v != 0).count());
                let bbox = match bbox_type {
                    BboxType::Modal => mask_box(&visib, w),
                    BboxType::Amodal => full.as_ref().and_then(|m| mask_box(m, w)),
                };
                let Some(bbox) = bbox else { continue };
                let visib_fract = f
                    .gt_info
                    .as_ref()
                    .and_then(|info| info.get(i))
                    .map(|info| info.visib_fract)
                    .or_else(|| full_area.map(|a| area as f64 / a.max(1) as f64))
                    .unwrap_or(1.0);
                out.push((
                    GtInstance {
                        image,
                        category: g.obj_id,
                        bbox,
                        area: area as f64,
                        iscrowd: false,
                        segmentation: Some(Rle::from_mask(&visib, w, h)),
                    },
                    visib_fract,
                ));
            }
            Ok((out, rendered.is_some()))
        })
        .collect();
    let mut gt = CocoGt {
        images: frames
            .iter()
            .map(|f| (f.location.scene_id, f.location.im_id))
            .collect(),
        width: w,
        height: h,
        ..CocoGt::default()
    };
    for (instances, rendered) in per_frame? {
        gt.images_with_rendered_masks += usize::from(rendered);
        for (g, v) in instances {
            gt.instances.push(g);
            gt.visib_fract.push(v);
        }
    }
    Ok(gt)
}

/// Whether a frame lacks a mask the GT needs (a visible one; with amodal boxes, a full one):
/// its masks are then rendered.
fn lacks_masks(f: &SourceFrame, bbox_type: BboxType) -> bool {
    (0..f.gt.len()).any(|i| {
        f.masks_visib.get(i).and_then(Option::as_ref).is_none()
            || (bbox_type == BboxType::Amodal && f.masks.get(i).and_then(Option::as_ref).is_none())
    })
}

/// The (scene, image) pairs a BOP targets file names.
fn read_targets(path: &Path) -> Result<BTreeSet<(u32, u32)>> {
    #[derive(serde::Deserialize)]
    struct Target {
        scene_id: u32,
        im_id: u32,
    }
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let list: Vec<Target> = serde_json::from_str(&text).map_err(|e| {
        user_error(
            format!("{} is not a BOP targets file: {e}", path.display()),
            "a JSON list of {\"scene_id\", \"im_id\", \"obj_id\", \"inst_count\"}, as test_targets_bop19.json",
        )
    })?;
    Ok(list.into_iter().map(|t| (t.scene_id, t.im_id)).collect())
}

/// Scores `req.detections` against `req.data`'s GT as bop_toolkit does.
pub fn detection_eval_run(
    req: &DetectionEvalRequest,
    progress: &dyn Progress,
) -> Result<DetectionScores> {
    let log = Log::new(progress);
    crate::use_threads(req.jobs);
    let inputs = [
        ("dataset", req.data.as_path()),
        ("detections", req.detections.as_path()),
    ];
    for out in req
        .out
        .iter()
        .chain(&req.gt_out)
        .chain(req.draw.as_ref().map(|(d, _)| d))
    {
        check_apart(out, &inputs)?;
    }
    if let (Some(a), Some(b)) = (&req.out, &req.gt_out) {
        if a == b {
            return Err(user_error(
                format!("--out and --gt-out are both {}", a.display()),
                "give them two files",
            ));
        }
    }
    let source = open_source(&req.data)
        .with_context(|| format!("cannot open the dataset {}", req.data.display()))?;
    let split = pick_split(source.as_ref(), req.split.as_deref())?;
    let list = read_detections(&req.detections)?;
    let mut frames = source.annotation_frames(std::slice::from_ref(&split))?;
    let targets_path = match (&req.targets, req.all_frames) {
        (Some(_), true) => {
            return Err(user_error(
                "--targets and --all-frames both given",
                "give one: the images of a targets file, or every frame",
            ))
        }
        (Some(t), false) => Some(t.clone()),
        (None, false) => Some(source.root().join(TARGETS_FILE)).filter(|p| p.is_file()),
        (None, true) => None,
    };
    if let Some(t) = &targets_path {
        let targets = read_targets(t)?;
        let before = frames.len();
        frames.retain(|f| targets.contains(&(f.location.scene_id, f.location.im_id)));
        log.info(format!(
            "scoring the {} of {before} frames of {}/{split} that {} names",
            frames.len(),
            req.data.display(),
            t.display()
        ));
        if frames.is_empty() {
            return Err(user_error(
                format!(
                    "{} names none of the frames of {}/{split}",
                    t.display(),
                    req.data.display()
                ),
                "pass the targets file of this dataset, or --all-frames",
            ));
        }
    }
    if frames.is_empty() {
        return Err(user_error(
            format!("{}/{split} has no frames", req.data.display()),
            "pass a dataset with annotated frames",
        ));
    }
    let cam = source.camera();
    let size = (cam.width, cam.height);
    let lacking: Vec<SourceFrame> = frames
        .iter()
        .filter(|f| lacks_masks(f, req.bbox_type))
        .cloned()
        .collect();
    let renderer = if lacking.is_empty() {
        None
    } else {
        log.info(format!(
            "{} of {} frames have no GT masks: rendering them from the GT poses and models",
            lacking.len(),
            frames.len()
        ));
        Some(object_renderer(
            source.as_ref(),
            &frame_obj_ids(&lacking),
            progress,
        )?)
    };
    let gt = coco_gt(&frames, size, req.bbox_type, renderer.as_ref())?;

    // The detections of the scored images; the others are left out, as bop_toolkit does.
    let index: BTreeMap<(u32, u32), usize> =
        gt.images.iter().enumerate().map(|(i, &k)| (k, i)).collect();
    let gt_objects: BTreeSet<u32> = gt.instances.iter().map(|g| g.category).collect();
    let mut dts = Vec::with_capacity(list.len());
    let (mut other_images, mut objects_without_gt, mut off_image) = (0, 0, 0);
    for (i, d) in list.iter().enumerate() {
        let Some(&image) = index.get(&(d.scene_id, d.image_id)) else {
            other_images += 1;
            continue;
        };
        if let Some(m) = &d.segmentation {
            if (m.width, m.height) != size {
                return Err(user_error(
                    format!(
                        "{}: entry {i}'s mask is {}x{} but the images are {}x{}",
                        req.detections.display(),
                        m.width,
                        m.height,
                        size.0,
                        size.1
                    ),
                    "score detections of this dataset's images",
                ));
            }
        }
        objects_without_gt += usize::from(!gt_objects.contains(&d.category_id));
        let [x, y, w, h] = d.bbox;
        off_image += usize::from(
            x + w <= 0.0 || y + h <= 0.0 || x >= f64::from(size.0) || y >= f64::from(size.1),
        );
        dts.push(DtInstance {
            image,
            category: d.category_id,
            score: d.score,
            bbox: d.bbox,
            area: d.bbox[2] * d.bbox[3],
            segmentation: d.segmentation.clone(),
        });
    }
    if other_images > 0 {
        log.warning(format!(
            "{other_images} of {} detections are of images not scored (not in {}/{split}{}): left out",
            list.len(),
            req.data.display(),
            if targets_path.is_some() { " or not targets" } else { "" }
        ));
    }
    if off_image > 0 {
        log.warning(format!(
            "{off_image} detections in {} have a box wholly off the {}x{} images: scored as false positives, as bop_toolkit scores them",
            req.detections.display(),
            size.0,
            size.1
        ));
    }
    let bbox = evaluate(&gt.instances, &dts, gt.images.len(), IouType::Bbox)
        .map_err(|e| anyhow::anyhow!(e))?;
    let with_mask: Vec<DtInstance> = dts
        .iter()
        .filter(|d| d.segmentation.is_some())
        .cloned()
        .collect();
    let without_mask = dts.len() - with_mask.len();
    let segm = if with_mask.is_empty() {
        log.info(format!(
            "{} has no masks (\"segmentation\"): boxes scored only",
            req.detections.display()
        ));
        None
    } else {
        if without_mask > 0 {
            log.warning(format!(
                "{without_mask} of {} scored detections have no mask: left out of the mask scores",
                dts.len()
            ));
        }
        Some(
            evaluate(&gt.instances, &with_mask, gt.images.len(), IouType::Segm)
                .map_err(|e| anyhow::anyhow!(e))?,
        )
    };
    let scores = DetectionScores {
        detections: req.detections.clone(),
        dataset: req.data.clone(),
        split,
        bbox_type: req.bbox_type,
        targets: targets_path,
        n_images: gt.images.len(),
        n_gt: gt.instances.len(),
        images_with_rendered_masks: gt.images_with_rendered_masks,
        entries: list.len(),
        scored: dts.len(),
        other_images,
        objects_without_gt,
        without_mask,
        off_image,
        bbox: ScoreSet::of(&bbox),
        segm: segm.as_ref().map(ScoreSet::of),
    };
    if let Some(path) = &req.gt_out {
        write_json(path, &gt.to_json())?;
        log.info(format!("wrote the COCO GT to {}", path.display()));
    }
    if let Some(path) = &req.out {
        write_json(path, &serde_json::to_value(&scores)?)?;
        log.info(format!("wrote the scores to {}", path.display()));
    }
    if let Some((dir, count)) = &req.draw {
        let n = draw_frames(dir, *count, &frames, &gt, &dts)?;
        log.info(format!(
            "drew {n} images into {} (green: mask and GT agree, red: the detection only, blue: the GT only; GT boxes blue, detections' red)",
            dir.display()
        ));
    }
    Ok(scores)
}

/// Draws `count` of the scored images (spread evenly) into `dir` as
/// `SCENE_IMAGE.png`: per object with GT there, the GT's visible mask against the object's
/// best detection's mask (`mask_overlay`: green both, red the detection only, blue the GT
/// only), the GT box in blue and the detection's box in red with its object id and score;
/// best detections of objects without GT there in red too. Returns how many were drawn.
pub fn draw_frames(
    dir: &Path,
    count: usize,
    frames: &[SourceFrame],
    gt: &CocoGt,
    dts: &[DtInstance],
) -> Result<usize> {
    use synthgen_formats::annotate::mask_overlay;
    use synthgen_formats::bop::image::read_rgb;
    const BLUE: [u8; 3] = [40, 110, 255];
    const RED: [u8; 3] = [235, 40, 40];
    if count == 0 || frames.is_empty() {
        return Ok(0);
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let step = frames.len().div_ceil(count).max(1);
    let mut drawn = 0;
    for (image, f) in frames.iter().enumerate().step_by(step).take(count) {
        let img = read_rgb(&f.rgb)?;
        if (img.width, img.height) != (gt.width, gt.height) {
            anyhow::bail!(
                "{} is {}x{}, not the camera's {}x{}",
                f.rgb.display(),
                img.width,
                img.height,
                gt.width,
                gt.height
            );
        }
        let here: Vec<&GtInstance> = gt.instances.iter().filter(|g| g.image == image).collect();
        // The best detection of each object in the image.
        let mut best: BTreeMap<u32, &DtInstance> = BTreeMap::new();
        for d in dts.iter().filter(|d| d.image == image) {
            let e = best.entry(d.category).or_insert(d);
            if d.score > e.score {
                *e = d;
            }
        }
        let mask_of = |d: Option<&&DtInstance>| {
            d.and_then(|d| d.segmentation.as_ref())
                .map(Rle::decode)
                .unwrap_or_default()
        };
        let mut ours: Vec<Vec<u8>> = here
            .iter()
            .map(|g| mask_of(best.get(&g.category)))
            .collect();
        let mut theirs: Vec<Option<Vec<u8>>> = here
            .iter()
            .map(|g| g.segmentation.as_ref().map(Rle::decode))
            .collect();
        for (obj, d) in &best {
            if !here.iter().any(|g| g.category == *obj) {
                ours.push(mask_of(Some(d)));
                theirs.push(None);
            }
        }
        let mut c = mask_overlay(&img, &ours, &theirs);
        let rect = |c: &mut synthgen_formats::draw::Canvas, b: [f64; 4], col| {
            let [x, y, w, h] = b;
            let (x1, y1) = (x + w - 1.0, y + h - 1.0);
            c.line((x, y), (x1, y), col, 2);
            c.line((x1, y), (x1, y1), col, 2);
            c.line((x1, y1), (x, y1), col, 2);
            c.line((x, y1), (x, y), col, 2);
        };
        for g in &here {
            rect(&mut c, g.bbox, BLUE);
            c.text(
                g.bbox[0] as i64 + 3,
                g.bbox[1] as i64 + 3,
                &g.category.to_string(),
                2,
                BLUE,
            );
        }
        for (obj, d) in &best {
            rect(&mut c, d.bbox, RED);
            let y = (d.bbox[1] + d.bbox[3]) as i64 - 14;
            c.text(
                d.bbox[0] as i64 + 3,
                y,
                &format!("{obj} {:.2}", d.score),
                2,
                RED,
            );
        }
        let (scene, im) = gt.images[image];
        c.write_png(&dir.join(format!("{scene:06}_{im:06}.png")))?;
        drawn += 1;
    }
    Ok(drawn)
}

fn write_json(path: &Path, value: &serde_json::Value) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let text = serde_json::to_string(value)? + "\n";
    synthgen_train::train::write_atomic(path, text.as_bytes())?;
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn the_report_block_has_the_issues_keys() {
        use synthgen_detect::coco_eval::evaluate;
        let mask = |x0: usize| {
            let mut m = vec![0u8; 16 * 8];
            for y in 2..6 {
                for x in x0..x0 + 4 {
                    m[y * 16 + x] = 1;
                }
            }
            Rle::from_mask(&m, 16, 8)
        };
        let gts = vec![GtInstance {
            image: 0,
            category: 3,
            bbox: [2.0, 2.0, 4.0, 4.0],
            area: 16.0,
            iscrowd: false,
            segmentation: Some(mask(2)),
        }];
        let dts = vec![DtInstance {
            image: 0,
            category: 3,
            score: 0.9,
            bbox: [2.0, 2.0, 4.0, 4.0],
            area: 16.0,
            segmentation: Some(mask(3)),
        }];
        let bbox = evaluate(&gts, &dts, 1, IouType::Bbox).unwrap();
        let segm = evaluate(&gts, &dts, 1, IouType::Segm).unwrap();
        let scores = DetectionScores {
            detections: "d.json".into(),
            dataset: "data".into(),
            split: "test".into(),
            bbox_type: BboxType::Amodal,
            targets: None,
            n_images: 1,
            n_gt: 1,
            images_with_rendered_masks: 0,
            entries: 1,
            scored: 1,
            other_images: 0,
            objects_without_gt: 0,
            without_mask: 0,
            off_image: 0,
            bbox: ScoreSet::of(&bbox),
            segm: Some(ScoreSet::of(&segm)),
        };
        let block = scores.report_block();
        for key in [
            "n_gt",
            "bbox_ap",
            "bbox_ap50",
            "segm_ap",
            "segm_ap50",
            "objects",
        ] {
            assert!(block.get(key).is_some(), "{key} missing: {block}");
        }
        // The box is exact; the mask is one column off (IoU 12/20 = 0.6): AP50 1, AP 0.3.
        assert!((block["bbox_ap"].as_f64().unwrap() - 1.0).abs() < 1e-9);
        assert!((block["segm_ap50"].as_f64().unwrap() - 1.0).abs() < 1e-9);
        assert!(
            (block["segm_ap"].as_f64().unwrap() - 0.3).abs() < 1e-9,
            "{block}"
        );
        assert_eq!(block["objects"]["3"]["n_gt"], 1.0);
        assert!(
            scores.table().contains("| AP | 1.000 | 0.300 |"),
            "{}",
            scores.table()
        );
    }

    #[test]
    fn coco_boxes_of_masks_include_the_last_pixel() {
        let mut m = vec![0u8; 20];
        m[5 + 2] = 255; // (2, 1)
        m[3 * 5 + 4] = 255; // (4, 3)
        assert_eq!(mask_box(&m, 5), Some([2.0, 1.0, 3.0, 3.0]));
        assert_eq!(mask_box(&[0; 20], 5), None);
    }
}
