//! Reading BOP datasets: `camera.json`, `models/models_info.json`, splits, scene folders and
//! their JSON files, with errors that name the file and the problem.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use synthgen_core::{GtInfo, Pose};

use super::image::{self, Plane};
use super::types::{CameraInfo, GtEntry, ModelInfo, SceneCamera};
use crate::error::{Error, Result};
use crate::io;

/// Reads and deserializes a JSON file; syntax and type errors carry serde's line and column.
pub fn read_json<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let bytes = io::read(path)?;
    serde_json::from_slice(&bytes).map_err(|e| Error::json(path, e))
}

/// An error naming the file when any value is NaN or infinite.
pub(crate) fn check_finite(path: &Path, what: &str, values: &[f64]) -> Result<()> {
    if values.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(Error::malformed(
            path,
            format!("non-finite value in {what}"),
        ))
    }
}

/// Checks a pose as the file stores it: finite, and a rotation within
/// [`synthgen_core::pose::rotation_tolerance`] (real BOP files store ~6 digits of hand-made
/// annotations).
fn check_pose(path: &Path, what: &str, r: &[f64; 9], t: &[f64; 3]) -> Result<Pose> {
    check_finite(path, what, r)?;
    check_finite(path, what, t)?;
    let pose = Pose::from_bop(r, t);
    pose.validate(synthgen_core::pose::rotation_tolerance())
        .map_err(|e| Error::malformed(path, format!("{what}: {e}")))?;
    Ok(pose)
}

/// Reads `camera.json`.
pub fn read_camera_info(path: &Path) -> Result<CameraInfo> {
    let c: CameraInfo = read_json(path)?;
    check_finite(path, "camera", &[c.cx, c.cy, c.fx, c.fy, c.depth_scale])?;
    if c.fx <= 0.0 || c.fy <= 0.0 || c.width == 0 || c.height == 0 || c.depth_scale <= 0.0 {
        return Err(Error::malformed(
            path,
            "focal lengths, image size and depth_scale must be positive",
        ));
    }
    Ok(c)
}

/// Reads `models_info.json` (object id → model info).
pub fn read_models_info(path: &Path) -> Result<BTreeMap<u32, ModelInfo>> {
    let m: BTreeMap<u32, ModelInfo> = read_json(path)?;
    for (id, info) in &m {
        let what = format!("object {id}");
        check_finite(
            path,
            &what,
            &[
                info.diameter,
                info.min_x,
                info.min_y,
                info.min_z,
                info.size_x,
                info.size_y,
                info.size_z,
            ],
        )?;
        if info.diameter <= 0.0 {
            return Err(Error::malformed(
                path,
                format!("{what}: diameter must be positive"),
            ));
        }
        for (k, s) in info.symmetries.symmetries_discrete.iter().enumerate() {
            check_finite(path, &what, s)?;
            let r = [s[0], s[1], s[2], s[4], s[5], s[6], s[8], s[9], s[10]];
            let sym = format!("{what}, symmetries_discrete[{k}]");
            check_pose(path, &sym, &r, &[s[3], s[7], s[11]])?;
        }
        for s in &info.symmetries.symmetries_continuous {
            check_finite(path, &what, &s.axis)?;
            check_finite(path, &what, &s.offset)?;
        }
    }
    Ok(m)
}

/// Reads `scene_camera.json` (image id → camera).
pub fn read_scene_camera(path: &Path) -> Result<BTreeMap<u32, SceneCamera>> {
    let m: BTreeMap<u32, SceneCamera> = read_json(path)?;
    for (im, c) in &m {
        let what = format!("image {im}");
        check_finite(path, &what, &c.cam_k)?;
        check_finite(path, &what, &[c.depth_scale])?;
        match (&c.cam_r_w2c, &c.cam_t_w2c) {
            (Some(r), Some(t)) => {
                check_pose(path, &format!("cam_R_w2c of image {im}"), r, t)?;
            }
            (None, None) => {}
            _ => {
                return Err(Error::malformed(
                    path,
                    format!("image {im} has only one of cam_R_w2c and cam_t_w2c"),
                ))
            }
        }
    }
    Ok(m)
}

/// Reads `scene_gt.json` (image id → objects; list index = gt id).
pub fn read_scene_gt(path: &Path) -> Result<BTreeMap<u32, Vec<GtEntry>>> {
    let m: BTreeMap<u32, Vec<GtEntry>> = read_json(path)?;
    for (im, gts) in &m {
        for (gt_id, g) in gts.iter().enumerate() {
            let what = format!("cam_R_m2c of image {im}, gt {gt_id}");
            check_pose(path, &what, &g.cam_r_m2c, &g.cam_t_m2c)?;
        }
    }
    Ok(m)
}

