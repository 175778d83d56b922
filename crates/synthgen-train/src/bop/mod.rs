//! The BOP 2019 Average Recall (AR = mean of AR_VSD, AR_MSSD, AR_MSPD) of pose estimates, as
//! bop_toolkit's `eval_bop19_pose.py` computes it with `eval_calc_errors.py` and
//! `eval_calc_scores.py` (6D localization, `n_top = -1`). Conventions and the checks against
//! bop_toolkit are in docs/metrics.md.
//!
//! For each target (image, object, inst_count) the `inst_count` highest-scoring estimates of
//! that object in that image get an error against every GT instance of the object there.
//! Then, per error threshold, estimates are matched greedily in descending score to the free
//! valid GT instance with the lowest error below the threshold; recall = matched valid GT /
//! valid GT. A GT without an estimate is a miss.

pub mod errors;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use synthgen_assets::Units;
use synthgen_core::glam::DVec3;
use synthgen_core::{DepthRenderer, DepthWindowMm, Intrinsics, NoProgress, Progress};
use synthgen_formats::bop::{GtEntry, ModelInfo};
use synthgen_formats::source::FrameSource;

use crate::error::{Error, Result};
use crate::results::Estimate;
use errors::{
    bbox_corners, k_matrix, mspd, mssd, overlapping_sphere_projections, quantize_like_vispy,
    symmetry_transformations, vsd, DepthMm, DistFactors, RawPose, SymTransform,
};

/// VSD misalignment tolerance τ and the MSSD thresholds: 0.05 to 0.5 of the diameter, the
/// values of numpy's `arange(0.05, 0.51, 0.05)` bit for bit.
pub fn diameter_fractions() -> Vec<f64> {
    (0..10).map(|i| 0.05 + i as f64 * 0.05).collect()
}

/// VSD's thresholds of correctness (the same 0.05 … 0.5).
pub fn vsd_thresholds() -> Vec<f64> {
    diameter_fractions()
}

/// MSPD thresholds in pixels at an image width of 640 (scaled by 640 / width).
pub fn mspd_thresholds() -> Vec<f64> {
    (1..=10).map(|i| 5.0 * i as f64).collect()
}

/// Settings of the evaluation; the defaults are bop_toolkit's for BOP 2019.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BopOptions {
    /// Minimum visible fraction of a GT instance to count (`visib_gt_min`). Below 0 (the
    /// default, −1), the `inst_count` most visible instances of each target are the ones.
    pub visib_gt_min: f64,
    /// VSD's δ (mm), 15 for every BOP dataset but ITODD (5).
    pub vsd_delta_mm: f64,
    /// Discretization of continuous symmetries (fraction of the diameter).
    pub max_sym_disc_step: f64,
    /// Render VSD's depths with OpenGL's pixel centres (pixel (x, y) samples the projection at
    /// (x + 0.5, y + 0.5)), as bop_toolkit's vispy, cpp and python renderers do; otherwise
    /// at (x, y), the intrinsics' own convention.
    pub gl_pixel_centres: bool,
    /// Quantize VSD's rendered depths as bop_toolkit's default renderer (vispy) does: a 16-bit
    /// depth buffer between the model box's near and far corners (see
    /// [`errors::quantize_like_vispy`]). Off: exact depth.
    pub vispy_depth: bool,
}

impl Default for BopOptions {
    fn default() -> Self {
        BopOptions {
            visib_gt_min: -1.0,
            vsd_delta_mm: 15.0,
            max_sym_disc_step: 0.01,
            gl_pixel_centres: true,
            vispy_depth: true,
        }
    }
}

/// One estimation target of `test_targets_bop19.json`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Target {
    pub scene_id: u32,
    pub im_id: u32,
    pub obj_id: u32,
    pub inst_count: usize,
}

/// Reads a BOP targets file (a JSON list of `{scene_id, im_id, obj_id, inst_count}`).
pub fn read_targets(path: &Path) -> Result<Vec<Target>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io("read", path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::Malformed {
        what: "targets file",
        message: format!(
            "{e} (expected a list of {{\"scene_id\", \"im_id\", \"obj_id\", \"inst_count\"}})"
        ),
        path: path.to_path_buf(),
    })
}

/// Every object of every image as a target, with all its GT instances.
pub fn targets_from_gt(images: &[BopImage]) -> Vec<Target> {
    let mut out = Vec::new();
    for im in images {
        let mut counts: BTreeMap<u32, usize> = BTreeMap::new();
        for g in &im.gt {
            *counts.entry(g.obj_id).or_default() += 1;
        }
        out.extend(counts.into_iter().map(|(obj_id, inst_count)| Target {
            scene_id: im.scene_id,
            im_id: im.im_id,
            obj_id,
            inst_count,
        }));
    }
    out
}

/// One test image: camera, GT as stored, and where its depth is.
#[derive(Debug, Clone, PartialEq)]
pub struct BopImage {
    pub scene_id: u32,
    pub im_id: u32,
    pub cam_k: [f64; 9],
    pub width: u32,
    pub height: u32,
    /// List index = gt id.
    pub gt: Vec<GtEntry>,
    /// Per gt id, from `scene_gt_info.json` (1 when the dataset has none).
    pub visib_fract: Vec<f64>,
    pub depth: Option<PathBuf>,
    /// Millimetres per depth unit.
    pub depth_scale: f64,
}

