//! `synthgen predict`: poses from frames with no GT at all. Per frame: the colour (and the
//! depth where the pose model reads it) → the detector's boxes and masks → per detection an
//! instance (the RGB models' region around the box, the depth models' points from the mask)
//! → the pose model → the estimates, written as BOP results (`results.csv`, what
//! `synthgen eval --results` and bop_toolkit score) and as one JSON line per frame
//! (`predictions.jsonl`, a line even when nothing was found), with the time of each stage.
//!
//! The frames come from a folder of photographs with the camera's intrinsics (`camera.json`,
//! BOP's or a plain `K`), with depth images of the same names where the model needs depth, or
//! from a dataset (BOP, Linemod, YCB-Video) whose GT is not used (a BOP split is read without
//! its `scene_gt*.json`).

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::Serialize;
use synthgen_core::glam::DVec3;
use synthgen_core::{Intrinsics, Pose, Progress};
use synthgen_detect::detections::bop_box;
use synthgen_detect::detector::{Detector, Found};
use synthgen_fit::edge_refine::EdgeRefineOptions;
use synthgen_formats::bop::{read_depth_m, read_rgb, Plane, RgbImage};
use synthgen_formats::coco::Rle;
use synthgen_formats::identity::ObjectIdentity;
use synthgen_formats::layout::open_source;
use synthgen_formats::output::{check_apart, OutputLock};
use synthgen_ros::rosbag::{read_bag, BagFrames, Decoded};
use synthgen_train::data::{detection_instance, DataOptions, FramePixels, InstanceKey};
use synthgen_train::eval::pick_split;
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::{load_dataset_objects, Objects, PoseModel, Prediction};
use synthgen_train::results::{write_results_csv, Estimate};
use synthgen_train::train::{self, load_model, read_config, TrainConfig, CONFIG_FILE};

use crate::rgb_refine::Refiner;
use crate::{user_error, Log};

/// `--min-score`'s default: what `synthgen detector run` keeps.
pub const DEFAULT_MIN_SCORE: f64 = 0.05;

/// The results file `predict` writes into its `--out` folder (BOP's results format).
pub const RESULTS_FILE: &str = "results.csv";
/// The per-frame JSON lines `predict` writes into its `--out` folder.
pub const PREDICTIONS_FILE: &str = "predictions.jsonl";

/// Where the frames come from.
#[derive(Debug, Clone)]
pub enum PredictInput {
    /// A folder of photographs (PNG or JPEG, sorted by name), the camera's intrinsics, and
    /// where the model reads depth a folder of depth PNGs with the photographs' stems.
    Images {
        dir: PathBuf,
        camera: PathBuf,
        depth: Option<PathBuf>,
    },
    /// A dataset (BOP, Linemod or YCB-Video); its GT is not used.
    Data { dir: PathBuf, split: Option<String> },
    /// A ROS 2 bag in MCAP: the image topic's messages (`sensor_msgs/msg/Image` or
    /// `CompressedImage`), each with the camera info in force and, for the depth models, the
    /// depth topic's message nearest in stamp.
    Bag {
        path: PathBuf,
        image_topic: String,
        depth_topic: Option<String>,
        camera_info_topic: String,
    },
}

/// `synthgen predict`'s arguments as data.
#[derive(Debug, Clone)]
pub struct PredictRequest {
    /// The pose model: a `synthgen train` run folder, or its `model.safetensors`.
    pub model: PathBuf,
    /// The detector: a `synthgen detector train` run folder, or its checkpoint.
    pub detector: PathBuf,
    pub input: PredictInput,
    /// The output folder (`results.csv`, `predictions.jsonl`).
    pub out: PathBuf,
    /// Detections scoring less are left out.
    pub min_score: f64,
    /// At most this many detections (and so estimates) per object and frame, best first.
    pub per_object: usize,
    /// Draw each frame's detections and poses into this folder.
    pub draw: Option<PathBuf>,
    pub jobs: Option<usize>,
    pub cuda: bool,
    /// Refine the RGB models' estimates on the image ([`PredictorOptions::refine`]).
    pub refine: Option<EdgeRefineOptions>,
    pub refine_models: Option<PathBuf>,
    /// Replace the files of an earlier run in `out`.
    pub force: bool,
}

/// One frame to predict on.
struct FrameJob {
    /// The frame's name in `predictions.jsonl`: the photograph's file name, or the dataset's
    /// `SCENE/IMAGE`.
    name: String,
    scene_id: u32,
    im_id: u32,
    rgb: PathBuf,
    depth: Option<PathBuf>,
    cam_k: [f64; 9],
    /// Depth PNG value × `depth_scale` = millimetres.
    depth_scale: f64,
    size: [u32; 2],
}

/// One object found in a frame, as `predictions.jsonl` gives it.
#[derive(Debug, Clone, Serialize)]
pub struct FoundObject {
    pub obj_id: u32,
    /// The detection's score.
    pub score: f64,
    /// The pose model's confidence (1 where it gives none).
    pub pose_score: f64,
    /// `[x, y, width, height]`, pixels.
    pub bbox: [f64; 4],
    /// The rotation, row-major (camera from object); null when the model predicts none (TNet).
    #[serde(rename = "R")]
    pub r: Option<[f64; 9]>,
    /// The translation in metres (the object's origin in the camera frame); null when the
    /// model predicts none (RNet) or the detection gave no usable pixels.
    pub t: Option<[f64; 3]>,
    /// The visible mask as COCO RLE, when the detector gives masks.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub segmentation: Option<Rle>,
}

