//! YCB-Video ⇄ BOP. Poses keep their numbers (only t changes unit, metres ⇄ millimetres);
//! YCB-Video's labels become BOP's `mask_visib` and back. What only a render of the models
//! can give (BOP's `mask/` and `scene_gt_info`, YCB-Video's `vertmap` and `-box.txt`) comes
//! from a [`PoseRenderer`] at the GT poses.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use synthgen_core::glam::DVec3;
use synthgen_core::{GtInfo, Intrinsics, PoseRenderer, Progress};

use super::rescale_depth;
use crate::annotate::{annotate_frame, frame_intrinsics, render_gt, write_completed_masks};
use crate::bop::chunk::write_map;
use crate::bop::image::{encode_gray8_png, read_depth_raw, read_label, read_rgb};
use crate::bop::writer::write_camera_info;
use crate::bop::{GtEntry, ModelInfo, PngCompression, SceneCamera};
use crate::error::{Error, Result};
use crate::io::{self, atomic_write, create_dir_all};
use crate::source::{FrameSource, SourceFrame};
use crate::ycbv::{
    format_label_values, stray_label_values, YcbvFrame, YcbvObject, YcbvPose, YcbvSource,
    YcbvWriter, YcbvWriterOptions,
};

use super::ConvertSummary;

/// An object's model from a dataset's model file, in the dataset's units.
fn load_source_model(source: &dyn FrameSource, obj_id: u32) -> Result<synthgen_core::Model> {
    let path = source.model_file(obj_id);
    synthgen_assets::load_model(&path, source.model_units(), &synthgen_core::NoProgress)
        .map(|l| l.model)
        .map_err(|e| Error::model(&path, e))
}

/// Image sizes of one frame's files, checked before anything is written.
fn check_sizes(files: &[&Path], want: (u32, u32)) -> Result<()> {
    for p in files {
        if !p.is_file() {
            continue;
        }
        let got = image::image_dimensions(p).map_err(|e| match e {
            image::ImageError::IoError(io) => Error::io("read", *p, io),
            e => Error::Decode {
                message: e.to_string(),
                path: p.to_path_buf(),
            },
        })?;
        if got != want {
            return Err(Error::malformed(
                p,
                format!(
                    "image is {}x{} but the dataset's images are {}x{}",
                    got.0, got.1, want.0, want.1
                ),
            ));
        }
    }
    Ok(())
}

type SceneFiles = (
    BTreeMap<u32, SceneCamera>,
    BTreeMap<u32, Vec<GtEntry>>,
    BTreeMap<u32, Vec<GtInfo>>,
);

/// A YCB-Video frame's label image (present or not).
fn label_path(f: &SourceFrame) -> std::path::PathBuf {
    f.rgb
        .with_file_name(format!("{:06}-label.png", f.location.im_id))
}