/// The images of a split of any layout synthgen reads.
pub fn read_images(ds: &dyn FrameSource, split: &str) -> Result<Vec<BopImage>> {
    let cam = ds.camera();
    Ok(ds
        .annotation_frames(&[split.to_string()])?
        .into_iter()
        .map(|f| BopImage {
            scene_id: f.location.scene_id,
            im_id: f.location.im_id,
            cam_k: f.camera.cam_k,
            width: cam.width,
            height: cam.height,
            visib_fract: (0..f.gt.len())
                .map(|g| {
                    f.gt_info
                        .as_ref()
                        .and_then(|v| v.get(g))
                        .map_or(1.0, |i| i.visib_fract)
                })
                .collect(),
            gt: f.gt,
            depth: f.depth,
            depth_scale: f.camera.depth_scale,
        })
        .collect())
}

/// What the pose errors need of an object: its model's vertices (mm, as stored), diameter
/// (from models_info) and symmetry transformations.
#[derive(Debug, Clone, PartialEq)]
pub struct BopObject {
    pub pts_mm: Vec<DVec3>,
    pub diameter_mm: f64,
    pub syms: Vec<SymTransform>,
    /// The model box's corners (bop_toolkit's renderers set their clipping planes from it).
    pub bbox_corners: [DVec3; 8],
}

impl BopObject {
    pub fn new(pts_mm: Vec<DVec3>, info: &ModelInfo, max_sym_disc_step: f64) -> BopObject {
        BopObject {
            bbox_corners: bbox_corners(&pts_mm),
            pts_mm,
            diameter_mm: info.diameter,
            syms: symmetry_transformations(&info.symmetries, max_sym_disc_step),
        }
    }
}

pub use crate::dataset_objects::eval_model_paths;

/// Loads the objects `obj_ids` for the metrics (see [`eval_model_paths`]).
pub fn load_bop_objects(
    ds: &dyn FrameSource,
    obj_ids: impl IntoIterator<Item = u32>,
    max_sym_disc_step: f64,
) -> Result<BTreeMap<u32, BopObject>> {
    let (info_path, model_path) = eval_model_paths(ds);
    let read;
    let infos = if info_path == ds.models_info_path() {
        ds.models_info()
    } else {
        read = synthgen_formats::bop::reader::read_models_info(&info_path)?;
        Some(&read)
    };
    // Units::M leaves the file's numbers as they are: millimetres in BOP's models (and
    // models_eval), metres in a dataset whose models are in metres (YCB-Video's own layout),
    // which are scaled to millimetres here (models_info's diameter is in millimetres).
    let to_mm = if info_path == ds.models_info_path() && ds.model_units() == Units::M {
        1000.0
    } else {
        1.0
    };
    crate::dataset_objects::load_each_object(
        infos,
        &info_path,
        &*model_path,
        Units::M,
        obj_ids,
        |m, info| {
            let pts: Vec<DVec3> = m.positions().map(|p| p.as_dvec3() * to_mm).collect();
            BopObject::new(pts, info, max_sym_disc_step)
        },
    )
}

/// The models VSD renders (metres): the same files as [`load_bop_objects`] reads.
pub fn load_render_models(
    ds: &dyn FrameSource,
    obj_ids: impl IntoIterator<Item = u32>,
) -> Result<Vec<(u32, synthgen_core::Model)>> {
    let (_, model_path) = eval_model_paths(ds);
    let mut out: Vec<(u32, synthgen_core::Model)> = Vec::new();
    for obj_id in obj_ids {
        if out.iter().any(|(id, _)| *id == obj_id) {
            continue;
        }
        let loaded =
            synthgen_assets::load_model(&model_path(obj_id), ds.model_units(), &NoProgress)
                .map_err(|source| Error::Model { obj_id, source })?;
        out.push((obj_id, loaded.model));
    }
    Ok(out)
}

/// Where a [`BopSetup`]'s targets came from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TargetsFrom {
    /// The file the caller named.
    File(PathBuf),
    /// `test_targets_bop19.json` in the dataset.
    DatasetFile(PathBuf),
    /// Every object of every image, with all its GT instances.
    AllGt,
}

/// A split ready to score: its images, targets and the objects' models for the errors.
#[derive(Debug, Clone)]
pub struct BopSetup {
    pub images: Vec<BopImage>,
    pub targets: Vec<Target>,
    pub targets_from: TargetsFrom,
    /// The targets' objects.
    pub objects: BTreeMap<u32, BopObject>,
    /// Every object the dataset has a model of (its evaluation `models_info.json`), so that
    /// an estimate of a non-target object is told from one of an object without a model.
    pub model_ids: BTreeSet<u32>,
}

/// Reads what scoring `split` of `ds` needs: images, targets (`targets`, else the dataset's
/// `test_targets_bop19.json`, else every GT instance) and the targets' objects. VSD's
/// renderer is the caller's: [`load_render_models`] gives its models for
/// [`BopSetup::obj_ids`].
pub fn prepare_bop(
    ds: &dyn FrameSource,
    split: &str,
    targets: Option<&Path>,
    opts: &BopOptions,
) -> Result<BopSetup> {
    let images = read_images(ds, split)?;
    let in_dataset = ds.root().join("test_targets_bop19.json");
    let (targets, targets_from) = match targets {
        Some(p) => (read_targets(p)?, TargetsFrom::File(p.to_path_buf())),
        None if in_dataset.is_file() => (
            read_targets(&in_dataset)?,
            TargetsFrom::DatasetFile(in_dataset),
        ),
        None => (targets_from_gt(&images), TargetsFrom::AllGt),
    };
    if targets.is_empty() {
        return Err(Error::NoInstances {
            reason: format!(
                "no BOP targets in split {split} (no GT instances, or an empty targets file)"
            ),
            path: ds.root().to_path_buf(),
        });
    }
    let mut obj_ids: Vec<u32> = targets.iter().map(|t| t.obj_id).collect();
    obj_ids.sort_unstable();
    obj_ids.dedup();
    let objects = load_bop_objects(ds, obj_ids, opts.max_sym_disc_step)?;
    let (info_path, _) = eval_model_paths(ds);
    let model_ids = if info_path == ds.models_info_path() {
        ds.models_info()
            .map(|m| m.keys().copied().collect())
            .unwrap_or_default()
    } else {
        synthgen_formats::bop::reader::read_models_info(&info_path)?
            .into_keys()
            .collect()
    };
    Ok(BopSetup {
        images,
        targets,
        targets_from,
        objects,
        model_ids,
    })
}

