//! Pose refinement on depth: an object's model fitted to the real depth points of one instance
//! by ICP, the way PoseCNN and DenseFusion finish a network's estimate.
//!
//! The network gives a centre; the rotation is unknown. From that centre, trimmed
//! point-to-plane ICP runs from a spread of starting rotations (directions of a Fibonacci
//! sphere for the model's z-axis, times turns about it): the instance's points are paired with
//! their closest points on the model's surface (parry's BVH), pairs whose surface faces away
//! from the camera or lie far off are left out, and each step solves the linearized
//! point-to-plane problem. The start whose converged pose explains the points best wins
//! (truncated squared distance; a point that lands on a back-facing surface counts as an
//! outlier, so the model is never put in front of the points it should lie under). Among
//! near-ties the pose closest to the given centre wins: where the points cannot tell (a face
//! seen through a small hole), the network's centre decides.
//!
//! [`refine_pose`] finishes a whole pose (the Full model's): the given rotation is one more
//! start, and it decides among the poses the depth cannot tell apart.
//!
//! A refined centre farther than [`RefineOptions::max_shift_m`] from the given one, or one
//! that explains too few points, is refused and the given centre kept: ICP into a wrong
//! minimum must not make a good estimate worse.

use rapier3d::parry::math::Vector as PVec;
use rapier3d::parry::query::PointQueryWithLocation;
use rapier3d::parry::shape::TriMesh;
use synthgen_core::glam::{DMat3, DQuat, DVec3};
use synthgen_core::{Model, Pose};

use crate::align::{surface_samples, tri_mesh, AlignError};

/// How [`refine_centre`] searches and when it refuses.
#[derive(Debug, Clone, PartialEq)]
pub struct RefineOptions {
    /// Directions for the model's z-axis (Fibonacci sphere) at the start.
    pub directions: usize,
    /// Turns about that axis per direction.
    pub turns: usize,
    /// ICP iterations per start (coarse stage, on `coarse_points` of the points).
    pub coarse_iterations: usize,
    pub coarse_points: usize,
    /// The best starts continued on every point for `fine_iterations`.
    pub fine_starts: usize,
    pub fine_iterations: usize,
    /// Distance at which a point stops counting as explained (score truncation), metres;
    /// twice it is the smallest search radius of the ICP steps. 2 cm was chosen on the
    /// validation splits of docs/experiments.md (1.5–3 cm a plateau, 0.5 and 1 cm worse).
    pub inlier_m: f64,
    /// Refined centres farther than this from the given one are refused, metres.
    pub max_shift_m: f64,
    /// Poses that explain fewer than this fraction of the points are refused.
    pub min_inlier_fraction: f64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        Self {
            directions: 14,
            turns: 6,
            coarse_iterations: 8,
            coarse_points: 150,
            fine_starts: 4,
            fine_iterations: 30,
            inlier_m: 0.02,
            max_shift_m: 0.03,
            min_inlier_fraction: 0.5,
        }
    }
}

/// An object's surface, ready for [`refine_centre`].
pub struct Surface {
    mesh: TriMesh,
    /// Outward unit normal per triangle (model frame).
    normals: Vec<DVec3>,
}

