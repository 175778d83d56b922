//! The per-pixel ADD distance with the minimum over an object's symmetries, as one node.
//!
//! Full's loss (and the RGB model's rotation loss) compares, per pixel i of cloud b, the
//! model points posed by the pixel's prediction with the GT-posed points under each symmetry
//! k: `min_k (1/M) Σ_j ‖R_bi x_bj + t_bi − y_bkj‖`. Written with candle's ops it is a
//! (B, N, K, M, 3) tensor (4.8 M values for 32 clouds of 500 pixels and 100 model points)
//! through a broadcast subtraction, a square, a sum, a square root, a mean and a minimum, each
//! on one thread, forward and backward: a third of a Full training step on 2 cores
//! (docs/benchmarks.md). Here the forward pass computes each pixel's distances in place and
//! the backward pass the gradients of `R` and `t` (the points and targets are data), both in
//! parallel over the pixels; the values are those of the composed ops up to the order of the
//! three products of `R x` (and bit-identical for any number of threads).

use candle_core::{CpuStorage, CustomOp2, Layout, Result, Shape, Tensor, D};
use rayon::prelude::*;

use crate::fused::{f32_slice, fused_path};

/// Inside the square root, as the composed form has it: keeps the gradient finite at zero
/// distance.
const EPS: f32 = 1e-12;

/// Per pixel, min over the symmetries k of the mean distance (B, N). `pred_r`: (B, N, 3, 3)
/// row-major rotations; `pred_t`: (B, N, 3) or (B, 1, 3) (one translation per cloud);
/// `points`: (B, M, 3) model points; `targets`: (B, K, M, 3) the points under the GT pose
/// composed with each symmetry. Gradients flow to `pred_r` and `pred_t` only: on the CPU the
/// fused node treats `points` and `targets` as data (when either tracks a gradient, the
/// composed ops run instead).
pub fn symmetric_add_distances(
    pred_r: &Tensor,
    pred_t: &Tensor,
    points: &Tensor,
    targets: &Tensor,
) -> Result<Tensor> {
    let (b, n, r1, r2) = pred_r.dims4()?;
    let (bt, nt, t3) = pred_t.dims3()?;
    let (bp, m, p3) = points.dims3()?;
    let (bk, k, mk, k3) = targets.dims4()?;
    if r1 != 3 || r2 != 3 || t3 != 3 || p3 != 3 || k3 != 3 {
        candle_core::bail!(
            "symmetric ADD: rotations {:?}, translations {:?}, points {:?}, targets {:?} are not 3-D",
            pred_r.dims(),
            pred_t.dims(),
            points.dims(),
            targets.dims()
        );
    }
    if bt != b || bp != b || bk != b || mk != m || !(nt == n || nt == 1) || m == 0 || k == 0 {
        candle_core::bail!(
            "symmetric ADD: rotations {:?}, translations {:?}, points {:?} and targets {:?} do not fit",
            pred_r.dims(),
            pred_t.dims(),
            points.dims(),
            targets.dims()
        );
    }
    let fused = [pred_r, pred_t, points, targets]
        .iter()
        .all(|t| fused_path(t))
        && !points.track_op()
        && !targets.track_op();
    if !fused {
        return composed(pred_r, pred_t, points, targets);
    }
    let op = SymmetricAdd {
        points: points.flatten_all()?.to_vec1()?,
        targets: targets.flatten_all()?.to_vec1()?,
        n,
        nt,
        m,
        k,
    };
    pred_r.contiguous()?.apply_op2(&pred_t.contiguous()?, op)
}

/// The same with candle's ops: any device, gradients to every input.
pub fn composed(
    pred_r: &Tensor,
    pred_t: &Tensor,
    points: &Tensor,
    targets: &Tensor,
) -> Result<Tensor> {
    let (b, n, _, _) = pred_r.dims4()?;
    let (_, m, _) = points.dims3()?;
    // All pixels' rotations in one batched matmul: x (B, M, 3) · R̂ as (B, 3, N·3), where
    // entry [k, (i, r)] = R̂_i[r, k]; gives (B, M, N, 3) = (R̂_i x_j)_r.
    let r_cols = pred_r
        .permute((0, 3, 1, 2))?
        .contiguous()?
        .reshape((b, 3, n * 3))?;
    let posed = points
        .matmul(&r_cols)?
        .reshape((b, m, n, 3))?
        .transpose(1, 2)?
        .broadcast_add(&pred_t.unsqueeze(2)?)?; // (B, N, M, 3)
                                                // (B, N, 1, M, 3) − (B, 1, K, M, 3).
    let diff = posed.unsqueeze(2)?.broadcast_sub(&targets.unsqueeze(1)?)?;
    let dist = (diff.sqr()?.sum(D::Minus1)? + f64::from(EPS))?.sqrt()?; // (B, N, K, M)
    dist.mean(D::Minus1)?.min(D::Minus1)
}