impl BopSetup {
    /// The targets' object ids, sorted.
    pub fn obj_ids(&self) -> Vec<u32> {
        self.objects.keys().copied().collect()
    }

    /// Scores `estimates` (see [`evaluate_bop`]).
    pub fn evaluate(
        &self,
        estimates: &[Estimate],
        renderer: Option<&dyn DepthRenderer>,
        opts: &BopOptions,
        progress: &dyn Progress,
    ) -> Result<BopReport> {
        evaluate_bop(self, estimates, renderer, opts, progress)
    }
}

/// Recall of one error over its thresholds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ErrorRecall {
    /// Thresholds of correctness (VSD: fraction of the diameter; MSSD: fraction of the
    /// diameter; MSPD: pixels at width 640).
    pub thresholds: Vec<f64>,
    /// Recall at each threshold (VSD: averaged over τ).
    pub recall_per_threshold: Vec<f64>,
    /// The average recall (AR of this error): mean over every threshold (and τ).
    pub mean_recall: f64,
    pub per_object_mean_recall: BTreeMap<u32, f64>,
    pub per_scene_mean_recall: BTreeMap<u32, f64>,
    /// VSD only: the τ values and the recall per (τ, threshold), τ-major.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub taus: Option<Vec<f64>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recall_per_tau_threshold: Option<Vec<Vec<f64>>>,
}

/// Counts of what was scored and what was not.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct BopCounts {
    /// Targets (image, object) and the GT instances they ask for.
    pub targets: usize,
    pub target_instances: usize,
    /// Estimates given an error (the top `inst_count` of each target).
    pub estimates_scored: usize,
    /// Estimates of a target beyond its `inst_count` best, as bop_toolkit drops them.
    pub estimates_beyond_top_n: usize,
    /// Estimates of an image that is not a target image, or of an object that is not a
    /// target in it.
    pub estimates_not_target: usize,
    /// Estimates naming an image the dataset does not have.
    pub estimates_unknown_image: usize,
    /// Estimates naming an object without a model.
    pub estimates_unknown_object: usize,
    /// Entries of the targets file that repeat an (image, object) listed before; the last
    /// one's `inst_count` counts, as bop_toolkit reads them.
    pub targets_repeated: usize,
}

/// The BOP 2019 scores.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BopReport {
    /// None when the test images have no depth (VSD needs it); see `note`.
    pub vsd: Option<ErrorRecall>,
    pub mssd: ErrorRecall,
    pub mspd: ErrorRecall,
    /// mean(AR_VSD, AR_MSSD, AR_MSPD); None without VSD.
    pub ar: Option<f64>,
    pub counts: BopCounts,
    /// Every scored estimate's errors (as bop_toolkit's `errors_*.json`), in image order.
    #[serde(skip)]
    pub errors: Vec<EstimateErrors>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// Scores `estimates` against the setup's images for its targets. `renderer` renders VSD's
