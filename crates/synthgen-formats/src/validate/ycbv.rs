//! YCB-Video checks: classes.txt and the frame lists, each frame's `-meta.mat` (keys, shapes,
//! class indexes, rotations), its images (present, decodable, one size, label values known to
//! the meta), depth under each label against the model's extent, and the models of every
//! class the frames use (present, loadable; a missing texture is a warning).

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;
use std::sync::Mutex;

use synthgen_assets::Units;
use synthgen_core::Progress;

use super::Ctx;
use crate::bop::image::{read_depth_raw, read_label, read_rgb};
use crate::bop::ModelInfo;
use crate::ycbv::{
    format_label_values, read_meta_with, stray_label_values, YcbvDataset, YcbvFrameFiles,
};

/// Collects the loader's warnings (a missing texture) instead of printing them.
#[derive(Default)]
struct Warnings(Mutex<Vec<String>>);

impl Progress for Warnings {
    fn warn(&self, message: &str) {
        if let Ok(mut w) = self.0.lock() {
            w.push(message.to_string());
        }
    }
}

pub(super) fn validate(ctx: &mut Ctx, progress: &dyn Progress) {
    let root = ctx.root.clone();
    let ds = match YcbvDataset::open(&root) {
        Ok(ds) => ds,
        Err(e) => return ctx.error(&root, &e),
    };
    for w in ds.left_out.warnings() {
        ctx.report.warnings.push(super::Problem {
            path: root.join("data"),
            message: w,
        });
    }
    progress.start("validating", ds.frames.len() as u64);
    let mut size = None;
    let mut shared: Vec<String> = Vec::new();
    let mut used: BTreeSet<u32> = BTreeSet::new();
    let mut frames = Vec::new();
    for f in &ds.frames {
        let meta_path = f.meta_path();
        match read_meta_with(&meta_path, Some(ds.classes.len()), false) {
            Ok(meta) => {
                ctx.report.frames += 1;
                for (i, p) in meta.poses.iter().enumerate() {
                    ctx.report.instances += 1;
                    let what = format!("poses of instance {i} (class {})", meta.cls_indexes[i]);
                    let g = p.gt_entry(0);
                    ctx.check_rotation(&meta_path, &what, &g.cam_r_m2c, &g.cam_t_m2c);
                }
                used.extend(meta.cls_indexes.iter().copied());
                let s = meta.shared_classes();
                if !s.is_empty() {
                    let classes: Vec<String> =
                        s.iter().map(|(c, n)| format!("class {c} x{n}")).collect();
                    shared.push(format!(
                        "data/{:04}/{:06} ({})",
                        f.scene_id,
                        f.im_id,
                        classes.join(", ")
                    ));
                }
                frames.push((f, meta));
            }
            Err(e) => ctx.error(&meta_path, &e),
        }
    }
    if !shared.is_empty() {
        let n = shared.len();
        if n > 10 {
            let more = format!("... and {} more", n - 10);
            shared.truncate(10);
            shared.push(more);
        }
        ctx.report.warnings.push(super::Problem {
            path: root.join("data"),
            message: format!(
                "{n} frames have two or more instances of one class, which label.png cannot tell apart: synthgen reads no visible mask for them, and `convert --to bop` splits the label along the render at the GT poses: {}",
                shared.join(", ")
            ),
        });
    }
    let models = check_models(ctx, &ds, &used);
    for (f, meta) in &frames {
        check_images(ctx, f, meta, &models, &mut size);
        progress.advance(1);
    }
    progress.finish();
}

/// Loads the model of every class the frames use; returns their extents (millimetres).
fn check_models(ctx: &mut Ctx, ds: &YcbvDataset, used: &BTreeSet<u32>) -> BTreeMap<u32, ModelInfo> {
    let mut out = BTreeMap::new();
    for &id in used {
        let Some(path) = ds.model_path(id) else {
            continue; // read_meta already reported the class index
        };
        let class = ds.class_name(id).unwrap_or_default();
        if !path.is_file() {
            ctx.problem(
                &path,
                format!("model of class {id} ({class}), used by the frames, is missing"),
            );
            continue;
        }
        let warnings = Warnings::default();
        match synthgen_assets::load_model(&path, Units::M, &warnings) {
            Ok(l) => {
                out.insert(id, ModelInfo::from_model(&l.model));
            }
            Err(e) => ctx.problem(&path, e.to_string()),
        }
        for w in warnings.0.into_inner().unwrap_or_default() {
            ctx.report.warnings.push(super::Problem {
                path: path.clone(),
                message: w,
            });
        }
    }
    out
}

fn check_images(
    ctx: &mut Ctx,
    f: &YcbvFrameFiles,
    meta: &crate::ycbv::YcbvMeta,
    models: &BTreeMap<u32, ModelInfo>,
    size: &mut Option<(u32, u32)>,
) {
    let mut check_size = |ctx: &mut Ctx, path: &Path, what: &str, got: (u32, u32)| match size {
        Some(want) if *want != got => ctx.problem(
            path,
            format!(
                "{what} is {}x{} but the first image is {}x{}",
                got.0, got.1, want.0, want.1
            ),
        ),
        Some(_) => {}
        None => *size = Some(got),
    };
    let color = f.color_path();
    ctx.report.images_checked += 1;
    match read_rgb(&color) {
        Ok(img) => check_size(ctx, &color, "color image", (img.width, img.height)),
        Err(e) => ctx.error(&color, &e),
    }
    let depth_path = f.depth_path();
    ctx.report.images_checked += 1;
    let depth = match read_depth_raw(&depth_path) {
        Ok(d) => {
            check_size(ctx, &depth_path, "depth image", (d.width, d.height));
            Some(d)
        }
        Err(e) => {
            ctx.error(&depth_path, &e);
            None
        }
    };
    let label_path = f.label_path();
    ctx.report.images_checked += 1;
    let label = match read_label(&label_path) {
        Ok(l) => {
            check_size(ctx, &label_path, "label image", (l.width, l.height));
            Some(l)
        }
        Err(e) => {
            ctx.error(&label_path, &e);
            None
        }
    };
    let Some(label) = label else { return };
    let stray = stray_label_values(&label.data, &meta.cls_indexes);
    if !stray.is_empty() {
        ctx.problem(
            &label_path,
            format!(
                "label values {} are not classes of this frame's -meta.mat (cls_indexes {:?})",
                format_label_values(&stray),
                meta.cls_indexes
            ),
        );
    }
    let shared: Vec<u32> = meta.shared_classes().into_iter().map(|c| c.0).collect();
    let Some(depth) = depth else { return };
    if depth.data.len() != label.data.len() {
        return;
    }
    for (c, p) in meta.cls_indexes.iter().zip(&meta.poses) {
        // One label for two instances: the depth under it is not one object's.
        if shared.contains(c) {
            continue;
        }
        let Some(model) = models.get(c) else { continue };
        let mask: Vec<u8> = label
            .data
            .iter()
            .map(|&v| u8::from(v == *c as u16))
            .collect();
        ctx.check_depth(
            &depth_path,
            &format!("the label of class {c}"),
            &depth,
            meta.depth_scale(),
            &mask,
            p.t_m[2] * 1000.0,
            model,
        );
    }
}