/// One line of `predictions.jsonl`.
#[derive(Debug, Clone, Serialize)]
pub struct FramePrediction {
    pub frame: String,
    pub scene_id: u32,
    pub image_id: u32,
    /// Seconds since the Unix epoch when the frame was done (photographs carry no stamp).
    pub stamp: f64,
    pub objects: Vec<FoundObject>,
    /// Seconds per stage: reading, detection, instances, pose model, total.
    pub time: StageTimes,
}

/// Seconds spent per stage.
#[derive(Debug, Clone, Copy, Default, Serialize)]
pub struct StageTimes {
    pub read: f64,
    pub detect: f64,
    pub instances: f64,
    pub pose: f64,
    /// The refinement on the image (0 without `--refine`).
    pub refine: f64,
    pub total: f64,
}

impl StageTimes {
    fn add(&mut self, o: &StageTimes) {
        self.read += o.read;
        self.detect += o.detect;
        self.instances += o.instances;
        self.pose += o.pose;
        self.refine += o.refine;
        self.total += o.total;
    }
}

/// What a prediction run did.
#[derive(Debug, Clone, Default, Serialize)]
pub struct PredictSummary {
    pub frames: usize,
    /// Frames where at least one object was found.
    pub frames_with_objects: usize,
    /// Objects found, per object id.
    pub found: BTreeMap<u32, usize>,
    /// Rows of `results.csv` (whole poses).
    pub results: usize,
    /// Detections whose instance had too few valid pixels (no pose).
    pub without_pose: usize,
    /// Summed seconds per stage.
    pub time: StageTimes,
    /// The frames' total time per frame, median and 95th percentile, seconds.
    pub median_frame_s: f64,
    pub p95_frame_s: f64,
}

/// The camera of `--camera`: BOP's `camera.json` (`fx, fy, cx, cy, width, height`,
/// `depth_scale`) or a plain intrinsics file (`K` or `cam_K`: nine numbers, row-major;
/// optional `width`, `height`, `depth_scale`). Returns K, the depth scale and the image size
/// when the file states it.
pub fn read_camera_file(path: &Path) -> Result<([f64; 9], f64, Option<[u32; 2]>)> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the camera file {}", path.display()))?;
    let bad = |m: String| {
        user_error(
            format!("the camera file {} {m}", path.display()),
            "give BOP's camera.json ({\"fx\", \"fy\", \"cx\", \"cy\", \"width\", \"height\"}) or {\"K\": [fx, 0, cx, 0, fy, cy, 0, 0, 1]}",
        )
    };
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| bad(format!("is not JSON: {e}")))?;
    let num = |key: &str| -> Result<Option<f64>> {
        match v.get(key) {
            None | Some(serde_json::Value::Null) => Ok(None),
            Some(x) => x
                .as_f64()
                .filter(|f| f.is_finite())
                .map(Some)
                .ok_or_else(|| bad(format!("has a \"{key}\" that is not a finite number"))),
        }
    };
    let k = if let Some(list) = v.get("K").or_else(|| v.get("cam_K")) {
        let nums: Vec<f64> = list
            .as_array()
            .map(|a| a.iter().filter_map(serde_json::Value::as_f64).collect())
            .unwrap_or_default();
        let flat: Vec<f64> = if nums.len() == 9 {
            nums
        } else {
            // [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
            list.as_array()
                .map(|rows| {
                    rows.iter()
                        .filter_map(serde_json::Value::as_array)
                        .flatten()
                        .filter_map(serde_json::Value::as_f64)
                        .collect()
                })
                .unwrap_or_default()
        };
        if flat.len() != 9 || flat.iter().any(|f| !f.is_finite()) {
            return Err(bad("has a \"K\" that is not nine finite numbers".into()));
        }
        std::array::from_fn(|i| flat[i])
    } else {
        match (num("fx")?, num("fy")?, num("cx")?, num("cy")?) {
            (Some(fx), Some(fy), Some(cx), Some(cy)) => [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            _ => {
                return Err(bad(
                    "has neither \"K\" nor \"fx\", \"fy\", \"cx\", \"cy\"".into()
                ))
            }
        }
    };
    if k[0] <= 0.0 || k[4] <= 0.0 {
        return Err(bad("has a focal length that is not positive".into()));
    }
    let depth_scale = num("depth_scale")?.unwrap_or(1.0);
    if depth_scale <= 0.0 {
        return Err(bad("has a depth_scale that is not positive".into()));
    }
    let size = match (num("width")?, num("height")?) {
        (Some(w), Some(h)) if w >= 1.0 && h >= 1.0 => Some([w as u32, h as u32]),
        (None, None) => None,
        _ => {
            return Err(bad(
                "has a width or height that is not a positive number".into()
            ))
        }
    };
    Ok((k, depth_scale, size))
}

/// The photographs of a folder (PNG, JPEG), sorted by name.
fn list_images(dir: &Path) -> Result<Vec<PathBuf>> {
    let entries = std::fs::read_dir(dir)
        .with_context(|| format!("cannot read the image folder {}", dir.display()))?;
    let mut out: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                    ["png", "jpg", "jpeg"].contains(&e.to_ascii_lowercase().as_str())
                })
        })
        .collect();
    out.sort();
    Ok(out)
}