impl Surface {
    /// The surface of `model` (metres). Triangle windings are taken as they are, unless most
    /// face inwards (normals towards the area-weighted centroid), when all are turned.
    pub fn new(model: &Model) -> Result<Surface, AlignError> {
        let tris = model.triangles_m();
        if tris.is_empty() {
            return Err(AlignError::Empty(model.name.clone()));
        }
        let mesh = tri_mesh(&tris).map_err(|e| AlignError::Mesh(model.name.clone(), e))?;
        let centroid = {
            let pts = surface_samples(&tris, 2000);
            pts.iter().copied().sum::<DVec3>() / pts.len().max(1) as f64
        };
        let mut normals: Vec<DVec3> = tris
            .iter()
            .map(|t| (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero())
            .collect();
        let outward: f64 = tris
            .iter()
            .zip(&normals)
            .map(|(t, n)| {
                let area = 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
                area * n.dot((t[0] + t[1] + t[2]) / 3.0 - centroid).signum()
            })
            .sum();
        if outward < 0.0 {
            for n in &mut normals {
                *n = -*n;
            }
        }
        Ok(Surface { mesh, normals })
    }

    /// The closest surface point to `p` (model frame) within `max_m`, and its triangle's
    /// outward normal.
    fn project(&self, p: DVec3, max_m: f64) -> Option<(DVec3, DVec3)> {
        let q = PVec::new(p.x as f32, p.y as f32, p.z as f32);
        let (proj, (tri, _)) = self
            .mesh
            .project_local_point_and_get_location_with_max_dist(q, false, max_m as f32)?;
        let n = self
            .normals
            .get(tri as usize)
            .copied()
            .unwrap_or(DVec3::ZERO);
        let c = DVec3::new(
            f64::from(proj.point.x),
            f64::from(proj.point.y),
            f64::from(proj.point.z),
        );
        Some((c, n))
    }
}

/// What [`refine_centre`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refined {
    /// The fitted `cam_from_obj` (its translation is the refined centre).
    pub pose: Pose,
    /// The centre to use: the fitted one, or the given one when the fit was refused.
    pub centre_m: DVec3,
    /// Whether the fit was accepted.
    pub accepted: bool,
    /// Share of the points within `inlier_m` of a camera-facing surface.
    pub inlier_fraction: f64,
    /// Distance between the fitted and the given centre, metres.
    pub shift_m: f64,
}

/// Fits `surface` to `points` (camera frame, metres; the instance's depth points) starting
/// from the centre `init_m`; `None` when there are fewer than 10 finite points.
pub fn refine_centre(
    surface: &Surface,
    points: &[DVec3],
    init_m: DVec3,
    opts: &RefineOptions,
) -> Option<Refined> {
    fit(surface, points, init_m, None, opts)
}

/// Refines a whole pose (`init`, `cam_from_obj`, metres) on the instance's depth points: the
/// same search as [`refine_centre`] over rotations spread on SO(3), with the given rotation
/// as one more start continued on every point; among the near-ties of the fit (poses the
/// points explain within 10 % of the best, e.g. a box's faces that geometry cannot tell
/// apart) the one nearest the given rotation wins, so the depth decides what it can see and
/// the network what only colour can tell. The fit is refused as [`refine_centre`] refuses it
/// (a centre moved too far, too few points explained); the caller then keeps the given pose.
pub fn refine_pose(
    surface: &Surface,
    points: &[DVec3],
    init: &Pose,
    opts: &RefineOptions,
) -> Option<Refined> {
    fit(
        surface,
        points,
        init.translation_m,
        Some(init.rotation),
        opts,
    )
}

