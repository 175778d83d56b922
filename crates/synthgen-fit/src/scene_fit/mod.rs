//! A scene spec derived from real annotated frames (`synthgen scene fit`): per frame the table
//! plane from the real depth ([`plane`], RANSAC), the camera's elevation, distance and roll
//! relative to it and each object's up axis and tilt ([`frame`]); over the frames the ranges
//! of a [`SceneSpec`] that [`spec_text`] writes as a commented TOML. Method and numbers:
//! docs/scenes.md, "Fitting a scene to real frames".

pub mod frame;
pub mod plane;
pub mod spec_text;

use std::collections::BTreeMap;
use std::path::PathBuf;

use rayon::prelude::*;
use serde::Serialize;
use synthgen_core::glam::DVec3;
use synthgen_core::rest::UpAxis;
use synthgen_core::scene::{CameraPoseSpec, CameraSpec, ObjectSpec, PlacementSpec};
use synthgen_core::{Intrinsics, Model, PoseRenderer, Progress, SceneSpec};

pub use frame::{FrameFit, ObjectObservation};
pub use plane::{Plane, PlaneFit, RansacOptions};

use synthgen_formats::source::{FrameLocation, FrameSource, SourceFrame};
use synthgen_formats::{Error, Result};

/// Angle ranges are the observed range widened by this on each side, degrees.
pub const ANGLE_MARGIN_DEG: f64 = 3.0;
/// Length ranges are the observed range widened by this share on each side.
pub const LENGTH_MARGIN: f64 = 0.1;
/// The placement area is never smaller than this per side, metres.
pub const MIN_AREA_M: f64 = 0.05;

/// How to fit.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneFitOptions {
    /// Only these scene ids (all when empty).
    pub scenes: Vec<u32>,
    pub ransac: RansacOptions,
    /// Depth points per frame for the plane, about (a regular pixel grid).
    pub max_points: usize,
    /// The objects' visible masks are grown by this many pixels before their points are left
    /// out of the plane fit.
    pub mask_margin_px: u32,
}

impl Default for SceneFitOptions {
    fn default() -> Self {
        SceneFitOptions {
            scenes: Vec::new(),
            ransac: RansacOptions::default(),
            max_points: 20_000,
            mask_margin_px: 3,
        }
    }
}

/// Minimum, maximum, mean and median of observed values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Observed {
    pub min: f64,
    pub max: f64,
    pub mean: f64,
    pub median: f64,
    pub count: usize,
}

impl Observed {
    /// None when there are no values.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<Observed> {
        let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        Some(Observed {
            min: v[0],
            max: v[n - 1],
            mean: v.iter().sum::<f64>() / n as f64,
            median,
            count: n,
        })
    }
}

/// A frame that was left out, and why.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SkippedFrame {
    pub location: FrameLocation,
    pub reason: String,
    /// The median ratio of its depth readings on the objects to their depth at the GT poses,
    /// when that is why it was left out.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub depth_ratio: Option<f64>,
}

/// The camera the frames were taken with.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FittedCamera {
    /// The most common intrinsics.
    pub intrinsics: Intrinsics,
    /// Frames with exactly these.
    pub frames: usize,
    /// Other intrinsics (row-major K) and how many frames have each.
    pub others: Vec<([f64; 9], usize)>,
}

/// One object, over the frames it is annotated in.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FittedObject {
    pub obj_id: u32,
    /// The model file's stem, or its folder when several objects share a stem (YCB-Video).
    pub name: String,
    pub model: PathBuf,
    pub units: String,
    /// Frames (of those used) the object is annotated in.
    pub frames: usize,
    /// Most instances of it in one frame (the spec's `count`).
    pub count: u32,
    /// The model axis along the table's normal in most frames, and in how many.
    pub up: UpAxis,
    pub up_frames: usize,
    /// The angle between that axis and the normal, over those frames, degrees.
    pub tilt_deg: Observed,
    /// What the spec gets: the largest observed tilt rounded up to a degree, 0 under 0.05°
    /// (`tilt_deg` is a maximum there).
    pub spec_tilt_deg: f64,
    /// Height of the model origin above the table, metres.
    pub centre_height_m: Observed,
    /// Height of the model's lowest point above the table, metres (about 0: it stands on it).
    pub lowest_point_m: Option<Observed>,
    pub visib_fract: Option<Observed>,
}