/// depths; VSD is skipped (with a note) when it is None or a target image has no depth.
pub fn evaluate_bop(
    setup: &BopSetup,
    estimates: &[Estimate],
    renderer: Option<&dyn DepthRenderer>,
    opts: &BopOptions,
    progress: &dyn Progress,
) -> Result<BopReport> {
    let (images, targets, objects) = (&setup.images, &setup.targets, &setup.objects);
    let by_image: BTreeMap<(u32, u32), &BopImage> = images
        .iter()
        .map(|im| ((im.scene_id, im.im_id), im))
        .collect();
    let mut target_org: BTreeMap<(u32, u32), BTreeMap<u32, usize>> = BTreeMap::new();
    let mut counts = BopCounts::default();
    for t in targets {
        if !by_image.contains_key(&(t.scene_id, t.im_id)) {
            return Err(Error::InvalidOption(format!(
                "target scene {} image {} (object {}) is not in the dataset",
                t.scene_id, t.im_id, t.obj_id
            )));
        }
        if !objects.contains_key(&t.obj_id) {
            return Err(Error::InvalidOption(format!(
                "target object {} (scene {} image {}) has no model",
                t.obj_id, t.scene_id, t.im_id
            )));
        }
        target_org
            .entry((t.scene_id, t.im_id))
            .or_default()
            .insert(t.obj_id, t.inst_count);
    }
    counts.targets = target_org.values().map(BTreeMap::len).sum();
    counts.target_instances = target_org.values().flat_map(BTreeMap::values).sum();
    counts.targets_repeated = targets.len() - counts.targets;
    // Estimates by image and object, in file order.
    let mut est_org: BTreeMap<(u32, u32, u32), Vec<&Estimate>> = BTreeMap::new();
    for e in estimates {
        let im = (e.scene_id, e.im_id);
        if !by_image.contains_key(&im) {
            counts.estimates_unknown_image += 1;
        } else if !target_org
            .get(&im)
            .is_some_and(|t| t.contains_key(&e.obj_id))
        {
            // Targets all have models (checked above); others may or may not.
            if objects.contains_key(&e.obj_id) || setup.model_ids.contains(&e.obj_id) {
                counts.estimates_not_target += 1;
            } else {
                counts.estimates_unknown_object += 1;
            }
        } else {
            est_org
                .entry((e.scene_id, e.im_id, e.obj_id))
                .or_default()
                .push(e);
        }
    }
    let missing_depth = target_org
        .keys()
        .filter(|k| by_image[k].depth.is_none())
        .count();
    let do_vsd = renderer.is_some() && missing_depth == 0;
    let note = if renderer.is_none() {
        Some("VSD not computed: no renderer given".to_string())
    } else if missing_depth > 0 {
        Some(format!(
            "VSD needs depth images: {missing_depth} of {} target images have none, so AR_VSD and AR are not computed",
            target_org.len()
        ))
    } else {
        None
    };
    let taus = diameter_fractions();

    progress.start("BOP errors", target_org.len() as u64);
    let results: Vec<Result<(ImageResult, usize)>> = target_org
        .par_iter()
        .map(|(key, im_targets)| {
            let im = by_image[key];
            let out = score_image(
                im,
                im_targets,
                &est_org,
                objects,
                if do_vsd { renderer } else { None },
                opts,
                &taus,
            );
            progress.advance(1);
            out
        })
        .collect();
    progress.finish();
    let mut per_image = Vec::with_capacity(results.len());
    let mut all_errors = Vec::new();
    for r in results {
        let (ir, beyond) = r?;
        all_errors.extend(ir.scored.iter().map(|s| s.raw.clone()));
        counts.estimates_scored += ir.scored.len();
        counts.estimates_beyond_top_n += beyond;
        per_image.push(ir);
    }

    let obj_ids: BTreeSet<u32> = targets.iter().map(|t| t.obj_id).collect();
    let scene_ids: BTreeSet<u32> = targets.iter().map(|t| t.scene_id).collect();
    let curve = |thresholds: Vec<f64>, err: &(dyn Fn(&ErrorsVsGt) -> f64 + Sync)| {
        let recalls: Vec<Recall> = thresholds
            .iter()
            .map(|&th| recall(&per_image, err, th, &obj_ids, &scene_ids))
            .collect();
        (thresholds, recalls)
    };
    let mssd_curve = curve(diameter_fractions(), &|e| e.mssd);
    let mspd_curve = curve(mspd_thresholds(), &|e| e.mspd);
    let mssd = summarize(&mssd_curve.0, &[mssd_curve.1], None);
    let mspd = summarize(&mspd_curve.0, &[mspd_curve.1], None);
    let vsd = do_vsd.then(|| {
        let th = vsd_thresholds();
        let per_tau: Vec<Vec<Recall>> = (0..taus.len())
            .map(|i| curve(th.clone(), &move |e: &ErrorsVsGt| e.vsd[i]).1)
            .collect();
        summarize(&th, &per_tau, Some(&taus))
    });
    let ar = vsd
        .as_ref()
        .map(|v| (v.mean_recall + mssd.mean_recall + mspd.mean_recall) / 3.0);
    Ok(BopReport {
        vsd,
        mssd,
        mspd,
        ar,
        counts,
        errors: all_errors,
        note,
    })
}

impl BopReport {
    /// The BOP table in markdown: AR and each error's average recall, overall and per object.
    pub fn to_markdown(&self) -> String {
        // Fractions (0–1), as bop_toolkit and `--json` report them.
        let frac = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.3}"));
        let mut md = String::from(
            "| object | AR | AR_VSD | AR_MSSD | AR_MSPD |\n|---|---:|---:|---:|---:|\n",
        );
        for (obj, &m) in &self.mssd.per_object_mean_recall {
            let v = self
                .vsd
                .as_ref()
                .and_then(|v| v.per_object_mean_recall.get(obj).copied());
            let p = self.mspd.per_object_mean_recall.get(obj).copied();
            let ar = v.zip(p).map(|(v, p)| (v + m + p) / 3.0);
            md += &format!(
                "| {obj} | {} | {} | {} | {} |\n",
                frac(ar),
                frac(v),
                frac(Some(m)),
                frac(p)
            );
        }
        md += &format!(
            "| all | {} | {} | {} | {} |\n",
            frac(self.ar),
            frac(self.vsd.as_ref().map(|v| v.mean_recall)),
            frac(Some(self.mssd.mean_recall)),
            frac(Some(self.mspd.mean_recall))
        );
        md
    }
}

/// One scored estimate and its errors against each GT instance of its object in its image.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EstimateErrors {
    pub scene_id: u32,
    pub im_id: u32,
    pub obj_id: u32,
    /// Index among the file's estimates of this object in this image (bop_toolkit's est_id).
    pub est_id: usize,
    pub score: f64,
    /// By gt id: MSSD (mm), MSPD (px), VSD per τ (empty without VSD).
    pub errors: BTreeMap<usize, (f64, f64, Vec<f64>)>,
}

/// One estimate's errors against one GT instance, normalized as `eval_calc_scores.py` does
/// before thresholding: MSSD / diameter, MSPD × 640 / image width, VSD as is (per τ).
#[derive(Debug, Clone, PartialEq)]
struct ErrorsVsGt {
    gt_id: usize,
    mssd: f64,
    mspd: f64,
    vsd: Vec<f64>,
}

