//! One frame's measurements: its table plane from the real depth (or, without depth, from the
//! objects' GT poses), the camera's elevation,
//! distance and roll relative to it, and each object's up axis, tilt and height.

use std::collections::BTreeMap;

use serde::Serialize;
use synthgen_core::glam::DVec3;
use synthgen_core::rest::UpAxis;
use synthgen_core::rng::splitmix64;
use synthgen_core::{Intrinsics, Pose, PoseRenderer};

use super::plane::{plane_from_poses, ransac_plane, Plane, PlaneFit, RansacOptions};
use synthgen_formats::annotate::complete_annotations;
use synthgen_formats::bop::image::read_depth_m;
use synthgen_formats::source::{FrameLocation, SourceFrame};
use synthgen_formats::{Error, Result};

/// What was measured of one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameFit {
    pub location: FrameLocation,
    /// The table's unit normal in camera coordinates (OpenCV), pointing up (towards the
    /// camera's side).
    pub normal_cam: [f64; 3],
    /// The camera's height above the table, metres.
    pub camera_height_m: f64,
    /// Depth points sampled for the plane (outside the objects' visible masks) and the share
    /// within the inlier band of the fitted plane.
    pub plane_points: usize,
    pub plane_inlier_share: f64,
    /// RMS distance of the inliers from the plane, millimetres.
    pub plane_rms_mm: f64,
    /// Angle between the optical axis and the table, degrees (synthgen's
    /// `camera_pose.elevation_deg`).
    pub elevation_deg: f64,
    /// From the camera along the optical axis to where it passes the height of the objects'
    /// mean centre: the sampler's look-at point, so synthgen's `camera_pose.distance_m`.
    pub distance_m: f64,
    /// From the camera to the objects' mean centre, metres.
    pub centre_distance_m: f64,
    /// From the objects' mean centre to that look-at point (horizontal), metres: synthgen's
    /// `look_at_jitter_m` offset.
    pub look_at_offset_m: f64,
    /// Rotation about the optical axis, degrees: 0 when the table's up direction points up in
    /// the image (synthgen's `camera_pose.inplane_deg`).
    pub roll_deg: f64,
    /// Extent of the object centres on the table along their principal axes (larger first),
    /// metres.
    pub extent_m: [f64; 2],
    /// Whether the objects' visible masks were left out of the plane's points.
    pub masked: bool,
    /// Where the table plane came from: the depth, or (a frame without depth) the objects'
    /// lowest points at their GT poses; then `plane_points` and `plane_inlier_share` count
    /// objects.
    pub plane_from: PlaneSource,
    /// Where the objects' `visib_fract` came from (`scene_gt_info`, or `visible masks /
    /// rendered silhouettes`); None when unknown.
    pub visib_source: Option<String>,
    pub objects: Vec<ObjectObservation>,
}

/// One annotated instance in one frame.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObjectObservation {
    pub obj_id: u32,
    /// The model axis closest to the table's normal.
    pub up: UpAxis,
    /// The angle between that axis and the normal, degrees.
    pub tilt_deg: f64,
    /// Height of the model origin above the table, metres.
    pub centre_height_m: f64,
    /// Height of the model's lowest extreme point above the table, metres (about 0 when the
    /// object stands on it); None without the model.
    pub lowest_point_m: Option<f64>,
    /// BOP `visib_fract`, when known.
    pub visib_fract: Option<f64>,
}

/// The inputs every frame shares.
pub(crate) struct FrameContext<'a> {
    pub width: u32,
    pub height: u32,
    /// Extreme points of each model (model frame, metres), by obj_id.
    pub support: &'a BTreeMap<u32, Vec<DVec3>>,
    pub renderer: Option<&'a dyn PoseRenderer>,
    pub ransac: RansacOptions,
    pub max_points: usize,
    pub mask_margin_px: u32,
}

/// Object centres must lie between this far below a candidate plane ...
const CENTRE_BELOW_M: f64 = 0.03;
/// ... and this far above it, for the candidate to count as their support.
const CENTRE_ABOVE_M: f64 = 0.5;

/// Why a frame is left out of the fit.
pub(crate) struct Skip {
    pub reason: String,
    /// The median ratio of the depth readings on the objects to their depth rendered at the
    /// GT poses, when that is what disagreed.
    pub depth_ratio: Option<f64>,
}

impl From<String> for Skip {
    fn from(reason: String) -> Skip {
        Skip {
            reason,
            depth_ratio: None,
        }
    }
}

