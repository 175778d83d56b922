//! Linemod checks. Linemod stores no image size: the first RGB image read sets it and every
//! other image must match.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use synthgen_core::Progress;

use super::{count_nonzero, Ctx};
use crate::bop::image::{read_depth_raw, read_mask, read_rgb};
use crate::bop::ModelInfo;
use crate::linemod::{read_gt_yml, read_id_list, read_info_yml, read_models_info_yml};
use crate::linemod::{LinemodDataset, LinemodFolder};

pub(super) fn validate(ctx: &mut Ctx, progress: &dyn Progress) {
    let root = ctx.root.clone();
    let lm = match LinemodDataset::open(&root) {
        Ok(lm) => lm,
        Err(e) => {
            // open only fails on data/ itself or models_info.yml; report and go on without it.
            ctx.error(&root.join("data"), &e);
            let data_ok = root.join("data").is_dir();
            if !data_ok {
                return;
            }
            LinemodDataset {
                root: root.clone(),
                objects: folder_ids(&root),
                models_info: None,
            }
        }
    };
    let models = check_models(ctx, &lm);
    if lm.objects.is_empty() {
        ctx.problem(
            &root.join("data"),
            "no object folders (expected data/01/ ...)",
        );
    }
    progress.start("validating", lm.objects.len() as u64);
    let mut size = None;
    for &obj in &lm.objects {
        check_folder(ctx, &lm, obj, models.as_ref(), &mut size);
        progress.advance(1);
    }
    progress.finish();
}

fn folder_ids(root: &Path) -> Vec<u32> {
    let mut ids: Vec<u32> = std::fs::read_dir(root.join("data"))
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| e.file_name().to_str()?.parse::<u32>().ok())
        .collect();
    ids.sort_unstable();
    ids
}

fn check_models(ctx: &mut Ctx, lm: &LinemodDataset) -> Option<BTreeMap<u32, ModelInfo>> {
    let path = lm.models_info_path();
    let info = match read_models_info_yml(&path) {
        Ok(m) => m,
        Err(e) => {
            ctx.error(&path, &e);
            return None;
        }
    };
    for &id in info.keys() {
        let ply = lm.model_ply_path(id);
        if !ply.is_file() {
            ctx.problem(
                &ply,
                format!("model file of object {id} (in models_info.yml) is missing"),
            );
        }
    }
    for &id in &lm.objects {
        if !info.contains_key(&id) {
            ctx.problem(
                &path,
                format!("data/{id:02} has no entry in models_info.yml"),
            );
        }
    }
    Some(info)
}

fn check_folder(
    ctx: &mut Ctx,
    lm: &LinemodDataset,
    obj: u32,
    models: Option<&BTreeMap<u32, ModelInfo>>,
    size: &mut Option<(u32, u32)>,
) {
    let dir = lm.folder_dir(obj);
    let gt_path = dir.join("gt.yml");
    let info_path = dir.join("info.yml");
    let gt = match read_gt_yml(&gt_path) {
        Ok(g) => g,
        Err(e) => return ctx.error(&gt_path, &e),
    };
    let info = match read_info_yml(&info_path) {
        Ok(i) => i,
        Err(e) => return ctx.error(&info_path, &e),
    };
    let mut lists = [Vec::new(), Vec::new()];
    for (k, name) in ["train.txt", "test.txt"].into_iter().enumerate() {
        let p = dir.join(name);
        match read_id_list(&p) {
            Ok(ids) => lists[k] = ids,
            Err(e) => ctx.error(&p, &e),
        }
    }
    for (k, name) in ["train.txt", "test.txt"].into_iter().enumerate() {
        let missing: BTreeSet<u64> = lists[k]
            .iter()
            .copied()
            .filter(|i| !gt.contains_key(i))
            .collect();
        if let Some(first) = missing.first() {
            ctx.problem(
                &dir.join(name),
                format!(
                    "{} frame id(s) not in gt.yml (first: {first:04})",
                    missing.len()
                ),
            );
        }
    }
    let folder = LinemodFolder {
        obj_id: obj,
        dir: dir.clone(),
        gt,
        info,
        train: Vec::new(),
        test: Vec::new(),
    };
    for (&frame, gts) in &folder.gt {
        ctx.report.frames += 1;
        let Some(cam) = folder.info.get(&frame) else {
            ctx.problem(&info_path, format!("frame {frame} of gt.yml is missing"));
            continue;
        };
        for (i, g) in gts.iter().enumerate() {
            ctx.report.instances += 1;
            let what = format!("cam_R_m2c of frame {frame}, entry {i}");
            ctx.check_rotation(&gt_path, &what, &g.cam_r_m2c, &g.cam_t_m2c);
            if models.is_some_and(|m| !m.contains_key(&g.obj_id)) {
                ctx.problem(
                    &gt_path,
                    format!(
                        "frame {frame}, entry {i}: obj_id {} is not in models_info.yml",
                        g.obj_id
                    ),
                );
            }
        }
        let own = folder.folder_gt(frame).copied();
        if own.is_none() {
            ctx.problem(
                &gt_path,
                format!("frame {frame} has no entry for the folder's object {obj}"),
            );
        }
        let rgb_path = folder.rgb_path(frame);
        ctx.report.images_checked += 1;
        match read_rgb(&rgb_path) {
            Ok(img) => {
                let got = (img.width, img.height);
                match *size {
                    None => *size = Some(got),
                    Some(want) if want != got => ctx.problem(
                        &rgb_path,
                        format!(
                            "image is {}x{} but earlier images are {}x{}",
                            got.0, got.1, want.0, want.1
                        ),
                    ),
                    Some(_) => {}
                }
            }
            Err(e) => ctx.error(&rgb_path, &e),
        }
        let depth_path = folder.depth_path(frame);
        ctx.report.images_checked += 1;
        let depth = match read_depth_raw(&depth_path) {
            Ok(d) => Some(d),
            Err(e) => {
                ctx.error(&depth_path, &e);
                None
            }
        };
        let mask_path = folder.mask_path(frame);
        ctx.report.images_checked += 1;
        let mask = match read_mask(&mask_path) {
            Ok(m) => Some(m),
            Err(e) => {
                ctx.error(&mask_path, &e);
                None
            }
        };
        for (p, wh) in [
            (&depth_path, depth.as_ref().map(|d| (d.width, d.height))),
            (&mask_path, mask.as_ref().map(|m| (m.width, m.height))),
        ] {
            if let (Some(got), Some(want)) = (wh, *size) {
                if got != want {
                    ctx.problem(
                        p,
                        format!(
                            "image is {}x{} but the RGB images are {}x{}",
                            got.0, got.1, want.0, want.1
                        ),
                    );
                }
            }
        }
        if let Some(m) = &mask {
            if count_nonzero(&m.data) == 0 {
                ctx.problem(
                    &mask_path,
                    "mask is empty (the folder's object must be visible)",
                );
            }
        }
        let model = models.and_then(|m| m.get(&obj));
        if let (Some(d), Some(m), Some(g), Some(model)) = (&depth, &mask, own, model) {
            if d.data.len() == m.data.len() {
                let mask_name = format!("mask/{frame:04}.png");
                ctx.check_depth(
                    &depth_path,
                    &mask_name,
                    d,
                    cam.depth_scale,
                    &m.data,
                    g.cam_t_m2c[2],
                    model,
                );
            }
        }
    }
}