/// The frames of a folder of photographs: their camera file, and their depth PNGs where the
/// model reads depth.
fn image_jobs(
    dir: &Path,
    camera: &Path,
    depth: Option<&Path>,
    needs_depth: bool,
) -> Result<Vec<FrameJob>> {
    let (cam_k, depth_scale, size) = read_camera_file(camera)?;
    if needs_depth && depth.is_none() {
        return Err(user_error(
            "this pose model reads depth, and no --depth folder was given",
            "give --depth DIR with a 16-bit depth PNG per photograph (the same file stem; camera.json's depth_scale: value × depth_scale = mm), or use an rgb / rgb-dense model",
        ));
    }
    let images = list_images(dir)?;
    if images.is_empty() {
        return Err(user_error(
            format!("{} holds no PNG or JPEG images", dir.display()),
            "give the folder of the photographs to predict on",
        ));
    }
    // Image ids: the file stems' numbers where every stem is a distinct number (BOP's
    // rgb/000003.png is image 3), else the images' places in name order.
    let numbers: Vec<Option<u32>> = images
        .iter()
        .map(|p| p.file_stem()?.to_str()?.parse().ok())
        .collect();
    let distinct: std::collections::BTreeSet<u32> = numbers.iter().flatten().copied().collect();
    let by_stem = distinct.len() == images.len();
    images
        .into_iter()
        .enumerate()
        .map(|(i, rgb)| {
            let name = rgb
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let depth = match depth.filter(|_| needs_depth) {
                Some(d) => {
                    let stem = rgb.file_stem().unwrap_or_default();
                    let p = d.join(stem).with_extension("png");
                    if !p.is_file() {
                        return Err(user_error(
                            format!("{name} has no depth image {}", p.display()),
                            "give each photograph a depth PNG of the same stem in --depth",
                        ));
                    }
                    Some(p)
                }
                None => None,
            };
            Ok(FrameJob {
                name,
                scene_id: 0,
                im_id: if by_stem {
                    numbers[i].unwrap_or(i as u32)
                } else {
                    i as u32
                },
                rgb,
                depth,
                cam_k,
                depth_scale,
                size: size.unwrap_or([0, 0]),
            })
        })
        .collect()
}

/// The frames of a dataset's split, read without their GT.
fn dataset_jobs(dir: &Path, split: Option<&str>, needs_depth: bool) -> Result<Vec<FrameJob>> {
    let ds =
        open_source(dir).with_context(|| format!("cannot open the dataset {}", dir.display()))?;
    let split = pick_split(ds.as_ref(), split)?;
    let cam = ds.camera();
    let frames = ds.image_frames(std::slice::from_ref(&split))?;
    frames
        .into_iter()
        .map(|f| {
            if needs_depth && f.depth.is_none() {
                return Err(user_error(
                    format!(
                        "image {} of scene {} in {} has no depth image, and this pose model reads depth",
                        f.location.im_id,
                        f.location.scene_id,
                        dir.display()
                    ),
                    "predict with an rgb / rgb-dense model, or on RGB-D frames",
                ));
            }
            Ok(FrameJob {
                name: format!("{:06}/{:06}", f.location.scene_id, f.location.im_id),
                scene_id: f.location.scene_id,
                im_id: f.location.im_id,
                rgb: f.rgb,
                depth: f.depth,
                cam_k: f.camera.cam_k,
                depth_scale: f.camera.depth_scale,
                size: [cam.width, cam.height],
            })
        })
        .collect()
}

/// A detector and a pose model, loaded, that turn a frame's colour (and depth) into the
/// objects found and their poses: what `synthgen predict` runs per frame, and Python's
/// `synthgen.Predictor`.
pub struct Predictor {
    cfg: TrainConfig,
    pose: PoseModel,
    detector: Detector,
    objects: Option<Objects>,
    /// The objects both the detector and the pose model know.
    shared: Vec<u32>,
    opts: DataOptions,
    min_score: f64,
    per_object: usize,
    /// The RGB models' estimates refined on the image (`--refine edges|views`).
    refiner: Option<Refiner>,
}

/// How a [`Predictor`] is made.
#[derive(Debug, Clone)]
pub struct PredictorOptions {
    /// The pose model: a `synthgen train` run folder, or its `model.safetensors`.
    pub model: PathBuf,
    /// The detector: a `synthgen detector train` run folder, or its checkpoint.
    pub detector: PathBuf,
    /// The dataset whose object models the pose model reads (Full, rgb, rgb-dense); None:
    /// the model's training dataset.
    pub objects_from: Option<PathBuf>,
    /// Detections scoring less are left out.
    pub min_score: f64,
    /// At most this many detections (and so estimates) per object and frame, best first.
    pub per_object: usize,
    pub cuda: bool,
    /// Refine the RGB models' estimates on the image (`eval --refine edges|views`), each
    /// kept to its detection's box.
    pub refine: Option<EdgeRefineOptions>,
    /// With `refine`: the colours from these meshes (`eval --refine-models`).
    pub refine_models: Option<PathBuf>,
}

/// One frame's objects and the seconds of each stage (reading aside).
#[derive(Debug, Clone)]
pub struct FrameObjects {
    pub objects: Vec<FoundObject>,
    pub detect_s: f64,
    pub instances_s: f64,
    pub pose_s: f64,
    /// 0 without a refinement.
    pub refine_s: f64,
}

