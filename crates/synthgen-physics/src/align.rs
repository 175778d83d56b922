//! Rigid alignment of one mesh onto another of the same object: a textured scan onto the model
//! that annotations refer to (YCB's google_16k scans onto the YCB-Video models, which are the
//! same surfaces simplified and shifted by a per-object offset that no file stores).
//!
//! Coarse: the area-weighted surface centroids are matched (optionally under each of the 24
//! axis-aligned rotations, for files whose axes differ). Fine: trimmed ICP, point to surface —
//! scan points are projected onto the target's triangles (parry's BVH) and the rigid motion
//! that best maps them onto their projections (Horn's quaternion method) is applied, until the
//! motion is below a micrometre. The residual is measured both ways (scan points to the target
//! surface and target points to the scan surface): different tessellations of one surface agree
//! to a fraction of a millimetre; different shapes do not.

use rapier3d::parry::math::Vector as PVec;
use rapier3d::parry::query::PointQuery;
use rapier3d::parry::shape::TriMesh;
use synthgen_core::glam::{DMat3, DMat4, DQuat, DVec3, DVec4};
use synthgen_core::Model;

/// How [`align`] searches.
#[derive(Debug, Clone, PartialEq)]
pub struct AlignOptions {
    /// Also try the 24 axis-aligned rotations as starting points (files whose axes differ);
    /// the best residual wins.
    pub rotation_search: bool,
    /// Scan points used by ICP (spread over the surface by area).
    pub samples: usize,
    /// ICP iterations at most.
    pub max_iterations: usize,
}

impl Default for AlignOptions {
    fn default() -> Self {
        Self {
            rotation_search: false,
            samples: 4000,
            max_iterations: 100,
        }
    }
}

/// The motion that puts the scan onto the target: `target ≈ rotation · scan + translation_m`,
/// and how well the surfaces then agree.
#[derive(Debug, Clone, PartialEq)]
pub struct Alignment {
    pub rotation: DMat3,
    pub translation_m: DVec3,
    /// Distances of the scan's surface points to the target's surface, metres.
    pub scan_to_target: Residual,
    /// Distances of the target's surface points to the scan's surface, metres.
    pub target_to_scan: Residual,
    pub iterations: usize,
}

/// Surface distances, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Residual {
    pub median_m: f64,
    pub p95_m: f64,
    pub max_m: f64,
    pub points: usize,
}

impl Alignment {
    /// The larger of the two directions' medians: both surfaces must lie on each other.
    pub fn median_m(&self) -> f64 {
        self.scan_to_target
            .median_m
            .max(self.target_to_scan.median_m)
    }

    /// The larger of the two directions' 95th percentiles.
    pub fn p95_m(&self) -> f64 {
        self.scan_to_target.p95_m.max(self.target_to_scan.p95_m)
    }

    /// The motion as a 4x4 matrix (column vectors: `target = M · scan`).
    pub fn matrix(&self) -> DMat4 {
        DMat4::from_cols(
            self.rotation.x_axis.extend(0.0),
            self.rotation.y_axis.extend(0.0),
            self.rotation.z_axis.extend(0.0),
            self.translation_m.extend(1.0),
        )
    }
}

/// Why two meshes cannot be aligned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AlignError {
    #[error("{0} has no triangles")]
    Empty(String),
    #[error("cannot build a search structure for {0}: {1}")]
    Mesh(String, String),
}