/// Depth readings on the objects over their depth rendered at the GT poses (median) must lie
/// within this of 1: a misread depth scale is off by a factor of 10 (YCB-Video's
/// factor_depth, BOP's depth_scale), GT poses off by millimetres by well under 1 %.
pub const MAX_DEPTH_RATIO_ERROR: f64 = 0.1;
/// With fewer object pixels that have both a reading and a rendered depth, the frame is not
/// judged (the plane fit decides).
const MIN_DEPTH_CHECK_PX: usize = 100;

/// The median of reading / rendered depth over the pixels where the GT render shows an object
/// and both are positive; `None` with too few such pixels.
fn depth_ratio(reading_m: &[f32], rendered: &synthgen_core::RenderedFrame) -> Option<f64> {
    let mut v: Vec<f32> = reading_m
        .iter()
        .zip(&rendered.depth_m)
        .zip(&rendered.instance)
        .filter(|((&d, &z), &i)| i > 0 && d > 0.0 && z > 0.0)
        .map(|((&d, &z), _)| d / z)
        .collect();
    if v.len() < MIN_DEPTH_CHECK_PX {
        return None;
    }
    let mid = v.len() / 2;
    Some(f64::from(*v.select_nth_unstable_by(mid, f32::total_cmp).1))
}

/// Measures `frame`; `Ok(Err(skip))` when it has no usable table plane or its depth disagrees
/// with its GT poses (the frame is skipped), `Err` when its files cannot be read.
pub(crate) fn measure_frame(
    ctx: &FrameContext<'_>,
    frame: &SourceFrame,
) -> Result<std::result::Result<FrameFit, Skip>> {
    let (w, h) = (ctx.width, ctx.height);
    let k = frame.camera.intrinsics(w, h);
    // Without depth (RGB-only data) the table comes from the objects' poses alone.
    let depth = match &frame.depth {
        Some(path) => Some((path, read_depth_m(path, frame.camera.depth_scale)?)),
        None => None,
    };
    if let Some((depth_path, depth)) = &depth {
        if (depth.width, depth.height) != (w, h) {
            return Err(Error::malformed(
                depth_path,
                format!(
                    "depth image is {}x{} but the camera is {w}x{h}",
                    depth.width, depth.height
                ),
            ));
        }
    }
    // The depth must agree with the GT poses, as `sensor fit` checks: a misread depth scale
    // would fit a table a tenth as far away, under the objects' centres.
    if let (Some((_, depth)), Some(renderer)) = (&depth, ctx.renderer) {
        let rendered = synthgen_formats::annotate::render_gt(renderer, frame, &k)?;
        if let Some(ratio) = depth_ratio(&depth.data, &rendered) {
            if (ratio - 1.0).abs() > MAX_DEPTH_RATIO_ERROR {
                return Ok(Err(Skip {
                    reason: format!(
                        "the depth disagrees with the GT poses: the readings on the objects are {ratio:.3} times their depth rendered at the GT poses (median; accepted {:.1} to {:.1})",
                        1.0 - MAX_DEPTH_RATIO_ERROR,
                        1.0 + MAX_DEPTH_RATIO_ERROR
                    ),
                    depth_ratio: Some(ratio),
                }));
            }
        }
    }
    let mut visib: Vec<Option<Vec<u8>>> = Vec::with_capacity(frame.gt.len());
    for m in &frame.masks_visib {
        visib.push(match m {
            Some(m) => Some(m.read_sized(w, h)?.data),
            None => None,
        });
    }
    let masked = !visib.is_empty() && visib.iter().all(Option::is_some);
    let mut objects_mask = vec![false; (w * h) as usize];
    for m in visib.iter().flatten() {
        for (o, &v) in objects_mask.iter_mut().zip(m) {
            *o |= v > 0;
        }
    }
    let objects_mask = dilate(&objects_mask, w, h, ctx.mask_margin_px);
    let poses: Vec<_> = frame.gt.iter().map(|g| g.cam_from_obj()).collect();
    let centres: Vec<DVec3> = poses.iter().map(|p| p.translation_m).collect();
    let accept = |p: &Plane| {
        centres
            .iter()
            .all(|&c| (-CENTRE_BELOW_M..=CENTRE_ABOVE_M).contains(&p.height(c)))
    };
    let (fit, plane_from) = if let Some((_, depth)) = &depth {
        let points = sample_points(&depth.data, &objects_mask, &k, ctx.max_points);
        let ransac = RansacOptions {
            seed: ctx.ransac.seed
                ^ splitmix64(
                    (u64::from(frame.location.scene_id) << 32) | u64::from(frame.location.im_id),
                ),
            ..ctx.ransac
        };
        let Some(fit) = ransac_plane(&points, &ransac, accept) else {
            return Ok(Err(Skip::from(format!(
                "no table plane under the objects: no plane within {} mm holds {:.0} % (and {}) of the {} depth points outside the objects with every object centre {:.0} cm below to {:.0} cm above it",
                ransac.inlier_band_m * 1000.0,
                ransac.min_inlier_share * 100.0,
                ransac.min_inliers,
                points.len(),
                CENTRE_BELOW_M * 100.0,
                CENTRE_ABOVE_M * 100.0
            ))));
        };
        (fit, PlaneSource::Depth)
    } else {
        // No depth: the objects' support points at their poses.
        let objects: Vec<Vec<DVec3>> = frame
            .gt
            .iter()
            .zip(&poses)
            .map(|(g, pose)| {
                ctx.support.get(&g.obj_id).map_or_else(Vec::new, |pts| {
                    pts.iter().map(|&p| pose.transform_point(p)).collect()
                })
            })
            .collect();
        let Some(fit) = plane_from_poses(&objects, POSE_PLANE_BAND_M).filter(|f| accept(&f.plane))
        else {
            return Ok(Err(Skip::from(format!(
                "no depth image, and no table plane from the object poses: fewer than 3 of its {} objects (with models) have their lowest points within {} mm of one plane with every object centre {:.0} cm below to {:.0} cm above it",
                objects.iter().filter(|o| !o.is_empty()).count(),
                POSE_PLANE_BAND_M * 1000.0,
                CENTRE_BELOW_M * 100.0,
                CENTRE_ABOVE_M * 100.0
            ))));
        };
        (fit, PlaneSource::ObjectPoses)
    };
    finish(ctx, frame, &visib, (w, h), &poses, fit, masked, plane_from)
}

