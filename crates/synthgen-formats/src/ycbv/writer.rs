//! Writing the YCB-Video layout: `classes.txt`, `models/<class>/` (OBJ in metres, MTL,
//! `points.xyz`), per frame `-color.png`, `-depth.png`, `-label.png`, `-meta.mat` (see
//! [`super::meta::encode_meta`]) and `-box.txt`, and `image_sets/<split>.txt`.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use synthgen_core::glam::DVec3;
use synthgen_core::{Intrinsics, Model};

use super::meta::encode_meta;
use super::{YcbvMeta, YcbvPose, CLASSES_FILE, MODEL_FILE, POINTS_FILE};
use crate::bop::image::{encode_gray16_png, encode_gray8_png, encode_rgb_png};
use crate::bop::PngCompression;
use crate::error::{Error, Result};
use crate::io::{atomic_write, create_dir_all};

/// How the files are written.
#[derive(Debug, Clone, PartialEq)]
pub struct YcbvWriterOptions {
    /// Depth PNG value / factor_depth = metres (YCB-Video: 10000, i.e. 0.1 mm).
    pub factor_depth: f64,
    pub png_compression: PngCompression,
}

impl Default for YcbvWriterOptions {
    fn default() -> Self {
        YcbvWriterOptions {
            factor_depth: 10000.0,
            png_compression: PngCompression::default(),
        }
    }
}

/// One object instance of a frame.
#[derive(Debug, Clone, PartialEq)]
pub struct YcbvObject {
    /// Class index (1-based line of classes.txt).
    pub obj_id: u32,
    /// `cam_from_obj` as it is to be stored.
    pub pose: YcbvPose,
}

/// One frame, ready to write.
#[derive(Debug, Clone, PartialEq)]
pub struct YcbvFrame {
    pub split: String,
    pub scene_id: u32,
    pub im_id: u32,
    pub width: u32,
    pub height: u32,
    /// `width * height * 3` sRGB bytes, row-major.
    pub rgb: Vec<u8>,
    /// Depth PNG values (1 / factor_depth metres), 0 = no reading.
    pub depth: Vec<u16>,
    /// Per pixel the class index of the visible object, 0 for none.
    pub label: Vec<u8>,
    /// Per pixel (row-major, xyz) the model coordinates of the visible surface in metres,
    /// 0 where no object is.
    pub vertmap: Vec<f32>,
    /// Row-major 3x3 K.
    pub cam_k: [f64; 9],
    pub cam_from_world: Option<YcbvPose>,
    pub objects: Vec<YcbvObject>,
}

/// What a writer wrote.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct YcbvSummary {
    pub frames: u64,
    pub scenes: usize,
    pub models: usize,
}

/// Writes a YCB-Video dataset. `write_frame` may be called from several threads.
pub struct YcbvWriter {
    root: PathBuf,
    classes: Vec<String>,
    opts: YcbvWriterOptions,
    /// Model points by class index (metres), for `-box.txt`.
    points: Mutex<BTreeMap<u32, Vec<DVec3>>>,
    frames: Mutex<BTreeSet<(String, u32, u32)>>,
    depth_out_of_range: AtomicU64,
}

/// At most this many model vertices go into `points.xyz` (YCB-Video's have ~2600).
const MAX_POINTS: usize = 2620;

impl YcbvWriter {
    /// Creates `root/data` and writes `classes.txt` (line i = class index i).
    pub fn create(root: &Path, classes: Vec<String>, opts: YcbvWriterOptions) -> Result<Self> {
        if !(opts.factor_depth.is_finite() && opts.factor_depth > 0.0) {
            return Err(Error::InvalidOptions(format!(
                "factor_depth must be positive, got {}",
                opts.factor_depth
            )));
        }
        super::check_class_names(&classes).map_err(Error::InvalidOptions)?;
        create_dir_all(&root.join("data"))?;
        let mut text = classes.join("\n");
        text.push('\n');
        atomic_write(&root.join(CLASSES_FILE), text.as_bytes())?;
        Ok(YcbvWriter {
            root: root.to_path_buf(),
            classes,
            opts,
            points: Mutex::new(BTreeMap::new()),
            frames: Mutex::new(BTreeSet::new()),
            depth_out_of_range: AtomicU64::new(0),
        })
    }

