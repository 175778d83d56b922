//! Frames of a dataset on disk, independent of its layout: what `mix`, `stats` and `preview`
//! read, and what `train` and `eval` learn from. BOP is implemented here, Linemod in
//! [`crate::linemod::source`], YCB-Video in [`crate::ycbv::source`];
//! [`crate::layout::open_source`] tells them apart.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use synthgen_assets::Units;
use synthgen_core::{GtInfo, Model, Progress};

use crate::bop::image::{read_label, read_mask, Plane};
use crate::bop::{BopDataset, CameraInfo, GtEntry, ModelInfo, SceneCamera};
use crate::error::{Error, Result};

/// One instance's mask in a dataset's files.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum MaskRef {
    /// A PNG whose non-zero pixels are the mask (BOP's `mask/`, `mask_visib/`; Linemod's
    /// `mask/`).
    File(PathBuf),
    /// The pixels of a label image equal to `value` (YCB-Video's `-label.png`).
    Label { path: PathBuf, value: u16 },
}

impl MaskRef {
    /// The file the mask is read from.
    pub fn path(&self) -> &Path {
        match self {
            MaskRef::File(p) | MaskRef::Label { path: p, .. } => p,
        }
    }

    /// The mask: 0 outside; inside, the file's value (BOP: 255) or 255 for a label.
    pub fn read(&self) -> Result<Plane<u8>> {
        match self {
            MaskRef::File(p) => read_mask(p),
            MaskRef::Label { path, value } => {
                let l = read_label(path)?;
                Ok(Plane {
                    width: l.width,
                    height: l.height,
                    data: l
                        .data
                        .iter()
                        .map(|&v| if v == *value { 255 } else { 0 })
                        .collect(),
                })
            }
        }
    }

    /// [`MaskRef::read`], with a mask of another size than the camera's `w` x `h` an error
    /// naming its file.
    pub fn read_sized(&self, w: u32, h: u32) -> Result<Plane<u8>> {
        let plane = self.read()?;
        if (plane.width, plane.height) != (w, h) {
            return Err(Error::malformed(
                self.path(),
                format!(
                    "mask is {}x{} but the camera is {w}x{h}",
                    plane.width, plane.height
                ),
            ));
        }
        Ok(plane)
    }
}

/// Where a frame lives in its dataset.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub struct FrameLocation {
    pub split: String,
    pub scene_id: u32,
    pub im_id: u32,
}

/// One annotated image: its annotations and the paths of its files.
#[derive(Debug, Clone, PartialEq)]
pub struct SourceFrame {
    pub location: FrameLocation,
    pub camera: SceneCamera,
    /// List index = gt id.
    pub gt: Vec<GtEntry>,
    /// `scene_gt_info` entries, when the dataset has them.
    pub gt_info: Option<Vec<GtInfo>>,
    pub rgb: PathBuf,
    /// Depth PNG, when present.
    pub depth: Option<PathBuf>,
    /// Per gt id: the full and the visible mask, each when the dataset has it.
    pub masks: Vec<Option<MaskRef>>,
    pub masks_visib: Vec<Option<MaskRef>>,
}

impl SourceFrame {
    /// The visible box (`[x, y, w, h]`, BOP's: last pixel `x + w`) of instance `gt_id`:
    /// `scene_gt_info`'s `bbox_visib`, else (no info, or an empty box there) the bounding box
    /// of its visible mask; None when neither shows a pixel.
    pub fn visible_bbox(&self, gt_id: usize) -> Result<Option<[i32; 4]>> {
        let info = self.gt_info.as_ref().and_then(|i| i.get(gt_id));
        let b = match info
            .map(|i| i.bbox_visib)
            .filter(|b| b[2] >= 0 && b[3] >= 0)
        {
            Some(b) => b,
            None => match self.masks_visib.get(gt_id).and_then(Option::as_ref) {
                Some(mask) => {
                    let m = mask.read()?;
                    synthgen_core::annotate::mask_bbox(&m.data, m.width)
                }
                None => return Ok(None),
            },
        };
        Ok((b[2] >= 0 && b[3] >= 0).then_some(b))
    }

    /// Sorted, distinct object ids in the frame.
    pub fn object_set(&self) -> Vec<u32> {
        let mut ids: Vec<u32> = self.gt.iter().map(|g| g.obj_id).collect();
        ids.sort_unstable();
        ids.dedup();
        ids
    }
}

/// A dataset as a list of frames plus its camera and models.
pub trait FrameSource: Send + Sync {
    fn root(&self) -> &Path;
    /// `camera.json`-level camera (image size, default intrinsics).
    fn camera(&self) -> CameraInfo;
    /// The split names (BOP: the split folders with scenes; Linemod: `train`, `test`).
    fn splits(&self) -> Vec<String>;
    /// Model info by object id, when the dataset has it.
    fn models_info(&self) -> Option<&BTreeMap<u32, ModelInfo>>;
    /// Where `models_info` is read from (present or not).
    fn models_info_path(&self) -> PathBuf;
    /// Where the model file of an object belongs (present or not).
    fn model_file(&self, obj_id: u32) -> PathBuf;
    /// Units of the model files: millimetres (BOP, Linemod) unless the layout says otherwise.
    fn model_units(&self) -> Units {
        Units::Mm
    }
    /// Loads an object's model (metres) from its model file; the loader's warnings (a
    /// missing texture) go to `progress`.
    fn load_model(&self, obj_id: u32, progress: &dyn Progress) -> Result<Model> {
        let path = self.model_file(obj_id);
        synthgen_assets::load_model(&path, self.model_units(), progress)
            .map(|l| l.model)
            .map_err(|e| Error::model(&path, e))
    }
    /// The model file of an object, when present.
    fn model_path(&self, obj_id: u32) -> Option<PathBuf> {
        let p = self.model_file(obj_id);
        p.is_file().then_some(p)
    }
    /// Every frame, sorted by location. `splits` limits the splits read (all when empty).
    fn frames(&self, splits: &[String]) -> Result<Vec<SourceFrame>>;

