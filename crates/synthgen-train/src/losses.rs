//! The losses of RNet and Full: the confidence-weighted quaternion loss and the per-pixel
//! ADD loss with the minimum over an object's symmetries (equation (6) of the reference
//! study), plain and confidence-weighted; and the RGB model's: smooth L1 for the translation,
//! the rotation's point-matching loss with the minimum over the symmetries.

use candle_core::{Result, Tensor, D};
use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::{Pose, Symmetries};

/// RNet: (1/BN) Σ (L_i c_i − w log c_i) with L_i = 1 − |⟨q, q̂_i⟩|.
/// `q_gt`: (B, 4) unit; `q_pred`: (B, N, 4) unit; `conf`: (B, N) in (0, 1].
pub fn quaternion_confidence_loss(
    q_gt: &Tensor,
    q_pred: &Tensor,
    conf: &Tensor,
    w: f64,
) -> Result<Tensor> {
    let dot = q_pred.broadcast_mul(&q_gt.unsqueeze(1)?)?.sum(D::Minus1)?; // (B, N)
    let l = (1.0 - dot.abs()?)?;
    ((l * conf)? - (conf.log()? * w)?)?.mean_all()
}

/// Full: per pixel i, min over symmetries k of (1/M) Σ_j ‖(R̂_i x_j + t̂_i) − y_kj‖, averaged
/// over pixels and clouds. `pred_r`: (B, N, 3, 3); `pred_t`: (B, N, 3); `points`: (B, M, 3)
/// model points; `targets`: (B, K, M, 3), the model points under the GT pose composed with
/// each symmetry (see [`symmetric_targets`]; K = 1 for asymmetric objects).
pub fn symmetric_add_loss(
    pred_r: &Tensor,
    pred_t: &Tensor,
    points: &Tensor,
    targets: &Tensor,
) -> Result<Tensor> {
    symmetric_add_per_pixel(pred_r, pred_t, points, targets)?.mean_all()
}

/// The per-pixel distances of [`symmetric_add_loss`], (B, N), before averaging.
pub fn symmetric_add_per_pixel(
    pred_r: &Tensor,
    pred_t: &Tensor,
    points: &Tensor,
    targets: &Tensor,
) -> Result<Tensor> {
    // One multi-threaded node on the CPU (candle's ops elsewhere).
    synthgen_nn::point_distance::symmetric_add_distances(pred_r, pred_t, points, targets)
}

/// Full's confidence-weighted form (DenseFusion): (1/BN) Σ (d_i c_i − w log c_i), with d_i
/// the per-pixel distances of [`symmetric_add_per_pixel`] (metres) and `conf`: (B, N).
pub fn confident_add_loss(dist: &Tensor, conf: &Tensor, w: f64) -> Result<Tensor> {
    ((dist * conf)? - (conf.log()? * w)?)?.mean_all()
}

/// Smooth L1 (Huber with slope 1): 0.5 d²/β where |d| < β, |d| − β/2 beyond, summed over the
/// last dimension and averaged over the rest. `pred`, `target`: (B, C).
pub fn smooth_l1_loss(pred: &Tensor, target: &Tensor, beta: f64) -> Result<Tensor> {
    let d = (pred - target)?.abs()?;
    let m = d.minimum(beta)?;
    ((m.sqr()? * (0.5 / beta))? + (&d - &m)?)?
        .sum(D::Minus1)?
        .mean_all()
}

/// The RGB model's rotation loss: per crop, min over the symmetry transforms k of
/// (1/M) Σ_j ‖R̂ x_j − y_kj‖, averaged over crops. PoseCNN's point-matching loss, with the
/// minimum over the object's symmetries (as Full's) for symmetric objects instead of its
/// nearest-point ShapeMatch loss. `quats`: (B, 4) unit (w, x, y, z); `points`: (B, M, 3) model
/// points; `targets`: (B, K, M, 3) the points under the GT rotation composed with each
/// symmetry, without translation (see [`symmetric_targets`] with a zero GT translation).
pub fn rotation_points_loss(quats: &Tensor, points: &Tensor, targets: &Tensor) -> Result<Tensor> {
    let b = quats.dim(0)?;
    let r = crate::quat::quaternion_to_matrix(quats)?.unsqueeze(1)?;
    let t = Tensor::zeros((b, 1, 3), quats.dtype(), quats.device())?;
    symmetric_add_per_pixel(&r, &t, points, targets)?.mean_all()
}