impl FittedObject {
    /// Whether its lowest point is mostly more than [`OFF_TABLE_M`] above the table (it
    /// rests on another object, or its GT is off).
    pub fn off_table(&self) -> bool {
        self.lowest_point_m.is_some_and(|l| l.median > OFF_TABLE_M)
    }
}

/// An object whose lowest point is this far above the table does not stand on it, metres.
pub const OFF_TABLE_M: f64 = 0.02;

/// How hidden the annotated objects are.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Occlusion {
    /// `scene_gt_info` or `visible masks / rendered silhouettes`.
    pub source: String,
    pub visib_fract: Observed,
    /// Share of instances with `visib_fract` < 0.5.
    pub share_below_half: f64,
}

/// Everything `fit_scene` derived, the spec included.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SceneFit {
    pub data: PathBuf,
    pub scenes: Vec<u32>,
    /// Frames with GT in the chosen scenes, and those measured.
    pub frames_total: usize,
    pub frames_used: usize,
    pub frames_skipped: Vec<SkippedFrame>,
    /// Frames used without every visible mask (their plane points include the objects').
    pub frames_without_masks: usize,
    /// Frames without depth whose table plane came from the objects' GT poses.
    pub frames_plane_from_poses: usize,
    pub camera: FittedCamera,
    pub elevation_deg: Observed,
    pub distance_m: Observed,
    pub centre_distance_m: Observed,
    pub look_at_offset_m: Observed,
    pub camera_height_m: Observed,
    pub roll_deg: Observed,
    pub plane_rms_mm: Observed,
    pub plane_inlier_share: Observed,
    /// The mean table normal in camera coordinates.
    pub normal_cam_mean: [f64; 3],
    pub objects_per_frame: Observed,
    /// Largest extents of the object centres on the table over the frames (larger first).
    pub extent_m: [f64; 2],
    pub objects: Vec<FittedObject>,
    pub occlusion: Option<Occlusion>,
    /// Instances whose lowest point is more than [`OFF_TABLE_M`] above the table (resting on
    /// another object), of those with a lowest point: the spec's `placement.stack_prob`.
    pub off_table: [usize; 2],
    /// The derived spec: [camera], [camera_pose], [placement] and [[objects]] (absolute model
    /// paths); every other section at its default.
    pub spec: SceneSpec,
    pub frames: Vec<FrameFit>,
}

/// The frames of `source` to fit to: those with GT in `scenes` (all when empty), with or
/// without depth.
pub fn select_frames(source: &dyn FrameSource, scenes: &[u32]) -> Result<Vec<SourceFrame>> {
    crate::sensor::select_frames_for(
        source,
        scenes,
        "fitting a scene needs objects at known poses",
        // Without depth the table plane comes from the objects' poses (frame.rs).
        None,
    )
}

/// Fits a scene to `frames` of `source` (from [`select_frames`]). `models` (metres, by
/// obj_id) give each object's lowest point above the table, a check that it stands on it;
/// `renderer` renders the objects at their GT poses: the check that the depth agrees with
/// them (its scale) and the visible fraction of frames without `scene_gt_info` (neither
/// without one). One `progress` step per frame. Frames without a table plane or whose depth
/// disagrees with the GT are skipped (listed); an error when none is left.
pub fn fit_scene(
    source: &dyn FrameSource,
    frames: &[SourceFrame],
    models: &BTreeMap<u32, Model>,
    renderer: Option<&dyn PoseRenderer>,
    options: &SceneFitOptions,
    progress: &dyn Progress,
) -> Result<SceneFit> {
    let cam = source.camera();
    let support: BTreeMap<u32, Vec<DVec3>> = models
        .iter()
        .map(|(&id, m)| {
            let pts = m
                .support_points(synthgen_core::SceneObject::SUPPORT_POINTS)
                .into_iter()
                .map(|p| p.as_dvec3())
                .collect();
            (id, pts)
        })
        .collect();
    let ctx = frame::FrameContext {
        width: cam.width,
        height: cam.height,
        support: &support,
        renderer,
        ransac: options.ransac,
        max_points: options.max_points,
        mask_margin_px: options.mask_margin_px,
    };
    let measured: Vec<std::result::Result<FrameFit, frame::Skip>> = frames
        .par_iter()
        .map(|f| {
            let r = frame::measure_frame(&ctx, f);
            progress.advance(1);
            r
        })
        .collect::<Result<_>>()?;
    let mut used = Vec::new();
    let mut used_frames: Vec<&SourceFrame> = Vec::new();
    let mut skipped = Vec::new();
    for (f, r) in frames.iter().zip(measured) {
        match r {
            Ok(fit) => {
                used.push(fit);
                used_frames.push(f);
            }
            Err(skip) => skipped.push(SkippedFrame {
                location: f.location.clone(),
                reason: skip.reason,
                depth_ratio: skip.depth_ratio,
            }),
        }
    }
    let ratios: Vec<f64> = skipped.iter().filter_map(|s| s.depth_ratio).collect();
    if used.is_empty() && !ratios.is_empty() {
        let mut sorted = ratios.clone();
        sorted.sort_by(f64::total_cmp);
        return Err(Error::InvalidRequest(format!(
            "the depth disagrees with the GT poses in {} of the {} frames of {}: the readings on the objects are {:.3} times their depth rendered at the GT poses (median over those frames; accepted {:.1} to {:.1}); check the depth scale (BOP: depth_scale in scene_camera.json; YCB-Video: factor_depth in -meta.mat)",
            ratios.len(),
            frames.len(),
            source.root().display(),
            sorted[sorted.len() / 2],
            1.0 - frame::MAX_DEPTH_RATIO_ERROR,
            1.0 + frame::MAX_DEPTH_RATIO_ERROR
        )));
    }
    if used.is_empty() {
        return Err(Error::InvalidRequest(format!(
            "no table plane found in any of the {} frames of {} (first: {}/{:06} image {}: {})",
            frames.len(),
            source.root().display(),
            skipped[0].location.split,
            skipped[0].location.scene_id,
            skipped[0].location.im_id,
            skipped[0].reason
        )));
    }
    let camera = fitted_camera(&used_frames, cam.width, cam.height);
    let objects = fitted_objects(source, &used)?;
    summarize(
        source,
        options,
        frames.len(),
        used,
        skipped,
        camera,
        objects,
    )
}

