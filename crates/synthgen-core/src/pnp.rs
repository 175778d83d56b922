//! Perspective-n-point: an object's pose from correspondences between points of its model
//! (metres, model frame) and the pixels they project to, as correspondence-based RGB pose
//! models need (per-pixel object coordinates → pose). Our own, no dependency:
//!
//! 1. [`dlt`]: the direct linear transform on normalized image coordinates, the model points
//!    centred and scaled (Hartley's conditioning); the 3x4 matrix is the eigenvector of the
//!    smallest eigenvalue of AᵀA (12x12, cyclic Jacobi), its 3x3 part projected to the nearest
//!    rotation (polar decomposition), the sign chosen so the points lie in front of the
//!    camera. Needs ≥ 6 points not on one line (coplanar ones: the homography start below).
//! 2. [`refine`]: Levenberg-Marquardt on the reprojection error in pixels (rotation updated
//!    on the left by exp(ω), translation additively; analytic 2x6 Jacobians).
//! 3. [`ransac`]: 6-point samples from a seeded generator (deterministic), inliers by
//!    reprojection error, the iteration count adapted to the best inlier ratio so far for the
//!    asked confidence; the winner refined on its inliers, inliers recounted, refined again.
//!
//! Coplanar model points (one face of a box) are degenerate for the 3D DLT: [`dlt`] then
//! starts from the plane's homography instead (Zhang's decomposition); collinear points give
//! no pose.

use glam::{DMat3, DVec2, DVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::{Intrinsics, Pose};

/// RANSAC settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RansacOptions {
    /// A correspondence is an inlier when its reprojection error is below this, pixels.
    pub inlier_px: f64,
    /// Stop once a sample of inliers has been drawn with this probability.
    pub confidence: f64,
    /// At most this many samples.
    pub max_iterations: usize,
    /// Fewer inliers than this: no pose.
    pub min_inliers: usize,
    /// The sampler's seed.
    pub seed: u64,
}

impl Default for RansacOptions {
    fn default() -> Self {
        RansacOptions {
            inlier_px: 3.0,
            confidence: 0.999,
            max_iterations: 2000,
            min_inliers: 6,
            seed: 0,
        }
    }
}

/// A pose from [`ransac`].
#[derive(Debug, Clone, PartialEq)]
pub struct PnpSolution {
    /// cam_from_model.
    pub pose: Pose,
    /// Indices of the correspondences within `inlier_px` of the final pose.
    pub inliers: Vec<usize>,
    /// Root mean square reprojection error over the inliers, pixels.
    pub rms_px: f64,
    /// Samples drawn.
    pub iterations: usize,
}

/// The object coordinates of a rendered frame, the training target of a correspondence
/// model: per pixel showing object `i` (`instance` = i + 1, as the renderers write it), the
/// model-frame point `poses[i]⁻¹ (z · K⁻¹ (x, y, 1))` at the pixel centre with the frame's z
/// depth `depth_m`; NaN elsewhere (background, ids without a pose, no depth).
pub fn object_coordinates(
    k: &Intrinsics,
    depth_m: &[f32],
    instance: &[u16],
    poses: &[Pose],
) -> Vec<[f32; 3]> {
    let w = k.width as usize;
    let inverse: Vec<Pose> = poses.iter().map(Pose::inverse).collect();
    depth_m
        .iter()
        .zip(instance)
        .enumerate()
        .map(|(i, (&z, &id))| {
            let Some(obj_from_cam) = (id as usize).checked_sub(1).and_then(|o| inverse.get(o))
            else {
                return [f32::NAN; 3];
            };
            if z <= 0.0 || !z.is_finite() {
                return [f32::NAN; 3];
            }
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let z = f64::from(z);
            let cam = DVec3::new((x - k.cx) / k.fx * z, (y - k.cy) / k.fy * z, z);
            obj_from_cam.transform_point(cam).as_vec3().to_array()
        })
        .collect()
}

