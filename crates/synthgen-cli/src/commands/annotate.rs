//! `synthgen annotate`: masks and scene_gt_info.json for a BOP dataset that has only poses
//! (real captures labelled with poses), computed as bop_toolkit's calc_gt_masks/calc_gt_info
//! do: each object rendered alone at its GT pose by the embedded renderer; the visibility
//! test compares against the real depth PNG when there is one (bop19 rule), else the
//! rendered scene depth.

use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{Context, Result};
use synthgen_assets::Units;
use synthgen_core::sample::ObjectInstance;
use synthgen_core::{annotate, FrameScene, GtInfo, Progress};
use synthgen_dataset::bop::image::encode_gray8_png;
use synthgen_dataset::bop::{write_map, BopDataset, BopScene, PngCompression, SCENE_GT_INFO};
use synthgen_dataset::io::{atomic_write, create_dir_all};
use synthgen_render::{CpuRenderer, Renderer};

use crate::cli::AnnotateArgs;
use crate::commands::user_error;
use crate::{ExitStatus, Printer};

pub fn run(args: AnnotateArgs, printer: &Printer) -> Result<ExitStatus> {
    let ds = BopDataset::open(&args.dir)
        .with_context(|| format!("cannot open dataset {}", args.dir.display()))?;
    let splits: Vec<String> = match &args.split {
        Some(s) if ds.splits.contains(s) => vec![s.clone()],
        Some(s) => {
            return Err(user_error(
                format!("no split {s:?} in {}", args.dir.display()),
                format!("splits there: {}", ds.splits.join(", ")),
            ))
        }
        None => ds.splits.clone(),
    };
    // Models of every object the poses mention, in millimetres as BOP stores them.
    let mut scenes = Vec::new();
    for split in &splits {
        for scene_id in ds.scene_ids(split)? {
            scenes.push(ds.read_scene(split, scene_id)?);
        }
    }
    let mut obj_ids: Vec<u32> = scenes
        .iter()
        .flat_map(|s| s.gt.values().flatten().map(|g| g.obj_id))
        .collect();
    obj_ids.sort_unstable();
    obj_ids.dedup();
    let mut models = Vec::new();
    let mut model_index = BTreeMap::new();
    for &id in &obj_ids {
        let path = ds.model_ply_path(id);
        let loaded = synthgen_assets::load_model(&path, Units::Mm, printer)
            .with_context(|| format!("cannot load the model of object {id}"))?;
        model_index.insert(id, models.len());
        models.push(loaded.model);
    }
    let renderer = CpuRenderer::new(models, vec![])?;
    let delta_m = args.visib_delta_m as f32;

    let total: usize = scenes.iter().map(|s| s.camera.len()).sum();
    printer.start("annotating", total as u64);
    let mut failures: Vec<String> = Vec::new();
    let (mut frames, mut real_depth) = (0usize, 0usize);
    for scene in &scenes {
        let mut infos: BTreeMap<u32, Vec<GtInfo>> = BTreeMap::new();
        let failed_before = failures.len();
        for im_id in scene.im_ids() {
            match annotate_frame(&ds, scene, im_id, &renderer, &model_index, delta_m) {
                Ok((info, used_real_depth)) => {
                    infos.insert(im_id, info);
                    frames += 1;
                    real_depth += usize::from(used_real_depth);
                }
                Err(e) => {
                    let msg = format!("{}/{:06} image {im_id}: {e:#}", scene.split, scene.scene_id);
                    if args.fail_fast {
                        printer.finish();
                        return Err(e.context(msg));
                    }
                    printer.warning(&msg);
                    failures.push(msg);
                }
            }
            printer.advance(1);
        }
        if failures.len() == failed_before {
            write_map(&scene.dir.join(SCENE_GT_INFO), &infos, true)?;
        } else {
            // A partial scene_gt_info.json would make the scene unreadable (every image of
            // scene_gt.json needs its entries); the masks of the good frames are written.
            printer.warning(format!(
                "{} not written: some frames of this scene failed",
                scene.dir.join(SCENE_GT_INFO).display()
            ));
        }
    }
    printer.finish();
    println!(
        "annotated {frames} frames in {} scene folders ({real_depth} with real depth, {} with rendered depth)",
        scenes.len(),
        frames - real_depth
    );
    if failures.is_empty() {
        Ok(ExitStatus::Success)
    } else {
        eprintln!("error: {} frames failed:", failures.len());
        for f in &failures {
            eprintln!("  {f}");
        }
        Ok(ExitStatus::Failure)
    }
}

fn annotate_frame(
    ds: &BopDataset,
    scene: &BopScene,
    im_id: u32,
    renderer: &CpuRenderer,
    model_index: &BTreeMap<u32, usize>,
    delta_m: f32,
) -> Result<(Vec<GtInfo>, bool)> {
    let (w, h) = (ds.camera.width, ds.camera.height);
    let camera = scene
        .camera
        .get(&im_id)
        .context("image missing from scene_camera.json")?;
    let gts = scene.gt.get(&im_id).cloned().unwrap_or_default();
    let objects = gts
        .iter()
        .map(|g| ObjectInstance {
            model_index: model_index.get(&g.obj_id).copied().unwrap_or(0),
            obj_id: g.obj_id,
            cam_from_obj: g.cam_from_obj(),
            brightness: 1.0,
            specular: 0.0,
            shininess: 1.0,
            tint: [1.0; 3],
            hue_deg: 0.0,
        })
        .collect();
    let frame_scene = FrameScene::bare(u64::from(im_id), camera.intrinsics(w, h), objects);
    let frame = renderer.render(&frame_scene)?;
    let depth_path = scene.depth_path(im_id);
    let (depth, real) = if depth_path.is_file() {
        let d = scene.read_depth_m(im_id)?;
        if (d.width, d.height) != (w, h) {
            anyhow::bail!(
                "depth is {}x{} but camera.json says {w}x{h}: {}",
                d.width,
                d.height,
                depth_path.display()
            );
        }
        (d.data, true)
    } else {
        (frame.depth_m, false)
    };
    let anns = annotate(w, h, &depth, &frame.alone, delta_m);
    for (gt_id, a) in anns.iter().enumerate() {
        write_mask(&scene.mask_path(im_id, gt_id), &a.mask, w, h)?;
        write_mask(&scene.mask_visib_path(im_id, gt_id), &a.mask_visib, w, h)?;
    }
    Ok((anns.into_iter().map(|a| a.info).collect(), real))
}

fn write_mask(path: &Path, mask: &[u8], w: u32, h: u32) -> Result<()> {
    if let Some(dir) = path.parent() {
        create_dir_all(dir)?;
    }
    let png = encode_gray8_png(mask, w, h, PngCompression::default(), path)?;
    atomic_write(path, &png)?;
    Ok(())
}
