//! A Linemod dataset as a [`FrameSource`]: the frames of its object folders in BOP terms
//! (split, scene, image, gt id), numbered exactly as `convert --to bop` numbers them (see
//! [`super::images`]), each gt entry's visible mask being its folder's `mask/` image.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::images::{image_gts, plan_images, validate_gt_rotations, LinemodImage};
use super::{LinemodDataset, LinemodFolder};
use crate::bop::{CameraInfo, GtEntry, ModelInfo, SceneCamera};
use crate::error::{Error, Result};
use crate::source::{FrameLocation, FrameSource, MaskRef, SourceFrame};

/// An opened Linemod dataset: its folders read and its images planned.
#[derive(Debug, Clone)]
pub struct LinemodSource {
    pub dataset: LinemodDataset,
    pub folders: Vec<LinemodFolder>,
    shared: bool,
    images: Vec<LinemodImage>,
    camera: CameraInfo,
}

impl LinemodSource {
    /// Reads every folder's YAML and id lists, checks the rotations, and takes the image
    /// size and default intrinsics from the first frame.
    pub fn open(root: &Path) -> Result<LinemodSource> {
        let dataset = LinemodDataset::open(root)?;
        let mut folders = Vec::with_capacity(dataset.objects.len());
        for &id in &dataset.objects {
            folders.push(dataset.read_folder(id)?);
        }
        validate_gt_rotations(&folders)?;
        let (shared, images) = plan_images(&folders)?;
        let first = images.first().ok_or_else(|| {
            Error::malformed(&root.join("data"), "no frames in any object folder")
        })?;
        let folder = &folders[first.folders[0]];
        let info = folder.info.get(&first.frame_id).copied().ok_or_else(|| {
            Error::malformed(
                &folder.dir.join("info.yml"),
                format!("frame {} is missing", first.frame_id),
            )
        })?;
        let rgb = folder.rgb_path(first.frame_id);
        let (w, h) = image::image_dimensions(&rgb)
            .map_err(|e| Error::malformed(&rgb, format!("cannot read the image size: {e}")))?;
        let k = synthgen_core::Intrinsics::from_k(&info.cam_k, w, h);
        Ok(LinemodSource {
            dataset,
            folders,
            shared,
            images,
            camera: CameraInfo::new(&k, info.depth_scale),
        })
    }
}

impl FrameSource for LinemodSource {
    fn root(&self) -> &Path {
        &self.dataset.root
    }

    fn camera(&self) -> CameraInfo {
        self.camera
    }

    /// The splits that have frames (`test`, `train`), sorted.
    fn splits(&self) -> Vec<String> {
        let mut s: Vec<String> = self.images.iter().map(|i| i.split.to_string()).collect();
        s.sort();
        s.dedup();
        s
    }

    fn models_info(&self) -> Option<&BTreeMap<u32, ModelInfo>> {
        self.dataset.models_info.as_ref()
    }

    fn models_info_path(&self) -> PathBuf {
        self.dataset.models_info_path()
    }

    fn model_file(&self, obj_id: u32) -> PathBuf {
        self.dataset.model_ply_path(obj_id)
    }

    fn frames(&self, splits: &[String]) -> Result<Vec<SourceFrame>> {
        let mut out = Vec::new();
        for image in &self.images {
            if !splits.is_empty() && !splits.iter().any(|s| s == image.split) {
                continue;
            }
            let folder = &self.folders[image.folders[0]];
            let frame = image.frame_id;
            let Some(info) = folder.info.get(&frame) else {
                continue;
            };
            let gts = image_gts(&self.folders, image, self.shared);
            let depth = folder.depth_path(frame);
            out.push(SourceFrame {
                location: FrameLocation {
                    split: image.split.to_string(),
                    scene_id: image.scene_id,
                    im_id: image.im_id,
                },
                camera: SceneCamera::without_world(info.cam_k, info.depth_scale),
                gt: gts
                    .iter()
                    .map(|(g, _)| GtEntry {
                        cam_r_m2c: g.cam_r_m2c,
                        cam_t_m2c: g.cam_t_m2c,
                        obj_id: g.obj_id,
                    })
                    .collect(),
                gt_info: None,
                rgb: folder.rgb_path(frame),
                depth: depth.is_file().then_some(depth),
                masks: vec![None; gts.len()],
                masks_visib: gts
                    .iter()
                    .map(|(_, owner)| {
                        owner
                            .map(|i| self.folders[i].mask_path(frame))
                            .filter(|p| p.is_file())
                            .map(MaskRef::File)
                    })
                    .collect(),
            });
        }
        out.sort_by(|a, b| a.location.cmp(&b.location));
        Ok(out)
    }
}
