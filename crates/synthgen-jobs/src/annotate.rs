//! An annotation as `synthgen annotate` runs it: masks and scene_gt_info.json for a BOP
//! dataset that has only poses
//! (real captures labelled with poses), computed as bop_toolkit's calc_gt_masks/calc_gt_info
//! do (`synthgen_formats::annotate`); and, on any layout, the comparison of those visible
//! masks with the dataset's own (YCB-Video's label.png, a BOP mask_visib), per scene and per
//! object.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use serde::Serialize;
use synthgen_core::{GtInfo, Progress};
use synthgen_formats::annotate::{annotate_frame, mask_iou, mask_overlay, percentile};
use synthgen_formats::bop::image::{encode_gray8_png, read_rgb};
use synthgen_formats::bop::{write_map, PngCompression, SCENE_GT_INFO};
use synthgen_formats::io::{atomic_write, create_dir_all};
use synthgen_formats::layout::open_source;
use synthgen_formats::layout::{detect_layout, Layout};
use synthgen_formats::output::OutputLock;
use synthgen_formats::source::{FrameSource, SourceFrame};
use synthgen_render::ObjectRenderer;

use crate::models::{frame_obj_ids, object_renderer};
use crate::{user_error, Log};

/// What to annotate: `synthgen annotate`'s arguments as data.
#[derive(Debug, Clone)]
pub struct AnnotateRequest {
    /// The dataset (BOP to write into; any layout with `compare`).
    pub dir: PathBuf,
    /// Compare the computed visible masks with the dataset's own, writing nothing into it.
    pub compare: bool,
    /// Write the comparison as JSON here.
    pub report: Option<PathBuf>,
    /// Write mask overlays into this folder.
    pub overlay: Option<PathBuf>,
    /// At most this many overlays.
    pub overlay_count: usize,
    pub split: Option<String>,
    /// bop_toolkit's visibility delta, metres.
    pub visib_delta_m: f64,
    /// Stop at the first failed frame.
    pub fail_fast: bool,
}

/// What an annotation printed and what failed.
#[derive(Debug, Clone, Default)]
pub struct AnnotateOutcome {
    /// The comparison table (with `compare`): what the CLI prints on stdout.
    pub stdout: String,
    /// The frames that failed, with their messages (the CLI exits with 1).
    pub failures: Vec<String>,
}

/// One instance's computed visible mask against the dataset's own.
#[derive(Debug, Clone, Serialize)]
struct Agreement {
    split: String,
    scene_id: u32,
    im_id: u32,
    gt_id: usize,
    obj_id: u32,
    /// The computed visible mask (bop19, against the frame's depth).
    iou: f64,
    /// The object's pixels in the render of all annotated objects (a z-buffer, no depth
    /// image): a check of poses, intrinsics and models alone.
    iou_rendered: f64,
    px_computed: u64,
    px_dataset: u64,
}

/// IoU summary of a group of instances.
#[derive(Debug, Clone, Serialize)]
struct Summary {
    n: usize,
    median_iou: f64,
    p10_iou: f64,
    mean_iou: f64,
    median_iou_rendered: f64,
    p10_iou_rendered: f64,
}

fn summarize(rows: &[&Agreement]) -> Option<Summary> {
    let v: Vec<f64> = rows.iter().map(|r| r.iou).collect();
    let r: Vec<f64> = rows.iter().map(|r| r.iou_rendered).collect();
    Some(Summary {
        n: v.len(),
        median_iou: percentile(&v, 50.0)?,
        p10_iou: percentile(&v, 10.0)?,
        mean_iou: v.iter().sum::<f64>() / v.len() as f64,
        median_iou_rendered: percentile(&r, 50.0)?,
        p10_iou_rendered: percentile(&r, 10.0)?,
    })
}

#[derive(Debug, Serialize)]
struct Report {
    dataset: PathBuf,
    visib_delta_m: f64,
    all: Option<Summary>,
    scenes: BTreeMap<String, Summary>,
    objects: BTreeMap<u32, Summary>,
    instances: Vec<Agreement>,
}