/// One scored estimate (the estimates of an object are kept in descending score).
#[derive(Debug, Clone)]
struct Scored {
    raw: EstimateErrors,
    per_gt: Vec<ErrorsVsGt>,
}

/// One image's scored estimates and its GT instances' objects and validity.
struct ImageResult {
    scene_id: u32,
    gt_obj: Vec<u32>,
    valid: Vec<bool>,
    scored: Vec<Scored>,
}

/// bop19's valid GT instances of an image: with `visib_gt_min >= 0` those of target objects
/// at least that visible; else per target object its `inst_count` most visible.
fn valid_gt(im: &BopImage, targets: &BTreeMap<u32, usize>, visib_gt_min: f64) -> Vec<bool> {
    if visib_gt_min >= 0.0 {
        return im
            .gt
            .iter()
            .zip(&im.visib_fract)
            .map(|(g, &v)| targets.contains_key(&g.obj_id) && v >= visib_gt_min)
            .collect();
    }
    let mut order: Vec<usize> = (0..im.gt.len()).collect();
    // Stable, like Python's sorted(): ties keep the gt order.
    order.sort_by(|&a, &b| im.visib_fract[b].total_cmp(&im.visib_fract[a]));
    let mut left = targets.clone();
    let mut valid = vec![false; im.gt.len()];
    for g in order {
        if let Some(n) = left.get_mut(&im.gt[g].obj_id) {
            if *n > 0 {
                valid[g] = true;
                *n -= 1;
            }
        }
    }
    valid
}

/// The errors of one image's top-n estimates per target object; also how many estimates
/// fell beyond the top n.
fn score_image(
    im: &BopImage,
    im_targets: &BTreeMap<u32, usize>,
    est_org: &BTreeMap<(u32, u32, u32), Vec<&Estimate>>,
    objects: &BTreeMap<u32, BopObject>,
    renderer: Option<&dyn DepthRenderer>,
    opts: &BopOptions,
    taus: &[f64],
) -> Result<(ImageResult, usize)> {
    let k = k_matrix(&im.cam_k);
    let mspd_factor = 640.0 / im.width as f64;
    let vsd_ctx = match (renderer, &im.depth) {
        (Some(r), Some(path)) => {
            let raw = synthgen_formats::bop::image::read_depth_raw(path)?;
            if raw.width != im.width || raw.height != im.height {
                return Err(Error::Malformed {
                    what: "depth image",
                    message: format!(
                        "{}x{} pixels, the camera says {}x{}",
                        raw.width, raw.height, im.width, im.height
                    ),
                    path: path.clone(),
                });
            }
            let test = DepthMm::from_raw(raw.width, raw.height, &raw.data, im.depth_scale);
            let factors = DistFactors::new(&im.cam_k, im.width, im.height);
            let shift = if opts.gl_pixel_centres { 0.5 } else { 0.0 };
            let render_k = Intrinsics {
                width: im.width,
                height: im.height,
                fx: im.cam_k[0],
                fy: im.cam_k[4],
                cx: im.cam_k[2] - shift,
                cy: im.cam_k[5] - shift,
            };
            Some((r, test, factors, render_k))
        }
        _ => None,
    };
    let render = |obj_id: u32, p: &RawPose| -> Result<DepthWindowMm> {
        let Some((r, _, _, rk)) = &vsd_ctx else {
            return Ok(DepthWindowMm::default());
        };
        let mut out = DepthWindowMm::default();
        r.render_depth_mm(rk, obj_id, &p.r, p.t_mm, &mut out)
            .map_err(|e| Error::InvalidOption(format!("rendering object {obj_id}: {e}")))?;
        if opts.vispy_depth {
            quantize_like_vispy(&mut out, &p.r, p.t_mm, &objects[&obj_id].bbox_corners);
        }
        Ok(out)
    };
    let gt_poses: Vec<RawPose> = im
        .gt
        .iter()
        .map(|g| RawPose::from_bop(&g.cam_r_m2c, &g.cam_t_m2c))
        .collect();
    let mut gt_renders: BTreeMap<usize, DepthWindowMm> = BTreeMap::new();
    let mut scored = Vec::new();
    let mut beyond = 0;
    for (&obj_id, &n) in im_targets {
        let Some(ests) = est_org.get(&(im.scene_id, im.im_id, obj_id)) else {
            continue;
        };
        let obj = &objects[&obj_id];
        let mut sorted: Vec<(usize, &Estimate)> = ests.iter().copied().enumerate().collect();
        // Stable: equal scores keep the file's order, as bop_toolkit's sorted().
        sorted.sort_by(|a, b| b.1.score.total_cmp(&a.1.score));
        beyond += sorted.len().saturating_sub(n);
        sorted.truncate(n);
        for (est_id, e) in sorted {
            let mut raw = EstimateErrors {
                scene_id: im.scene_id,
                im_id: im.im_id,
                obj_id,
                est_id,
                score: e.score,
                errors: BTreeMap::new(),
            };
            let est = e.stored;
            // Rendered when a GT instance is near enough to need it.
            let mut est_render: Option<DepthWindowMm> = None;
            let mut per_gt = Vec::new();
            for (gt_id, g) in im.gt.iter().enumerate() {
                if g.obj_id != obj_id {
                    continue;
                }
                let gt = &gt_poses[gt_id];
                let mssd_mm = if (est.t_mm - gt.t_mm).length() < obj.diameter_mm {
                    mssd(&est, gt, &obj.pts_mm, &obj.syms)
                } else {
                    f64::INFINITY
                };
                let mspd_px = mspd(&est, gt, &k, &obj.pts_mm, &obj.syms);
                let vsd_e = match &vsd_ctx {
                    Some((_, test, factors, _)) => {
                        if overlapping_sphere_projections(0.5 * obj.diameter_mm, est.t_mm, gt.t_mm)
                        {
                            let gt_depth = match gt_renders.entry(gt_id) {
                                std::collections::btree_map::Entry::Occupied(e) => e.into_mut(),
                                std::collections::btree_map::Entry::Vacant(e) => {
                                    e.insert(render(obj_id, gt)?)
                                }
                            };
                            let est_depth = match &mut est_render {
                                Some(d) => d,
                                None => est_render.insert(render(obj_id, &est)?),
                            };
                            vsd(
                                est_depth,
                                gt_depth,
                                test,
                                factors,
                                opts.vsd_delta_mm,
                                taus,
                                true,
                                obj.diameter_mm,
                            )
                        } else {
                            vec![1.0; taus.len()]
                        }
                    }
                    None => Vec::new(),
                };
                raw.errors.insert(gt_id, (mssd_mm, mspd_px, vsd_e.clone()));
                per_gt.push(ErrorsVsGt {
                    gt_id,
                    mssd: mssd_mm / obj.diameter_mm,
                    mspd: mspd_factor * mspd_px,
                    vsd: vsd_e,
                });
            }
            scored.push(Scored { raw, per_gt });
        }
    }
    Ok((
        ImageResult {
            scene_id: im.scene_id,
            gt_obj: im.gt.iter().map(|g| g.obj_id).collect(),
            valid: valid_gt(im, im_targets, opts.visib_gt_min),
            scored,
        },
        beyond,
    ))
}