impl Predictor {
    /// The model kind of the pose model.
    pub fn kind(&self) -> ModelKind {
        self.cfg.model
    }

    /// Whether the pose model reads depth.
    pub fn needs_depth(&self) -> bool {
        self.cfg.model.needs_depth()
    }

    /// The objects both the detector and the pose model know.
    pub fn object_ids(&self) -> &[u32] {
        &self.shared
    }

    /// An object's identity (name, diameter, bounding-box size) as the models were trained
    /// on it.
    pub fn object_identity(&self, id: u32) -> Option<&ObjectIdentity> {
        self.cfg
            .objects
            .iter()
            .chain(&self.detector.cfg.objects)
            .find(|o| o.id == id)
    }

    /// The objects found in one frame: `rgb`, `depth` in metres (0 where none; the depth
    /// models need it), the camera matrix row-major; `scene_id`/`im_id` name the frame.
    pub fn predict_image(
        &self,
        rgb: &RgbImage,
        depth: Option<&Plane<f32>>,
        cam_k: &[f64; 9],
        ids: (u32, u32),
    ) -> Result<FrameObjects> {
        if self.needs_depth() && depth.is_none() {
            return Err(user_error(
                format!("the {} model reads depth, and the frame has none", self.cfg.model.name()),
                "give the frame's depth (registered to the colour image), or use an rgb / rgb-dense model",
            ));
        }
        if let Some(d) = depth {
            if [d.width, d.height] != [rgb.width, rgb.height] {
                return Err(user_error(
                    format!(
                        "the depth is {}x{}, and the colour image {}x{}",
                        d.width, d.height, rgb.width, rgb.height
                    ),
                    "give depth registered to the colour image (the same size)",
                ));
            }
        }
        if cam_k.iter().any(|v| !v.is_finite()) || cam_k[0] <= 0.0 || cam_k[4] <= 0.0 {
            return Err(user_error(
                format!("the camera matrix {cam_k:?} is not a camera's (finite, positive focal lengths)"),
                "give K as [fx, 0, cx, 0, fy, cy, 0, 0, 1]",
            ));
        }
        let t1 = Instant::now();
        let found = self.detector.detect_image(
            &rgb.rgb,
            rgb.width,
            rgb.height,
            self.min_score,
            self.per_object,
        )?;
        let detect_s = t1.elapsed().as_secs_f64();
        let t2 = Instant::now();
        let instances = self.frame_instances(ids, cam_k, rgb, depth, &found)?;
        let instances_s = t2.elapsed().as_secs_f64();
        let t3 = Instant::now();
        let refs: Vec<_> = instances.iter().filter_map(Option::as_ref).collect();
        let preds: Vec<Prediction> = if refs.is_empty() {
            Vec::new()
        } else {
            self.pose.predict(&refs, self.objects.as_ref(), 64)?
        };
        let pose_s = t3.elapsed().as_secs_f64();
        let mut preds = preds.into_iter();
        let objects = found
            .iter()
            .zip(&instances)
            .map(|((obj, score, bbox, mask), inst)| {
                let pred = inst.as_ref().and_then(|_| preds.next());
                let r = pred.as_ref().and_then(|p| p.rotation.map(|(r, _)| r));
                let t = pred
                    .as_ref()
                    .and_then(|p| p.centre_m)
                    .map(|c| [c[0], c[1], c[2]].map(f64::from));
                FoundObject {
                    obj_id: *obj,
                    score: *score,
                    pose_score: pred.as_ref().map_or(1.0, Prediction::score),
                    bbox: *bbox,
                    r: r.map(|r| {
                        let c = r.to_cols_array();
                        // glam is column-major; BOP's R is row-major.
                        [c[0], c[3], c[6], c[1], c[4], c[7], c[2], c[5], c[8]]
                    }),
                    t,
                    segmentation: mask.clone(),
                }
            })
            .collect::<Vec<_>>();
        let t4 = Instant::now();
        let objects = match &self.refiner {
            Some(refiner) => {
                let k = Intrinsics::from_k(cam_k, rgb.width, rgb.height);
                objects
                    .into_par_iter()
                    .map(|mut o| {
                        if let (Some(r), Some(t)) = (o.r, o.t) {
                            let pose = Pose::from_bop(&r, &t.map(|v| v * 1000.0));
                            if let Some(done) =
                                refiner.refine_pose(rgb, &k, o.obj_id, &pose, &[o.bbox])
                            {
                                o.r = Some(done.pose.rotation_row_major());
                                o.t = Some(done.pose.translation_m.to_array());
                            }
                        }
                        o
                    })
                    .collect()
            }
            None => objects,
        };
        let refine_s = if self.refiner.is_some() {
            t4.elapsed().as_secs_f64()
        } else {
            0.0
        };
        Ok(FrameObjects {
            objects,
            detect_s,
            instances_s,
            pose_s,
            refine_s,
        })
    }

