//! Eigen-decomposition of small symmetric matrices by cyclic Jacobi rotations: the plane fit's
//! 3x3 scatter matrix (`scene fit`) and Horn's 4x4 quaternion matrix (`model align`).

/// Rotates the symmetric `a` towards diagonal form, sweep after sweep over the pairs
/// (p, q), p < q, in order, until `done(a)` holds before a sweep or 50 sweeps have run.
/// Returns the diagonal (eigenvalues) and `v` with the eigenvectors as columns
/// (`v[row][col]`).
pub fn symmetric_eigen<const N: usize>(
    mut a: [[f64; N]; N],
    done: impl Fn(&[[f64; N]; N]) -> bool,
) -> ([f64; N], [[f64; N]; N]) {
    let mut v = [[0.0f64; N]; N];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _ in 0..50 {
        if done(&a) {
            break;
        }
        for p in 0..N.saturating_sub(1) {
            for q in p + 1..N {
                if a[p][q].abs() < 1e-300 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                // a' = Jᵀ a J with J the rotation in the (p, q) plane.
                for row in a.iter_mut() {
                    let (akp, akq) = (row[p], row[q]);
                    row[p] = c * akp - s * akq;
                    row[q] = s * akp + c * akq;
                }
                let (rp, rq) = (a[p], a[q]);
                a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
                a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
                for row in v.iter_mut() {
                    let (vp, vq) = (row[p], row[q]);
                    row[p] = c * vp - s * vq;
                    row[q] = s * vp + c * vq;
                }
            }
        }
    }
    (std::array::from_fn(|i| a[i][i]), v)
}