/// (true positives, targets) by object or scene id.
type Counts = BTreeMap<u32, (usize, usize)>;

/// True positives and targets at one threshold, overall, per object and per scene.
#[derive(Debug, Clone, Default)]
struct Recall {
    tp: usize,
    targets: usize,
    obj: Counts,
    scene: Counts,
}

fn ratio(tp: usize, n: usize) -> f64 {
    if n == 0 {
        0.0
    } else {
        tp as f64 / n as f64
    }
}

/// bop_toolkit's `match_poses_scene` + `calc_localization_scores` at one threshold.
fn recall(
    images: &[ImageResult],
    err: &(dyn Fn(&ErrorsVsGt) -> f64 + Sync),
    th: f64,
    obj_ids: &BTreeSet<u32>,
    scene_ids: &BTreeSet<u32>,
) -> Recall {
    let mut r = Recall {
        obj: obj_ids.iter().map(|&o| (o, (0, 0))).collect(),
        scene: scene_ids.iter().map(|&s| (s, (0, 0))).collect(),
        ..Recall::default()
    };
    for im in images {
        let mut matched = vec![false; im.gt_obj.len()];
        // The scored estimates are grouped by object in descending score: greedy matching.
        for s in &im.scored {
            let mut best: Option<usize> = None;
            let mut best_err = th;
            for e in &s.per_gt {
                if im.valid[e.gt_id] && !matched[e.gt_id] {
                    let v = err(e);
                    if v < best_err {
                        best = Some(e.gt_id);
                        best_err = v;
                    }
                }
            }
            if let Some(g) = best {
                matched[g] = true;
            }
        }
        for (g, &obj) in im.gt_obj.iter().enumerate() {
            if !im.valid[g] {
                continue;
            }
            let tp = usize::from(matched[g]);
            r.targets += 1;
            r.tp += tp;
            if let Some(o) = r.obj.get_mut(&obj) {
                o.0 += tp;
                o.1 += 1;
            }
            if let Some(sc) = r.scene.get_mut(&im.scene_id) {
                sc.0 += tp;
                sc.1 += 1;
            }
        }
    }
    r
}

fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// The recall curve(s) of one error: `per_tau[i][j]` at τ i and threshold j (one τ row for
/// MSSD and MSPD).
fn summarize(thresholds: &[f64], per_tau: &[Vec<Recall>], taus: Option<&[f64]>) -> ErrorRecall {
    let all: Vec<&Recall> = per_tau.iter().flatten().collect();
    let recall_per_threshold = (0..thresholds.len())
        .map(|j| {
            mean(
                &per_tau
                    .iter()
                    .map(|row| ratio(row[j].tp, row[j].targets))
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    let mean_recall = mean(
        &all.iter()
            .map(|r| ratio(r.tp, r.targets))
            .collect::<Vec<_>>(),
    );
    let keyed_mean = |pick: &dyn Fn(&Recall) -> &Counts| {
        let keys: Vec<u32> = all
            .first()
            .map_or(vec![], |r| pick(r).keys().copied().collect());
        keys.into_iter()
            .map(|k| {
                let v: Vec<f64> = all
                    .iter()
                    .map(|r| {
                        let (tp, n) = pick(r)[&k];
                        ratio(tp, n)
                    })
                    .collect();
                (k, mean(&v))
            })
            .collect()
    };
    ErrorRecall {
        thresholds: thresholds.to_vec(),
        recall_per_threshold,
        mean_recall,
        per_object_mean_recall: keyed_mean(&|r| &r.obj),
        per_scene_mean_recall: keyed_mean(&|r| &r.scene),
        taus: taus.map(<[f64]>::to_vec),
        recall_per_tau_threshold: taus.map(|_| {
            per_tau
                .iter()
                .map(|row| row.iter().map(|r| ratio(r.tp, r.targets)).collect())
                .collect()
        }),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::DMat3;
    use synthgen_core::Pose;

    const K: [f64; 9] = [600.0, 0.0, 320.0, 0.0, 600.0, 240.0, 0.0, 0.0, 1.0];

    fn gt(obj_id: u32, t_mm: [f64; 3]) -> GtEntry {
        GtEntry {
            cam_r_m2c: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            cam_t_m2c: t_mm,
            obj_id,
        }
    }

    fn image(im_id: u32, gt: Vec<GtEntry>, visib: Vec<f64>) -> BopImage {
        BopImage {
            scene_id: 0,
            im_id,
            cam_k: K,
            width: 640,
            height: 480,
            gt,
            visib_fract: visib,
            depth: None,
            depth_scale: 1.0,
        }
    }

    fn est(im_id: u32, obj_id: u32, score: f64, t_mm: [f64; 3]) -> Estimate {
        Estimate::new(
            0,
            im_id,
            obj_id,
            score,
            Pose::new(DMat3::IDENTITY, DVec3::from_array(t_mm) / 1000.0),
        )
    }

    /// A 100 mm cube's corners: MSSD of a pure shift is the shift.
    fn objects() -> BTreeMap<u32, BopObject> {
        let pts: Vec<DVec3> = (0..8)
            .map(|i| {
                DVec3::new(
                    if i & 1 == 0 { -50.0 } else { 50.0 },
                    if i & 2 == 0 { -50.0 } else { 50.0 },
                    if i & 4 == 0 { -50.0 } else { 50.0 },
                )
            })
            .collect();
        let info = ModelInfo {
            diameter: 100.0 * 3f64.sqrt(),
            min_x: -50.0,
            min_y: -50.0,
            min_z: -50.0,
            size_x: 100.0,
            size_y: 100.0,
            size_z: 100.0,
            symmetries: Default::default(),
        };
        [1, 2]
            .into_iter()
            .map(|id| (id, BopObject::new(pts.clone(), &info, 0.01)))
            .collect()
    }

    fn run(images: &[BopImage], ests: &[Estimate]) -> BopReport {
        run_with(
            images,
            &targets_from_gt(images),
            ests,
            &BopOptions::default(),
        )
        .unwrap()
    }

    fn run_with(
        images: &[BopImage],
        targets: &[Target],
        ests: &[Estimate],
        opts: &BopOptions,
    ) -> Result<BopReport> {
        let setup = BopSetup {
            images: images.to_vec(),
            targets: targets.to_vec(),
            targets_from: TargetsFrom::AllGt,
            objects: objects(),
            model_ids: objects().keys().copied().collect(),
        };
        evaluate_bop(&setup, ests, None, opts, &NoProgress)
    }

    #[test]
    fn thresholds_are_numpy_arange_values() {
        let f = diameter_fractions();
        assert_eq!(f.len(), 10);
        assert_eq!(f[2], 0.15000000000000002);
        assert_eq!(f[6], 0.35000000000000003);
        assert_eq!(
            mspd_thresholds(),
            vec![5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0]
        );
    }

    #[test]
    fn a_shift_is_correct_from_the_threshold_above_it() {
        // MSSD 20 mm = 0.115 of the diameter: correct at 0.15 and above (8 of 10).
        let ims = vec![image(0, vec![gt(1, [0.0, 0.0, 800.0])], vec![1.0])];
        let r = run(&ims, &[est(0, 1, 1.0, [20.0, 0.0, 800.0])]);
        assert_eq!(
            r.mssd
                .recall_per_threshold
                .iter()
                .filter(|&&v| v == 1.0)
                .count(),
            8
        );
        assert!((r.mssd.mean_recall - 0.8).abs() < 1e-12);
        // MSPD: 20 mm at 800 mm and f = 600 is 15 px: correct from 20 px (7 of 10).
        assert!((r.mspd.mean_recall - 0.7).abs() < 1e-12);
        assert!(r.vsd.is_none() && r.ar.is_none());
        assert!(r.note.as_deref().unwrap().contains("VSD"));
    }

    #[test]
    fn a_gt_without_estimate_is_a_miss_and_extra_estimates_are_dropped() {
        let ims = vec![image(
            0,
            vec![gt(1, [0.0, 0.0, 800.0]), gt(2, [100.0, 0.0, 800.0])],
            vec![1.0, 1.0],
        )];
        let exact = est(0, 1, 1.0, [0.0, 0.0, 800.0]);
        // A duplicate of the exact estimate and a worse one scoring higher: only the top one
        // (the worse) counts for inst_count 1.
        let worse = est(0, 1, 2.0, [80.0, 0.0, 800.0]);
        let r = run(&ims, &[exact, exact, worse]);
        assert_eq!(r.counts.estimates_scored, 1);
        assert_eq!(r.counts.estimates_beyond_top_n, 2);
        // Object 2 has no estimate: a miss. Object 1's 80 mm shift: MSSD 0.46 of diameter,
        // correct at 0.5 only.
        assert!((r.mssd.mean_recall - 0.05).abs() < 1e-12);
        assert_eq!(r.mssd.per_object_mean_recall[&2], 0.0);
        assert!((r.mssd.per_object_mean_recall[&1] - 0.1).abs() < 1e-12);
    }

    #[test]
    fn two_instances_take_the_best_free_match_in_score_order() {
        let ims = vec![image(
            0,
            vec![gt(1, [0.0, 0.0, 800.0]), gt(1, [30.0, 0.0, 800.0])],
            vec![1.0, 1.0],
        )];
        // The higher-scoring estimate sits 5 mm from GT 1 and 25 mm from GT 0: it takes GT 1.
        // The other, 12 mm from GT 0, takes GT 0.
        let r = run(
            &ims,
            &[
                est(0, 1, 0.5, [-12.0, 0.0, 800.0]),
                est(0, 1, 0.9, [25.0, 0.0, 800.0]),
            ],
        );
        // At 0.05 of the diameter (8.7 mm) only the first is correct (recall 1/2); from 0.1
        // (17.3 mm) on both are: (0.5 + 9) / 10. Had the first taken GT 0 (25 mm), the second
        // would have found no free GT within 30 mm.
        assert!((r.mssd.mean_recall - 0.95).abs() < 1e-12, "{:?}", r.mssd);
    }

    #[test]
    fn the_most_visible_instances_are_the_targets() {
        let ims = vec![image(
            0,
            vec![gt(1, [0.0, 0.0, 800.0]), gt(1, [200.0, 0.0, 800.0])],
            vec![0.2, 0.9],
        )];
        let targets = vec![Target {
            scene_id: 0,
            im_id: 0,
            obj_id: 1,
            inst_count: 1,
        }];
        // An exact estimate of the less visible instance does not count: it is not valid.
        let exact = [est(0, 1, 1.0, [0.0, 0.0, 800.0])];
        let r = run_with(&ims, &targets, &exact, &BopOptions::default()).unwrap();
        assert_eq!(r.mssd.mean_recall, 0.0);
        // With visib_gt_min 0.1 both are valid targets' instances: one of two found.
        let opts = BopOptions {
            visib_gt_min: 0.1,
            ..BopOptions::default()
        };
        let r = run_with(&ims, &targets, &exact, &opts).unwrap();
        assert!((r.mssd.mean_recall - 0.5).abs() < 1e-12);
    }

    #[test]
    fn estimates_outside_the_targets_are_counted_not_scored() {
        let ims = vec![image(0, vec![gt(1, [0.0, 0.0, 800.0])], vec![1.0])];
        let r = run(
            &ims,
            &[
                est(0, 1, 1.0, [0.0, 0.0, 800.0]),
                est(0, 2, 1.0, [0.0, 0.0, 800.0]),
                est(5, 1, 1.0, [0.0, 0.0, 800.0]),
                est(0, 7, 1.0, [0.0, 0.0, 800.0]),
            ],
        );
        assert_eq!(r.counts.estimates_not_target, 1);
        assert_eq!(r.counts.estimates_unknown_image, 1);
        assert_eq!(r.counts.estimates_unknown_object, 1);
        assert_eq!(r.mssd.mean_recall, 1.0);
    }

    /// Issue 26: an estimate of a non-target object with a model was counted "without a
    /// model" (only the targets' models are loaded); a target listed twice was counted twice
    /// (bop_toolkit keeps the last entry).
    #[test]
    fn non_target_objects_and_repeated_targets_are_counted_as_bop_toolkit_reads_them() {
        let ims = vec![image(
            0,
            vec![gt(1, [0.0, 0.0, 800.0]), gt(2, [100.0, 0.0, 800.0])],
            vec![1.0, 1.0],
        )];
        let t = Target {
            scene_id: 0,
            im_id: 0,
            obj_id: 1,
            inst_count: 1,
        };
        let mut objs = objects();
        objs.remove(&2);
        let setup = BopSetup {
            images: ims,
            targets: vec![t, t, t],
            targets_from: TargetsFrom::AllGt,
            objects: objs,
            model_ids: BTreeSet::from([1, 2]),
        };
        let ests = [
            est(0, 1, 1.0, [0.0, 0.0, 800.0]),
            est(0, 2, 1.0, [100.0, 0.0, 800.0]),
            est(0, 7, 1.0, [0.0, 0.0, 800.0]),
        ];
        let r = evaluate_bop(&setup, &ests, None, &BopOptions::default(), &NoProgress).unwrap();
        let c = &r.counts;
        assert_eq!(
            (c.targets, c.target_instances, c.targets_repeated),
            (1, 1, 2)
        );
        assert_eq!(c.estimates_not_target, 1, "object 2: a model, not a target");
        assert_eq!(c.estimates_unknown_object, 1, "object 7: no model");
        assert_eq!(r.mssd.mean_recall, 1.0);
    }

    #[test]
    fn mspd_scales_with_the_image_width() {
        let mut im = image(0, vec![gt(1, [0.0, 0.0, 800.0])], vec![1.0]);
        im.width = 1280;
        // 15 px at width 1280 counts as 7.5 px: correct from 10 px (9 of 10).
        let r = run(&[im], &[est(0, 1, 1.0, [20.0, 0.0, 800.0])]);
        assert!((r.mspd.mean_recall - 0.9).abs() < 1e-12);
    }

    #[test]
    fn a_target_outside_the_dataset_is_an_error() {
        let ims = vec![image(0, vec![gt(1, [0.0, 0.0, 800.0])], vec![1.0])];
        let targets = vec![Target {
            scene_id: 0,
            im_id: 3,
            obj_id: 1,
            inst_count: 1,
        }];
        let e = run_with(&ims, &targets, &[], &BopOptions::default()).unwrap_err();
        assert!(e.to_string().contains("image 3"), "{e}");
    }
}