/// Objects whose lowest points lie within this of the plane fitted to them (frames without
/// depth) are standing on it.
const POSE_PLANE_BAND_M: f64 = 0.01;

/// Where a frame's table plane came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PlaneSource {
    /// RANSAC on the depth readings around the objects.
    Depth,
    /// The objects' lowest points at their GT poses (a frame without depth).
    ObjectPoses,
}

/// The frame's measurements from its table plane `fit`.
#[allow(clippy::too_many_arguments)]
fn finish(
    ctx: &FrameContext<'_>,
    frame: &SourceFrame,
    visib: &[Option<Vec<u8>>],
    (w, h): (u32, u32),
    poses: &[Pose],
    fit: PlaneFit,
    masked: bool,
    plane_from: PlaneSource,
) -> Result<std::result::Result<FrameFit, Skip>> {
    let centres: Vec<DVec3> = poses.iter().map(|p| p.translation_m).collect();
    let plane = fit.plane;
    let n = plane.normal;

    let mean = centres.iter().sum::<DVec3>() / centres.len().max(1) as f64;
    let mean_height = plane.height(mean);
    // The optical axis s·(0, 0, 1) meets the plane at the height of the mean centre.
    let s = (mean_height - plane.d) / n.z;
    if !(s.is_finite() && s > 0.0) {
        return Ok(Err(Skip::from(format!(
            "the optical axis does not reach the objects' height (table normal in the camera frame {:.2}, {:.2}, {:.2})",
            n.x, n.y, n.z
        ))));
    }
    let look_at = DVec3::new(0.0, 0.0, s);

    let (info, visib_source) = match visibility(ctx, frame, visib, (w, h))? {
        Some((v, s)) => (Some(v), Some(s.to_string())),
        None => (None, None),
    };
    let objects = frame
        .gt
        .iter()
        .zip(poses)
        .enumerate()
        .map(|(i, (g, pose))| {
            let (up, tilt) = up_axis_of(pose, n);
            let lowest_point_m = ctx.support.get(&g.obj_id).and_then(|pts| {
                pts.iter()
                    .map(|&p| plane.height(pose.transform_point(p)))
                    .min_by(f64::total_cmp)
            });
            ObjectObservation {
                obj_id: g.obj_id,
                up,
                tilt_deg: tilt.to_degrees(),
                centre_height_m: plane.height(pose.translation_m),
                lowest_point_m,
                visib_fract: info.as_ref().and_then(|v| v.get(i).copied()),
            }
        })
        .collect();
    Ok(Ok(FrameFit {
        location: frame.location.clone(),
        normal_cam: n.to_array(),
        camera_height_m: plane.d,
        plane_points: fit.points,
        plane_inlier_share: fit.inliers as f64 / fit.points as f64,
        plane_rms_mm: fit.rms_m * 1000.0,
        elevation_deg: (-n.z).clamp(-1.0, 1.0).asin().to_degrees(),
        distance_m: s,
        centre_distance_m: mean.length(),
        look_at_offset_m: (look_at - mean).length(),
        roll_deg: roll_deg(n),
        extent_m: extent_on_plane(&centres, n),
        masked,
        plane_from,
        visib_source,
        objects,
    }))
}