/// Converts a YCB-Video dataset into BOP at `dst`: splits `train`/`test` from the image
/// sets, scene = video, image = frame, obj_id = class index; `rgb/` and `depth/` copied
/// (depth_scale 1000 / factor_depth), `mask_visib/` from the labels, `models/obj_NNNNNN.ply`
/// (millimetres) with `models_info.json`. With a `renderer`, also `mask/` (the rendered
/// silhouette, plus any label pixel it misses) and `scene_gt_info.json` (`bbox_obj` and
/// `px_count_all` from the render, the visible counts from the labels). Every `-meta.mat`
/// and image size is checked before anything is written.
pub fn ycbv_to_bop(
    src: &Path,
    dst: &Path,
    renderer: Option<&dyn PoseRenderer>,
    progress: &dyn Progress,
) -> Result<ConvertSummary> {
    let source = YcbvSource::open(src)?;
    for w in source.dataset.left_out.warnings() {
        progress.warn(&w);
    }
    let cam = source.camera();
    let size = (cam.width, cam.height);
    let frames = source.frames(&[])?;
    for f in &frames {
        let label = Some(label_path(f)).filter(|p| p.is_file());
        let Some(depth) = f.depth.as_deref() else {
            return Err(Error::MissingFile {
                path: f
                    .rgb
                    .with_file_name(format!("{:06}-depth.png", f.location.im_id)),
            });
        };
        let mut files = vec![f.rgb.as_path(), depth];
        files.extend(label.as_deref());
        check_sizes(&files, size)?;
    }
    let used: BTreeSet<u32> = frames.iter().flat_map(|f| f.object_set()).collect();
    let mut summary = ConvertSummary::default();

    // Models of the classes the frames use, in millimetres, and their info.
    let models_dir = dst.join("models");
    create_dir_all(&models_dir)?;
    let mut infos: BTreeMap<u32, ModelInfo> = BTreeMap::new();
    for &id in &used {
        let path = source.model_file(id);
        if !path.is_file() {
            continue;
        }
        let model = load_source_model(&source, id)?;
        let ply = models_dir.join(format!("obj_{id:06}.ply"));
        synthgen_assets::write_ply(&ply, &model, 1000.0).map_err(|e| Error::model(&ply, e))?;
        infos.insert(id, ModelInfo::from_model(&model));
        summary.models += 1;
    }
    if !infos.is_empty() {
        write_map(&models_dir.join("models_info.json"), &infos, false)?;
    }

    progress.start("converting", frames.len() as u64);
    let mut scenes: BTreeMap<(String, u32), SceneFiles> = BTreeMap::new();
    // Frames with label values that are no class of theirs, and with two instances of a class.
    let (mut stray, mut shared_frames): (Vec<String>, Vec<String>) = (Vec::new(), Vec::new());
    let mut stray_values: BTreeMap<u16, u64> = BTreeMap::new();
    for f in &frames {
        let loc = &f.location;
        let scene_dir = dst.join(&loc.split).join(format!("{:06}", loc.scene_id));
        for sub in ["rgb", "depth", "mask_visib"] {
            create_dir_all(&scene_dir.join(sub))?;
        }
        let ext = f
            .rgb
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_else(|| "png".into());
        let name = format!("{:06}", loc.im_id);
        atomic_write(
            &scene_dir.join("rgb").join(format!("{name}.{ext}")),
            &io::read(&f.rgb)?,
        )?;
        // Checked above: every frame has its depth image.
        let Some(d) = &f.depth else { continue };
        atomic_write(
            &scene_dir.join("depth").join(format!("{name}.png")),
            &io::read(d)?,
        )?;
        // The label's instances as BOP masks.
        let lp = label_path(f);
        let label = if lp.is_file() {
            Some(read_label(&lp)?)
        } else {
            None
        };
        let n = (cam.width * cam.height) as usize;
        let cls: Vec<u32> = f.gt.iter().map(|g| g.obj_id).collect();
        let shared: Vec<u32> = cls
            .iter()
            .copied()
            .filter(|c| cls.iter().filter(|&d| d == c).count() > 1)
            .collect();
        if let Some(l) = &label {
            let s = stray_label_values(&l.data, &cls);
            if !s.is_empty() {
                stray.push(format!("{}: {}", lp.display(), format_label_values(&s)));
                for (v, k) in s {
                    *stray_values.entry(v).or_default() += k;
                }
            }
        }
        // Two instances of one class share the label's pixels: each gets those where the
        // render at the GT poses shows it (without the models, none).
        let split = match (shared.is_empty(), renderer) {
            (false, Some(r)) => {
                let k = frame_intrinsics(f, cam.width, cam.height);
                Some(render_gt(r, f, &k)?.instance)
            }
            _ => None,
        };
        if !shared.is_empty() {
            shared_frames.push(format!(
                "{}/{:06} image {}",
                loc.split, loc.scene_id, loc.im_id
            ));
        }
        let visib: Vec<Vec<u8>> =
            f.gt.iter()
                .enumerate()
                .map(|(gt_id, g)| match &label {
                    Some(l) => l
                        .data
                        .iter()
                        .enumerate()
                        .map(|(i, &v)| {
                            let mine = u32::from(v) == g.obj_id
                                && (!shared.contains(&g.obj_id)
                                    || split
                                        .as_ref()
                                        .is_some_and(|s| usize::from(s[i]) == gt_id + 1));
                            if mine {
                                255
                            } else {
                                0
                            }
                        })
                        .collect(),
                    None => vec![0; n],
                })
                .collect();
        for (gt_id, m) in visib.iter().enumerate() {
            let p = scene_dir
                .join("mask_visib")
                .join(format!("{name}_{gt_id:06}.png"));
            let png = encode_gray8_png(m, cam.width, cam.height, PngCompression::Fast, &p)?;
            atomic_write(&p, &png)?;
        }
        let info = match renderer {
            Some(r) => Some(write_completed_masks(
                r, f, &visib, &scene_dir, loc.im_id, size,
            )?),
            None => None,
        };
        summary.instances += f.gt.len() as u64;
        summary.instances_without_mask +=
            visib.iter().filter(|m| !m.iter().any(|&v| v > 0)).count() as u64;
        let entry = scenes.entry((loc.split.clone(), loc.scene_id)).or_default();
        entry.0.insert(loc.im_id, f.camera);
        entry.1.insert(loc.im_id, f.gt.clone());
        if let Some(info) = info {
            entry.2.insert(loc.im_id, info);
        }
        summary.frames += 1;
        progress.advance(1);
    }
    for ((split, scene_id), (camera, gt, info)) in &scenes {
        let dir = dst.join(split).join(format!("{scene_id:06}"));
        if info.len() == camera.len() {
            write_map(&dir.join("scene_gt_info.json"), info, false)?;
        }
        write_map(&dir.join("scene_gt.json"), gt, false)?;
        write_map(&dir.join("scene_camera.json"), camera, false)?;
    }
    write_camera_info(&dst.join("camera.json"), &cam)?;
    progress.finish();
    if !stray.is_empty() {
        let n = stray.len();
        stray.truncate(10);
        progress.warn(&format!(
            "{n} frames have label values that are no class of their -meta.mat (values {}): those pixels are in no mask_visib: {}{}",
            format_label_values(&stray_values),
            stray.join("; "),
            if n > 10 { format!("; ... and {} more", n - 10) } else { String::new() }
        ));
    }
    if !shared_frames.is_empty() {
        let n = shared_frames.len();
        shared_frames.truncate(10);
        progress.warn(&format!(
            "{n} frames have two or more instances of one class, which label.png cannot tell apart: {}: {}{}",
            if renderer.is_some() {
                "their label pixels were split along the render at the GT poses"
            } else {
                "without the models they have empty mask_visib"
            },
            shared_frames.join(", "),
            if n > 10 { format!(", ... and {} more", n - 10) } else { String::new() }
        ));
    }
    Ok(summary)
}