    /// Per detection, the instance the pose model reads: None for the objects the pose model
    /// does not know and for detections with too few valid pixels.
    fn frame_instances(
        &self,
        (scene_id, im_id): (u32, u32),
        cam_k: &[f64; 9],
        rgb: &RgbImage,
        depth: Option<&Plane<f32>>,
        found: &[Found],
    ) -> Result<Vec<Option<synthgen_train::data::Instance>>> {
        let pixels = FramePixels {
            scene_id,
            im_id,
            cam_k,
            rgb: Some(rgb),
            depth,
        };
        let source = Path::new("the frame");
        found
            .iter()
            .enumerate()
            .map(|(k, (obj, _, bbox, mask))| {
                if !self.shared.contains(obj) {
                    return Ok(None);
                }
                // The depth models read their points from the detection's mask (a detector
                // with masks: checked when loaded), the RGB models the colour around its box.
                let mask = if self.cfg.model.is_rgb_only() {
                    None
                } else {
                    mask.as_ref()
                };
                Ok(detection_instance(
                    &pixels,
                    InstanceKey {
                        gt_id: k,
                        obj_id: *obj,
                    },
                    bop_box(*bbox),
                    mask,
                    source,
                    &self.opts,
                )?)
            })
            .collect()
    }

    /// Loads the detector and the pose model of `o`; warnings go to `log`.
    pub fn load(o: &PredictorOptions, log: &Log<'_>) -> Result<Predictor> {
        if !(0.0..=1.0).contains(&o.min_score) {
            return Err(user_error(
                format!("--min-score {} is not in 0..1", o.min_score),
                "give a detection score between 0 and 1 (e.g. 0.3)",
            ));
        }
        if o.per_object == 0 || o.per_object > 100 {
            return Err(user_error(
                format!("--per-object {} is not in 1..=100", o.per_object),
                "give how many of each object a frame may show (1 for BOP's LM-O and YCB-V)",
            ));
        }
        load_models(o, log)
    }
}

fn load_models(req: &PredictorOptions, log: &Log<'_>) -> Result<Predictor> {
    let ckpt = train::checkpoint_in(&req.model);
    let cfg_path = ckpt.with_file_name(CONFIG_FILE);
    if !cfg_path.is_file() {
        return Err(user_error(
            format!("no {CONFIG_FILE} beside {}", ckpt.display()),
            "give --model the run folder of `synthgen train` (or its model.safetensors)",
        ));
    }
    let cfg = read_config(&cfg_path)?;
    let device = train::device(req.cuda)?;
    let pose = load_model(&ckpt, &cfg, &device)
        .with_context(|| format!("cannot load the pose model {}", ckpt.display()))?;
    let detector = Detector::load(&req.detector, &device)
        .with_context(|| format!("cannot load the detector {}", req.detector.display()))?;
    // The objects both know, and the same objects under the same ids.
    let of = |list: &[ObjectIdentity]| -> BTreeMap<u32, ObjectIdentity> {
        list.iter().map(|o| (o.id, o.clone())).collect()
    };
    let (pose_objects, det_objects) = (of(&cfg.objects), of(&detector.cfg.objects));
    let model_ids: Vec<u32> = if cfg.classes.is_empty() {
        cfg.objects.iter().map(|o| o.id).collect()
    } else {
        cfg.classes.clone()
    };
    // A model with no objects of its own (a class-free TNet) takes every object.
    let any_object = model_ids.is_empty();
    let mut shared = Vec::new();
    for &id in &detector.cfg.classes {
        if !any_object && !model_ids.contains(&id) {
            continue;
        }
        if let (Some(a), Some(b)) = (pose_objects.get(&id), det_objects.get(&id)) {
            if !a.same_object(b) {
                return Err(user_error(
                    format!(
                        "object {id} is {} for the pose model and {} for the detector",
                        a.describe(),
                        b.describe()
                    ),
                    "give a detector and a pose model trained on the same objects",
                ));
            }
        }
        shared.push(id);
    }
    if shared.is_empty() {
        return Err(user_error(
            format!(
                "the detector finds objects {:?} and the pose model knows {:?}: none in common",
                detector.cfg.classes, model_ids
            ),
            "give a detector and a pose model trained on the same objects",
        ));
    }
    let left: Vec<u32> = detector
        .cfg
        .classes
        .iter()
        .copied()
        .filter(|c| !shared.contains(c))
        .collect();
    if !left.is_empty() {
        log.warning(format!(
            "the pose model has no head for the detector's objects {left:?}: their detections are written without a pose"
        ));
    }
    if cfg.model.needs_depth() && !detector.cfg.masks {
        return Err(user_error(
            format!(
                "the {} model reads each object's points from its mask, and the detector {} gives boxes only",
                cfg.model.name(),
                req.detector.display()
            ),
            "train the detector with masks (detector train without --no-masks), or predict with an rgb / rgb-dense model",
        ));
    }
    if req.refine.is_none() && req.refine_models.is_some() {
        return Err(user_error(
            "--refine-models gives the refinement its colours, and no --refine is asked for",
            "add --refine views (or edges), or drop --refine-models",
        ));
    }
    if req.refine.is_some() && !cfg.model.is_rgb_only() {
        return Err(user_error(
            format!(
                "--refine edges and views refine the RGB models' estimates, and this is a {} model",
                cfg.model.name()
            ),
            "drop --refine, or predict with an rgb or rgb-dense model",
        ));
    }
    // Full and the RGB models need the objects' models (their points, their symmetries); the
    // refinement (RGB models only) reads the same dataset's meshes.
    let (objects, refiner) = if cfg.model.predicts_rotation() {
        let source = req.objects_from.clone().unwrap_or_else(|| cfg.data.clone());
        let ds = open_source(&source).map_err(|e| {
            user_error(
                format!(
                    "the pose model needs its objects' models, read from {} (the model's training dataset), and it cannot be opened: {e}",
                    source.display()
                ),
                "keep the training dataset where `synthgen train` read it (its models/ folder), or predict on a dataset with --data",
            )
        })?;
        let objects = load_dataset_objects(ds.as_ref(), shared.iter().copied(), cfg.loss_points)?;
        let refiner = match &req.refine {
            Some(refine) => Some(Refiner::load(
                ds.as_ref(),
                &shared.iter().copied().collect(),
                refine,
                req.refine_models.as_deref(),
            )?),
            None => None,
        };
        (Some(objects), refiner)
    } else {
        (None, None)
    };
    let base = cfg.data_options();
    let opts = DataOptions {
        split: None,
        // The RGB models read the colour around the box: every detection gets an estimate
        // (its score says how much to trust it). The depth models need points: a detection
        // whose mask holds fewer valid depth pixels than the training's minimum gets none.
        min_pixels: if cfg.model.is_rgb_only() {
            1
        } else {
            base.min_pixels
        },
        ..base
    };
    Ok(Predictor {
        cfg,
        pose,
        detector,
        objects,
        shared,
        opts,
        min_score: req.min_score,
        per_object: req.per_object,
        refiner,
    })
}

