//! Pose estimates refined on the colour images they came from (`synthgen eval --refine
//! edges`): each estimate's model contour moved onto the image's edges
//! (`synthgen_fit::edge_refine`). It reads only the estimate, the RGB image, the camera and
//! the object's model, so it refines any BOP results file, not only synthgen's.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use synthgen_core::glam::DVec3;
use synthgen_core::Intrinsics;
use synthgen_core::{Pose, Progress};
use synthgen_fit::appearance::{Appearance, ColouredSurface};
use synthgen_fit::edge_refine::{
    refine, refine_with_views, EdgeField, EdgeRefineOptions, Rect, ViewTemplates, VisibleBox,
};
use synthgen_formats::bop::image::read_rgb;
use synthgen_formats::bop::RgbImage;
use synthgen_formats::source::{FrameSource, SourceFrame};
use synthgen_train::bop::{eval_model_paths, load_render_models};
use synthgen_train::data::CropBoxes;
use synthgen_train::results::{Estimate, RawPose};

/// The refined region's side over the side of the estimate's projected model box.
pub const REGION_CONTEXT: f64 = 2.0;

/// What a refinement pass did.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct RefineSummary {
    pub estimates: usize,
    /// Estimates refined (the others: no RGB image, a model behind the camera or off the
    /// image): kept as they were.
    pub refined: usize,
    /// Of those, refinements refused (too few contour points on matching edges): the
    /// estimate kept.
    pub refused: usize,
    /// Mean cost of the refined estimates before and after: contour pixels, plus the colour
    /// regions' and the model colours' weighted costs where the options weigh them
    /// (`--refine views`).
    pub mean_cost_before_px: f64,
    pub mean_cost_after_px: f64,
    pub seconds: f64,
    /// The objects whose colours came from `colour_models` (see [`refine_estimates`]).
    pub colours_from_folder: Vec<u32>,
    /// Of the refined estimates, those refined within a visible box ([`VisibleBoxes`]).
    pub with_box: usize,
}

/// Where the refinement learns what of each instance shows ([`VisibleBox`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum VisibleBoxes {
    /// Nothing: the whole contour counts wherever it falls.
    #[default]
    None,
    /// The GT visible box (`scene_gt_info`'s `bbox_visib`, else the visible mask's bounding
    /// box) of the frame's instance of the estimate's object nearest the estimate (its
    /// projected origin): the box an RGB model's crop comes from with GT boxes. Numbers made
    /// with it are numbers with GT boxes.
    Gt,
    /// The detections of the estimate's object in its image (a detector's boxes, as
    /// `eval --detections` crops from), the one nearest the estimate: numbers without GT boxes.
    Detected,
}

/// Where [`refine_estimates`] reads each instance's visible box from: [`VisibleBoxes`] with
/// the detections' boxes.
#[derive(Debug, Clone, Copy)]
pub enum BoxSource<'a> {
    None,
    Gt,
    Detected(&'a CropBoxes),
}