/// Aligns `scan` onto `target` (both in metres).
pub fn align(scan: &Model, target: &Model, opts: &AlignOptions) -> Result<Alignment, AlignError> {
    let scan_tris = scan.triangles_m();
    let target_tris = target.triangles_m();
    if scan_tris.is_empty() {
        return Err(AlignError::Empty(scan.name.clone()));
    }
    if target_tris.is_empty() {
        return Err(AlignError::Empty(target.name.clone()));
    }
    let target_mesh =
        tri_mesh(&target_tris).map_err(|e| AlignError::Mesh(target.name.clone(), e))?;
    let scan_mesh = tri_mesh(&scan_tris).map_err(|e| AlignError::Mesh(scan.name.clone(), e))?;
    let scan_pts = surface_samples(&scan_tris, opts.samples.max(16));
    let target_pts = surface_samples(&target_tris, opts.samples.max(16));
    let (c_scan, c_target) = (mean(&scan_pts), mean(&target_pts));

    let starts: Vec<DMat3> = if opts.rotation_search {
        axis_rotations()
    } else {
        vec![DMat3::IDENTITY]
    };
    let mut best: Option<Alignment> = None;
    for r0 in starts {
        let t0 = c_target - r0 * c_scan;
        let (rotation, translation_m, iterations) =
            icp(&scan_pts, &target_mesh, r0, t0, opts.max_iterations);
        let moved: Vec<DVec3> = scan_pts
            .iter()
            .map(|p| rotation * *p + translation_m)
            .collect();
        let scan_to_target = residual(&moved, &target_mesh);
        // The target's points, brought into the scan's frame.
        let inv = rotation.transpose();
        let back: Vec<DVec3> = target_pts
            .iter()
            .map(|p| inv * (*p - translation_m))
            .collect();
        let target_to_scan = residual(&back, &scan_mesh);
        let a = Alignment {
            rotation,
            translation_m,
            scan_to_target,
            target_to_scan,
            iterations,
        };
        if best.as_ref().is_none_or(|b| a.median_m() < b.median_m()) {
            best = Some(a);
        }
    }
    // At least one start was tried.
    best.ok_or_else(|| AlignError::Empty(scan.name.clone()))
}

pub(crate) fn tri_mesh(tris: &[[DVec3; 3]]) -> Result<TriMesh, String> {
    let mut vertices = Vec::with_capacity(tris.len() * 3);
    let mut indices = Vec::with_capacity(tris.len());
    for (i, t) in tris.iter().enumerate() {
        for v in t {
            vertices.push(PVec::new(v.x as f32, v.y as f32, v.z as f32));
        }
        let k = (3 * i) as u32;
        indices.push([k, k + 1, k + 2]);
    }
    TriMesh::new(vertices, indices).map_err(|e| e.to_string())
}

/// `n` points spread over the surface by area: a deterministic low-discrepancy walk over the
/// triangles' cumulative area, each point at its triangle's barycentre offset by a fixed
/// pattern (no RNG: the same meshes always give the same alignment).
pub(crate) fn surface_samples(tris: &[[DVec3; 3]], n: usize) -> Vec<DVec3> {
    let areas: Vec<f64> = tris
        .iter()
        .map(|t| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length())
        .collect();
    let total: f64 = areas.iter().sum();
    if total <= 0.0 {
        return tris.iter().map(|t| (t[0] + t[1] + t[2]) / 3.0).collect();
    }
    let mut out = Vec::with_capacity(n);
    let step = total / n as f64;
    let mut next = 0.5 * step;
    let mut acc = 0.0;
    // Golden-ratio sequences place the points inside their triangles.
    let (g1, g2) = (0.754_877_666_246_692_7, 0.569_840_290_998_053_3);
    for (t, a) in tris.iter().zip(&areas) {
        acc += a;
        while next <= acc && out.len() < n {
            let k = out.len() as f64;
            let (mut u, mut v) = ((0.5 + g1 * k).fract(), (0.5 + g2 * k).fract());
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            out.push(t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0]));
            next += step;
        }
    }
    out
}

fn mean(p: &[DVec3]) -> DVec3 {
    p.iter().copied().sum::<DVec3>() / p.len().max(1) as f64
}

fn closest(mesh: &TriMesh, p: DVec3) -> DVec3 {
    let q = mesh.project_local_point(PVec::new(p.x as f32, p.y as f32, p.z as f32), false);
    DVec3::new(
        f64::from(q.point.x),
        f64::from(q.point.y),
        f64::from(q.point.z),
    )
}