    /// The frames for readers of the annotations only (the metrics: GT, cameras, depth, models;
    /// no colour). A BOP image without its `rgb/` file is kept, `rgb` the path it would have;
    /// layouts that need a colour image to know a frame (YCB-Video, Linemod) give [`frames`].
    ///
    /// [`frames`]: FrameSource::frames
    fn annotation_frames(&self, splits: &[String]) -> Result<Vec<SourceFrame>> {
        self.frames(splits)
    }

    /// The frames for readers of the images alone (`synthgen predict`): colour, depth and
    /// camera, and no GT where the layout keeps it apart (BOP: `scene_gt*.json` are not read,
    /// so a test split shipped without them, as BOP's challenge test sets are, is read;
    /// YCB-Video's `-meta.mat` holds the intrinsics with the poses and is read whole, its
    /// GT then ignored by the caller).
    fn image_frames(&self, splits: &[String]) -> Result<Vec<SourceFrame>> {
        self.frames(splits)
    }
}

impl FrameSource for BopDataset {
    fn root(&self) -> &Path {
        &self.root
    }

    fn camera(&self) -> CameraInfo {
        self.camera
    }

    fn splits(&self) -> Vec<String> {
        self.splits.clone()
    }

    fn models_info(&self) -> Option<&BTreeMap<u32, ModelInfo>> {
        self.models_info.as_ref()
    }

    fn models_info_path(&self) -> PathBuf {
        self.root.join("models").join("models_info.json")
    }

    fn model_file(&self, obj_id: u32) -> PathBuf {
        self.model_ply_path(obj_id)
    }

    fn frames(&self, splits: &[String]) -> Result<Vec<SourceFrame>> {
        self.bop_frames(splits, true, true)
    }

    fn annotation_frames(&self, splits: &[String]) -> Result<Vec<SourceFrame>> {
        self.bop_frames(splits, false, true)
    }

    fn image_frames(&self, splits: &[String]) -> Result<Vec<SourceFrame>> {
        self.bop_frames(splits, true, false)
    }
}

impl BopDataset {
    fn bop_frames(
        &self,
        splits: &[String],
        need_rgb: bool,
        need_gt: bool,
    ) -> Result<Vec<SourceFrame>> {
        let mut out = Vec::new();
        for split in &self.splits {
            if !splits.is_empty() && !splits.contains(split) {
                continue;
            }
            for scene_id in self.scene_ids(split)? {
                let scene = self.read_scene_opts(split, scene_id, need_rgb, need_gt)?;
                for im_id in scene.im_ids() {
                    let Some(camera) = scene.camera.get(&im_id) else {
                        continue;
                    };
                    let rgb = match scene.rgb_path(im_id) {
                        Some(p) => p.to_path_buf(),
                        None if !need_rgb => scene.dir.join("rgb").join(format!("{im_id:06}.png")),
                        None => continue,
                    };
                    let gt = scene.gt.get(&im_id).cloned().unwrap_or_default();
                    let gt_info = scene.gt_info.as_ref().and_then(|m| m.get(&im_id).cloned());
                    let depth = Some(scene.depth_path(im_id)).filter(|p| p.is_file());
                    let existing = |p: PathBuf| p.is_file().then_some(MaskRef::File(p));
                    let masks = (0..gt.len())
                        .map(|g| existing(scene.mask_path(im_id, g)))
                        .collect();
                    let masks_visib = (0..gt.len())
                        .map(|g| existing(scene.mask_visib_path(im_id, g)))
                        .collect();
                    out.push(SourceFrame {
                        location: FrameLocation {
                            split: split.clone(),
                            scene_id,
                            im_id,
                        },
                        camera: *camera,
                        gt,
                        gt_info,
                        rgb,
                        depth,
                        masks,
                        masks_visib,
                    });
                }
            }
        }
        Ok(out)
    }
}

/// Writes an object's model into a BOP `models/` folder as `obj_NNNNNN.ply` (millimetres):
/// hard-linked or copied when the source's file already is one, else loaded and written
/// (a YCB-Video OBJ in metres). Returns whether the file was converted.
pub fn write_bop_model(source: &dyn FrameSource, obj_id: u32, dst: &Path) -> Result<bool> {
    let src = source.model_file(obj_id);
    let is_ply = src
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    if is_ply && source.model_units() == Units::Mm {
        if std::fs::hard_link(&src, dst).is_err() {
            let bytes = crate::io::read(&src)?;
            crate::io::atomic_write(dst, &bytes)?;
        }
        return Ok(false);
    }
    let model = source.load_model(obj_id, &synthgen_core::NoProgress)?;
    synthgen_assets::write_ply(dst, &model, 1000.0).map_err(|e| Error::model(dst, e))?;
    Ok(true)
}