/// The model axis of an object at `cam_from_obj` closest to the table's up direction
/// `normal_cam` (camera frame), and the angle between them in radians.
pub fn up_axis_of(cam_from_obj: &Pose, normal_cam: DVec3) -> (UpAxis, f64) {
    UpAxis::nearest(cam_from_obj.rotation.transpose() * normal_cam)
}

/// The roll of a camera whose frame holds the table's up direction `n`: the sampler's camera
/// is `look_at(...)` turned by Rz(roll), which puts up at (−sin r cos e, −cos r cos e, ·).
pub fn roll_deg(n: DVec3) -> f64 {
    (-n.x).atan2(-n.y).to_degrees()
}

/// The extent of `points` projected on the plane with normal `n`, along their principal
/// axes, larger first.
fn extent_on_plane(points: &[DVec3], n: DVec3) -> [f64; 2] {
    if points.len() < 2 {
        return [0.0, 0.0];
    }
    let e1 = (DVec3::X - n * n.x).normalize_or(n.any_orthonormal_vector());
    let e2 = n.cross(e1);
    let uv: Vec<[f64; 2]> = points.iter().map(|p| [p.dot(e1), p.dot(e2)]).collect();
    let m = uv.len() as f64;
    let (mu, mv) = (
        uv.iter().map(|p| p[0]).sum::<f64>() / m,
        uv.iter().map(|p| p[1]).sum::<f64>() / m,
    );
    let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
    for p in &uv {
        let (x, y) = (p[0] - mu, p[1] - mv);
        a += x * x;
        b += x * y;
        c += y * y;
    }
    // The principal direction of the 2x2 covariance [[a, b], [b, c]].
    let angle = 0.5 * (2.0 * b).atan2(a - c);
    let (d1, d2) = ([angle.cos(), angle.sin()], [-angle.sin(), angle.cos()]);
    let extent = |d: [f64; 2]| {
        let proj = uv.iter().map(|p| p[0] * d[0] + p[1] * d[1]);
        let (lo, hi) = proj.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        hi - lo
    };
    let (x, y) = (extent(d1), extent(d2));
    [x.max(y), x.min(y)]
}

/// Back-projected depth readings outside `exclude`, on a regular grid of at most about
/// `max_points` pixels.
fn sample_points(
    depth_m: &[f32],
    exclude: &[bool],
    k: &Intrinsics,
    max_points: usize,
) -> Vec<DVec3> {
    let (w, h) = (k.width as usize, k.height as usize);
    let stride = ((w * h) as f64 / max_points.max(1) as f64)
        .sqrt()
        .ceil()
        .max(1.0) as usize;
    let mut out = Vec::with_capacity((w / stride + 1) * (h / stride + 1));
    for y in (stride / 2..h).step_by(stride) {
        for x in (stride / 2..w).step_by(stride) {
            let i = y * w + x;
            let z = f64::from(depth_m[i]);
            if z > 0.0 && z.is_finite() && !exclude[i] {
                out.push(k.back_project(x as f64, y as f64, z));
            }
        }
    }
    out
}

/// `mask` grown by `r` pixels (a square neighbourhood), so that edge pixels that mix an
/// object and the table stay out of the plane fit.
fn dilate(mask: &[bool], w: u32, h: u32, r: u32) -> Vec<bool> {
    let (w, h, r) = (w as usize, h as usize, r as usize);
    if r == 0 {
        return mask.to_vec();
    }
    let mut rows = vec![false; mask.len()];
    for y in 0..h {
        for x in 0..w {
            let (x0, x1) = (x.saturating_sub(r), (x + r).min(w - 1));
            rows[y * w + x] = mask[y * w + x0..=y * w + x1].iter().any(|&v| v);
        }
    }
    let mut out = vec![false; mask.len()];
    for y in 0..h {
        let (y0, y1) = (y.saturating_sub(r), (y + r).min(h - 1));
        for x in 0..w {
            out[y * w + x] = (y0..=y1).any(|yy| rows[yy * w + x]);
        }
    }
    out
}

