//! BOP checks. The JSON files are parsed without the reader's content checks, so that every
//! bad pose or count becomes its own problem.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use synthgen_core::{GtInfo, Progress};

use super::{count_nonzero, Ctx};
use crate::bop::image::{read_depth_raw, read_mask, read_rgb};
use crate::bop::reader::{read_camera_info, read_json, read_models_info};
use crate::bop::{CameraInfo, GtEntry, ModelInfo, SceneCamera};

fn list_dirs(dir: &Path) -> Vec<(String, PathBuf)> {
    let mut out: Vec<(String, PathBuf)> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| std::fs::metadata(e.path()).is_ok_and(|m| m.is_dir()))
        .map(|e| (e.file_name().to_string_lossy().into_owned(), e.path()))
        .filter(|(n, _)| !n.starts_with('.'))
        .collect();
    out.sort();
    out
}

fn is_id(name: &str) -> bool {
    !name.is_empty() && name.bytes().all(|b| b.is_ascii_digit())
}

pub(super) fn validate(ctx: &mut Ctx, progress: &dyn Progress) {
    let root = ctx.root.clone();
    let cam_path = root.join("camera.json");
    let camera = match read_camera_info(&cam_path) {
        Ok(c) => Some(c),
        Err(e) => {
            ctx.error(&cam_path, &e);
            None
        }
    };
    let models = check_models(ctx, &root);

    let mut scenes = Vec::new();
    for (split, path) in list_dirs(&root) {
        if split.starts_with("models") {
            continue;
        }
        for (name, scene_dir) in list_dirs(&path) {
            if is_id(&name) {
                scenes.push(scene_dir);
            }
        }
    }
    if scenes.is_empty() {
        ctx.problem(
            &root,
            "no scene folders (expected SPLIT/000000/ beside camera.json)",
        );
    }
    progress.start("validating", scenes.len() as u64);
    for dir in scenes {
        check_scene(ctx, &dir, camera.as_ref(), models.as_ref());
        progress.advance(1);
    }
    progress.finish();
}

fn check_models(ctx: &mut Ctx, root: &Path) -> Option<BTreeMap<u32, ModelInfo>> {
    let dir = root.join("models");
    let info_path = dir.join("models_info.json");
    let info = match read_models_info(&info_path) {
        Ok(m) => m,
        Err(e) => {
            ctx.error(&info_path, &e);
            return None;
        }
    };
    for &id in info.keys() {
        let ply = dir.join(format!("obj_{id:06}.ply"));
        if !ply.is_file() {
            ctx.problem(
                &ply,
                format!("model file of object {id} (in models_info.json) is missing"),
            );
        }
    }
    let mut extra: BTreeSet<u32> = BTreeSet::new();
    for e in std::fs::read_dir(&dir).into_iter().flatten().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if let Some(id) = name
            .strip_prefix("obj_")
            .and_then(|s| s.strip_suffix(".ply"))
            .and_then(|s| s.parse::<u32>().ok())
        {
            if !info.contains_key(&id) {
                extra.insert(id);
            }
        }
    }
    for id in extra {
        ctx.problem(
            &info_path,
            format!("models/obj_{id:06}.ply has no entry in models_info.json"),
        );
    }
    Some(info)
}

fn read_or_report<T: serde::de::DeserializeOwned>(ctx: &mut Ctx, path: &Path) -> Option<T> {
    match read_json::<T>(path) {
        Ok(v) => Some(v),
        Err(e) => {
            ctx.error(path, &e);
            None
        }
    }
}

fn check_size(ctx: &mut Ctx, path: &Path, what: &str, got: (u32, u32), want: Option<(u32, u32)>) {
    if let Some(want) = want {
        if got != want {
            ctx.problem(
                path,
                format!(
                    "{what} is {}x{} but the camera is {}x{}",
                    got.0, got.1, want.0, want.1
                ),
            );
        }
    }
}

