//! Conversion between the BOP, Linemod and YCB-Video layouts, lossless for what both sides
//! can express (poses, K, RGB, depth, visible masks); docs/formats.md lists what maps to what
//! and what is lost. YCB-Video in [`ycbv`].

pub mod ycbv;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use synthgen_core::annotate::mask_bbox;
use synthgen_core::Progress;

use crate::bop::chunk::write_map;
use crate::bop::image::{encode_gray16_png, encode_gray8_png, read_depth_raw, read_mask, read_rgb};
use crate::bop::writer::write_camera_info;
use crate::bop::{BopDataset, CameraInfo, GtEntry, PngCompression, SceneCamera};
use crate::error::{Error, Result};
use crate::io::{self, atomic_write, create_dir_all};
use crate::linemod::images::{image_gts, plan_images, validate_gt_rotations};
use crate::linemod::{
    LinemodDataset, LinemodFrame, LinemodGt, LinemodObject, LinemodWriter, LinemodWriterOptions,
    ListFile, DEFAULT_MIN_VISIB_FRACT,
};

/// Options of [`bop_to_linemod`] and [`linemod_to_bop`].
#[derive(Debug, Clone, PartialEq)]
pub struct ConvertOptions {
    /// Depth unit of the output in mm per PNG value. `None`: 1.0 for Linemod (what DenseFusion
    /// assumes), the source's for BOP. Equal scales copy depth values unchanged.
    pub depth_scale: Option<f64>,
    /// BOP → Linemod: see [`DEFAULT_MIN_VISIB_FRACT`].
    pub min_visib_fract: f64,
}

impl Default for ConvertOptions {
    fn default() -> Self {
        ConvertOptions {
            depth_scale: None,
            min_visib_fract: DEFAULT_MIN_VISIB_FRACT,
        }
    }
}

/// What a conversion did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ConvertSummary {
    pub frames: u64,
    pub instances: u64,
    /// Linemod → BOP: instances with no Linemod mask (written as empty `mask_visib`).
    /// BOP → Linemod: instances not visible enough for a folder of their own (their pose is
    /// still in the other folders' `gt.yml`).
    pub instances_without_mask: u64,
    /// Depth values that did not fit 16 bits after rescaling (written as 0).
    pub depth_out_of_range_px: u64,
    pub models: usize,
}

/// Depth PNG values from one `depth_scale` to another (round half to even, as bop_toolkit);
/// 0 stays 0; values over 16 bits become 0 and are counted.
pub fn rescale_depth(values: &[u16], from: f64, to: f64) -> (Vec<u16>, u64) {
    if from == to {
        return (values.to_vec(), 0);
    }
    let k = from / to;
    let mut overflow = 0;
    let out = values
        .iter()
        .map(|&v| {
            if v == 0 {
                return 0;
            }
            let x = (v as f64 * k).round_ties_even();
            if x <= 65535.0 {
                x as u16
            } else {
                overflow += 1;
                0
            }
        })
        .collect();
    (out, overflow)
}

fn copy_file(from: &Path, to: &Path) -> Result<()> {
    let bytes = io::read(from)?;
    atomic_write(to, &bytes)
}