/// Options of [`source_to_ycbv`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct YcbvConvertOptions {
    /// `classes.txt` to write (line i = obj_id i); default: `obj_NNNNNN` names.
    pub classes: Option<Vec<String>>,
    pub writer: YcbvWriterOptions,
}

/// Converts any dataset synthgen reads (BOP, Linemod) into the YCB-Video layout at `dst`.
/// Poses keep their rotation numbers (t becomes metres); `-label.png` comes from the
/// dataset's visible masks (the nearer object where two overlap), or from the render where an
/// instance has none; `vertmap`, `center` and `-box.txt` from the render at the GT poses.
/// Depth is rescaled to 1 / factor_depth metres. Refuses frames with two instances of one
/// object (a label image holds one per class) or object ids over 255, before writing.
pub fn source_to_ycbv(
    source: &dyn FrameSource,
    dst: &Path,
    opts: &YcbvConvertOptions,
    renderer: &dyn PoseRenderer,
    progress: &dyn Progress,
) -> Result<ConvertSummary> {
    let frames = source.frames(&[])?;
    let mut ids: BTreeSet<u32> = frames.iter().flat_map(|f| f.object_set()).collect();
    ids.extend(
        source
            .models_info()
            .into_iter()
            .flat_map(|m| m.keys().copied()),
    );
    for f in &frames {
        let loc = &f.location;
        if let Some(id) =
            f.gt.iter()
                .map(|g| g.obj_id)
                .find(|&id| id == 0 || id > 255)
        {
            return Err(Error::InvalidRequest(format!(
                "{}/{:06} image {}: object id {id} does not fit YCB-Video's 8-bit label image (1..=255)",
                loc.split, loc.scene_id, loc.im_id
            )));
        }
        let mut seen = BTreeSet::new();
        if let Some(g) = f.gt.iter().find(|g| !seen.insert(g.obj_id)) {
            return Err(Error::InvalidRequest(format!(
                "{}/{:06} image {}: object {} appears twice; YCB-Video's label image holds one instance per class",
                loc.split, loc.scene_id, loc.im_id, g.obj_id
            )));
        }
    }
    let ids: Vec<u32> = ids.into_iter().collect();
    let classes = match &opts.classes {
        Some(c) => {
            if let Some(id) = ids.iter().find(|&&id| id as usize > c.len()) {
                return Err(Error::InvalidRequest(format!(
                    "object id {id} has no line in the class list ({} classes)",
                    c.len()
                )));
            }
            c.clone()
        }
        None => crate::ycbv::class_list(&ids, false),
    };
    let writer = YcbvWriter::create(dst, classes, opts.writer.clone())?;
    let mut summary = ConvertSummary::default();
    for &id in &ids {
        let path = source.model_file(id);
        if !path.is_file() {
            continue;
        }
        writer.write_model(id, &load_source_model(source, id)?)?;
        summary.models += 1;
    }
    progress.start("converting", frames.len() as u64);
    for f in &frames {
        let rgb = read_rgb(&f.rgb)?;
        let (w, h) = (rgb.width, rgb.height);
        let k = f.camera.intrinsics(w, h);
        let ann = annotate_frame(
            renderer,
            f,
            w,
            h,
            synthgen_core::annotate::DEFAULT_VISIB_DELTA_M,
        )?;
        // YCB-Video frames need depth (PoseCNN and DenseFusion read it): none is an error,
        // never a frame of zeros.
        let Some(depth_path) = &f.depth else {
            return Err(Error::malformed(
                &f.rgb,
                "this frame has no depth image, and YCB-Video frames need one",
            ));
        };
        let raw = read_depth_raw(depth_path)?;
        if (raw.width, raw.height) != (w, h) {
            return Err(Error::malformed(
                depth_path,
                format!(
                    "depth image is {}x{} but the colour image is {w}x{h}",
                    raw.width, raw.height
                ),
            ));
        }
        let to = 1000.0 / opts.writer.factor_depth;
        let (depth, overflow) = rescale_depth(&raw.data, f.camera.depth_scale, to);
        summary.depth_out_of_range_px += overflow;
        let label = label_of(f, &ann.rendered, w, h)?;
        summary.instances_without_mask +=
            f.gt.iter()
                .filter(|g| !label.iter().any(|&l| u32::from(l) == g.obj_id))
                .count() as u64;
        let vertmap = vertmap_of(f, &ann.rendered, &label, &k);
        let cam_from_world = match (f.camera.cam_r_w2c, f.camera.cam_t_w2c) {
            (Some(r), Some(t)) => Some(YcbvPose {
                r_row_major: r,
                t_m: t.map(|v| v / 1000.0),
            }),
            _ => None,
        };
        let frame = YcbvFrame {
            split: f.location.split.clone(),
            scene_id: f.location.scene_id,
            im_id: f.location.im_id,
            width: w,
            height: h,
            rgb: rgb.rgb,
            depth,
            label,
            vertmap,
            cam_k: f.camera.cam_k,
            cam_from_world,
            objects: f
                .gt
                .iter()
                .map(|g| YcbvObject {
                    obj_id: g.obj_id,
                    pose: YcbvPose::from_gt(g),
                })
                .collect(),
        };
        writer.write_frame(&frame)?;
        summary.frames += 1;
        summary.instances += f.gt.len() as u64;
        progress.advance(1);
    }
    writer.finish()?;
    progress.finish();
    Ok(summary)
}