fn check_scene(
    ctx: &mut Ctx,
    dir: &Path,
    camera: Option<&CameraInfo>,
    models: Option<&BTreeMap<u32, ModelInfo>>,
) {
    let cam_path = dir.join("scene_camera.json");
    let gt_path = dir.join("scene_gt.json");
    let info_path = dir.join("scene_gt_info.json");
    let Some(cams) = read_or_report::<BTreeMap<u32, SceneCamera>>(ctx, &cam_path) else {
        return;
    };
    let Some(gt) = read_or_report::<BTreeMap<u32, Vec<GtEntry>>>(ctx, &gt_path) else {
        return;
    };
    let gt_info = if info_path.exists() {
        read_or_report::<BTreeMap<u32, Vec<GtInfo>>>(ctx, &info_path)
    } else {
        None
    };
    let size = camera.map(|c| (c.width, c.height));
    for im in gt.keys().filter(|im| !cams.contains_key(im)) {
        ctx.problem(&gt_path, format!("image {im} is not in scene_camera.json"));
    }
    let has_depth = dir.join("depth").is_dir();
    if !has_depth && !cams.is_empty() {
        // Every image's depth_scale promises a depth image (bop_toolkit reads depth/ for
        // visibility and VSD); a dataset that lost its depth/ is not one that has none.
        ctx.problem(
            &dir.join("depth"),
            format!(
                "missing folder: scene_camera.json gives a depth_scale for {} images but there is no depth/",
                cams.len()
            ),
        );
    }
    for (&im, cam) in &cams {
        ctx.report.frames += 1;
        let rgb = ["png", "jpg", "jpeg"]
            .iter()
            .map(|ext| dir.join("rgb").join(format!("{im:06}.{ext}")))
            .find(|p| p.exists())
            .or_else(|| {
                let p = dir.join("gray").join(format!("{im:06}.png"));
                p.exists().then_some(p)
            });
        match rgb {
            None => ctx.problem(
                &dir.join("rgb").join(format!("{im:06}.png")),
                "missing file (image is in scene_camera.json)",
            ),
            Some(p) => {
                ctx.report.images_checked += 1;
                match read_rgb(&p) {
                    Ok(img) => check_size(ctx, &p, "image", (img.width, img.height), size),
                    Err(e) => ctx.error(&p, &e),
                }
            }
        }
        let depth_path = dir.join("depth").join(format!("{im:06}.png"));
        let depth = if has_depth {
            ctx.report.images_checked += 1;
            match read_depth_raw(&depth_path) {
                Ok(d) => {
                    check_size(ctx, &depth_path, "depth", (d.width, d.height), size);
                    Some(d)
                }
                Err(e) => {
                    ctx.error(&depth_path, &e);
                    None
                }
            }
        } else {
            None
        };
        let gts = gt.get(&im).map(Vec::as_slice).unwrap_or(&[]);
        let infos = gt_info
            .as_ref()
            .map(|i| i.get(&im).map(Vec::as_slice).unwrap_or(&[]));
        if let Some(infos) = infos {
            if infos.len() != gts.len() {
                ctx.problem(
                    &info_path,
                    format!(
                        "image {im} has {} entries but scene_gt.json has {}",
                        infos.len(),
                        gts.len()
                    ),
                );
            }
        }
        for (gt_id, g) in gts.iter().enumerate() {
            ctx.report.instances += 1;
            let what = format!("cam_R_m2c of image {im}, gt {gt_id}");
            ctx.check_rotation(&gt_path, &what, &g.cam_r_m2c, &g.cam_t_m2c);
            let model = models.and_then(|m| m.get(&g.obj_id));
            if models.is_some() && model.is_none() {
                ctx.problem(
                    &gt_path,
                    format!(
                        "image {im}, gt {gt_id}: obj_id {} is not in models_info.json",
                        g.obj_id
                    ),
                );
            }
            let name = format!("{im:06}_{gt_id:06}.png");
            let mut counts = [None, None];
            let mut visib_mask = None;
            for (k, sub) in ["mask", "mask_visib"].into_iter().enumerate() {
                if !dir.join(sub).is_dir() {
                    continue;
                }
                let p = dir.join(sub).join(&name);
                ctx.report.images_checked += 1;
                match read_mask(&p) {
                    Ok(m) => {
                        check_size(ctx, &p, "mask", (m.width, m.height), size);
                        counts[k] = Some(count_nonzero(&m.data));
                        if k == 1 {
                            visib_mask = Some(m.data);
                        }
                    }
                    Err(e) => ctx.error(&p, &e),
                }
            }
            if let Some(info) = infos.and_then(|i| i.get(gt_id)) {
                check_counts(ctx, &info_path, im, gt_id, &name, info, counts, size);
            }
            if let (Some(d), Some(m), Some(model)) = (&depth, &visib_mask, model) {
                if d.data.len() == m.len() {
                    let mask_name = format!("mask_visib/{name}");
                    ctx.check_depth(
                        &depth_path,
                        &mask_name,
                        d,
                        cam.depth_scale,
                        m,
                        g.cam_t_m2c[2],
                        model,
                    );
                }
            }
        }
    }
    check_orphans(ctx, dir, &cams, &gt);
}