/// The angle between two rotations, radians.
fn angle_between(a: &DMat3, b: &DMat3) -> f64 {
    let m = *a * b.transpose();
    let tr = m.x_axis.x + m.y_axis.y + m.z_axis.z;
    ((tr - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
}

fn fit(
    surface: &Surface,
    points: &[DVec3],
    init_m: DVec3,
    prior: Option<DMat3>,
    opts: &RefineOptions,
) -> Option<Refined> {
    let pts: Vec<DVec3> = points.iter().copied().filter(|p| p.is_finite()).collect();
    if pts.len() < 10 || !init_m.is_finite() || prior.is_some_and(|r| !r.is_finite()) {
        return None;
    }
    let coarse: Vec<DVec3> = stride(&pts, opts.coarse_points.max(10));
    let coarse_fit = |r0: DMat3| {
        let (r, t) = icp(surface, &coarse, r0, init_m, opts.coarse_iterations, opts);
        (score(surface, &coarse, r, t, opts).0, r, t)
    };
    let mut starts: Vec<(f64, DMat3, DVec3)> = start_rotations(opts.directions, opts.turns)
        .into_iter()
        .map(coarse_fit)
        .collect();
    starts.sort_by(|a, b| a.0.total_cmp(&b.0));
    starts.truncate(opts.fine_starts.max(1));
    // The given rotation is always continued, whatever its coarse score.
    starts.extend(prior.map(coarse_fit));
    let mut fine: Vec<(f64, f64, DMat3, DVec3)> = starts
        .iter()
        .map(|&(_, r0, t0)| {
            let (r, t) = icp(surface, &pts, r0, t0, opts.fine_iterations, opts);
            let (s, inliers) = score(surface, &pts, r, t, opts);
            (s, inliers, r, t)
        })
        .collect();
    fine.sort_by(|a, b| a.0.total_cmp(&b.0));
    let best = fine.first()?.0;
    // Near-ties (within 10 % of the best score): the pose nearest the given rotation, else
    // the given centre.
    let near = |f: &(f64, f64, DMat3, DVec3)| match &prior {
        Some(r0) => angle_between(&f.2, r0),
        None => f.3.distance(init_m),
    };
    let (_, inlier_fraction, r, t) = fine
        .iter()
        .filter(|f| f.0 <= 1.1 * best + 1e-9)
        .min_by(|a, b| near(a).total_cmp(&near(b)))
        .copied()?;
    let shift_m = t.distance(init_m);
    let accepted = shift_m <= opts.max_shift_m && inlier_fraction >= opts.min_inlier_fraction;
    Some(Refined {
        pose: Pose::new(r, t),
        centre_m: if accepted { t } else { init_m },
        accepted,
        inlier_fraction,
        shift_m,
    })
}

/// Every `len / n`-th point (all when there are at most `n`).
fn stride(pts: &[DVec3], n: usize) -> Vec<DVec3> {
    if pts.len() <= n {
        return pts.to_vec();
    }
    (0..n).map(|i| pts[i * pts.len() / n]).collect()
}

/// `directions × turns` rotations spread over SO(3): the model's z-axis along each direction
/// of a Fibonacci sphere, turned about it in equal steps.
fn start_rotations(directions: usize, turns: usize) -> Vec<DMat3> {
    let mut out = Vec::with_capacity(directions * turns);
    for d in synthgen_core::mesh::fibonacci_sphere(directions.max(1)) {
        let z = d.as_dvec3().normalize();
        let align = DQuat::from_rotation_arc(DVec3::Z, z);
        for k in 0..turns.max(1) {
            let turn = DQuat::from_axis_angle(
                DVec3::Z,
                std::f64::consts::TAU * k as f64 / turns.max(1) as f64,
            );
            out.push(DMat3::from_quat(align * turn));
        }
    }
    out
}

/// Whether a surface with outward normal `n_cam` (camera frame) at `p` faces the camera.
fn faces_camera(n_cam: DVec3, p: DVec3) -> bool {
    n_cam.dot(p) < 0.0
}

/// Trimmed point-to-plane ICP of the model posed (r, t) onto `pts`: each point is paired with
/// its closest surface point; pairs on back-facing surface or farther than the search radius
/// (5 cm, shrinking with the fit to 2x the kept distances) are left out, and so are those
/// beyond 2.5x the median pair distance (at least 2 mm). Each step solves the linearized
/// point-to-plane problem about the pairs' centroid; a slight damping keeps directions the
/// points do not constrain (a face slid along itself) where they are.
fn icp(
    surface: &Surface,
    pts: &[DVec3],
    mut r: DMat3,
    mut t: DVec3,
    iterations: usize,
    opts: &RefineOptions,
) -> (DMat3, DVec3) {
    let mut radius = 0.05f64.max(2.0 * opts.inlier_m);
    for _ in 0..iterations {
        let rt = r.transpose();
        // (surface point, its normal, the depth point, their distance), camera frame.
        let mut pairs: Vec<(DVec3, DVec3, DVec3, f64)> = Vec::with_capacity(pts.len());
        for p in pts {
            let Some((c, n)) = surface.project(rt * (*p - t), radius) else {
                continue;
            };
            let (c, n) = (r * c + t, r * n);
            if faces_camera(n, c) {
                pairs.push((c, n, *p, c.distance(*p)));
            }
        }
        if pairs.len() < 6 {
            break;
        }
        let mut d: Vec<f64> = pairs.iter().map(|p| p.3).collect();
        d.sort_by(f64::total_cmp);
        let keep = (2.5 * d[d.len() / 2]).max(0.002);
        pairs.retain(|p| p.3 <= keep);
        if pairs.len() < 6 {
            break;
        }
        let centre = pairs.iter().map(|p| p.0).sum::<DVec3>() / pairs.len() as f64;
        let mut jtj = [[0.0f64; 6]; 6];
        let mut jtb = [0.0f64; 6];
        for (c, n, p, _) in &pairs {
            let a = (*c - centre).cross(*n);
            let row = [a.x, a.y, a.z, n.x, n.y, n.z];
            let b = (*p - *c).dot(*n);
            for i in 0..6 {
                jtb[i] += row[i] * b;
                for j in 0..6 {
                    jtj[i][j] += row[i] * row[j];
                }
            }
        }
        let damping = 1e-6 * pairs.len() as f64;
        for (i, row) in jtj.iter_mut().enumerate() {
            row[i] += damping;
        }
        let Some(x) = synthgen_core::pnp::solve6(jtj, jtb) else {
            break;
        };
        let mut omega = DVec3::new(x[0], x[1], x[2]);
        if omega.length() > 0.3 {
            omega *= 0.3 / omega.length();
        }
        let v = DVec3::new(x[3], x[4], x[5]);
        let dr = DMat3::from_quat(DQuat::from_scaled_axis(omega));
        r = dr * r;
        t = dr * (t - centre) + centre + v;
        radius = (2.0 * keep).clamp(2.0 * opts.inlier_m, radius);
        if v.length() + 0.1 * omega.length() < 1e-6 {
            break;
        }
    }
    (r, t)
}

/// The mean truncated squared distance of `pts` to the posed model (a point with no
/// camera-facing surface within `inlier_m` counts as `inlier_m`), and the share of points
/// within `inlier_m` of camera-facing surface.
fn score(surface: &Surface, pts: &[DVec3], r: DMat3, t: DVec3, opts: &RefineOptions) -> (f64, f64) {
    let tau = opts.inlier_m;
    let rt = r.transpose();
    let (mut sum, mut inliers) = (0.0, 0usize);
    for p in pts {
        let d = surface
            .project(rt * (*p - t), tau)
            .filter(|(c, n)| faces_camera(r * *n, r * *c + t))
            .map(|(c, _)| (r * c + t).distance(*p));
        match d {
            Some(d) if d < tau => {
                sum += d * d;
                inliers += 1;
            }
            _ => sum += tau * tau,
        }
    }
    let n = pts.len().max(1) as f64;
    (sum / n, inliers as f64 / n)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use synthgen_core::glam::Vec3;

    /// The camera-facing, unoccluded surface points of `model` posed by `pose` (camera at the
    /// origin), as a depth camera would see them: a ray cast per sample (parry).
    fn visible_points(model: &Model, pose: &Pose, noise_m: f64, seed: u64) -> Vec<DVec3> {
        let tris = model.triangles_m();
        let s = Surface::new(model).unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        surface_samples(&tris, 4000)
            .into_iter()
            .map(|p| pose.rotation * p + pose.translation_m)
            .filter(|p| {
                // Visible: the first hit along the ray from the camera is this point.
                use rapier3d::parry::query::{Ray, RayCast};
                let rt = pose.rotation.transpose();
                let o = rt * (DVec3::ZERO - pose.translation_m);
                let dir = rt * p.normalize();
                let ray = Ray::new(
                    PVec::new(o.x as f32, o.y as f32, o.z as f32),
                    PVec::new(dir.x as f32, dir.y as f32, dir.z as f32),
                );
                let hit = s.mesh.cast_local_ray(&ray, 10.0, false).unwrap_or(f32::MAX);
                (f64::from(hit) - p.length()).abs() < 1e-3
            })
            .map(|p| p + DVec3::new(0.0, 0.0, rng.gen_range(-noise_m..=noise_m)))
            .collect()
    }

    fn rotation(axis: DVec3, deg: f64) -> DMat3 {
        DMat3::from_axis_angle(axis.normalize(), deg.to_radians())
    }

    #[test]
    fn the_centre_is_found_behind_the_visible_faces_of_a_box() {
        let model = Model::cuboid("box", Vec3::new(0.16, 0.08, 0.05));
        let surface = Surface::new(&model).unwrap();
        let opts = RefineOptions::default();
        for (k, (axis, deg)) in [
            (DVec3::new(1.0, 0.3, 0.2), 35.0),
            (DVec3::new(0.2, 1.0, -0.4), 120.0),
            (DVec3::new(-0.5, 0.1, 1.0), 200.0),
        ]
        .into_iter()
        .enumerate()
        {
            let gt = Pose::new(rotation(axis, deg), DVec3::new(0.05, -0.03, 0.8));
            let pts = visible_points(&model, &gt, 0.001, k as u64);
            assert!(pts.len() > 200, "{} visible points", pts.len());
            // The start: the visible points' mean (in front of the centre) shifted sideways.
            let mean = pts.iter().copied().sum::<DVec3>() / pts.len() as f64;
            let init = mean + DVec3::new(0.01, 0.005, 0.0);
            let before = init.distance(gt.translation_m);
            let r = refine_centre(&surface, &pts, init, &opts).unwrap();
            let after = r.centre_m.distance(gt.translation_m);
            assert!(r.accepted, "pose {k}: refused ({r:?})");
            assert!(
                after < 0.004,
                "pose {k}: {before:.4} m → {after:.4} m ({r:?})"
            );
            assert!(
                after < 0.5 * before,
                "pose {k}: {before:.4} m → {after:.4} m"
            );
        }
    }

    #[test]
    fn a_whole_pose_is_refined_and_the_given_rotation_breaks_the_ties_of_geometry() {
        // A box looks the same turned 180° about any of its axes: the depth cannot tell
        // those poses apart, the given rotation does.
        let model = Model::cuboid("box", Vec3::new(0.16, 0.08, 0.05));
        let surface = Surface::new(&model).unwrap();
        let opts = RefineOptions::default();
        let gt = Pose::new(
            rotation(DVec3::new(0.3, 1.0, 0.2), 40.0),
            DVec3::new(0.02, 0.01, 0.7),
        );
        let pts = visible_points(&model, &gt, 0.001, 4);
        let flip = gt.rotation * rotation(DVec3::Z, 180.0);
        let off = rotation(DVec3::new(1.0, -0.5, 0.3), 25.0);
        for (k, want) in [gt.rotation, flip].into_iter().enumerate() {
            let init = Pose::new(
                off * want,
                gt.translation_m + DVec3::new(0.008, -0.006, 0.01),
            );
            let r = refine_pose(&surface, &pts, &init, &opts).unwrap();
            let err = angle_between(&r.pose.rotation, &want).to_degrees();
            assert!(r.accepted, "start {k}: refused ({r:?})");
            assert!(
                err < 3.0,
                "start {k}: {err:.2}° from the expected pose ({r:?})"
            );
            assert!(
                r.centre_m.distance(gt.translation_m) < 0.004,
                "start {k}: {r:?}"
            );
        }
        // A rotation with NaN is no start.
        let bad = Pose::new(DMat3::from_cols_array(&[f64::NAN; 9]), gt.translation_m);
        assert!(refine_pose(&surface, &pts, &bad, &opts).is_none());
    }

    #[test]
    fn a_fit_far_from_the_given_centre_is_refused() {
        let model = Model::cuboid("box", Vec3::new(0.1, 0.1, 0.1));
        let surface = Surface::new(&model).unwrap();
        let gt = Pose::new(
            rotation(DVec3::new(1.0, 1.0, 0.0), 30.0),
            DVec3::new(0.0, 0.0, 0.7),
        );
        let pts = visible_points(&model, &gt, 0.0, 9);
        // A start 2.5 cm off with a 1 cm limit: the fit moves it back, further than allowed.
        let init = gt.translation_m + DVec3::new(0.025, 0.0, 0.0);
        let opts = RefineOptions {
            max_shift_m: 0.01,
            ..RefineOptions::default()
        };
        let r = refine_centre(&surface, &pts, init, &opts).unwrap();
        assert!(!r.accepted);
        assert_eq!(r.centre_m, init);
        assert!(
            r.pose.translation_m.distance(gt.translation_m) < 0.004,
            "{r:?}"
        );
        // Too few points: nothing to fit.
        assert!(refine_centre(&surface, &pts[..5], init, &opts).is_none());
    }

    #[test]
    fn inward_windings_are_turned_outwards() {
        let mut model = Model::cuboid("box", Vec3::new(0.1, 0.2, 0.3));
        let outward = Surface::new(&model).unwrap().normals;
        for p in &mut model.primitives {
            for t in &mut p.triangles {
                t.swap(1, 2);
            }
        }
        let turned = Surface::new(&model).unwrap().normals;
        for (a, b) in outward.iter().zip(&turned) {
            assert!(a.distance(*b) < 1e-9);
        }
    }
}