/// Each instance's `visib_fract` and where it came from: the dataset's `scene_gt_info`, else
/// (with a renderer and every visible mask) the visible mask against the silhouette rendered
/// at the GT pose.
fn visibility(
    ctx: &FrameContext<'_>,
    frame: &SourceFrame,
    visib: &[Option<Vec<u8>>],
    size: (u32, u32),
) -> Result<Option<(Vec<f64>, &'static str)>> {
    if let Some(info) = &frame.gt_info {
        if info.len() == frame.gt.len() {
            let v = info.iter().map(|i| i.visib_fract).collect();
            return Ok(Some((v, "scene_gt_info")));
        }
    }
    let (Some(renderer), true) = (ctx.renderer, visib.iter().all(Option::is_some)) else {
        return Ok(None);
    };
    let masks: Vec<Vec<u8>> = visib.iter().flatten().cloned().collect();
    if masks.len() != frame.gt.len() {
        return Ok(None);
    }
    let done = complete_annotations(renderer, frame, &masks, size)?;
    let v = done.iter().map(|(_, i)| i.visib_fract).collect();
    Ok(Some((v, "visible masks / rendered silhouettes")))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use synthgen_core::glam::DMat3;
    use synthgen_core::rest::upright_rotation;

    /// The roll the sampler gives a camera (look-at, then Rz(roll)) is the roll read back from
    /// the table's normal in that camera's frame; the elevation likewise.
    #[test]
    fn roll_and_elevation_match_the_samplers_camera() {
        for (elev, azim, roll) in [
            (36.0f64, 20.0f64, -4.0f64),
            (60.0, 200.0, 12.0),
            (15.0, 95.0, 0.0),
        ] {
            let (e, a) = (elev.to_radians(), azim.to_radians());
            let target = DVec3::new(0.1, -0.05, 0.04);
            let eye = target + 0.9 * DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
            let mut world_from_cam = Pose::world_from_cam_look_at(eye, target, DVec3::Z);
            world_from_cam.rotation *= DMat3::from_rotation_z(roll.to_radians());
            let n = world_from_cam.rotation.transpose() * DVec3::Z;
            assert!((roll_deg(n) - roll).abs() < 1e-9, "{roll}: {}", roll_deg(n));
            let got = (-n.z).asin().to_degrees();
            assert!((got - elev).abs() < 1e-9, "{elev}: {got}");
        }
    }

    /// Objects placed as the sampler places them (a rest axis, a yaw, a tilt) and seen by a
    /// camera: the axis and the tilt come back from the pose and the table's normal.
    #[test]
    fn up_axis_and_tilt_of_placed_objects() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let world_from_cam = Pose::world_from_cam_look_at(
            DVec3::new(0.5, -0.4, 0.6),
            DVec3::new(0.0, 0.0, 0.05),
            DVec3::Z,
        );
        let cam_from_world = world_from_cam.inverse();
        let n = cam_from_world.rotation * DVec3::Z;
        for (i, up) in UpAxis::ALL.into_iter().enumerate() {
            for tilt in [0.0, 20.0, 40.0] {
                let r = upright_rotation(i as f64, up, tilt, &mut rng);
                let world_from_obj = Pose::new(r, DVec3::new(0.1, 0.0, 0.04));
                let cam_from_obj = cam_from_world.compose(&world_from_obj);
                let (got, angle) = up_axis_of(&cam_from_obj, n);
                assert_eq!(got, up, "tilt {tilt}");
                let want = (r * up.model_axis()).z.acos();
                assert!((angle - want).abs() < 1e-9, "{angle} {want}");
                assert!(angle.to_degrees() <= tilt + 1e-9);
            }
        }
    }

    #[test]
    fn extent_along_principal_axes() {
        let n = DVec3::new(0.0, -0.8, -0.6);
        let e1 = DVec3::X;
        let e2 = n.cross(e1);
        let pts: Vec<DVec3> = [(-0.2, 0.0), (0.2, 0.0), (0.0, 0.05), (0.0, -0.05)]
            .iter()
            .map(|&(u, v)| {
                DVec3::new(0.0, 0.0, 1.0)
                    + u * (e1 + e2) / 2f64.sqrt()
                    + v * (e1 - e2) / 2f64.sqrt()
            })
            .collect();
        let [a, b] = extent_on_plane(&pts, n);
        assert!((a - 0.4).abs() < 1e-9 && (b - 0.1).abs() < 1e-9, "{a} {b}");
    }

    #[test]
    fn dilation_grows_by_r() {
        let mut m = vec![false; 25];
        m[12] = true;
        let d = dilate(&m, 5, 5, 1);
        assert_eq!(d.iter().filter(|&&v| v).count(), 9);
        assert!(d[6] && d[18] && !d[0]);
    }
}