impl<'a> BoxSource<'a> {
    /// `boxes`, reading `detections` when it is [`VisibleBoxes::Detected`] (refused without).
    pub fn new(boxes: VisibleBoxes, detections: Option<&'a CropBoxes>) -> Result<BoxSource<'a>> {
        Ok(match (boxes, detections) {
            (VisibleBoxes::None, _) => BoxSource::None,
            (VisibleBoxes::Gt, _) => BoxSource::Gt,
            (VisibleBoxes::Detected, Some(d)) => BoxSource::Detected(d),
            (VisibleBoxes::Detected, None) => {
                return Err(crate::user_error(
                    "the visible box from detections needs the detections",
                    "pass --detections FILE (the boxes of `synthgen detector run`)",
                ))
            }
        })
    }
}

/// The GT visible boxes (`[x, y, w, h]`) of `frame`'s instances of `obj_id`
/// ([`SourceFrame::visible_bbox`]).
fn gt_boxes(frame: &SourceFrame, obj_id: u32) -> Result<Vec<[f64; 4]>> {
    let mut out = Vec::new();
    for (gt_id, g) in frame.gt.iter().enumerate() {
        if g.obj_id == obj_id {
            if let Some(b) = frame.visible_bbox(gt_id)? {
                out.push(b.map(f64::from));
            }
        }
    }
    Ok(out)
}

/// Of `boxes`, the one whose centre is nearest `pose`'s projected origin.
fn nearest_box(boxes: &[[f64; 4]], pose: &Pose, k: &synthgen_core::Intrinsics) -> Option<[f64; 4]> {
    let t = pose.translation_m;
    let (x, y) = if t.z > 1e-6 {
        (k.fx * t.x / t.z + k.cx, k.fy * t.y / t.z + k.cy)
    } else {
        (k.cx, k.cy)
    };
    let d = |b: &[f64; 4]| (b[0] + 0.5 * b[2] - x).hypot(b[1] + 0.5 * b[3] - y);
    boxes.iter().copied().min_by(|a, b| d(a).total_cmp(&d(b)))
}

/// `n` vertices of the model, strided: where its projected box is read from.
fn box_points(tris: &[[DVec3; 3]], n: usize) -> Vec<DVec3> {
    let step = (tris.len() / n.max(1)).max(1);
    tris.iter().step_by(step).map(|t| t[0]).collect()
}

/// The square around the model's projection at `pose`, [`REGION_CONTEXT`] times its box's
/// longer side; None when a point is behind the camera or nothing of it is in the image.
fn region(points: &[DVec3], pose: &Pose, k: &synthgen_core::Intrinsics) -> Option<Rect> {
    let (mut lo, mut hi) = (
        [f64::INFINITY, f64::INFINITY],
        [f64::NEG_INFINITY, f64::NEG_INFINITY],
    );
    for p in points {
        let c = pose.rotation * *p + pose.translation_m;
        if c.z <= 1e-3 {
            return None;
        }
        let (x, y) = (k.fx * c.x / c.z + k.cx, k.fy * c.y / c.z + k.cy);
        lo = [lo[0].min(x), lo[1].min(y)];
        hi = [hi[0].max(x), hi[1].max(y)];
    }
    let side = REGION_CONTEXT * (hi[0] - lo[0]).max(hi[1] - lo[1]);
    if !side.is_finite() {
        return None;
    }
    Rect::square_in(
        0.5 * (lo[0] + hi[0]),
        0.5 * (lo[1] + hi[1]),
        side,
        k.width,
        k.height,
    )
}

/// The refinement named as `--refine` names it: "none" (None), "edges", "views" (the view
/// search, with its defaults).
pub fn refine_options(mode: &str) -> Result<Option<EdgeRefineOptions>> {
    Ok(match mode {
        "none" => None,
        "edges" => Some(EdgeRefineOptions::default()),
        "views" => Some(EdgeRefineOptions::with_view_search()),
        other => {
            return Err(crate::user_error(
                format!("refine {other:?} is not a refinement"),
                "give none, edges or views",
            ))
        }
    })
}

/// The models a refinement reads, loaded once: each object's triangles and box points, its
/// coloured surface where the options compare colours, its view templates where they search
/// views. [`refine_estimates`] refines a results file with it; `synthgen predict` and the ROS
/// node refine each frame's estimates with it ([`Refiner::refine_pose`]).
pub struct Refiner {
    opts: EdgeRefineOptions,
    tris: BTreeMap<u32, Vec<[DVec3; 3]>>,
    points: BTreeMap<u32, Vec<DVec3>>,
    surfaces: BTreeMap<u32, ColouredSurface>,
    templates: BTreeMap<u32, ViewTemplates>,
    /// The objects whose colours came from `colour_models` (see [`Refiner::load`]).
    pub colours_from_folder: Vec<u32>,
}

/// One estimate refined: its new pose, the cost before and after, whether the refinement was
/// accepted (else the pose is the estimate's), whether a visible box bounded it.
#[derive(Debug, Clone, Copy)]
pub struct Refined {
    pub pose: Pose,
    pub initial_cost: f64,
    pub cost: f64,
    pub accepted: bool,
    pub boxed: bool,
}

impl Refiner {
    /// Loads `ds`' models of `ids`. `colour_models`: a folder with one subfolder per object
    /// (`synthgen model align` writes one, in the dataset's frame) whose meshes give the
    /// colours compared with the image instead of the dataset's models (a dataset whose models
    /// carry no texture, as YCB-Video's own); objects without a subfolder keep their dataset
    /// model's colours. The contour is always the dataset model's.
    pub fn load(
        ds: &dyn FrameSource,
        ids: &std::collections::BTreeSet<u32>,
        opts: &EdgeRefineOptions,
        colour_models: Option<&Path>,
    ) -> Result<Refiner> {
        let models = load_render_models(ds, ids.iter().copied())
            .with_context(|| format!("cannot load the object models of {}", ds.root().display()))?;
        let tris: BTreeMap<u32, Vec<[DVec3; 3]>> = models
            .iter()
            .map(|(id, m)| (*id, m.triangles_m()))
            .collect();
        let points: BTreeMap<u32, Vec<DVec3>> = tris
            .iter()
            .map(|(id, t)| (*id, box_points(t, 500)))
            .collect();
        // With colours to compare: each object's coloured model (`colour_models`' mesh, else
        // the dataset's own model, which carries the colours; the eval models may not), None
        // when it has no colours to compare.
        let mut colours_from_folder = Vec::new();
        let surfaces: BTreeMap<u32, ColouredSurface> = if opts.reads_model_colours() {
            let replaced: BTreeMap<u32, PathBuf> = match colour_models {
                Some(dir) => {
                    let (meshes, _) = crate::models::replacement_meshes(
                        ds,
                        dir,
                        ids.iter().copied(),
                        "--refine-models",
                    )?;
                    ids.iter()
                        .zip(meshes)
                        .filter_map(|(id, m)| Some((*id, m?)))
                        .collect()
                }
                None => BTreeMap::new(),
            };
            colours_from_folder = replaced.keys().copied().collect();
            // Without `models_eval/` the models above are the dataset's own: not loaded twice.
            let own_models_loaded = eval_model_paths(ds).0 == ds.models_info_path();
            let mut surfaces = BTreeMap::new();
            for &id in ids {
                let loaded = match replaced.get(&id) {
                    Some(path) => synthgen_assets::load_model(
                        path,
                        synthgen_assets::Units::Auto,
                        &synthgen_core::NoProgress,
                    )
                    .map(|l| Some(l.model))
                    .with_context(|| format!("cannot load {}", path.display())),
                    None if own_models_loaded => Ok(None),
                    None => ds
                        .load_model(id, &synthgen_core::NoProgress)
                        .map(Some)
                        .map_err(anyhow::Error::from),
                }
                .with_context(|| {
                    format!(
                        "cannot load the coloured object models of {}",
                        ds.root().display()
                    )
                })?;
                let model = match &loaded {
                    Some(m) => m,
                    None => match models.iter().find(|(i, _)| *i == id) {
                        Some((_, m)) => m,
                        None => continue,
                    },
                };
                if let Some(s) = ColouredSurface::from_model(model) {
                    surfaces.insert(id, s);
                }
            }
            surfaces
        } else {
            BTreeMap::new()
        };
        // With a view search: each object's contours from every viewpoint, once.
        let templates: BTreeMap<u32, ViewTemplates> = if opts.view_search.is_some() {
            tris.par_iter()
                .map(|(id, t)| (*id, ViewTemplates::new(t, opts)))
                .collect()
        } else {
            BTreeMap::new()
        };
        Ok(Refiner {
            opts: opts.clone(),
            tris,
            points,
            surfaces,
            templates,
            colours_from_folder,
        })
    }