/// Runs `req`: the frames' estimates into `req.out`, progress and messages to `progress`.
pub fn predict(req: &PredictRequest, progress: &dyn Progress) -> Result<PredictSummary> {
    let log = Log::new(progress);
    crate::use_threads(req.jobs);
    let mut inputs: Vec<(&str, &Path)> = vec![("model", &req.model), ("detector", &req.detector)];
    match &req.input {
        PredictInput::Images { dir, camera, depth } => {
            inputs.push(("image folder", dir));
            inputs.push(("camera file", camera));
            if let Some(d) = depth {
                inputs.push(("depth folder", d));
            }
        }
        PredictInput::Data { dir, .. } => inputs.push(("dataset", dir)),
        PredictInput::Bag { path, .. } => inputs.push(("bag", path)),
    }
    check_apart(&req.out, &inputs)?;
    if let Some(d) = &req.draw {
        check_apart(d, &inputs)?;
    }
    let models = Predictor::load(
        &PredictorOptions {
            model: req.model.clone(),
            detector: req.detector.clone(),
            objects_from: match &req.input {
                PredictInput::Data { dir, .. } => Some(dir.clone()),
                PredictInput::Images { .. } | PredictInput::Bag { .. } => None,
            },
            min_score: req.min_score,
            per_object: req.per_object,
            cuda: req.cuda,
            refine: req.refine.clone(),
            refine_models: req.refine_models.clone(),
        },
        &log,
    )?;
    let kind = models.kind();
    let frames = Frames::of(&req.input, kind.needs_depth())?;
    std::fs::create_dir_all(&req.out)
        .with_context(|| format!("cannot create {}", req.out.display()))?;
    let _lock = OutputLock::acquire(&req.out)?;
    let results_path = req.out.join(RESULTS_FILE);
    let jsonl_path = req.out.join(PREDICTIONS_FILE);
    if !req.force && (results_path.exists() || jsonl_path.exists()) {
        return Err(user_error(
            format!("{} already holds predictions", req.out.display()),
            "give another --out, or --force to replace them",
        ));
    }
    if let Some(d) = &req.draw {
        std::fs::create_dir_all(d).with_context(|| format!("cannot create {}", d.display()))?;
    }
    // The lines go to a temporary file renamed at the end: an interrupted run leaves no
    // half-written predictions.jsonl that looks finished.
    let tmp_jsonl = req.out.join(format!("{PREDICTIONS_FILE}.partial"));
    let mut jsonl = std::io::BufWriter::new(
        std::fs::File::create(&tmp_jsonl)
            .with_context(|| format!("cannot create {}", tmp_jsonl.display()))?,
    );
    log.info(format!(
        "predicting on {} frames: detector ({} objects, input {}x{}) then the {} model",
        frames.len(),
        models.detector.cfg.classes.len(),
        models.detector.cfg.input[0],
        models.detector.cfg.input[1],
        kind.name()
    ));
    progress.start("predicting", frames.len() as u64);
    let mut summary = PredictSummary::default();
    let mut estimates = Vec::new();
    let mut frame_times = Vec::with_capacity(frames.len());
    for i in 0..frames.len() {
        let t0 = Instant::now();
        let frame = frames.load(i)?;
        let (line, ests) = predict_frame(&frame, t0, &models)?;
        if let Some(dir) = &req.draw {
            draw_frame(
                &dir.join(format!("{:06}_{:06}.png", frame.scene_id, frame.im_id)),
                &frame,
                &line,
            )?;
        }
        serde_json::to_writer(&mut jsonl, &line)?;
        jsonl.write_all(b"\n")?;
        summary.frames += 1;
        if !line.objects.is_empty() {
            summary.frames_with_objects += 1;
        }
        for o in &line.objects {
            *summary.found.entry(o.obj_id).or_insert(0) += 1;
            // No pose at all: an RNet's rotation has no t, a TNet's centre no R.
            if o.t.is_none() && o.r.is_none() && models.shared.contains(&o.obj_id) {
                summary.without_pose += 1;
            }
        }
        summary.time.add(&line.time);
        frame_times.push(line.time.total);
        estimates.extend(ests);
        progress.advance(1);
    }
    progress.finish();
    jsonl
        .into_inner()
        .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", tmp_jsonl.display()))?
        .sync_all()?;
    // The results first, the JSON lines last: predictions.jsonl is the run's "done" mark.
    write_results_csv(&results_path, &estimates)?;
    std::fs::rename(&tmp_jsonl, &jsonl_path)
        .with_context(|| format!("cannot write {}", jsonl_path.display()))?;
    summary.results = estimates.len();
    frame_times.sort_by(f64::total_cmp);
    let pick = |q: f64| {
        frame_times
            .get(((frame_times.len() as f64 - 1.0) * q).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    summary.median_frame_s = pick(0.5);
    summary.p95_frame_s = pick(0.95);
    if !kind.predicts_rotation() || kind == ModelKind::Rnet {
        log.info(format!(
            "the {} model predicts {} only: {RESULTS_FILE} (whole poses) has no rows; predictions.jsonl has them",
            kind.name(),
            if kind == ModelKind::Tnet { "the centre" } else { "the rotation" }
        ));
    }
    Ok(summary)
}

/// The frames of a request: files (photographs or a dataset's) or a bag's messages.
enum Frames {
    Files(Vec<FrameJob>),
    Bag { bag: BagFrames, needs_depth: bool },
}

/// A frame read: its images and camera.
struct LoadedFrame {
    name: String,
    scene_id: u32,
    im_id: u32,
    /// The message's header stamp (bags), seconds.
    stamp: Option<f64>,
    rgb: RgbImage,
    depth: Option<Plane<f32>>,
    cam_k: [f64; 9],
}

impl Frames {
    fn of(input: &PredictInput, needs_depth: bool) -> Result<Frames> {
        match input {
            PredictInput::Bag {
                path,
                image_topic,
                depth_topic,
                camera_info_topic,
            } => {
                if needs_depth && depth_topic.is_none() {
                    return Err(user_error(
                        "this pose model reads depth, and no --depth-topic was given",
                        "give --depth-topic (sensor_msgs/Image, 16UC1 mm or 32FC1 m, registered to the colour image), or use an rgb / rgb-dense model",
                    ));
                }
                let bag = read_bag(
                    path,
                    image_topic,
                    depth_topic.as_deref().filter(|_| needs_depth),
                    camera_info_topic,
                )?;
                Ok(Frames::Bag { bag, needs_depth })
            }
            PredictInput::Images { dir, camera, depth } => Ok(Frames::Files(image_jobs(
                dir,
                camera,
                depth.as_deref(),
                needs_depth,
            )?)),
            PredictInput::Data { dir, split } => Ok(Frames::Files(dataset_jobs(
                dir,
                split.as_deref(),
                needs_depth,
            )?)),
        }
    }

    fn len(&self) -> usize {
        match self {
            Frames::Files(f) => f.len(),
            Frames::Bag { bag, .. } => bag.images.len(),
        }
    }

    fn load(&self, i: usize) -> Result<LoadedFrame> {
        match self {
            Frames::Files(f) => load_file_frame(&f[i]),
            Frames::Bag { bag, needs_depth } => {
                let m = &bag.images[i];
                let rgb = match bag.decode(m)? {
                    Decoded::Colour(c) => c,
                    Decoded::Depth(_) => {
                        return Err(user_error(
                            format!(
                                "message {} on the image topic of {} is a depth image",
                                m.index,
                                bag.path.display()
                            ),
                            "give --image-topic the colour topic and --depth-topic the depth",
                        ))
                    }
                };
                let depth = if *needs_depth {
                    // A frame without depth near its stamp has no depth: its objects get no
                    // points (and so no pose), and the frame still gets its line.
                    match bag.depth_for(m).map(|d| bag.decode(d)).transpose()? {
                        Some(Decoded::Depth(d)) => Some(d),
                        Some(Decoded::Colour(_)) => {
                            return Err(user_error(
                                format!(
                                    "the depth topic of {} holds colour images",
                                    bag.path.display()
                                ),
                                "give --depth-topic a 16UC1 or 32FC1 image topic",
                            ))
                        }
                        None => Some(Plane {
                            width: rgb.width,
                            height: rgb.height,
                            data: vec![0.0; (rgb.width * rgb.height) as usize],
                        }),
                    }
                } else {
                    None
                };
                let info = bag.camera_for(m).ok_or_else(|| {
                    user_error(
                        format!("{} has no camera info", bag.path.display()),
                        "give --camera-info-topic",
                    )
                })?;
                if [info.width, info.height] != [rgb.width, rgb.height]
                    && info.width != 0
                    && info.height != 0
                {
                    return Err(user_error(
                        format!(
                            "message {} of {} is {}x{}, and its camera info says {}x{}",
                            m.index,
                            bag.path.display(),
                            rgb.width,
                            rgb.height,
                            info.width,
                            info.height
                        ),
                        "give the camera info topic of the image topic's camera",
                    ));
                }
                Ok(LoadedFrame {
                    name: format!("{}@{:.9}", m.header.frame_id, m.header.seconds()),
                    scene_id: 0,
                    im_id: i as u32,
                    stamp: Some(m.header.seconds()),
                    rgb,
                    depth,
                    cam_k: info.k,
                })
            }
        }
    }
}

/// A photograph's or a dataset frame's files, read.
fn load_file_frame(job: &FrameJob) -> Result<LoadedFrame> {
    let rgb = read_rgb(&job.rgb)?;
    if job.size != [0, 0] && [rgb.width, rgb.height] != job.size {
        return Err(user_error(
            format!(
                "{} is {}x{}, and the camera is {}x{}",
                job.rgb.display(),
                rgb.width,
                rgb.height,
                job.size[0],
                job.size[1]
            ),
            "give the intrinsics of the camera that took these images (the same size)",
        ));
    }
    let depth: Option<Plane<f32>> = match &job.depth {
        Some(p) => {
            let d = read_depth_m(p, job.depth_scale)?;
            if [d.width, d.height] != [rgb.width, rgb.height] {
                return Err(user_error(
                    format!(
                        "the depth image {} is {}x{}, and its colour image {}x{}",
                        p.display(),
                        d.width,
                        d.height,
                        rgb.width,
                        rgb.height
                    ),
                    "give depth registered to the colour image (the same size)",
                ));
            }
            Some(d)
        }
        None => None,
    };
    Ok(LoadedFrame {
        name: job.name.clone(),
        scene_id: job.scene_id,
        im_id: job.im_id,
        stamp: None,
        rgb,
        depth,
        cam_k: job.cam_k,
    })
}

/// One frame read (since `t0`), then the predictor; the frame's line and its whole poses.
fn predict_frame(
    frame: &LoadedFrame,
    t0: Instant,
    models: &Predictor,
) -> Result<(FramePrediction, Vec<Estimate>)> {
    let (rgb, depth) = (&frame.rgb, &frame.depth);
    let read_s = t0.elapsed().as_secs_f64();
    let found = models.predict_image(
        rgb,
        depth.as_ref(),
        &frame.cam_k,
        (frame.scene_id, frame.im_id),
    )?;
    let total = t0.elapsed().as_secs_f64();
    let estimates = found
        .objects
        .iter()
        .filter_map(|o| {
            let (r, t) = (o.r?, o.t?);
            let r = synthgen_core::glam::DMat3::from_cols_array(&[
                r[0], r[3], r[6], r[1], r[4], r[7], r[2], r[5], r[8],
            ]);
            let mut e = Estimate::new(
                frame.scene_id,
                frame.im_id,
                o.obj_id,
                o.score * o.pose_score,
                Pose::new(r, DVec3::from_array(t)),
            );
            e.time_s = total;
            Some(e)
        })
        .collect();
    let stamp = frame.stamp.unwrap_or_else(|| {
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64())
    });
    Ok((
        FramePrediction {
            frame: frame.name.clone(),
            scene_id: frame.scene_id,
            image_id: frame.im_id,
            stamp,
            time: StageTimes {
                read: read_s,
                detect: found.detect_s,
                instances: found.instances_s,
                pose: found.pose_s,
                refine: found.refine_s,
                total,
            },
            objects: found.objects,
        },
        estimates,
    ))
}

/// Draws a frame's detections (mask tinted, box, object id and score) and each pose's axes
/// (x red, y green, z blue; 5 cm), or a cross at a centre without rotation, into `path`.
fn draw_frame(path: &Path, job: &LoadedFrame, line: &FramePrediction) -> Result<()> {
    use synthgen_formats::annotate::mask_overlay;
    let img = &job.rgb;
    let masks: Vec<Vec<u8>> = line
        .objects
        .iter()
        .filter_map(|o| o.segmentation.as_ref().map(Rle::decode))
        .collect();
    let theirs = vec![None; masks.len()];
    let mut c = mask_overlay(img, &masks, &theirs);
    const BOX: [u8; 3] = [255, 200, 0];
    let k = &job.cam_k;
    let project = |p: DVec3| -> Option<(f64, f64)> {
        (p.z > 1e-6).then(|| (k[0] * p.x / p.z + k[2], k[4] * p.y / p.z + k[5]))
    };
    for o in &line.objects {
        let [x, y, w, h] = o.bbox;
        let (x1, y1) = (x + w - 1.0, y + h - 1.0);
        c.line((x, y), (x1, y), BOX, 2);
        c.line((x1, y), (x1, y1), BOX, 2);
        c.line((x1, y1), (x, y1), BOX, 2);
        c.line((x, y1), (x, y), BOX, 2);
        c.text(
            x as i64 + 3,
            y as i64 + 3,
            &format!("{} {:.2}", o.obj_id, o.score),
            2,
            BOX,
        );
        if let (None, Some(t)) = (o.r, o.t) {
            // A centre without a rotation (TNet): a cross.
            if let Some((u, v)) = project(DVec3::from_array(t)) {
                c.line((u - 8.0, v), (u + 8.0, v), BOX, 2);
                c.line((u, v - 8.0), (u, v + 8.0), BOX, 2);
            }
        }
        if let (Some(r), Some(t)) = (o.r, o.t) {
            let t = DVec3::from_array(t);
            let col = |j: usize| DVec3::new(r[j], r[3 + j], r[6 + j]);
            if let Some(o2) = project(t) {
                for (j, colour) in [[235, 40, 40], [40, 200, 40], [40, 110, 255]]
                    .into_iter()
                    .enumerate()
                {
                    if let Some(e) = project(t + col(j) * 0.05) {
                        c.line(o2, e, colour, 2);
                    }
                }
            }
        }
    }
    c.write_png(path)?;
    Ok(())
}