/// Trimmed point-to-surface ICP from (r, t): pairs farther than 2.5x the median distance
/// (at least 1 mm) are left out of each step.
fn icp(
    pts: &[DVec3],
    target: &TriMesh,
    mut r: DMat3,
    mut t: DVec3,
    max_iterations: usize,
) -> (DMat3, DVec3, usize) {
    for it in 0..max_iterations {
        let moved: Vec<DVec3> = pts.iter().map(|p| r * *p + t).collect();
        let proj: Vec<DVec3> = moved.iter().map(|p| closest(target, *p)).collect();
        let mut d: Vec<f64> = moved
            .iter()
            .zip(&proj)
            .map(|(a, b)| a.distance(*b))
            .collect();
        let keep = {
            let mut s = d.clone();
            s.sort_by(f64::total_cmp);
            (2.5 * s[s.len() / 2]).max(1e-3)
        };
        let pairs: Vec<(DVec3, DVec3)> = moved
            .iter()
            .zip(&proj)
            .zip(d.iter_mut())
            .filter(|(_, d)| **d <= keep)
            .map(|((a, b), _)| (*a, *b))
            .collect();
        if pairs.len() < 3 {
            return (r, t, it);
        }
        let (dr, dt) = horn(&pairs);
        r = dr * r;
        t = dr * t + dt;
        // The step's largest motion of a point near the object: a rotation of ~0.2 m radius.
        let angle = DQuat::from_mat3(&dr).to_axis_angle().1;
        if dt.length() + 0.2 * angle < 1e-6 {
            return (r, t, it + 1);
        }
    }
    (r, t, max_iterations)
}

/// The rotation and translation minimizing Σ‖R a + t − b‖² (Horn 1987: the unit quaternion is
/// the eigenvector of the largest eigenvalue of a symmetric 4x4 matrix).
fn horn(pairs: &[(DVec3, DVec3)]) -> (DMat3, DVec3) {
    let n = pairs.len() as f64;
    let ca = pairs.iter().map(|p| p.0).sum::<DVec3>() / n;
    let cb = pairs.iter().map(|p| p.1).sum::<DVec3>() / n;
    let mut s = [[0.0f64; 3]; 3];
    for (a, b) in pairs {
        let (a, b) = (*a - ca, *b - cb);
        let (a, b) = (a.to_array(), b.to_array());
        for i in 0..3 {
            for j in 0..3 {
                s[i][j] += a[i] * b[j];
            }
        }
    }
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    let k = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let q = largest_eigenvector(k);
    let rot = DMat3::from_quat(DQuat::from_xyzw(q.y, q.z, q.w, q.x).normalize());
    (rot, cb - rot * ca)
}