/// Annotates (or compares) `req`; messages go to `progress`.
pub fn annotate(req: &AnnotateRequest, progress: &dyn Progress) -> Result<AnnotateOutcome> {
    let printer = &Log::new(progress);
    let args = req;
    let mut stdout = String::new();
    if !args.dir.is_dir() {
        return Err(synthgen_formats::Error::NoSuchDataset {
            path: args.dir.clone(),
        }
        .into());
    }
    let layout = detect_layout(&args.dir);
    if !args.compare && layout != Some(Layout::Bop) {
        let what = layout.map_or("not a dataset synthgen recognises".into(), |l| {
            format!("a {l} dataset")
        });
        return Err(user_error(
            format!(
                "annotate writes BOP mask/, mask_visib/ and scene_gt_info.json into the dataset, and {} is {what}",
                args.dir.display()
            ),
            "convert it with `synthgen convert --to bop DIR OUT` (which computes them), or pass --compare to compare computed visible masks with the dataset's own without writing",
        ));
    }
    // Annotating writes into the dataset: one writer at a time.
    let _lock = match args.compare {
        false => Some(OutputLock::acquire(&args.dir)?),
        true => None,
    };
    let source = open_source(&args.dir)
        .with_context(|| format!("cannot open dataset {}", args.dir.display()))?;
    let splits: Vec<String> = match &args.split {
        Some(s) if source.splits().contains(s) => vec![s.clone()],
        Some(s) => {
            return Err(user_error(
                format!("no split {s:?} in {}", args.dir.display()),
                format!("splits there: {}", source.splits().join(", ")),
            ))
        }
        None => source.splits(),
    };
    let frames = source.frames(&splits)?;
    let renderer = object_renderer(source.as_ref(), &frame_obj_ids(&frames), printer)?;
    let cam = source.camera();
    let delta_m = args.visib_delta_m as f32;
    let overlay_every = match (&args.overlay, args.overlay_count) {
        (Some(_), n) if n > 0 => frames.len().div_ceil(n).max(1),
        _ => usize::MAX,
    };
    if let Some(dir) = &args.overlay {
        create_dir_all(dir)?;
    }

    // Frames grouped by scene folder, in order: a scene's scene_gt_info.json is written once
    // all its frames are annotated.
    let mut scenes: BTreeMap<(String, u32), Vec<(usize, &SourceFrame)>> = BTreeMap::new();
    for (i, f) in frames.iter().enumerate() {
        let l = &f.location;
        scenes
            .entry((l.split.clone(), l.scene_id))
            .or_default()
            .push((i, f));
    }
    printer.start(
        if args.compare {
            "comparing"
        } else {
            "annotating"
        },
        frames.len() as u64,
    );
    let mut failures: Vec<String> = Vec::new();
    let mut agreements: Vec<Agreement> = Vec::new();
    let (mut done, mut real_depth) = (0usize, 0usize);
    for ((split, scene_id), group) in &scenes {
        let scene_dir = args.dir.join(split).join(format!("{scene_id:06}"));
        let mut infos: BTreeMap<u32, Vec<GtInfo>> = BTreeMap::new();
        let failed_before = failures.len();
        for &(i, f) in group {
            let overlay = args.overlay.as_deref().filter(|_| i % overlay_every == 0);
            let step = FrameStep {
                renderer: &renderer,
                size: (cam.width, cam.height),
                delta_m,
                write_to: (!args.compare).then_some(scene_dir.as_path()),
                overlay,
            };
            match step.run(f, &mut agreements) {
                Ok((info, real)) => {
                    infos.insert(f.location.im_id, info);
                    done += 1;
                    real_depth += usize::from(real);
                }
                Err(e) => {
                    let msg = format!("{split}/{scene_id:06} image {}: {e:#}", f.location.im_id);
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
        if args.compare {
            continue;
        }
        if failures.len() == failed_before {
            write_map(&scene_dir.join(SCENE_GT_INFO), &infos, true)?;
        } else {
            // A partial scene_gt_info.json would make the scene unreadable (every image of
            // scene_gt.json needs its entries); the masks of the good frames are written.
            printer.warning(format!(
                "{} not written: some frames of this scene failed",
                scene_dir.join(SCENE_GT_INFO).display()
            ));
        }
    }
    printer.finish();
    let verb = if args.compare {
        "compared"
    } else {
        "annotated"
    };
    printer.info(format!(
        "{verb} {done} frames in {} scene folders ({real_depth} with real depth, {} with rendered depth)",
        scenes.len(),
        done - real_depth
    ));
    let report = report(args, agreements);
    // The comparison is what --compare asks for (stdout); otherwise a side note (stderr).
    let table = format_report(&report, source.as_ref());
    if args.compare {
        stdout.push_str(&table);
    } else if !table.is_empty() {
        printer.info(table.trim_end());
    }
    if let Some(path) = &args.report {
        let text = serde_json::to_string_pretty(&report).context("cannot write the report")?;
        atomic_write(path, text.as_bytes())?;
        printer.info(format!("wrote {}", path.display()));
    }
    if let Some(dir) = &args.overlay {
        printer.info(format!(
            "overlays in {}: green = both masks, red = computed only, blue = the dataset's only",
            dir.display()
        ));
    }
    Ok(AnnotateOutcome { stdout, failures })
}

/// What one frame's annotation needs.
struct FrameStep<'a> {
    renderer: &'a ObjectRenderer,
    size: (u32, u32),
    delta_m: f32,
    /// The scene folder to write masks into (`None` with --compare).
    write_to: Option<&'a Path>,
    overlay: Option<&'a Path>,
}

impl FrameStep<'_> {
    /// Annotates a frame, compares its visible masks with the dataset's, writes what is
    /// asked for. Returns the frame's gt info and whether real depth was used.
    fn run(&self, f: &SourceFrame, agreements: &mut Vec<Agreement>) -> Result<(Vec<GtInfo>, bool)> {
        let (w, h) = self.size;
        let ann = annotate_frame(self.renderer, f, w, h, self.delta_m)?;
        let mut theirs = Vec::with_capacity(f.gt.len());
        for (gt_id, (g, a)) in f.gt.iter().zip(&ann.objects).enumerate() {
            let old = match f.masks_visib.get(gt_id).and_then(Option::as_ref) {
                Some(m) => Some(m.read_sized(w, h)?.data),
                None => None,
            };
            if let Some(old) = &old {
                let own = gt_id + 1;
                let rendered: Vec<u8> = ann
                    .rendered
                    .instance
                    .iter()
                    .map(|&v| if usize::from(v) == own { 255 } else { 0 })
                    .collect();
                let iou_rendered = mask_iou(&rendered, old).unwrap_or(0.0);
                if let Some(iou) = mask_iou(&a.mask_visib, old) {
                    let count = |m: &[u8]| m.iter().filter(|&&v| v > 0).count() as u64;
                    agreements.push(Agreement {
                        split: f.location.split.clone(),
                        scene_id: f.location.scene_id,
                        im_id: f.location.im_id,
                        gt_id,
                        obj_id: g.obj_id,
                        iou,
                        iou_rendered,
                        px_computed: count(&a.mask_visib),
                        px_dataset: count(old),
                    });
                }
            }
            theirs.push(old);
        }
        if let Some(dir) = self.overlay {
            let img = read_rgb(&f.rgb)?;
            let ours: Vec<Vec<u8>> = ann.objects.iter().map(|a| a.mask_visib.clone()).collect();
            let l = &f.location;
            let path = dir.join(format!("{}_{:06}_{:06}.png", l.split, l.scene_id, l.im_id));
            mask_overlay(&img, &ours, &theirs).write_png(&path)?;
        }
        if let Some(dir) = self.write_to {
            let im = f.location.im_id;
            for (gt_id, a) in ann.objects.iter().enumerate() {
                let name = format!("{im:06}_{gt_id:06}.png");
                write_mask(&dir.join("mask").join(&name), &a.mask, w, h)?;
                write_mask(&dir.join("mask_visib").join(&name), &a.mask_visib, w, h)?;
            }
        }
        Ok((
            ann.objects.into_iter().map(|a| a.info).collect(),
            ann.real_depth,
        ))
    }
}

fn report(args: &AnnotateRequest, instances: Vec<Agreement>) -> Report {
    let all: Vec<&Agreement> = instances.iter().collect();
    let mut by_scene: BTreeMap<String, Vec<&Agreement>> = BTreeMap::new();
    let mut by_obj: BTreeMap<u32, Vec<&Agreement>> = BTreeMap::new();
    for a in &instances {
        by_scene
            .entry(format!("{}/{:06}", a.split, a.scene_id))
            .or_default()
            .push(a);
        by_obj.entry(a.obj_id).or_default().push(a);
    }
    Report {
        dataset: args.dir.clone(),
        visib_delta_m: args.visib_delta_m,
        all: summarize(&all),
        scenes: by_scene
            .iter()
            .filter_map(|(k, v)| Some((k.clone(), summarize(v)?)))
            .collect(),
        objects: by_obj
            .iter()
            .filter_map(|(k, v)| Some((*k, summarize(v)?)))
            .collect(),
        instances,
    }
}

fn format_report(r: &Report, source: &dyn FrameSource) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let Some(all) = &r.all else {
        return out;
    };
    let mask = if source.root().join("classes.txt").is_file() {
        "label.png"
    } else {
        "mask_visib"
    };
    let _ = writeln!(
        out,
        "IoU per instance with the dataset's own visible masks ({mask}): the computed mask_visib \
         (bop19, real depth) and the render of the annotated objects alone (z-buffer)\n  \
         {:<18} {:>5} {:>8} {:>8} {:>8} {:>10} {:>10}",
        "", "n", "median", "p10", "mean", "rendered", "rend. p10"
    );
    let mut line = |name: &str, s: &Summary| {
        let _ = writeln!(
            out,
            "  {name:<18} {:>5} {:>8.3} {:>8.3} {:>8.3} {:>10.3} {:>10.3}",
            s.n, s.median_iou, s.p10_iou, s.mean_iou, s.median_iou_rendered, s.p10_iou_rendered
        );
    };
    for (k, s) in &r.scenes {
        line(&format!("scene {k}"), s);
    }
    for (k, s) in &r.objects {
        line(&format!("object {k}"), s);
    }
    line("all", all);
    out
}

fn write_mask(path: &Path, mask: &[u8], w: u32, h: u32) -> Result<()> {
    if let Some(dir) = path.parent() {
        create_dir_all(dir)?;
    }
    let png = encode_gray8_png(mask, w, h, PngCompression::default(), path)?;
    atomic_write(path, &png)?;
    Ok(())
}