/// Reads `scene_gt_info.json` (image id → per-object info, in `scene_gt` order).
pub fn read_scene_gt_info(path: &Path) -> Result<BTreeMap<u32, Vec<GtInfo>>> {
    let m: BTreeMap<u32, Vec<GtInfo>> = read_json(path)?;
    for (im, infos) in &m {
        for (gt_id, i) in infos.iter().enumerate() {
            if !(0.0..=1.0).contains(&i.visib_fract) {
                return Err(Error::malformed(
                    path,
                    format!("visib_fract of image {im}, gt {gt_id} outside 0..1"),
                ));
            }
        }
    }
    Ok(m)
}

fn list_dir(dir: &Path) -> Result<Vec<(String, PathBuf, bool)>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io("read", dir, e))?;
    let mut out = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| Error::io("list directory", dir, e))?;
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with('.') {
            continue;
        }
        // Follows links: scene folders may be symlinks to where the frames live.
        let is_dir = std::fs::metadata(entry.path()).is_ok_and(|m| m.is_dir());
        out.push((name, entry.path(), is_dir));
    }
    out.sort();
    Ok(out)
}

fn parse_id(name: &str) -> Option<u32> {
    if name.is_empty() || !name.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    name.parse().ok()
}

/// Image files of a folder by id (`000012.png` → 12), for the given extensions.
fn images_by_id(dir: &Path, extensions: &[&str]) -> Result<BTreeMap<u32, PathBuf>> {
    let mut out = BTreeMap::new();
    if !dir.is_dir() {
        return Ok(out);
    }
    for (name, path, is_dir) in list_dir(dir)? {
        let Some((stem, ext)) = name.rsplit_once('.') else {
            continue;
        };
        if is_dir || !extensions.iter().any(|e| ext.eq_ignore_ascii_case(e)) {
            continue;
        }
        if let Some(id) = parse_id(stem) {
            out.insert(id, path);
        }
    }
    Ok(out)
}

/// A BOP dataset on disk.
#[derive(Debug, Clone)]
pub struct BopDataset {
    pub root: PathBuf,
    pub camera: CameraInfo,
    /// `models/models_info.json`; `None` when the dataset has no models folder.
    pub models_info: Option<BTreeMap<u32, ModelInfo>>,
    /// Folders that hold scene folders (`train_pbr`, `test`, ...), sorted.
    pub splits: Vec<String>,
}

impl BopDataset {
    /// Reads `camera.json` and `models/models_info.json` and lists the splits.
    pub fn open(root: &Path) -> Result<BopDataset> {
        if !root.is_dir() {
            return Err(Error::NoSuchDataset {
                path: root.to_path_buf(),
            });
        }
        let camera = read_camera_info(&root.join("camera.json"))?;
        let info_path = root.join("models").join("models_info.json");
        let models_info = if info_path.exists() {
            Some(read_models_info(&info_path)?)
        } else {
            None
        };
        let mut splits = Vec::new();
        for (name, path, is_dir) in list_dir(root)? {
            if !is_dir || name.starts_with("models") {
                continue;
            }
            let has_scene = list_dir(&path)?
                .iter()
                .any(|(n, _, d)| *d && parse_id(n).is_some());
            if has_scene {
                splits.push(name);
            }
        }
        Ok(BopDataset {
            root: root.to_path_buf(),
            camera,
            models_info,
            splits,
        })
    }

    /// `models/obj_{id:06d}.ply`.
    pub fn model_ply_path(&self, obj_id: u32) -> PathBuf {
        self.root
            .join("models")
            .join(format!("obj_{obj_id:06}.ply"))
    }

    /// Scene ids of a split, sorted.
    pub fn scene_ids(&self, split: &str) -> Result<Vec<u32>> {
        crate::io::check_plain_name(split, "split", &self.root)?;
        let dir = self.root.join(split);
        Ok(list_dir(&dir)?
            .into_iter()
            .filter(|(_, _, d)| *d)
            .filter_map(|(n, _, _)| parse_id(&n))
            .collect())
    }

    /// Reads a scene folder's JSON files and checks that every image has its files.
    pub fn read_scene(&self, split: &str, scene_id: u32) -> Result<BopScene> {
        self.read_scene_with(split, scene_id, true)
    }