/// Pixel of `p` (camera frame) through `k`; None behind the camera.
fn project(k: &Intrinsics, p: DVec3) -> Option<DVec2> {
    (p.z > 1e-9).then(|| DVec2::new(k.fx * p.x / p.z + k.cx, k.fy * p.y / p.z + k.cy))
}

/// Reprojection error of one correspondence, pixels (infinite behind the camera).
pub fn reprojection_error(k: &Intrinsics, pose: &Pose, model: DVec3, pixel: DVec2) -> f64 {
    project(k, pose.rotation * model + pose.translation_m)
        .map_or(f64::INFINITY, |q| q.distance(pixel))
}

/// The direct linear transform from ≥ 6 correspondences (module docs). None when there are
/// fewer than 6, the model points are (nearly) coplanar or collinear, or the solution puts
/// the points behind the camera.
pub fn dlt(model: &[DVec3], pixels: &[DVec2], k: &Intrinsics) -> Option<Pose> {
    let n = model.len();
    if n < 6 || pixels.len() != n {
        return None;
    }
    // Conditioning: the points centred, at unit RMS distance from their centroid.
    let c = model.iter().copied().sum::<DVec3>() / n as f64;
    let rms = (model.iter().map(|p| (*p - c).length_squared()).sum::<f64>() / n as f64).sqrt();
    if rms < 1e-12 {
        return None;
    }
    let s = 1.0 / rms;
    // Coplanar or collinear points: the scatter's smallest eigenvalue against its largest.
    let mut scatter = [[0.0f64; 3]; 3];
    for p in model {
        let d = (*p - c) * s;
        for (i, row) in scatter.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v += d[i] * d[j];
            }
        }
    }
    let (ev, evec) = crate::jacobi::symmetric_eigen(scatter, |a| off_diagonal(a) < 1e-24);
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| ev[b].total_cmp(&ev[a]));
    let [hi, mid, lo] = order.map(|i| ev[i]);
    let axis = |i: usize| DVec3::new(evec[0][i], evec[1][i], evec[2][i]).normalize();
    if mid < 1e-6 * hi {
        return None; // collinear
    }
    if lo < PLANAR * hi {
        return planar(model, pixels, k, c, [axis(order[0]), axis(order[1])]);
    }
    let v: [f64; 12] = null_vector(model.iter().zip(pixels).flat_map(|(p, u)| {
        let x = (*p - c) * s;
        let (xn, yn) = ((u.x - k.cx) / k.fx, (u.y - k.cy) / k.fy);
        let h = [x.x, x.y, x.z, 1.0];
        let mut r1 = [0.0f64; 12];
        let mut r2 = [0.0f64; 12];
        for j in 0..4 {
            r1[j] = h[j];
            r1[8 + j] = -xn * h[j];
            r2[4 + j] = h[j];
            r2[8 + j] = -yn * h[j];
        }
        [r1, r2]
    }))?;
    // P = [M | t] for the conditioned points.
    let mut m = DMat3::from_cols(
        DVec3::new(v[0], v[4], v[8]),
        DVec3::new(v[1], v[5], v[9]),
        DVec3::new(v[2], v[6], v[10]),
    );
    let mut t = DVec3::new(v[3], v[7], v[11]);
    if m.determinant() < 0.0 {
        m = -m;
        t = -t;
    }
    let (r, lambda) = rotation_and_scale(m)?;
    // Back from the conditioned points: M = λ R, so p_cam = R (X − c) + t / (λ s).
    let t_cam = t / (lambda * s) - r * c;
    in_front(model, Pose::new(r, t_cam))
}

/// Below this share of the largest scatter eigenvalue, the smallest one means coplanar model
/// points (thinner than ~3 % of their extent): the homography start.
const PLANAR: f64 = 1e-3;

/// `pose` when it puts the points in front of the camera on average (a sign error puts every
/// point behind).
fn in_front(model: &[DVec3], pose: Pose) -> Option<Pose> {
    let mean_z = model
        .iter()
        .map(|p| pose.transform_point(*p).z)
        .sum::<f64>()
        / model.len() as f64;
    (mean_z > 0.0).then_some(pose)
}