/// The symmetry transforms of an object (object frame, metres), the identity first:
/// `symmetries_discrete` as given (4x4 row-major, mm), each continuous symmetry discretized
/// into `continuous_steps` rotations about its axis through its offset.
pub fn symmetry_poses(sym: &Symmetries, continuous_steps: usize) -> Vec<Pose> {
    let mut out = vec![Pose::IDENTITY];
    for s in &sym.symmetries_discrete {
        let r = [s[0], s[1], s[2], s[4], s[5], s[6], s[8], s[9], s[10]];
        out.push(Pose::from_bop(&r, &[s[3], s[7], s[11]]).orthonormalized());
    }
    for c in &sym.symmetries_continuous {
        let axis = DVec3::from_array(c.axis).normalize_or_zero();
        let offset = DVec3::from_array(c.offset) / 1000.0;
        if axis == DVec3::ZERO {
            continue;
        }
        for k in 1..continuous_steps.max(1) {
            let r = DMat3::from_axis_angle(
                axis,
                std::f64::consts::TAU * k as f64 / continuous_steps as f64,
            );
            // Rotation about the axis through `offset`: x ↦ R (x − o) + o.
            out.push(Pose::new(r, offset - r * offset));
        }
    }
    out
}

/// (K·M·3) values for [`symmetric_add_loss`]'s targets of one cloud: y_kj = gt ∘ S_k (x_j).
pub fn symmetric_targets(points_m: &[DVec3], gt: &Pose, syms: &[Pose]) -> Vec<f32> {
    syms.iter()
        .flat_map(|s| {
            let p = gt.compose(s);
            points_m
                .iter()
                .flat_map(move |&x| p.transform_point(x).to_array().map(|v| v as f32))
        })
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_core::{DType, Device, Var};
    use rand::{Rng, SeedableRng};

    /// Central finite differences of `f` at every entry of `v`, against autograd.
    fn grad_check(v: &Var, f: &dyn Fn(&Tensor) -> Tensor) {
        let loss = f(v.as_tensor());
        let grads = loss.backward().unwrap();
        let g: Vec<f64> = grads
            .get(v)
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap();
        let x0: Vec<f64> = v.as_tensor().flatten_all().unwrap().to_vec1().unwrap();
        let shape = v.as_tensor().shape().clone();
        let h = 1e-6;
        for i in 0..x0.len() {
            let at = |d: f64| {
                let mut x = x0.clone();
                x[i] += d;
                let t = Tensor::from_vec(x, shape.clone(), &Device::Cpu).unwrap();
                f(&t).to_scalar::<f64>().unwrap()
            };
            let num = (at(h) - at(-h)) / (2.0 * h);
            assert!(
                (num - g[i]).abs() < 1e-5 * (1.0 + num.abs()),
                "entry {i}: numeric {num} vs autograd {}",
                g[i]
            );
        }
    }

    fn rand_tensor(rng: &mut rand_chacha::ChaCha8Rng, shape: &[usize], lo: f64, hi: f64) -> Tensor {
        let n: usize = shape.iter().product();
        let v: Vec<f64> = (0..n).map(|_| rng.gen_range(lo..hi)).collect();
        Tensor::from_vec(v, shape, &Device::Cpu).unwrap()
    }

    #[test]
    fn quaternion_loss_gradients_match_finite_differences() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let q = rand_tensor(&mut rng, &[2, 4], -1.0, 1.0);
        let q = q
            .broadcast_div(&q.sqr().unwrap().sum_keepdim(1).unwrap().sqrt().unwrap())
            .unwrap();
        let qp = Var::from_tensor(&rand_tensor(&mut rng, &[2, 3, 4], -1.0, 1.0)).unwrap();
        let c = Var::from_tensor(&rand_tensor(&mut rng, &[2, 3], 0.2, 1.0)).unwrap();
        let c_t = c.as_tensor().clone();
        grad_check(&qp, &|t| {
            quaternion_confidence_loss(&q, t, &c_t, 0.015).unwrap()
        });
        let qp_t = qp.as_tensor().clone();
        grad_check(&c, &|t| {
            quaternion_confidence_loss(&q, &qp_t, t, 0.015).unwrap()
        });
    }

    #[test]
    fn add_loss_gradients_match_finite_differences() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        let r = Var::from_tensor(&rand_tensor(&mut rng, &[1, 2, 3, 3], -1.0, 1.0)).unwrap();
        let t = Var::from_tensor(&rand_tensor(&mut rng, &[1, 2, 3], -0.1, 0.1)).unwrap();
        let pts = rand_tensor(&mut rng, &[1, 4, 3], -0.05, 0.05);
        let targets = rand_tensor(&mut rng, &[1, 2, 4, 3], -0.1, 0.1);
        let t_t = t.as_tensor().clone();
        grad_check(&r, &|x| {
            symmetric_add_loss(x, &t_t, &pts, &targets).unwrap()
        });
        let r_t = r.as_tensor().clone();
        grad_check(&t, &|x| {
            symmetric_add_loss(&r_t, x, &pts, &targets).unwrap()
        });
    }

    #[test]
    fn smooth_l1_values_and_gradients() {
        let dev = Device::Cpu;
        let p = Tensor::from_vec(vec![0.05f64, -0.3, 2.0, 0.0], (2, 2), &dev).unwrap();
        let y = Tensor::zeros((2, 2), DType::F64, &dev).unwrap();
        let l = smooth_l1_loss(&p, &y, 0.1)
            .unwrap()
            .to_scalar::<f64>()
            .unwrap();
        // 0.5·0.05²/0.1 + (0.3 − 0.05) and (2 − 0.05) + 0, averaged over the two rows.
        let want = (0.0125 + 0.25 + 1.95 + 0.0) / 2.0;
        assert!((l - want).abs() < 1e-12, "{l} vs {want}");
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let v = Var::from_tensor(&rand_tensor(&mut rng, &[3, 3], -0.5, 0.5)).unwrap();
        let target = rand_tensor(&mut rng, &[3, 3], -0.5, 0.5);
        grad_check(&v, &|x| smooth_l1_loss(x, &target, 0.1).unwrap());
    }

    #[test]
    fn rotation_loss_gradients_match_finite_differences_through_the_head() {
        // From the head's raw outputs: normalization, quaternion → matrix, point loss.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let raw = Var::from_tensor(&rand_tensor(&mut rng, &[2, 4], -0.8, 0.8)).unwrap();
        let pts = rand_tensor(&mut rng, &[2, 5, 3], -0.5, 0.5);
        let targets = rand_tensor(&mut rng, &[2, 3, 5, 3], -0.5, 0.5);
        grad_check(&raw, &|x| {
            let q = crate::models::rgb::normalize_quaternions(x).unwrap();
            rotation_points_loss(&q, &pts, &targets).unwrap()
        });
    }

    #[test]
    fn rotation_loss_is_zero_at_the_gt_and_the_same_for_minus_q() {
        let dev = Device::Cpu;
        let r = DMat3::from_axis_angle(DVec3::new(0.3, -1.0, 0.4).normalize(), 0.9);
        let pts = [
            DVec3::new(0.4, 0.1, -0.2),
            DVec3::new(-0.3, 0.5, 0.1),
            DVec3::new(0.0, -0.2, 0.6),
        ];
        let targets = Tensor::from_vec(
            symmetric_targets(&pts, &Pose::new(r, DVec3::ZERO), &[Pose::IDENTITY]),
            (1, 1, 3, 3),
            &dev,
        )
        .unwrap();
        let pts_t = Tensor::from_vec(
            pts.iter()
                .flat_map(|p| p.to_array().map(|v| v as f32))
                .collect::<Vec<_>>(),
            (1, 3, 3),
            &dev,
        )
        .unwrap();
        let q = crate::pose_model::quaternion_wxyz(&r).map(|v| v as f32);
        let loss = |q: [f32; 4]| {
            let t = Tensor::from_vec(q.to_vec(), (1, 4), &dev).unwrap();
            rotation_points_loss(&t, &pts_t, &targets)
                .unwrap()
                .to_scalar::<f32>()
                .unwrap()
        };
        assert!(loss(q) < 1e-3, "{}", loss(q));
        let off = crate::pose_model::quaternion_wxyz(&(r * DMat3::from_rotation_z(0.2)))
            .map(|v| v as f32);
        assert!(loss(off) > 0.02);
        assert!((loss(off) - loss(off.map(|v| -v))).abs() < 1e-6);
    }

    fn pred_tensors(poses: &[Pose]) -> (Tensor, Tensor) {
        let r: Vec<f32> = poses
            .iter()
            .flat_map(|p| p.rotation_row_major().map(|v| v as f32))
            .collect();
        let t: Vec<f32> = poses
            .iter()
            .flat_map(|p| p.translation_m.to_array().map(|v| v as f32))
            .collect();
        let n = poses.len();
        (
            Tensor::from_vec(r, (1, n, 3, 3), &Device::Cpu).unwrap(),
            Tensor::from_vec(t, (1, n, 3), &Device::Cpu).unwrap(),
        )
    }

    #[test]
    fn symmetric_loss_is_invariant_under_a_symmetry_of_the_prediction() {
        // A box-like object symmetric under 180° about z (discrete symmetry, 4x4 row-major, mm).
        let sym = Symmetries {
            symmetries_discrete: vec![[
                -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
            ]],
            symmetries_continuous: vec![],
        };
        let syms = symmetry_poses(&sym, 0);
        assert_eq!(syms.len(), 2);
        // The model's points are symmetric too: each point and its turned twin.
        let half = [
            (0.04, 0.02, 0.01),
            (-0.03, 0.02, -0.01),
            (0.01, -0.03, 0.02),
            (0.02, 0.0, 0.05),
        ];
        let pts: Vec<DVec3> = half
            .iter()
            .flat_map(|&(x, y, z)| [DVec3::new(x, y, z), DVec3::new(-x, -y, z)])
            .collect();
        let m = pts.len();
        let gt = Pose::new(DMat3::from_rotation_x(0.3), DVec3::new(0.05, -0.02, 0.7));
        let targets = Tensor::from_vec(
            symmetric_targets(&pts, &gt, &syms),
            (1, 2, m, 3),
            &Device::Cpu,
        )
        .unwrap();
        let pts_t = Tensor::from_vec(
            pts.iter()
                .flat_map(|p| p.to_array().map(|v| v as f32))
                .collect::<Vec<_>>(),
            (1, m, 3),
            &Device::Cpu,
        )
        .unwrap();
        let loss = |poses: &[Pose]| {
            let (r, t) = pred_tensors(poses);
            symmetric_add_loss(&r, &t, &pts_t, &targets)
                .unwrap()
                .to_dtype(DType::F64)
                .unwrap()
                .to_scalar::<f64>()
                .unwrap()
        };
        let preds = [
            Pose::new(DMat3::from_rotation_y(0.2), DVec3::new(0.04, -0.01, 0.72)),
            Pose::new(DMat3::from_rotation_z(1.0), DVec3::new(0.06, -0.03, 0.69)),
        ];
        let turned: Vec<Pose> = preds.iter().map(|p| p.compose(&syms[1])).collect();
        let (a, b) = (loss(&preds), loss(&turned));
        assert!(a > 1e-3, "{a}");
        assert!((a - b).abs() < 1e-6, "{a} vs {b}");
        // The GT turned by its symmetry scores zero; without the symmetry it would not.
        assert!(loss(&[gt.compose(&syms[1])]) < 1e-5);
    }

    #[test]
    fn continuous_symmetry_is_discretized_about_its_axis() {
        let sym = Symmetries {
            symmetries_discrete: vec![],
            symmetries_continuous: vec![synthgen_core::symmetry::ContinuousSymmetry {
                axis: [0.0, 0.0, 1.0],
                offset: [0.0; 3],
            }],
        };
        let s = symmetry_poses(&sym, 36);
        assert_eq!(s.len(), 36);
        // Points on the axis stay put.
        for p in &s {
            assert!(
                (p.transform_point(DVec3::new(0.0, 0.0, 0.1)) - DVec3::new(0.0, 0.0, 0.1)).length()
                    < 1e-12
            );
        }
    }
}