    /// `pose` of object `obj_id` refined on `img` (camera `k`); `boxes`: the visible boxes
    /// of the object's instances in the image (`[x, y, w, h]`), of which the one nearest the
    /// estimate bounds what of it shows. None when the object has no model here, or its model
    /// at `pose` is behind the camera or off the image.
    pub fn refine_pose(
        &self,
        img: &RgbImage,
        k: &Intrinsics,
        obj_id: u32,
        pose: &Pose,
        boxes: &[[f64; 4]],
    ) -> Option<Refined> {
        let opts = &self.opts;
        let visible = nearest_box(boxes, pose, k).and_then(|b| VisibleBox::from_xywh(b, opts));
        let (t, p) = (self.tris.get(&obj_id)?, self.points.get(&obj_id)?);
        let rect = region(p, pose, k)?;
        let field =
            EdgeField::new(&img.rgb, img.width, img.height, rect, opts).with_visible_box(visible);
        let appearance = self.surfaces.get(&obj_id).map(|surface| Appearance {
            rgb: &img.rgb,
            width: img.width,
            height: img.height,
            surface,
        });
        let a = appearance.as_ref();
        let r = match self.templates.get(&obj_id) {
            Some(views) => refine_with_views(&field, t, views, pose, k, opts, a),
            None => refine(&field, t, &[*pose], k, opts, a),
        }?;
        Some(Refined {
            pose: r.pose,
            initial_cost: r.initial_cost,
            cost: r.cost,
            accepted: r.accepted,
            boxed: visible.is_some(),
        })
    }
}

/// `estimates` refined on the RGB images of `split` (each estimate's own image; the others
/// kept), in the same order; the time each took is added to its `time_s` when known.
/// `colour_models`: see [`Refiner::load`]. `boxes`: what of each instance shows, when the
/// refinement should keep to it ([`BoxSource`]).
pub fn refine_estimates(
    ds: &dyn FrameSource,
    split: &str,
    estimates: &[Estimate],
    opts: &EdgeRefineOptions,
    colour_models: Option<&Path>,
    boxes: BoxSource<'_>,
    progress: &dyn Progress,
) -> Result<(Vec<Estimate>, RefineSummary)> {
    let started = Instant::now();
    let frames = ds.frames(&[split.to_string()])?;
    let by_frame: BTreeMap<(u32, u32), _> = frames
        .iter()
        .map(|f| ((f.location.scene_id, f.location.im_id), f))
        .collect();
    let ids: std::collections::BTreeSet<u32> = estimates.iter().map(|e| e.obj_id).collect();
    let refiner = Refiner::load(ds, &ids, opts, colour_models)?;
    let mut groups: BTreeMap<(u32, u32), Vec<usize>> = BTreeMap::new();
    for (i, e) in estimates.iter().enumerate() {
        groups.entry((e.scene_id, e.im_id)).or_default().push(i);
    }
    progress.start("refining on the RGB images", estimates.len() as u64);
    let groups: Vec<_> = groups.into_iter().collect();
    type Done = (usize, Option<(Estimate, f64, f64, bool, bool)>);
    let done: Vec<Vec<Done>> = groups
        .par_iter()
        .map(|(frame, idx)| -> Result<_> {
            let Some(f) = by_frame.get(frame) else {
                progress.advance(idx.len() as u64);
                return Ok(idx.iter().map(|&i| (i, None)).collect());
            };
            let img = read_rgb(&f.rgb)?;
            let k = f.camera.intrinsics(img.width, img.height);
            // With boxes: the frame's visible boxes (GT, or detected) of each estimated object.
            let mut frame_boxes: BTreeMap<u32, Vec<[f64; 4]>> = BTreeMap::new();
            for &i in idx {
                let obj = estimates[i].obj_id;
                if frame_boxes.contains_key(&obj) {
                    continue;
                }
                let found = match boxes {
                    BoxSource::None => continue,
                    BoxSource::Gt => gt_boxes(f, obj)?,
                    BoxSource::Detected(d) => {
                        d.get(&(frame.0, frame.1, obj)).cloned().unwrap_or_default()
                    }
                };
                frame_boxes.insert(obj, found);
            }
            let mut out = Vec::with_capacity(idx.len());
            for &i in idx {
                let e = &estimates[i];
                let t0 = Instant::now();
                let b = frame_boxes.get(&e.obj_id).map_or(&[][..], |b| b.as_slice());
                let refined = refiner.refine_pose(&img, &k, e.obj_id, &e.pose, b);
                out.push((
                    i,
                    refined.map(|r| {
                        let mut new = *e;
                        new.pose = r.pose;
                        new.stored = RawPose::from_pose(&r.pose);
                        if new.time_s >= 0.0 {
                            new.time_s += t0.elapsed().as_secs_f64();
                        }
                        (new, r.initial_cost, r.cost, r.accepted, r.boxed)
                    }),
                ));
                progress.advance(1);
            }
            Ok(out)
        })
        .collect::<Result<_>>()?;
    progress.finish();
    let mut out = estimates.to_vec();
    let mut summary = RefineSummary {
        estimates: estimates.len(),
        colours_from_folder: refiner.colours_from_folder.clone(),
        ..Default::default()
    };
    for (i, r) in done.into_iter().flatten() {
        if let Some((e, before, after, accepted, boxed)) = r {
            summary.with_box += usize::from(boxed);
            out[i] = e;
            summary.refined += 1;
            summary.refused += usize::from(!accepted);
            summary.mean_cost_before_px += before;
            summary.mean_cost_after_px += after;
        }
    }
    if summary.refined > 0 {
        summary.mean_cost_before_px /= summary.refined as f64;
        summary.mean_cost_after_px /= summary.refined as f64;
    }
    summary.seconds = started.elapsed().as_secs_f64();
    Ok((out, summary))
}

#[cfg(test)]
mod tests {
    use synthgen_core::annotate::GtInfo;
    use synthgen_core::glam::DMat3;
    use synthgen_core::Intrinsics;
    use synthgen_formats::bop::image::{encode_gray8_png, PngCompression};
    use synthgen_formats::bop::{GtEntry, SceneCamera};
    use synthgen_formats::source::{FrameLocation, MaskRef};