/// The rotation nearest to `m` (`m` with a positive determinant; [`crate::pose::nearest_rotation`],
/// on `m` scaled to a unit mean square so that a small DLT scale does not read as singular)
/// and the mean of `m`'s singular values (trace(Rᵀ M) / 3). None when `m` is singular.
fn rotation_and_scale(m: DMat3) -> Option<(DMat3, f64)> {
    let norm = (m.to_cols_array().iter().map(|v| v * v).sum::<f64>() / 3.0).sqrt();
    if !norm.is_finite() || norm <= 1e-300 {
        return None;
    }
    let r = crate::pose::nearest_rotation(&(m * (1.0 / norm)))?;
    let rtm = r.transpose() * m;
    Some((r, (rtm.x_axis.x + rtm.y_axis.y + rtm.z_axis.z) / 3.0))
}

/// The unit vector x minimizing |A x| for the matrix A whose rows are `rows` (the eigenvector
/// of AᵀA's smallest eigenvalue, cyclic Jacobi): the DLTs' solution.
fn null_vector<const N: usize>(rows: impl Iterator<Item = [f64; N]>) -> Option<[f64; N]> {
    let mut ata = [[0.0f64; N]; N];
    for r in rows {
        for (i, row) in ata.iter_mut().enumerate() {
            if r[i] == 0.0 {
                continue;
            }
            for (j, v) in row.iter_mut().enumerate() {
                *v += r[i] * r[j];
            }
        }
    }
    let scale = ata
        .iter()
        .map(|r| r.iter().map(|v| v.abs()).fold(0.0, f64::max))
        .fold(0.0, f64::max);
    if let Some(v) = smallest_eigenvector(&ata, scale) {
        return Some(v);
    }
    let (values, vectors) =
        crate::jacobi::symmetric_eigen(ata, |a| off_diagonal(a) < 1e-26 * scale * scale);
    let best = (0..N).min_by(|&a, &b| values[a].total_cmp(&values[b]))?;
    Some(std::array::from_fn(|i| vectors[i][best]))
}

/// The unit eigenvector of the symmetric positive semi-definite `m`'s smallest eigenvalue by
/// inverse iteration (`m` + a shift of 1e-13 × its largest entry, Cholesky-factored once), to
/// the precision of the Jacobi solve it stands in for: ~20x fewer operations for RANSAC's
/// 12x12 minimal systems, the same vector (up to its sign, which the DLTs fix). None when the
/// factorization or the convergence fails (a smallest eigenvalue barely apart from the next,
/// as in degenerate samples): the caller then takes the Jacobi solve.
#[allow(clippy::needless_range_loop)] // triangular solves: index arithmetic reads clearest
fn smallest_eigenvector<const N: usize>(m: &[[f64; N]; N], scale: f64) -> Option<[f64; N]> {
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    let shift = 1e-13 * scale;
    let mut l = [[0.0f64; N]; N];
    for i in 0..N {
        for j in 0..=i {
            let mut sum = m[i][j] + if i == j { shift } else { 0.0 };
            for k in 0..j {
                sum -= l[i][k] * l[j][k];
            }
            if i == j {
                if sum <= 0.0 || !sum.is_finite() {
                    return None;
                }
                l[i][i] = sum.sqrt();
            } else {
                l[i][j] = sum / l[j][j];
            }
        }
    }
    let normalized = |v: [f64; N]| -> Option<[f64; N]> {
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        (n.is_finite() && n > 0.0).then(|| v.map(|x| x / n))
    };
    // A start with a share of every direction (no eigenvector is orthogonal to it by chance).
    let mut x = normalized(std::array::from_fn(|i| 1.0 + 0.1 * i as f64))?;
    for _ in 0..40 {
        // Solve (L Lᵀ) z = x.
        let mut y = [0.0f64; N];
        for i in 0..N {
            let mut s = x[i];
            for k in 0..i {
                s -= l[i][k] * y[k];
            }
            y[i] = s / l[i][i];
        }
        let mut z = [0.0f64; N];
        for i in (0..N).rev() {
            let mut s = y[i];
            for k in i + 1..N {
                s -= l[k][i] * z[k];
            }
            z[i] = s / l[i][i];
        }
        let next = normalized(z)?;
        let dot: f64 = next.iter().zip(&x).map(|(a, b)| a * b).sum();
        let step = next
            .iter()
            .zip(&x)
            .map(|(a, b)| (a - dot.signum() * b).powi(2))
            .sum::<f64>()
            .sqrt();
        x = next;
        if step < 1e-14 {
            // Converged; accepted when the residual |m x − λ x| is at Jacobi's precision.
            let mx: [f64; N] = std::array::from_fn(|i| (0..N).map(|j| m[i][j] * x[j]).sum());
            let lambda: f64 = mx.iter().zip(&x).map(|(a, b)| a * b).sum();
            let r = mx
                .iter()
                .zip(&x)
                .map(|(a, b)| (a - lambda * b).powi(2))
                .sum::<f64>()
                .sqrt();
            return (r <= 1e-12 * scale).then_some(x);
        }
    }
    None
}