/// Rounds `v` down (`up` false) or up to a multiple of `step`.
fn round_to(v: f64, step: f64, up: bool) -> f64 {
    let q = v / step;
    // Products like 0.1 * 361 are not exact: snap values within 1e-9 of a step first.
    let q = if (q - q.round()).abs() < 1e-9 {
        q.round()
    } else if up {
        q.ceil()
    } else {
        q.floor()
    };
    // The shortest decimal of the multiple (36.1, not 36.1000000000000014).
    format!("{:.6}", q * step).parse().unwrap_or(q * step)
}

fn angle_range(o: &Observed, lo_limit: f64, hi_limit: f64) -> [f64; 2] {
    [
        round_to((o.min - ANGLE_MARGIN_DEG).max(lo_limit), 0.1, false),
        round_to((o.max + ANGLE_MARGIN_DEG).min(hi_limit), 0.1, true),
    ]
}

fn length_range(o: &Observed) -> [f64; 2] {
    [
        round_to(o.min * (1.0 - LENGTH_MARGIN), 0.001, false).max(0.001),
        round_to(o.max * (1.0 + LENGTH_MARGIN), 0.001, true),
    ]
}

fn summarize(
    source: &dyn FrameSource,
    options: &SceneFitOptions,
    frames_total: usize,
    used: Vec<FrameFit>,
    skipped: Vec<SkippedFrame>,
    camera: FittedCamera,
    objects: Vec<FittedObject>,
) -> Result<SceneFit> {
    let obs = |f: &dyn Fn(&FrameFit) -> f64| {
        Observed::of(used.iter().map(f)).ok_or_else(|| {
            Error::InvalidRequest("no finite measurement in the frames (please report this)".into())
        })
    };
    let elevation_deg = obs(&|f| f.elevation_deg)?;
    let distance_m = obs(&|f| f.distance_m)?;
    let centre_distance_m = obs(&|f| f.centre_distance_m)?;
    let look_at_offset_m = obs(&|f| f.look_at_offset_m)?;
    let camera_height_m = obs(&|f| f.camera_height_m)?;
    let roll_deg = obs(&|f| f.roll_deg)?;
    let plane_rms_mm = obs(&|f| f.plane_rms_mm)?;
    let plane_inlier_share = obs(&|f| f.plane_inlier_share)?;
    let objects_per_frame = obs(&|f| f.objects.len() as f64)?;
    let normal_sum: DVec3 = used.iter().map(|f| DVec3::from_array(f.normal_cam)).sum();
    let normal_cam_mean = normal_sum.normalize_or_zero().to_array();
    let extent_m = used.iter().fold([0.0f64; 2], |[a, b], f| {
        [a.max(f.extent_m[0]), b.max(f.extent_m[1])]
    });

    let visib: Vec<f64> = used
        .iter()
        .flat_map(|f| f.objects.iter().filter_map(|o| o.visib_fract))
        .collect();
    let instances: usize = used.iter().map(|f| f.objects.len()).sum();
    let occlusion = Observed::of(visib.iter().copied())
        .filter(|_| visib.len() == instances)
        .map(|v| Occlusion {
            source: {
                let mut kinds: Vec<&str> = used
                    .iter()
                    .filter_map(|f| f.visib_source.as_deref())
                    .collect();
                kinds.sort_unstable();
                kinds.dedup();
                kinds.join(" and ")
            },
            visib_fract: v,
            share_below_half: visib.iter().filter(|&&x| x < 0.5).count() as f64
                / visib.len() as f64,
        });

    let lowest: Vec<f64> = used
        .iter()
        .flat_map(|f| f.objects.iter().filter_map(|o| o.lowest_point_m))
        .collect();
    let off_table = [
        lowest.iter().filter(|&&l| l > OFF_TABLE_M).count(),
        lowest.len(),
    ];
    let stack_prob = if off_table[1] == 0 {
        0.0
    } else {
        round_to(off_table[0] as f64 / off_table[1] as f64, 0.01, false)
    };

    let k = camera.intrinsics;
    let area = |e: f64| round_to((e * (1.0 + LENGTH_MARGIN)).max(MIN_AREA_M), 0.01, true);
    let spec = SceneSpec {
        camera: CameraSpec {
            width: Some(k.width),
            height: Some(k.height),
            fx: Some(k.fx),
            fy: Some(k.fy),
            cx: Some(k.cx),
            cy: Some(k.cy),
            ..CameraSpec::default()
        },
        camera_pose: CameraPoseSpec {
            distance_m: length_range(&distance_m),
            elevation_deg: angle_range(&elevation_deg, -90.0, 90.0),
            azimuth_deg: [0.0, 360.0],
            look_at_jitter_m: round_to(look_at_offset_m.max * (1.0 + LENGTH_MARGIN), 0.001, true),
            inplane_deg: angle_range(&roll_deg, -180.0, 180.0),
        },
        placement: PlacementSpec {
            area_m: [area(extent_m[0]), area(extent_m[1])],
            objects_per_frame: Some([objects_per_frame.min as u32, objects_per_frame.max as u32]),
            stack_prob,
            ..PlacementSpec::default()
        },
        objects: objects
            .iter()
            .map(|o| ObjectSpec {
                obj_id: Some(o.obj_id),
                units: Some(o.units.clone()),
                count: o.count,
                up: o.up,
                tilt_deg: o.spec_tilt_deg,
                ..ObjectSpec::new(o.model.clone())
            })
            .collect(),
        ..SceneSpec::default()
    };
    spec.validate()
        .map_err(|e| Error::InvalidRequest(format!("the fitted scene is invalid: {e}")))?;
    let frames_without_masks = used
        .iter()
        .filter(|f| !f.masked && f.plane_from == frame::PlaneSource::Depth)
        .count();
    let frames_plane_from_poses = used
        .iter()
        .filter(|f| f.plane_from == frame::PlaneSource::ObjectPoses)
        .count();
    Ok(SceneFit {
        data: source.root().to_path_buf(),
        scenes: options.scenes.clone(),
        frames_total,
        frames_used: used.len(),
        frames_skipped: skipped,
        frames_without_masks,
        frames_plane_from_poses,
        camera,
        elevation_deg,
        distance_m,
        centre_distance_m,
        look_at_offset_m,
        camera_height_m,
        roll_deg,
        plane_rms_mm,
        plane_inlier_share,
        normal_cam_mean,
        objects_per_frame,
        extent_m,
        objects,
        occlusion,
        off_table,
        spec,
        frames: used,
    })
}