    use super::*;

    /// A 32 x 24 frame of object 3 (twice) and object 5; the first visible mask covers
    /// pixels 10..=14 x 20..=23, the others nothing.
    fn frame(dir: &Path, gt_info: Option<Vec<GtInfo>>) -> SourceFrame {
        let (w, h) = (32u32, 24u32);
        let mut m = vec![0u8; (w * h) as usize];
        for y in 20..24 {
            for x in 10..15 {
                m[(y * w + x) as usize] = 255;
            }
        }
        let path = dir.join("000000_000000.png");
        std::fs::write(
            &path,
            encode_gray8_png(&m, w, h, PngCompression::Fast, &path).unwrap(),
        )
        .unwrap();
        let empty = dir.join("empty.png");
        let none = vec![0u8; (w * h) as usize];
        std::fs::write(
            &empty,
            encode_gray8_png(&none, w, h, PngCompression::Fast, &empty).unwrap(),
        )
        .unwrap();
        let pose = Pose::new(DMat3::IDENTITY, DVec3::new(0.0, 0.0, 0.5));
        let k = Intrinsics {
            width: w,
            height: h,
            fx: 100.0,
            fy: 100.0,
            cx: 15.5,
            cy: 11.5,
        };
        SourceFrame {
            location: FrameLocation {
                split: "test".into(),
                scene_id: 0,
                im_id: 0,
            },
            camera: SceneCamera::without_world(k.k_row_major(), 1.0),
            gt: vec![
                GtEntry::new(3, &pose),
                GtEntry::new(5, &pose),
                GtEntry::new(3, &pose),
            ],
            gt_info,
            rgb: dir.join("rgb.png"),
            depth: None,
            masks: vec![None; 3],
            masks_visib: vec![
                Some(MaskRef::File(path)),
                Some(MaskRef::File(empty.clone())),
                Some(MaskRef::File(empty)),
            ],
        }
    }