/// The DLT for coplanar model points (a box seen on one face): in the plane's frame (origin
/// `c`, in-plane axes `axes`) the points are (a, b, 0), and the homography H from (a, b, 1) to
/// normalized image coordinates (9x9 DLT, the plane coordinates scaled to unit RMS) gives,
/// as in Zhang's calibration, r1 = h1 / λ, r2 = h2 / λ, r3 = r1 × r2 and t = h3 / λ with λ the
/// mean of |h1| and |h2|; the rotation made orthonormal, the sign with the points in front.
fn planar(
    model: &[DVec3],
    pixels: &[DVec2],
    k: &Intrinsics,
    c: DVec3,
    axes: [DVec3; 2],
) -> Option<Pose> {
    let normal = axes[0].cross(axes[1]);
    let basis = DMat3::from_cols(axes[0], axes[1], normal);
    let ab: Vec<DVec2> = model
        .iter()
        .map(|p| {
            let q = basis.transpose() * (*p - c);
            DVec2::new(q.x, q.y)
        })
        .collect();
    let rms = (ab.iter().map(|q| q.length_squared()).sum::<f64>() / ab.len() as f64).sqrt();
    if rms < 1e-12 {
        return None;
    }
    let s = 1.0 / rms;
    let h: [f64; 9] = null_vector(ab.iter().zip(pixels).flat_map(|(q, u)| {
        let (a, b) = (q.x * s, q.y * s);
        let (xn, yn) = ((u.x - k.cx) / k.fx, (u.y - k.cy) / k.fy);
        [
            [a, b, 1.0, 0.0, 0.0, 0.0, -xn * a, -xn * b, -xn],
            [0.0, 0.0, 0.0, a, b, 1.0, -yn * a, -yn * b, -yn],
        ]
    }))?;
    // Columns of H for the unscaled plane coordinates: h1, h2 times s.
    let mut h1 = DVec3::new(h[0], h[3], h[6]) * s;
    let mut h2 = DVec3::new(h[1], h[4], h[7]) * s;
    let mut h3 = DVec3::new(h[2], h[5], h[8]);
    if h3.z < 0.0 {
        (h1, h2, h3) = (-h1, -h2, -h3);
    }
    let lambda = (h1.length() + h2.length()) / 2.0;
    if lambda < 1e-300 {
        return None;
    }
    let (r1, r2) = (h1 / lambda, h2 / lambda);
    let (r_plane, _) = rotation_and_scale(DMat3::from_cols(r1, r2, r1.cross(r2)))?;
    let t_plane = h3 / lambda;
    // p_cam = R_p Bᵀ (X − c) + t_p.
    let r = r_plane * basis.transpose();
    in_front(model, Pose::new(r, t_plane - r * c))
}