/// Converts a BOP dataset into the Linemod layout at `dst`. Frames are numbered in the order
/// (split, scene, image); splits whose name starts with `test` go to `test.txt`.
pub fn bop_to_linemod(
    src: &Path,
    dst: &Path,
    opts: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<ConvertSummary> {
    let ds = BopDataset::open(src)?;
    let depth_scale = opts.depth_scale.unwrap_or(1.0);
    let writer = LinemodWriter::create(
        dst,
        LinemodWriterOptions {
            depth_scale,
            min_visib_fract: opts.min_visib_fract,
            png_compression: PngCompression::default(),
        },
    )?;
    let mut summary = ConvertSummary::default();
    if let Some(info) = &ds.models_info {
        writer.write_models_info(info)?;
        for &id in info.keys() {
            let ply = ds.model_ply_path(id);
            if ply.exists() {
                copy_file(&ply, &writer.model_ply_path(id))?;
                summary.models += 1;
            }
        }
    }
    let mut scenes = Vec::new();
    for split in &ds.splits {
        for scene_id in ds.scene_ids(split)? {
            scenes.push(ds.read_scene(split, scene_id)?);
        }
    }
    let total: usize = scenes.iter().map(|s| s.camera.len()).sum();
    progress.start("converting", total as u64);
    let mut frame_id = 0u64;
    for scene in &scenes {
        let list = if scene.split.starts_with("test") {
            ListFile::Test
        } else {
            ListFile::Train
        };
        for (&im, cam) in &scene.camera {
            let rgb_path = scene
                .rgb_path(im)
                .map(Path::to_path_buf)
                .unwrap_or_else(|| scene.dir.join("rgb").join(format!("{im:06}.png")));
            let rgb = read_rgb(&rgb_path)?;
            let (w, h) = (rgb.width, rgb.height);
            // Linemod frames need depth (DenseFusion reads it): a missing image is an error,
            // never a frame of zeros.
            let depth_path = scene.depth_path(im);
            let raw = read_depth_raw(&depth_path)?;
            if (raw.width, raw.height) != (w, h) {
                return Err(Error::malformed(&depth_path, "depth and rgb sizes differ"));
            }
            let (depth, overflow) = rescale_depth(&raw.data, cam.depth_scale, depth_scale);
            summary.depth_out_of_range_px += overflow;
            let gts = scene.gt.get(&im).map(Vec::as_slice).unwrap_or(&[]);
            let infos = scene.gt_info.as_ref().and_then(|i| i.get(&im));
            let mut objects = Vec::with_capacity(gts.len());
            for (gt_id, g) in gts.iter().enumerate() {
                // Linemod's masks are BOP's visible masks: without them every object would
                // look invisible and the frame would vanish.
                let mpath = scene.mask_visib_path(im, gt_id);
                if !mpath.is_file() {
                    return Err(Error::malformed(
                        &scene.dir.join("scene_gt.json"),
                        format!(
                            "image {im}, gt {gt_id} has no visible mask {}; `synthgen annotate` computes masks from the poses and models",
                            mpath.display()
                        ),
                    ));
                }
                let m = read_mask(&mpath)?;
                if (m.width, m.height) != (w, h) {
                    return Err(Error::malformed(&mpath, "mask and rgb sizes differ"));
                }
                let mask = Some(
                    m.data
                        .iter()
                        .map(|&v| if v > 0 { 255 } else { 0 })
                        .collect::<Vec<u8>>(),
                );
                let info = infos.and_then(|i| i.get(gt_id));
                let visib_fract = match (info, &mask) {
                    (Some(i), _) => i.visib_fract,
                    // Without scene_gt_info.json, a non-empty visible mask counts as visible.
                    (None, Some(m)) if m.iter().any(|&v| v > 0) => 1.0,
                    _ => 0.0,
                };
                let obj_bb = match (info, &mask) {
                    (Some(i), _) => i.bbox_obj,
                    (None, Some(m)) => mask_bbox(m, w),
                    (None, None) => [-1; 4],
                };
                objects.push(LinemodObject {
                    gt: LinemodGt {
                        cam_r_m2c: g.cam_r_m2c,
                        cam_t_m2c: g.cam_t_m2c,
                        obj_bb,
                        obj_id: g.obj_id,
                    },
                    visib_fract,
                    mask_visib: mask,
                });
            }
            let frame = LinemodFrame {
                frame_id,
                width: w,
                height: h,
                cam_k: cam.cam_k,
                rgb: rgb.rgb,
                depth,
                objects,
            };
            let record = writer.write_frame(&frame, list)?;
            summary.instances += frame.objects.len() as u64;
            summary.instances_without_mask += (frame.objects.len() - record.folders.len()) as u64;
            writer.add_record(record);
            summary.frames += 1;
            frame_id += 1;
            progress.advance(1);
        }
    }
    writer.finish()?;
    progress.finish();
    Ok(summary)
}

pub use crate::linemod::images::folders_share_frames;

/// Converts a Linemod dataset into BOP at `dst`: split `train` (frames of `train.txt` or no
/// list) and `test` (`test.txt`). Folders that share frame ids (synthgen's) become one scene
/// per 1000 frames (`scene = id / 1000`, `im = id % 1000`), with each frame's objects sorted
/// by id; separate sequences (real Linemod) become one scene per object folder (`scene` =
/// object id, `im` = frame id). Writes `mask_visib/` from `mask/`; `mask/` and
/// `scene_gt_info.json` need the models rendered and are not written.
pub fn linemod_to_bop(
    src: &Path,
    dst: &Path,
    opts: &ConvertOptions,
    progress: &dyn Progress,
) -> Result<ConvertSummary> {
    let lm = LinemodDataset::open(src)?;
    let mut folders = Vec::with_capacity(lm.objects.len());
    for &id in &lm.objects {
        folders.push(lm.read_folder(id)?);
    }
    let mut summary = ConvertSummary::default();
    let models_dir = dst.join("models");
    create_dir_all(&models_dir)?;
    if let Some(info) = &lm.models_info {
        let path = models_dir.join("models_info.json");
        write_map(&path, info, false)?;
        for &id in info.keys() {
            let ply = lm.model_ply_path(id);
            if ply.exists() {
                copy_file(&ply, &models_dir.join(format!("obj_{id:06}.ply")))?;
                summary.models += 1;
            }
        }
    }
    validate_gt_rotations(&folders)?;

    let (shared, targets) = plan_images(&folders)?;

    progress.start("converting", targets.len() as u64);
    type SceneFiles = (BTreeMap<u32, SceneCamera>, BTreeMap<u32, Vec<GtEntry>>);
    let mut scenes: BTreeMap<(&str, u32), SceneFiles> = BTreeMap::new();
    let mut camera_json: Option<CameraInfo> = None;
    for t in &targets {
        let first = &folders[t.folders[0]];
        let frame = t.frame_id;
        let info = first.info.get(&frame).copied().ok_or_else(|| {
            Error::malformed(
                &first.dir.join("info.yml"),
                format!("frame {frame} is missing"),
            )
        })?;
        let scene_dir = dst.join(t.split).join(format!("{:06}", t.scene_id));
        for sub in ["rgb", "depth", "mask_visib"] {
            create_dir_all(&scene_dir.join(sub))?;
        }
        let name = format!("{:06}.png", t.im_id);
        let rgb_src = first.rgb_path(frame);
        let rgb_bytes = io::read(&rgb_src)?;
        let rgb = read_rgb(&rgb_src)?;
        let (w, h) = (rgb.width, rgb.height);
        atomic_write(&scene_dir.join("rgb").join(&name), &rgb_bytes)?;
        let depth_scale = opts.depth_scale.unwrap_or(info.depth_scale);
        let depth_src = first.depth_path(frame);
        let depth_dst = scene_dir.join("depth").join(&name);
        if depth_scale == info.depth_scale {
            copy_file(&depth_src, &depth_dst)?;
        } else {
            let raw = read_depth_raw(&depth_src)?;
            let (v, overflow) = rescale_depth(&raw.data, info.depth_scale, depth_scale);
            summary.depth_out_of_range_px += overflow;
            let png =
                encode_gray16_png(&v, raw.width, raw.height, PngCompression::Fast, &depth_dst)?;
            atomic_write(&depth_dst, &png)?;
        }
        let gts = image_gts(&folders, t, shared);
        for (gt_id, (_, owner)) in gts.iter().enumerate() {
            let mask_dst = scene_dir
                .join("mask_visib")
                .join(format!("{:06}_{gt_id:06}.png", t.im_id));
            match owner {
                Some(i) => copy_file(&folders[*i].mask_path(frame), &mask_dst)?,
                None => {
                    let empty = vec![0u8; w as usize * h as usize];
                    let png = encode_gray8_png(&empty, w, h, PngCompression::Fast, &mask_dst)?;
                    atomic_write(&mask_dst, &png)?;
                    summary.instances_without_mask += 1;
                }
            }
        }
        summary.instances += gts.len() as u64;
        if camera_json.is_none() {
            let k = synthgen_core::Intrinsics::from_k(&info.cam_k, w, h);
            camera_json = Some(CameraInfo::new(&k, depth_scale));
        }
        let entry = scenes.entry((t.split, t.scene_id)).or_default();
        entry.0.insert(
            t.im_id,
            SceneCamera {
                cam_k: info.cam_k,
                cam_r_w2c: None,
                cam_t_w2c: None,
                depth_scale,
            },
        );
        entry.1.insert(
            t.im_id,
            gts.iter()
                .map(|(g, _)| GtEntry {
                    cam_r_m2c: g.cam_r_m2c,
                    cam_t_m2c: g.cam_t_m2c,
                    obj_id: g.obj_id,
                })
                .collect(),
        );
        summary.frames += 1;
        progress.advance(1);
    }
    for ((split, scene_id), (camera, gt)) in &scenes {
        let dir: PathBuf = dst.join(split).join(format!("{scene_id:06}"));
        write_map(&dir.join("scene_gt.json"), gt, false)?;
        write_map(&dir.join("scene_camera.json"), camera, false)?;
    }
    if let Some(cam) = camera_json {
        write_camera_info(&dst.join("camera.json"), &cam)?;
    } else {
        return Err(Error::malformed(
            &src.join("data"),
            "no frames in any object folder",
        ));
    }
    progress.finish();
    Ok(summary)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn depth_rescaling_rounds_half_even_and_counts_overflow() {
        let (v, o) = rescale_depth(&[0, 5, 15, 25, 10000], 0.1, 1.0);
        assert_eq!(v, [0, 0, 2, 2, 1000]);
        assert_eq!(o, 0);
        let (v, o) = rescale_depth(&[7000, 1], 10.0, 1.0);
        assert_eq!(v, [0, 10]);
        assert_eq!(o, 1);
        let (v, _) = rescale_depth(&[1, 2, 65535], 1.0, 1.0);
        assert_eq!(v, [1, 2, 65535]);
    }

    #[test]
    fn bbox_of_mask() {
        let m = [0, 0, 0, 0, 255, 255, 0, 255, 0];
        assert_eq!(mask_bbox(&m, 3), [1, 1, 1, 1]);
        assert_eq!(mask_bbox(&[0; 4], 2), [-1; 4]);
    }

    /// Two folders that reuse frame id 0 for different images, as in the real
    /// Linemod_preprocessed: each becomes its own BOP scene.
    #[test]
    fn separate_sequences_become_one_scene_per_folder() {
        use crate::bop::image::encode_rgb_png;
        use crate::linemod::{gt_yml_text, info_yml_text, LinemodInfo};
        let d = tempfile::tempdir().unwrap();
        let src = d.path().join("lm");
        let (w, h) = (4u32, 3u32);
        let n = (w * h) as usize;
        for (obj, z) in [(1u32, 500.0), (2, 700.0)] {
            let dir = src.join("data").join(format!("{obj:02}"));
            for sub in ["rgb", "depth", "mask"] {
                std::fs::create_dir_all(dir.join(sub)).unwrap();
            }
            let p = dir.join("rgb/0000.png");
            let rgb = vec![obj as u8; n * 3];
            std::fs::write(
                &p,
                encode_rgb_png(&rgb, w, h, PngCompression::Fast, &p).unwrap(),
            )
            .unwrap();
            let p = dir.join("depth/0000.png");
            let depth = vec![z as u16; n];
            std::fs::write(
                &p,
                encode_gray16_png(&depth, w, h, PngCompression::Fast, &p).unwrap(),
            )
            .unwrap();
            let p = dir.join("mask/0000.png");
            let mask: Vec<u8> = (0..n).map(|i| if i % 2 == 0 { 255 } else { 0 }).collect();
            std::fs::write(
                &p,
                encode_gray8_png(&mask, w, h, PngCompression::Fast, &p).unwrap(),
            )
            .unwrap();
            let gt = LinemodGt {
                cam_r_m2c: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                cam_t_m2c: [0.0, 0.0, z],
                obj_bb: [0, 0, 3, 2],
                obj_id: obj,
            };
            let info = LinemodInfo {
                cam_k: [
                    572.4114, 0.0, 325.2611, 0.0, 573.57043, 242.04899, 0.0, 0.0, 1.0,
                ],
                depth_scale: 1.0,
            };
            std::fs::write(
                dir.join("gt.yml"),
                gt_yml_text(&BTreeMap::from([(0, vec![gt])])).unwrap(),
            )
            .unwrap();
            std::fs::write(
                dir.join("info.yml"),
                info_yml_text(&BTreeMap::from([(0, info)])).unwrap(),
            )
            .unwrap();
            std::fs::write(dir.join("test.txt"), "0000\n").unwrap();
        }
        let dst = d.path().join("bop");
        let s = linemod_to_bop(
            &src,
            &dst,
            &ConvertOptions::default(),
            &synthgen_core::NoProgress,
        )
        .unwrap();
        assert_eq!((s.frames, s.instances, s.instances_without_mask), (2, 2, 0));
        let ds = BopDataset::open(&dst).unwrap();
        assert_eq!(ds.splits, ["test"]);
        assert_eq!(ds.scene_ids("test").unwrap(), [1, 2]);
        let scene = ds.read_scene("test", 2).unwrap();
        assert_eq!(scene.gt[&0][0].cam_t_m2c, [0.0, 0.0, 700.0]);
        assert_eq!(
            read_depth_raw(&scene.depth_path(0)).unwrap().data,
            vec![700u16; n]
        );
        assert_eq!(ds.camera.width, 4);
    }
}