/// The most common `cam_K` among the frames.
fn fitted_camera(frames: &[&SourceFrame], width: u32, height: u32) -> FittedCamera {
    let mut counts: Vec<([f64; 9], usize)> = Vec::new();
    for f in frames {
        match counts.iter_mut().find(|(k, _)| *k == f.camera.cam_k) {
            Some((_, c)) => *c += 1,
            None => counts.push((f.camera.cam_k, 1)),
        }
    }
    // Most frames first; ties in order of appearance (frames are sorted by location).
    counts.sort_by_key(|c| std::cmp::Reverse(c.1));
    let (k, n) = counts.remove(0);
    FittedCamera {
        intrinsics: Intrinsics::from_k(&k, width, height),
        frames: n,
        others: counts,
    }
}

/// Per object: its model, the up axis of most frames, tilt and heights over them.
fn fitted_objects(source: &dyn FrameSource, used: &[FrameFit]) -> Result<Vec<FittedObject>> {
    let mut by_id: BTreeMap<u32, Vec<&ObjectObservation>> = BTreeMap::new();
    let mut count: BTreeMap<u32, u32> = BTreeMap::new();
    for f in used {
        let mut here: BTreeMap<u32, u32> = BTreeMap::new();
        for o in &f.objects {
            by_id.entry(o.obj_id).or_default().push(o);
            *here.entry(o.obj_id).or_default() += 1;
        }
        for (id, n) in here {
            let c = count.entry(id).or_default();
            *c = (*c).max(n);
        }
    }
    let mut out = Vec::with_capacity(by_id.len());
    for (&obj_id, obs) in &by_id {
        let model = source
            .model_path(obj_id)
            .ok_or_else(|| Error::MissingFile {
                path: source.model_file(obj_id),
            })?;
        let mut votes: BTreeMap<UpAxis, usize> = BTreeMap::new();
        for o in obs {
            *votes.entry(o.up).or_default() += 1;
        }
        // Most frames; ties go to the first axis in UpAxis order.
        let (up, up_frames) =
            votes.iter().fold(
                (UpAxis::PlusZ, 0),
                |best, (&a, &n)| if n > best.1 { (a, n) } else { best },
            );
        let with_up: Vec<&&ObjectObservation> = obs.iter().filter(|o| o.up == up).collect();
        let tilt_deg = Observed::of(with_up.iter().map(|o| o.tilt_deg)).ok_or_else(|| {
            Error::InvalidRequest(format!(
                "object {obj_id}: no finite tilt (please report this)"
            ))
        })?;
        let centre_height_m =
            Observed::of(obs.iter().map(|o| o.centre_height_m)).ok_or_else(|| {
                Error::InvalidRequest(format!(
                    "object {obj_id}: no finite height (please report this)"
                ))
            })?;
        let lowest: Vec<f64> = obs.iter().filter_map(|o| o.lowest_point_m).collect();
        let visib: Vec<f64> = obs.iter().filter_map(|o| o.visib_fract).collect();
        out.push(FittedObject {
            obj_id,
            name: String::new(),
            model,
            units: source.model_units().to_string(),
            frames: used
                .iter()
                .filter(|f| f.objects.iter().any(|o| o.obj_id == obj_id))
                .count(),
            count: count.get(&obj_id).copied().unwrap_or(1),
            up,
            up_frames,
            // Rounding noise (1e-6°) is no tilt.
            spec_tilt_deg: round_to((tilt_deg.max - 0.05).max(0.0), 1.0, true).min(90.0),
            tilt_deg,
            centre_height_m,
            lowest_point_m: Observed::of(lowest),
            visib_fract: Observed::of(visib),
        });
    }
    name_objects(&mut out);
    Ok(out)
}