fn off_diagonal<const N: usize>(a: &[[f64; N]; N]) -> f64 {
    let mut s = 0.0;
    for (i, row) in a.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            if i != j {
                s += v * v;
            }
        }
    }
    s
}

/// Levenberg-Marquardt on the reprojection error of `idx` (all correspondences when None),
/// from `start`, up to `max_iterations` steps; stops when a step changes the pose by less
/// than 1e-10 (radians, metres). Returns the start unchanged when it projects a point behind
/// the camera.
pub fn refine(
    model: &[DVec3],
    pixels: &[DVec2],
    k: &Intrinsics,
    start: Pose,
    idx: Option<&[usize]>,
    max_iterations: usize,
) -> Pose {
    let all: Vec<usize>;
    let idx = match idx {
        Some(i) => i,
        None => {
            all = (0..model.len()).collect();
            &all
        }
    };
    let cost = |pose: &Pose| -> f64 {
        idx.iter()
            .map(|&i| reprojection_error(k, pose, model[i], pixels[i]).powi(2))
            .sum()
    };
    let mut pose = start;
    let mut c = cost(&pose);
    if !c.is_finite() {
        return start;
    }
    let mut mu = 1e-3;
    for _ in 0..max_iterations {
        // Normal equations JᵀJ δ = −Jᵀr, δ = (ω, dt).
        let mut jtj = [[0.0f64; 6]; 6];
        let mut jtr = [0.0f64; 6];
        for &i in idx {
            let q = pose.rotation * model[i];
            let p = q + pose.translation_m;
            let (iz, iz2) = (1.0 / p.z, 1.0 / (p.z * p.z));
            let r = [
                k.fx * p.x * iz + k.cx - pixels[i].x,
                k.fy * p.y * iz + k.cy - pixels[i].y,
            ];
            // dπ/dp (2x3) times dp/d(ω, t) = [−[q]×, I].
            let dpi = [
                [k.fx * iz, 0.0, -k.fx * p.x * iz2],
                [0.0, k.fy * iz, -k.fy * p.y * iz2],
            ];
            // −[q]× = [[0, qz, −qy], [−qz, 0, qx], [qy, −qx, 0]].
            let skew = [[0.0, q.z, -q.y], [-q.z, 0.0, q.x], [q.y, -q.x, 0.0]];
            let mut jrow = [[0.0f64; 6]; 2];
            for a in 0..2 {
                for b in 0..3 {
                    jrow[a][b] = (0..3).map(|m| dpi[a][m] * skew[m][b]).sum();
                    jrow[a][3 + b] = dpi[a][b];
                }
            }
            for a in 0..2 {
                for u in 0..6 {
                    jtr[u] += jrow[a][u] * r[a];
                    for v in 0..6 {
                        jtj[u][v] += jrow[a][u] * jrow[a][v];
                    }
                }
            }
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj;
            for (u, row) in a.iter_mut().enumerate() {
                row[u] += mu * (jtj[u][u] + 1e-12);
            }
            let Some(delta) = solve6(a, jtr.map(|v| -v)) else {
                mu *= 10.0;
                continue;
            };
            let w = DVec3::new(delta[0], delta[1], delta[2]);
            let dt = DVec3::new(delta[3], delta[4], delta[5]);
            let turn = if w.length() > 0.0 {
                DMat3::from_axis_angle(w.normalize(), w.length())
            } else {
                DMat3::IDENTITY
            };
            // R' = exp(ω) R, t' = t + dt: p' = exp(ω) R X + t + dt ≈ p + ω × (R X) + dt, the
            // model the Jacobian above linearizes.
            let candidate = Pose::new(turn * pose.rotation, pose.translation_m + dt);
            let nc = cost(&candidate);
            if nc.is_finite() && nc <= c {
                let step = w.length() + dt.length();
                pose = candidate;
                c = nc;
                mu = (mu * 0.3).max(1e-12);
                improved = true;
                if step < 1e-10 {
                    return pose;
                }
                break;
            }
            mu *= 10.0;
        }
        if !improved {
            break;
        }
    }
    pose
}