    /// [`read_scene`](Self::read_scene); with `need_rgb` false an image without its colour
    /// file is no error (readers of the annotations alone: the metrics read no colour).
    pub fn read_scene_with(&self, split: &str, scene_id: u32, need_rgb: bool) -> Result<BopScene> {
        self.read_scene_opts(split, scene_id, need_rgb, true)
    }

    /// [`read_scene_with`](Self::read_scene_with); with `need_gt` false the GT files
    /// (`scene_gt.json`, `scene_gt_info.json`) are not read at all, present or not: the scene
    /// has no GT instances (readers of the images alone, as `synthgen predict`).
    pub fn read_scene_opts(
        &self,
        split: &str,
        scene_id: u32,
        need_rgb: bool,
        need_gt: bool,
    ) -> Result<BopScene> {
        crate::io::check_plain_name(split, "split", &self.root)?;
        let dir = self.root.join(split).join(format!("{scene_id:06}"));
        let camera_path = dir.join("scene_camera.json");
        let gt_path = dir.join("scene_gt.json");
        let camera = read_scene_camera(&camera_path)?;
        let gt = if need_gt {
            read_scene_gt(&gt_path)?
        } else {
            BTreeMap::new()
        };
        let info_path = dir.join("scene_gt_info.json");
        let gt_info = if need_gt && info_path.exists() {
            Some(read_scene_gt_info(&info_path)?)
        } else {
            None
        };
        if let Some(im) = gt.keys().find(|im| !camera.contains_key(im)) {
            return Err(Error::malformed(
                &gt_path,
                format!("image {im} is not in scene_camera.json"),
            ));
        }
        if let Some(info) = &gt_info {
            for (im, gts) in &gt {
                let n = info.get(im).map_or(0, Vec::len);
                if n != gts.len() {
                    return Err(Error::malformed(
                        &info_path,
                        format!(
                            "image {im} has {n} entries but scene_gt.json has {}",
                            gts.len()
                        ),
                    ));
                }
            }
        }
        let mut rgb = images_by_id(&dir.join("rgb"), &["png", "jpg", "jpeg"])?;
        if rgb.is_empty() {
            // itodd keeps its grayscale images in gray/.
            rgb = images_by_id(&dir.join("gray"), &["png", "tif", "tiff"])?;
        }
        let depth_dir = dir.join("depth");
        let depth = images_by_id(&depth_dir, &["png"])?;
        for im in camera.keys() {
            if need_rgb && !rgb.contains_key(im) {
                return Err(Error::MissingFile {
                    path: dir.join("rgb").join(format!("{im:06}.png")),
                });
            }
            if depth_dir.is_dir() && !depth.contains_key(im) {
                return Err(Error::MissingFile {
                    path: depth_dir.join(format!("{im:06}.png")),
                });
            }
        }
        Ok(BopScene {
            split: split.to_string(),
            scene_id,
            dir,
            camera,
            gt,
            gt_info,
            rgb,
        })
    }
}

/// One scene folder of a split.
#[derive(Debug, Clone)]
pub struct BopScene {
    pub split: String,
    pub scene_id: u32,
    pub dir: PathBuf,
    pub camera: BTreeMap<u32, SceneCamera>,
    pub gt: BTreeMap<u32, Vec<GtEntry>>,
    /// `scene_gt_info.json`, when present.
    pub gt_info: Option<BTreeMap<u32, Vec<GtInfo>>>,
    rgb: BTreeMap<u32, PathBuf>,
}

impl BopScene {
    /// Image ids, sorted.
    pub fn im_ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.camera.keys().copied()
    }

    /// The image's `rgb/` file (`.png` or `.jpg`).
    pub fn rgb_path(&self, im_id: u32) -> Option<&Path> {
        self.rgb.get(&im_id).map(PathBuf::as_path)
    }

    pub fn depth_path(&self, im_id: u32) -> PathBuf {
        self.dir.join("depth").join(format!("{im_id:06}.png"))
    }

    pub fn mask_path(&self, im_id: u32, gt_id: usize) -> PathBuf {
        self.dir
            .join("mask")
            .join(format!("{im_id:06}_{gt_id:06}.png"))
    }

    pub fn mask_visib_path(&self, im_id: u32, gt_id: usize) -> PathBuf {
        self.dir
            .join("mask_visib")
            .join(format!("{im_id:06}_{gt_id:06}.png"))
    }

    /// The image's depth in metres, using its `depth_scale`.
    pub fn read_depth_m(&self, im_id: u32) -> Result<Plane<f32>> {
        let scale = self.camera.get(&im_id).map_or(1.0, |c| c.depth_scale);
        image::read_depth_m(&self.depth_path(im_id), scale)
    }
}