/// The label image: each instance's visible mask (the nearer object, by rendered depth, where
/// two overlap); an instance without a mask file takes its pixels from the render.
fn label_of(
    f: &SourceFrame,
    rendered: &synthgen_core::RenderedFrame,
    w: u32,
    h: u32,
) -> Result<Vec<u8>> {
    let n = (w * h) as usize;
    let mut label = vec![0u8; n];
    let mut best = vec![f32::INFINITY; n];
    for (gt_id, g) in f.gt.iter().enumerate() {
        let value = u8::try_from(g.obj_id).unwrap_or(0);
        let alone = &rendered.alone[gt_id];
        let mask: Vec<bool> = match f.masks_visib.get(gt_id).and_then(Option::as_ref) {
            Some(m) => {
                let plane = m.read()?;
                if (plane.width, plane.height) != (w, h) {
                    return Err(Error::malformed(
                        m.path(),
                        format!(
                            "mask is {}x{} but the colour image is {w}x{h}",
                            plane.width, plane.height
                        ),
                    ));
                }
                plane.data.iter().map(|&v| v > 0).collect()
            }
            None => rendered
                .instance
                .iter()
                .map(|&i| usize::from(i) == gt_id + 1)
                .collect(),
        };
        for (i, inside) in mask.into_iter().enumerate() {
            if !inside {
                continue;
            }
            let (x, y) = ((i % w as usize) as i32, (i / w as usize) as i32);
            let d = alone.at(x, y);
            let d = if d > 0.0 { d } else { f32::MAX };
            if label[i] == 0 || d < best[i] {
                label[i] = value;
                best[i] = d;
            }
        }
    }
    Ok(label)
}

/// Model coordinates (metres) of the labelled pixels, from the object's rendered depth there.
fn vertmap_of(
    f: &SourceFrame,
    rendered: &synthgen_core::RenderedFrame,
    label: &[u8],
    k: &Intrinsics,
) -> Vec<f32> {
    let w = k.width as usize;
    let mut out = vec![0f32; label.len() * 3];
    let by_id: BTreeMap<u32, usize> =
        f.gt.iter()
            .enumerate()
            .map(|(i, g)| (g.obj_id, i))
            .collect();
    let obj_from_cam: Vec<_> = f.gt.iter().map(|g| g.cam_from_obj().inverse()).collect();
    for (i, &l) in label.iter().enumerate() {
        let Some(&gt_id) = by_id.get(&u32::from(l)) else {
            continue;
        };
        let (x, y) = ((i % w) as i32, (i / w) as i32);
        let z = rendered.alone[gt_id].at(x, y);
        if z <= 0.0 {
            continue;
        }
        let p_cam: DVec3 = k.back_project(f64::from(x), f64::from(y), f64::from(z));
        let p = obj_from_cam[gt_id].transform_point(p_cam);
        out[3 * i..3 * i + 3].copy_from_slice(&p.as_vec3().to_array());
    }
    out
}