/// Solves the 6x6 system `a x = b` by Gaussian elimination with partial pivoting.
pub fn solve6(mut a: [[f64; 6]; 6], mut b: [f64; 6]) -> Option<[f64; 6]> {
    for col in 0..6 {
        let piv = (col..6).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        let pivot = a[col];
        for row in col + 1..6 {
            let f = a[row][col] / pivot[col];
            for (v, p) in a[row].iter_mut().zip(&pivot).skip(col) {
                *v -= f * p;
            }
            b[row] -= f * b[col];
        }
    }
    let mut x = [0.0f64; 6];
    for row in (0..6).rev() {
        let s: f64 = (row + 1..6).map(|c| a[row][c] * x[c]).sum();
        x[row] = (b[row] - s) / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// RANSAC over 6-point DLT samples, then refinement (module docs). None when no sample gives
/// `min_inliers` inliers.
pub fn ransac(
    model: &[DVec3],
    pixels: &[DVec2],
    k: &Intrinsics,
    options: &RansacOptions,
) -> Option<PnpSolution> {
    let n = model.len();
    if n < 6 || pixels.len() != n {
        return None;
    }
    let inlier = |pose: &Pose, i: usize| {
        reprojection_error(k, pose, model[i], pixels[i]) < options.inlier_px
    };
    let inliers_of = |pose: &Pose| -> Vec<usize> { (0..n).filter(|&i| inlier(pose, i)).collect() };
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let mut best: Option<(Pose, usize)> = None;
    let mut needed = options.max_iterations;
    let mut iterations = 0;
    let (mut sm, mut sp) = (Vec::with_capacity(6), Vec::with_capacity(6));
    while iterations < needed.min(options.max_iterations) {
        iterations += 1;
        let mut pick = [0usize; 6];
        for s in 0..6 {
            loop {
                let i = rng.gen_range(0..n);
                if !pick[..s].contains(&i) {
                    pick[s] = i;
                    break;
                }
            }
        }
        sm.clear();
        sp.clear();
        sm.extend(pick.iter().map(|&i| model[i]));
        sp.extend(pick.iter().map(|&i| pixels[i]));
        let Some(pose) = dlt(&sm, &sp, k) else {
            continue;
        };
        let count = (0..n).filter(|&i| inlier(&pose, i)).count();
        if best.as_ref().is_none_or(|(_, c)| count > *c) {
            best = Some((pose, count));
            let w = count as f64 / n as f64;
            let miss = 1.0 - w.powi(6);
            // Samples needed to draw one all-inlier sample with the asked confidence, at
            // the best inlier ratio so far (no bound while it is ~0).
            needed = if miss <= 1e-12 {
                iterations
            } else if miss >= 1.0 - 1e-12 {
                options.max_iterations
            } else {
                let k = ((1.0 - options.confidence).ln() / miss.ln()).ceil();
                if k.is_finite() && k >= 0.0 {
                    (k as usize).max(iterations)
                } else {
                    options.max_iterations
                }
            };
        }
    }
    let (pose, count) = best?;
    if count < options.min_inliers.max(6) {
        return None;
    }
    let mut inliers = inliers_of(&pose);
    let mut pose = refine(model, pixels, k, pose, Some(&inliers), 50);
    for _ in 0..2 {
        let again = inliers_of(&pose);
        if again.len() < options.min_inliers.max(6) {
            break;
        }
        inliers = again;
        pose = refine(model, pixels, k, pose, Some(&inliers), 50);
    }
    let inliers = inliers_of(&pose);
    if inliers.len() < options.min_inliers.max(6) {
        return None;
    }
    let rms_px = (inliers
        .iter()
        .map(|&i| reprojection_error(k, &pose, model[i], pixels[i]).powi(2))
        .sum::<f64>()
        / inliers.len() as f64)
        .sqrt();
    Some(PnpSolution {
        pose,
        inliers,
        rms_px,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k() -> Intrinsics {
        Intrinsics {
            width: 640,
            height: 480,
            fx: 572.4,
            fy: 573.6,
            cx: 325.3,
            cy: 242.0,
        }
    }

    /// Points on and in a 10 x 6 x 4 cm box, from a seeded generator.
    fn cloud(n: usize, seed: u64) -> Vec<DVec3> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                DVec3::new(
                    rng.gen_range(-0.05..0.05),
                    rng.gen_range(-0.03..0.03),
                    rng.gen_range(-0.02..0.02),
                )
            })
            .collect()
    }

    fn truth() -> Pose {
        Pose::new(
            DMat3::from_euler(glam::EulerRot::XYZ, 0.7, -0.4, 2.1),
            DVec3::new(0.04, -0.03, 0.62),
        )
    }

    fn angle_deg(a: &DMat3, b: &DMat3) -> f64 {
        let r = a.transpose() * *b;
        ((r.x_axis.x + r.y_axis.y + r.z_axis.z - 1.0) / 2.0)
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    }

    fn pixels(pose: &Pose, model: &[DVec3]) -> Vec<DVec2> {
        model
            .iter()
            .map(|p| project(&k(), pose.rotation * *p + pose.translation_m).unwrap())
            .collect()
    }

    #[test]
    fn exact_correspondences_give_the_pose_back() {
        let model = cloud(12, 1);
        let px = pixels(&truth(), &model);
        let pose = dlt(&model, &px, &k()).unwrap();
        assert!(angle_deg(&pose.rotation, &truth().rotation) < 1e-6);
        assert!((pose.translation_m - truth().translation_m).length() < 1e-8);
        // From a pose 5 degrees and 2 cm off, LM lands on the truth.
        let off = Pose::new(
            DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 5f64.to_radians())
                * truth().rotation,
            truth().translation_m + DVec3::new(0.02, -0.01, 0.015),
        );
        let refined = refine(&model, &px, &k(), off, None, 100);
        assert!(angle_deg(&refined.rotation, &truth().rotation) < 1e-7);
        assert!((refined.translation_m - truth().translation_m).length() < 1e-9);
    }

    #[test]
    fn outliers_and_noise_are_survived() {
        let model = cloud(300, 2);
        let mut px = pixels(&truth(), &model);
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut outliers = 0;
        for (i, p) in px.iter_mut().enumerate() {
            if i % 5 < 2 {
                // 40 % wrong correspondences: anywhere in the image.
                *p = DVec2::new(rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0));
                outliers += 1;
            } else {
                *p += DVec2::new(rng.gen_range(-0.7..0.7), rng.gen_range(-0.7..0.7));
            }
        }
        let sol = ransac(&model, &px, &k(), &RansacOptions::default()).unwrap();
        let (re, te) = (
            angle_deg(&sol.pose.rotation, &truth().rotation),
            (sol.pose.translation_m - truth().translation_m).length(),
        );
        assert!(re < 1.0 && te < 0.005, "{re} deg, {te} m");
        // The inliers are the true correspondences (plus the rare outlier that lands near).
        let true_in = sol.inliers.iter().filter(|&&i| i % 5 >= 2).count();
        assert_eq!(true_in, 300 - outliers, "every true correspondence kept");
        assert!(sol.inliers.len() <= 300 - outliers + 3);
        assert!(sol.rms_px < 0.7, "{}", sol.rms_px);
        // Deterministic: the same seed draws the same samples.
        assert_eq!(
            ransac(&model, &px, &k(), &RansacOptions::default()),
            Some(sol)
        );
    }

    /// One face of a box (every model point on z = 0.02): the homography start, exact on exact
    /// data, and through RANSAC with outliers.
    #[test]
    fn coplanar_points_take_the_homography_start() {
        let flat: Vec<DVec3> = cloud(200, 5)
            .into_iter()
            .map(|p| DVec3::new(p.x, p.y, 0.02))
            .collect();
        let px = pixels(&truth(), &flat);
        let pose = dlt(&flat[..8], &px[..8], &k()).unwrap();
        assert!(angle_deg(&pose.rotation, &truth().rotation) < 1e-6);
        assert!((pose.translation_m - truth().translation_m).length() < 1e-8);
        let mut noisy = px.clone();
        let mut rng = ChaCha8Rng::seed_from_u64(6);
        for (i, p) in noisy.iter_mut().enumerate() {
            if i % 3 == 0 {
                *p = DVec2::new(rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0));
            } else {
                *p += DVec2::new(rng.gen_range(-0.5..0.5), rng.gen_range(-0.5..0.5));
            }
        }
        let sol = ransac(&flat, &noisy, &k(), &RansacOptions::default()).unwrap();
        let re = angle_deg(&sol.pose.rotation, &truth().rotation);
        let te = (sol.pose.translation_m - truth().translation_m).length();
        assert!(re < 1.0 && te < 0.005, "{re} deg, {te} m");
    }

    #[test]
    fn inverse_iteration_gives_jacobis_smallest_eigenvector() {
        // RANSAC's minimal systems: 6 noisy correspondences, 12 DLT rows.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut agreed = 0;
        for trial in 0..200 {
            let mut rows = Vec::new();
            for _ in 0..12 {
                rows.push(std::array::from_fn::<f64, 12, _>(|_| {
                    rng.gen_range(-1.0..1.0)
                }));
            }
            // A near null direction: the rows made almost orthogonal to v.
            let v: [f64; 12] = std::array::from_fn(|i| ((i + trial) as f64).sin());
            let vn = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            for r in rows.iter_mut() {
                let d = r.iter().zip(&v).map(|(a, b)| a * b).sum::<f64>() / (vn * vn);
                for (a, b) in r.iter_mut().zip(&v) {
                    *a -= d * b * (1.0 - 1e-4);
                }
            }
            let mut ata = [[0.0f64; 12]; 12];
            for r in &rows {
                for i in 0..12 {
                    for j in 0..12 {
                        ata[i][j] += r[i] * r[j];
                    }
                }
            }
            let scale = ata
                .iter()
                .map(|r| r.iter().map(|v| v.abs()).fold(0.0, f64::max))
                .fold(0.0, f64::max);
            let (values, vectors) =
                crate::jacobi::symmetric_eigen(ata, |a| off_diagonal(a) < 1e-26 * scale * scale);
            let best = (0..12)
                .min_by(|&a, &b| values[a].total_cmp(&values[b]))
                .unwrap();
            let jac: [f64; 12] = std::array::from_fn(|i| vectors[i][best]);
            if let Some(inv) = smallest_eigenvector(&ata, scale) {
                let dot: f64 = jac.iter().zip(&inv).map(|(a, b)| a * b).sum();
                assert!(1.0 - dot.abs() < 1e-12, "trial {trial}: {jac:?} vs {inv:?}");
                agreed += 1;
            }
        }
        // Well-separated smallest eigenvalues: inverse iteration answers (nearly) always.
        assert!(agreed >= 190, "{agreed}");
    }

    #[test]
    fn degenerate_input_gives_no_pose() {
        let model = cloud(20, 3);
        let px = pixels(&truth(), &model);
        assert!(dlt(&model[..5], &px[..5], &k()).is_none(), "5 points");
        // Collinear: every point on the x axis.
        let line: Vec<DVec3> = model.iter().map(|p| DVec3::new(p.x, 0.0, 0.0)).collect();
        let lpx = pixels(&truth(), &line);
        assert!(dlt(&line, &lpx, &k()).is_none(), "collinear");
        // Pure noise: no consensus.
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let noise: Vec<DVec2> = (0..20)
            .map(|_| DVec2::new(rng.gen_range(0.0..640.0), rng.gen_range(0.0..480.0)))
            .collect();
        let options = RansacOptions {
            min_inliers: 12,
            ..RansacOptions::default()
        };
        assert!(ransac(&model, &noise, &k(), &options).is_none());
    }
}