/// The eigenvector of a symmetric 4x4 matrix's largest eigenvalue (cyclic Jacobi, until the
/// off-diagonal's squares sum below 1e-30).
fn largest_eigenvector(a: [[f64; 4]; 4]) -> DVec4 {
    let (values, v) = synthgen_core::jacobi::symmetric_eigen(a, |a| {
        let off: f64 = (0..4)
            .flat_map(|i| (0..4).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum();
        off < 1e-30
    });
    let i = (0..4)
        .max_by(|&x, &y| values[x].total_cmp(&values[y]))
        .unwrap_or(0);
    DVec4::new(v[0][i], v[1][i], v[2][i], v[3][i])
}

fn residual(pts: &[DVec3], mesh: &TriMesh) -> Residual {
    let mut d: Vec<f64> = pts.iter().map(|p| p.distance(closest(mesh, *p))).collect();
    d.sort_by(f64::total_cmp);
    let at = |q: f64| d[((d.len() - 1) as f64 * q).round() as usize];
    Residual {
        median_m: at(0.5),
        p95_m: at(0.95),
        max_m: d.last().copied().unwrap_or(0.0),
        points: d.len(),
    }
}

/// The 24 rotations that map coordinate axes onto coordinate axes.
fn axis_rotations() -> Vec<DMat3> {
    let axes = [
        DVec3::X,
        DVec3::NEG_X,
        DVec3::Y,
        DVec3::NEG_Y,
        DVec3::Z,
        DVec3::NEG_Z,
    ];
    let mut out = Vec::with_capacity(24);
    for x in axes {
        for y in axes {
            if x.dot(y).abs() < 0.5 {
                out.push(DMat3::from_cols(x, y, x.cross(y)));
            }
        }
    }
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::Vec3;

    fn moved(m: &Model, r: DMat3, t: DVec3) -> Model {
        let mut m = m.clone();
        for p in &mut m.primitives {
            for v in &mut p.positions_m {
                *v = (r * v.as_dvec3() + t).as_vec3();
            }
        }
        m
    }

    /// A shifted copy of a mesh comes back onto it: the motion is recovered to a micrometre
    /// and the surfaces agree; Horn's method on exact pairs is exact.
    #[test]
    fn a_shifted_mesh_is_put_back() {
        let target = synthgen_core::distractor::cylinder("can", 0.04, 0.1);
        let box_ = Model::cuboid("box", Vec3::new(0.06, 0.08, 0.03));
        let mut target_m = target.clone();
        // An asymmetric object: a can with a box on its side.
        let b = moved(&box_, DMat3::IDENTITY, DVec3::new(0.05, 0.0, 0.02));
        target_m.primitives.extend(b.primitives);
        let t = DVec3::new(0.012, 0.012, -0.03);
        let r = DMat3::from_rotation_z(0.05);
        let scan = moved(&target_m, r.transpose(), -(r.transpose() * t));
        let a = align(&scan, &target_m, &AlignOptions::default()).unwrap();
        assert!(
            (a.translation_m - t).length() < 1e-5,
            "{:?} vs {t}",
            a.translation_m
        );
        assert!(
            (a.rotation - r)
                .to_cols_array()
                .iter()
                .all(|x| x.abs() < 1e-4),
            "{:?}",
            a.rotation
        );
        assert!(a.median_m() < 1e-5 && a.p95_m() < 1e-4, "{a:?}");

        let pairs: Vec<(DVec3, DVec3)> = [DVec3::X, DVec3::Y, DVec3::Z, DVec3::ONE]
            .iter()
            .map(|p| (*p, r * *p + t))
            .collect();
        let (hr, ht) = horn(&pairs);
        assert!(
            (ht - t).length() < 1e-12 && (hr - r).to_cols_array().iter().all(|x| x.abs() < 1e-12)
        );
    }

    /// A different shape does not lie on the target: its residual says so, both ways.
    #[test]
    fn a_different_shape_leaves_a_large_residual() {
        let target = Model::cuboid("block", Vec3::new(0.09, 0.09, 0.09));
        let scan = Model::cuboid("block", Vec3::new(0.077, 0.077, 0.09));
        let a = align(&scan, &target, &AlignOptions::default()).unwrap();
        assert!(a.median_m() > 3e-3, "{a:?}");
    }

    /// With the rotation search, a scan whose axes are permuted is found.
    #[test]
    fn rotation_search_finds_permuted_axes() {
        let target = Model::cuboid("brick", Vec3::new(0.2, 0.1, 0.05));
        let r = DMat3::from_cols(DVec3::Y, DVec3::Z, DVec3::X);
        let scan = moved(&target, r.transpose(), DVec3::new(0.01, -0.02, 0.0));
        let plain = align(&scan, &target, &AlignOptions::default()).unwrap();
        assert!(plain.median_m() > 1e-3, "without the search: {plain:?}");
        let opts = AlignOptions {
            rotation_search: true,
            ..AlignOptions::default()
        };
        let a = align(&scan, &target, &opts).unwrap();
        assert!(a.median_m() < 1e-5, "{a:?}");
        assert_eq!(axis_rotations().len(), 24);
    }
}