struct SymmetricAdd {
    /// (B, M, 3) and (B, K, M, 3), row-major.
    points: Vec<f32>,
    targets: Vec<f32>,
    n: usize,
    /// N, or 1 for one translation per cloud.
    nt: usize,
    m: usize,
    k: usize,
}

impl SymmetricAdd {
    /// Pixel `row` (= b·N + i)'s rotation and translation.
    fn pose<'a>(&self, r: &'a [f32], t: &'a [f32], row: usize) -> (&'a [f32], &'a [f32]) {
        let (b, i) = (row / self.n, row % self.n);
        let ti = if self.nt == 1 { b } else { b * self.n + i };
        (&r[row * 9..row * 9 + 9], &t[ti * 3..ti * 3 + 3])
    }

    /// Model point j of cloud b posed by (r, t), and its offset from target (b, k, j).
    fn offset(&self, r: &[f32], t: &[f32], b: usize, k: usize, j: usize) -> ([f32; 3], [f32; 3]) {
        let x = &self.points[(b * self.m + j) * 3..(b * self.m + j) * 3 + 3];
        let y = &self.targets[((b * self.k + k) * self.m + j) * 3..][..3];
        let mut d = [0f32; 3];
        for (c, dc) in d.iter_mut().enumerate() {
            let p = r[c * 3] * x[0] + r[c * 3 + 1] * x[1] + r[c * 3 + 2] * x[2] + t[c];
            *dc = p - y[c];
        }
        ([x[0], x[1], x[2]], d)
    }

    /// The mean distance to symmetry k's targets of every k, for pixel `row`.
    fn means(&self, r: &[f32], t: &[f32], row: usize) -> Vec<f32> {
        let b = row / self.n;
        let scale = (1.0 / self.m as f64) as f32;
        (0..self.k)
            .map(|k| {
                let mut acc = 0f32;
                for j in 0..self.m {
                    let (_, d) = self.offset(r, t, b, k, j);
                    acc += (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + EPS).sqrt();
                }
                acc * scale
            })
            .collect()
    }
}

/// Rows of work per rayon task.
const ROWS_PER_TASK: usize = 64;