/// Image files that no entry of the scene's JSON owns: left over from another dataset written
/// into the same folder (`--force` used to leave them), or copied in by hand. One problem per
/// folder, with a count and the first file.
fn check_orphans(
    ctx: &mut Ctx,
    dir: &Path,
    cams: &BTreeMap<u32, SceneCamera>,
    gt: &BTreeMap<u32, Vec<GtEntry>>,
) {
    for sub in ["rgb", "gray", "depth", "mask", "mask_visib"] {
        let Ok(entries) = std::fs::read_dir(dir.join(sub)) else {
            continue;
        };
        let mut names: Vec<String> = entries
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with('.'))
            .filter(|n| {
                let stem = n.split('.').next().unwrap_or("");
                let mut parts = stem.split('_');
                let im = parts.next().and_then(|p| p.parse::<u32>().ok());
                let inst = parts.next().map(|p| p.parse::<usize>().ok());
                match (im, inst) {
                    (Some(im), None) => !cams.contains_key(&im),
                    (Some(im), Some(Some(g))) => {
                        !cams.contains_key(&im) || gt.get(&im).is_none_or(|v| g >= v.len())
                    }
                    _ => true,
                }
            })
            .collect();
        if names.is_empty() {
            continue;
        }
        names.sort();
        ctx.problem(
            &dir.join(sub),
            format!(
                "{} files belong to no image of scene_camera.json or no instance of scene_gt.json (first: {}): left over from another dataset written here?",
                names.len(),
                names[0]
            ),
        );
    }
}

#[allow(clippy::too_many_arguments)]
fn check_counts(
    ctx: &mut Ctx,
    info_path: &Path,
    im: u32,
    gt_id: usize,
    name: &str,
    info: &GtInfo,
    [mask_px, visib_px]: [Option<u64>; 2],
    size: Option<(u32, u32)>,
) {
    let at = format!("image {im}, gt {gt_id}");
    if let Some(v) = visib_px {
        if info.visib_fract > 0.0 && v == 0 {
            ctx.problem(
                info_path,
                format!(
                    "{at}: visib_fract is {} but mask_visib/{name} is empty",
                    info.visib_fract
                ),
            );
        } else if v != info.px_count_visib {
            ctx.problem(
                info_path,
                format!(
                    "{at}: px_count_visib is {} but mask_visib/{name} has {v} pixels",
                    info.px_count_visib
                ),
            );
        }
    }
    if let Some(m) = mask_px {
        // px_count_all counts the whole silhouette (also outside the image): equal to the mask
        // when bbox_obj lies inside the image, at least the mask otherwise.
        let [x, y, w, h] = info.bbox_obj;
        let inside = size.is_some_and(|(iw, ih)| {
            x >= 0 && y >= 0 && ((x + w) as i64) < iw as i64 && ((y + h) as i64) < ih as i64
        });
        if m > info.px_count_all || (inside && info.px_count_all > 0 && m != info.px_count_all) {
            ctx.problem(
                info_path,
                format!(
                    "{at}: px_count_all is {} but mask/{name} has {m} pixels",
                    info.px_count_all
                ),
            );
        }
    }
    if info.px_count_visib > info.px_count_all || info.px_count_valid > info.px_count_all {
        ctx.problem(
            info_path,
            format!("{at}: px_count_visib and px_count_valid must not exceed px_count_all"),
        );
    }
    if info.px_count_all > 0 {
        let want = info.px_count_visib as f64 / info.px_count_all as f64;
        if (want - info.visib_fract).abs() > 1e-4 {
            ctx.problem(
                info_path,
                format!(
                    "{at}: visib_fract {} is not px_count_visib / px_count_all = {want:.6}",
                    info.visib_fract
                ),
            );
        }
    }
}