    pub fn options(&self) -> &YcbvWriterOptions {
        &self.opts
    }

    fn class(&self, obj_id: u32) -> Result<&str> {
        obj_id
            .checked_sub(1)
            .and_then(|i| self.classes.get(i as usize))
            .map(String::as_str)
            .ok_or_else(|| {
                Error::InvalidRequest(format!(
                    "object id {obj_id} has no line in classes.txt ({} classes)",
                    self.classes.len()
                ))
            })
    }

    /// Depth in metres as this writer's PNG values (rounded half to even; values over 16
    /// bits become 0 and are counted, see [`Self::depth_out_of_range_px`]).
    pub fn depth_values(&self, depth_m: &[f32]) -> Vec<u16> {
        let (v, overflow) =
            crate::bop::image::depth_to_png_values(depth_m, 1000.0 / self.opts.factor_depth);
        self.depth_out_of_range
            .fetch_add(overflow, Ordering::Relaxed);
        v
    }

    /// Depth values [`Self::depth_values`] could not store so far.
    pub fn depth_out_of_range_px(&self) -> u64 {
        self.depth_out_of_range.load(Ordering::Relaxed)
    }

    /// Writes `models/<class>/textured_simple.obj` (+ `.mtl`, metres) and `points.xyz` (the
    /// model's vertices, evenly thinned to at most 2620, as YCB-Video's evaluation points).
    pub fn write_model(&self, obj_id: u32, model: &Model) -> Result<()> {
        let dir = self.root.join("models").join(self.class(obj_id)?);
        create_dir_all(&dir)?;
        let obj = dir.join(MODEL_FILE);
        synthgen_assets::write_obj(&obj, model, 1.0).map_err(|e| Error::model(&obj, e))?;
        let all: Vec<DVec3> = model.positions().map(|p| p.as_dvec3()).collect();
        let step = all.len().div_ceil(MAX_POINTS).max(1);
        let points: Vec<DVec3> = all.iter().step_by(step).copied().collect();
        let mut text = String::with_capacity(points.len() * 30);
        for p in &points {
            let _ = writeln!(text, "{:.6} {:.6} {:.6}", p.x, p.y, p.z);
        }
        atomic_write(&dir.join(POINTS_FILE), text.as_bytes())?;
        if let Ok(mut m) = self.points.lock() {
            m.insert(obj_id, all);
        }
        Ok(())
    }

    /// `data/{scene:04}/{im:06}-` of a frame.
    pub fn frame_prefix(&self, scene_id: u32, im_id: u32) -> PathBuf {
        self.root
            .join("data")
            .join(format!("{scene_id:04}"))
            .join(format!("{im_id:06}-"))
    }

