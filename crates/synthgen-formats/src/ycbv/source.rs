//! A YCB-Video dataset as a [`FrameSource`]: scene = video number, image = frame number,
//! obj_id = class index; visible masks are the `-label.png` pixels of each instance's class;
//! models are `models/<class>/textured_simple.obj` in metres.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use synthgen_assets::Units;

use super::{YcbvDataset, YcbvFrameFiles, MODEL_FILE};
use crate::bop::{CameraInfo, ModelInfo};
use crate::error::{Error, Result};
use crate::source::{FrameLocation, FrameSource, MaskRef, SourceFrame};

/// An opened YCB-Video dataset: classes and frames listed, the first frame's camera read.
#[derive(Debug)]
pub struct YcbvSource {
    pub dataset: YcbvDataset,
    camera: CameraInfo,
    /// Computed from the meshes on first use (loading every model costs about a second).
    models_info: OnceLock<Option<BTreeMap<u32, ModelInfo>>>,
}

impl YcbvSource {
    /// Lists the frames and reads the first frame's `-meta.mat` and image size.
    pub fn open(root: &Path) -> Result<YcbvSource> {
        let dataset = YcbvDataset::open(root)?;
        let first = &dataset.frames[0];
        let meta = dataset.read_meta(first)?;
        let color = first.color_path();
        let (w, h) = image::image_dimensions(&color).map_err(|e| match e {
            image::ImageError::IoError(io) => Error::io("read", &color, io),
            e => Error::malformed(&color, format!("cannot read the image size: {e}")),
        })?;
        let k = synthgen_core::Intrinsics::from_k(&meta.intrinsic_matrix, w, h);
        Ok(YcbvSource {
            dataset,
            camera: CameraInfo::new(&k, meta.depth_scale()),
            models_info: OnceLock::new(),
        })
    }

    /// The source frame of one YCB-Video frame (reads its `-meta.mat`).
    pub fn frame(&self, f: &YcbvFrameFiles) -> Result<SourceFrame> {
        let meta = self.dataset.read_meta(f)?;
        let gt = meta.gt();
        // Two instances of one class share the label's pixels: no visible mask is known for
        // either (`convert --to bop` splits them along the render at the GT poses).
        let shared: Vec<u32> = meta.shared_classes().into_iter().map(|c| c.0).collect();
        let label = f.label_path();
        let has_label = label.is_file();
        let depth = f.depth_path();
        Ok(SourceFrame {
            location: FrameLocation {
                split: f.split.clone(),
                scene_id: f.scene_id,
                im_id: f.im_id,
            },
            camera: meta.scene_camera(),
            masks: vec![None; gt.len()],
            masks_visib: gt
                .iter()
                .map(|g| {
                    let value = u16::try_from(g.obj_id).ok()?;
                    (has_label && !shared.contains(&g.obj_id)).then(|| MaskRef::Label {
                        path: label.clone(),
                        value,
                    })
                })
                .collect(),
            gt,
            gt_info: None,
            rgb: f.color_path(),
            depth: depth.is_file().then_some(depth),
        })
    }
}

impl FrameSource for YcbvSource {
    fn root(&self) -> &Path {
        &self.dataset.root
    }

    fn camera(&self) -> CameraInfo {
        self.camera
    }

    fn splits(&self) -> Vec<String> {
        let mut s: Vec<String> = self
            .dataset
            .frames
            .iter()
            .map(|f| f.split.clone())
            .collect();
        s.sort();
        s.dedup();
        s
    }

    /// Diameters and boxes of the classes whose model loads (millimetres, as BOP's).
    fn models_info(&self) -> Option<&BTreeMap<u32, ModelInfo>> {
        self.models_info
            .get_or_init(|| {
                let mut out = BTreeMap::new();
                for id in 1..=self.dataset.classes.len() as u32 {
                    let path = self.model_file(id);
                    if !path.is_file() {
                        continue;
                    }
                    let loaded =
                        synthgen_assets::load_model(&path, Units::M, &synthgen_core::NoProgress);
                    if let Ok(l) = loaded {
                        out.insert(id, ModelInfo::from_model(&l.model));
                    }
                }
                (!out.is_empty()).then_some(out)
            })
            .as_ref()
    }

    fn models_info_path(&self) -> PathBuf {
        self.dataset.root.join("models")
    }

    fn model_file(&self, obj_id: u32) -> PathBuf {
        self.dataset.model_path(obj_id).unwrap_or_else(|| {
            self.dataset
                .root
                .join("models")
                .join(format!("obj_{obj_id:06}"))
                .join(MODEL_FILE)
        })
    }

    fn model_units(&self) -> Units {
        Units::M
    }

    fn frames(&self, splits: &[String]) -> Result<Vec<SourceFrame>> {
        let mut out = Vec::new();
        for f in &self.dataset.frames {
            if !splits.is_empty() && !splits.contains(&f.split) {
                continue;
            }
            out.push(self.frame(f)?);
        }
        out.sort_by(|a, b| a.location.cmp(&b.location));
        Ok(out)
    }
}