    #[test]
    fn gt_boxes_are_bops_from_the_info_or_the_mask() {
        let dir = tempfile::tempdir().unwrap();
        // bop_toolkit's calc_2d_bbox: w = x_max - x_min.
        let want = vec![[10.0, 20.0, 4.0, 3.0]];
        // From the visible masks alone: the empty one gives no box.
        let from_masks = frame(dir.path(), None);
        assert_eq!(gt_boxes(&from_masks, 3).unwrap(), want);
        assert!(gt_boxes(&from_masks, 5).unwrap().is_empty());
        // scene_gt_info's bbox_visib as written (-1 where nothing shows) says the same.
        let info = |bbox_visib| GtInfo {
            bbox_obj: bbox_visib,
            bbox_visib,
            px_count_all: 20,
            px_count_valid: 20,
            px_count_visib: 20,
            visib_fract: 1.0,
        };
        let mut from_info = frame(dir.path(), None);
        from_info.gt_info = Some(vec![info([10, 20, 4, 3]), info([-1; 4]), info([-1; 4])]);
        from_info.masks_visib = vec![None; 3];
        assert_eq!(gt_boxes(&from_info, 3).unwrap(), want);
        assert!(gt_boxes(&from_info, 5).unwrap().is_empty());
        // And the box the refinement keeps to ends on the mask's last pixel (+ the margin).
        let opts = EdgeRefineOptions::default();
        let b = VisibleBox::from_xywh(want[0], &opts).unwrap();
        let m = opts.box_margin_px;
        assert_eq!(
            (b.lo.x, b.lo.y, b.hi.x, b.hi.y),
            (10.0 - m, 20.0 - m, 14.0 + m, 23.0 + m)
        );
    }
}