    /// Writes a frame's five files. Two instances of one class cannot share a label image:
    /// such a frame is refused.
    pub fn write_frame(&self, f: &YcbvFrame) -> Result<()> {
        let (w, h) = (f.width, f.height);
        let n = w as usize * h as usize;
        let prefix = self.frame_prefix(f.scene_id, f.im_id);
        let file = |suffix: &str| PathBuf::from(format!("{}{suffix}", prefix.display()));
        let invalid = |m: String| Error::InvalidFrame {
            frame_index: u64::from(f.im_id),
            message: format!("scene {} image {}: {m}", f.scene_id, f.im_id),
        };
        if f.rgb.len() != 3 * n || f.depth.len() != n || f.label.len() != n {
            return Err(invalid("image sizes differ".into()));
        }
        let mut seen = BTreeSet::new();
        for o in &f.objects {
            self.class(o.obj_id)?;
            if !seen.insert(o.obj_id) {
                return Err(invalid(format!(
                    "object {} appears twice; YCB-Video's label image holds one instance per class",
                    o.obj_id
                )));
            }
            o.pose
                .as_stored()
                .validate(synthgen_core::pose::rotation_tolerance())
                .map_err(|e| invalid(format!("object {}: {e}", o.obj_id)))?;
        }
        let k = Intrinsics::from_k(&f.cam_k, w, h);
        let center: Vec<[f64; 2]> = f
            .objects
            .iter()
            .map(|o| {
                let t = DVec3::from_array(o.pose.t_m);
                k.project(t).map_or([f64::NAN; 2], |(u, v)| [u, v])
            })
            .collect();
        if center.iter().flatten().any(|v| !v.is_finite()) {
            return Err(invalid("an object centre is behind the camera".into()));
        }
        let meta = YcbvMeta {
            cls_indexes: f.objects.iter().map(|o| o.obj_id).collect(),
            poses: f.objects.iter().map(|o| o.pose).collect(),
            intrinsic_matrix: f.cam_k,
            factor_depth: self.opts.factor_depth,
            center: Some(center),
            rotation_translation_matrix: f.cam_from_world,
        };
        let dir = prefix.parent().map(Path::to_path_buf).unwrap_or_default();
        create_dir_all(&dir)?;
        let c = self.opts.png_compression;
        let meta_path = file("meta.mat");
        let meta_bytes = encode_meta(&meta, &f.vertmap, w, h, &meta_path)?;
        let color = file("color.png");
        atomic_write(&color, &encode_rgb_png(&f.rgb, w, h, c, &color)?)?;
        let depth = file("depth.png");
        atomic_write(&depth, &encode_gray16_png(&f.depth, w, h, c, &depth)?)?;
        let label = file("label.png");
        atomic_write(&label, &encode_gray8_png(&f.label, w, h, c, &label)?)?;
        let mut boxes = String::new();
        for o in &f.objects {
            let b = self.box_of(o, &k, &f.label);
            let _ = writeln!(
                boxes,
                "{} {:.2} {:.2} {:.2} {:.2}",
                self.class(o.obj_id)?,
                b[0],
                b[1],
                b[2],
                b[3]
            );
        }
        atomic_write(&file("box.txt"), boxes.as_bytes())?;
        // The meta file last: a frame is listed (and read) by its -meta.mat.
        atomic_write(&meta_path, &meta_bytes)?;
        if let Ok(mut frames) = self.frames.lock() {
            frames.insert((f.split.clone(), f.scene_id, f.im_id));
        }
        Ok(())
    }

    /// `x1 y1 x2 y2`: the projected model's extent clipped to the image, as YCB-Video's
    /// boxes; the label's extent when the model was not written by this writer.
    fn box_of(&self, o: &YcbvObject, k: &Intrinsics, label: &[u8]) -> [f64; 4] {
        let (w, h) = (f64::from(k.width), f64::from(k.height));
        let points = self.points.lock().ok();
        let pts = points.as_ref().and_then(|p| p.get(&o.obj_id));
        let pose = o.pose.as_stored();
        let mut b = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut add = |u: f64, v: f64| {
            b = [b[0].min(u), b[1].min(v), b[2].max(u), b[3].max(v)];
        };
        match pts {
            Some(pts) => {
                for p in pts {
                    if let Some((u, v)) = k.project(pose.transform_point(*p)) {
                        add(u, v);
                    }
                }
            }
            None => {
                let value = u8::try_from(o.obj_id).unwrap_or(0);
                for (i, &l) in label.iter().enumerate() {
                    if l == value && value > 0 {
                        let (x, y) = (i % k.width as usize, i / k.width as usize);
                        add(x as f64, y as f64);
                    }
                }
            }
        }
        if !b[0].is_finite() {
            return [0.0; 4];
        }
        [
            b[0].clamp(0.0, w),
            b[1].clamp(0.0, h),
            b[2].clamp(0.0, w),
            b[3].clamp(0.0, h),
        ]
    }

    /// Writes `image_sets/<split>.txt` (`scene/frame` per line, sorted).
    pub fn finish(self) -> Result<YcbvSummary> {
        let frames = self.frames.into_inner().unwrap_or_default();
        let mut lists: BTreeMap<&str, String> = BTreeMap::new();
        let mut scenes = BTreeSet::new();
        for (split, scene, im) in &frames {
            let _ = writeln!(lists.entry(split).or_default(), "{scene:04}/{im:06}");
            scenes.insert(*scene);
        }
        if !lists.is_empty() {
            create_dir_all(&self.root.join("image_sets"))?;
        }
        for (split, text) in &lists {
            atomic_write(
                &self.root.join("image_sets").join(format!("{split}.txt")),
                text.as_bytes(),
            )?;
        }
        let models = self.points.into_inner().map(|m| m.len()).unwrap_or(0);
        Ok(YcbvSummary {
            frames: frames.len() as u64,
            scenes: scenes.len(),
            models,
        })
    }
}