/// Each object's model file stem, or its folder where stems repeat (YCB-Video's
/// `<class>/textured_simple.obj`).
fn name_objects(objects: &mut [FittedObject]) {
    let stem = |o: &FittedObject| {
        o.model
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    };
    let stems: Vec<String> = objects.iter().map(stem).collect();
    for (i, o) in objects.iter_mut().enumerate() {
        let shared = stems.iter().filter(|s| **s == stems[i]).count() > 1;
        let folder = o
            .model
            .parent()
            .and_then(|p| p.file_name())
            .map(|f| f.to_string_lossy().into_owned());
        o.name = match (shared, folder) {
            (true, Some(f)) => f,
            _ => stems[i].clone(),
        };
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn rounding_outwards_and_ranges() {
        assert_eq!(round_to(36.12, 0.1, false), 36.1);
        assert_eq!(round_to(36.12, 0.1, true), 36.2);
        assert_eq!(round_to(36.1, 0.1, true), 36.1);
        assert_eq!(round_to(0.5234, 0.001, true), 0.524);
        let o = Observed::of([35.1, 38.2, 36.0]).unwrap();
        assert_eq!(o.median, 36.0);
        assert_eq!(angle_range(&o, -90.0, 90.0), [32.1, 41.2]);
        let d = Observed::of([0.5, 1.0]).unwrap();
        assert_eq!(length_range(&d), [0.45, 1.1]);
        assert!(Observed::of([f64::NAN]).is_none());
    }
}