impl CustomOp2 for SymmetricAdd {
    fn name(&self) -> &'static str {
        "symmetric-add"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let r = f32_slice(s1, l1, self.name())?;
        let t = f32_slice(s2, l2, self.name())?;
        let rows = r.len() / 9;
        let mut out = vec![0f32; rows];
        out.par_chunks_mut(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(c, chunk)| {
                for (o, v) in chunk.iter_mut().enumerate() {
                    let row = c * ROWS_PER_TASK + o;
                    let (ri, ti) = self.pose(r, t, row);
                    *v = self
                        .means(ri, ti, row)
                        .into_iter()
                        .fold(f32::INFINITY, f32::min);
                }
            });
        Ok((CpuStorage::F32(out), Shape::from((rows / self.n, self.n))))
    }

    fn bwd(
        &self,
        arg1: &Tensor,
        arg2: &Tensor,
        _res: &Tensor,
        grad_res: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>)> {
        let r: Vec<f32> = arg1.flatten_all()?.to_vec1()?;
        let t: Vec<f32> = arg2.flatten_all()?.to_vec1()?;
        let g: Vec<f32> = grad_res.flatten_all()?.to_vec1()?;
        let rows = r.len() / 9;
        let scale = (1.0 / self.m as f64) as f32;
        // Per pixel: dR (9) and dt (3).
        let mut grads = vec![0f32; rows * 12];
        grads
            .par_chunks_mut(12 * ROWS_PER_TASK)
            .enumerate()
            .for_each(|(c, chunk)| {
                for (o, gr) in chunk.chunks_mut(12).enumerate() {
                    let row = c * ROWS_PER_TASK + o;
                    let (ri, ti) = self.pose(&r, &t, row);
                    let means = self.means(ri, ti, row);
                    let min = means.iter().copied().fold(f32::INFINITY, f32::min);
                    let gm = g[row] * scale;
                    let b = row / self.n;
                    // As candle's `min` backward: every k at the minimum gets the gradient.
                    for (k, _) in means.iter().enumerate().filter(|(_, &v)| v == min) {
                        for j in 0..self.m {
                            let (x, d) = self.offset(ri, ti, b, k, j);
                            let dist = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + EPS).sqrt();
                            for rr in 0..3 {
                                let u = gm * d[rr] / dist;
                                for cc in 0..3 {
                                    gr[rr * 3 + cc] += u * x[cc];
                                }
                                gr[9 + rr] += u;
                            }
                        }
                    }
                }
            });
        let mut dr = Vec::with_capacity(rows * 9);
        let mut dt_rows = Vec::with_capacity(rows * 3);
        for gr in grads.chunks(12) {
            dr.extend_from_slice(&gr[..9]);
            dt_rows.extend_from_slice(&gr[9..]);
        }
        let dr = Tensor::from_vec(dr, arg1.shape(), arg1.device())?;
        let dt = if self.nt == 1 {
            // One translation per cloud: the sum over its pixels, in pixel order.
            let mut dt = vec![0f32; rows / self.n * 3];
            for (row, d) in dt_rows.chunks(3).enumerate() {
                let b = row / self.n;
                for c in 0..3 {
                    dt[b * 3 + c] += d[c];
                }
            }
            Tensor::from_vec(dt, arg2.shape(), arg2.device())?
        } else {
            Tensor::from_vec(dt_rows, arg2.shape(), arg2.device())?
        };
        Ok((Some(dr), Some(dt)))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    fn max_rel(a: &Tensor, b: &Tensor) -> f32 {
        let d: f32 = (a - b)
            .unwrap()
            .abs()
            .unwrap()
            .max_all()
            .unwrap()
            .to_scalar()
            .unwrap();
        let m: f32 = b.abs().unwrap().max_all().unwrap().to_scalar().unwrap();
        d / m.max(1e-6)
    }

    /// The fused node and the composed ops: the same distances and gradients, for per-pixel
    /// and per-cloud translations, one symmetry and several (with the minimum switching
    /// between them across pixels).
    #[test]
    fn fused_distances_and_gradients_are_the_composed_ones() {
        let dev = Device::Cpu;
        let (b, n, m) = (3usize, 70usize, 11usize);
        for (k, nt) in [(1usize, n), (4, n), (3, 1)] {
            let r =
                Var::from_tensor(&Tensor::randn(0f32, 1.0, (b, n, 3, 3), &dev).unwrap()).unwrap();
            let t = Var::from_tensor(&Tensor::randn(0f32, 0.3, (b, nt, 3), &dev).unwrap()).unwrap();
            let points = Tensor::randn(0f32, 0.1, (b, m, 3), &dev).unwrap();
            let targets = Tensor::randn(0f32, 0.1, (b, k, m, 3), &dev).unwrap();
            let w = Tensor::randn(0f32, 1.0, (b, n), &dev).unwrap();
            let got = symmetric_add_distances(&r, &t, &points, &targets).unwrap();
            let want = composed(&r, &t, &points, &targets).unwrap();
            assert_eq!(got.dims(), &[b, n]);
            assert!(max_rel(&got, &want) < 1e-5, "k {k}: values");
            let gg = (&got * &w).unwrap().sum_all().unwrap().backward().unwrap();
            let gw = (&want * &w).unwrap().sum_all().unwrap().backward().unwrap();
            for v in [&r, &t] {
                let e = max_rel(gg.get(v).unwrap(), gw.get(v).unwrap());
                assert!(e < 1e-4, "k {k}, nt {nt}: gradient off by {e}");
            }
        }
    }

    #[test]
    fn mismatched_shapes_are_refused() {
        let dev = Device::Cpu;
        let r = Tensor::zeros((2, 5, 3, 3), candle_core::DType::F32, &dev).unwrap();
        let t = Tensor::zeros((2, 4, 3), candle_core::DType::F32, &dev).unwrap();
        let p = Tensor::zeros((2, 6, 3), candle_core::DType::F32, &dev).unwrap();
        let y = Tensor::zeros((2, 1, 6, 3), candle_core::DType::F32, &dev).unwrap();
        let e = symmetric_add_distances(&r, &t, &p, &y).unwrap_err();
        assert!(e.to_string().contains("do not fit"), "{e}");
    }
}
