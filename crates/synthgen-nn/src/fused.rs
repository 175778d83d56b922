//! Fused CPU kernels for the per-point layers: `relu(x·Wᵀ + b)` and the max-pool over points.
//!
//! Built from candle's primitives, one layer `relu(x·Wᵀ + b)` leaves four (rows × C) tensors in
//! the graph (product, broadcast bias, sum, relu) and its backward pass allocates and fills about
//! a dozen more (candle's relu gradient alone builds a zero tensor, a comparison, a cast and a
//! product; every gradient is first summed into a fresh zero tensor). With 16 000 rows per batch
//! that memory traffic, not the matrix products, was most of a TNet step (docs/benchmarks.md).
//! Here a whole layer `relu(x·Wᵀ + b)` ([`dense_relu`]) is one graph node: its forward pass
//! adds the bias and clamps in place on candle's matmul output, its backward pass masks the
//! gradient once (`grad` where the output is positive) and takes `dx`, `dW` and the bias
//! gradient (a column sum) from that; the max-pool ([`group_max`]) likewise. Only the CPU with
//! f32 takes these paths; other devices and dtypes compose candle's own ops, so the results
//! agree to rounding.

use candle_core::backend::BackendStorage;
use candle_core::{
    CpuStorage, CustomOp1, CustomOp2, CustomOp3, DType, Layout, Result, Shape, Tensor,
};
use rayon::prelude::*;

/// Rows per parallel chunk in the element-wise kernels.
const CHUNK_ROWS: usize = 512;

/// `relu(z + bias[group])` from candle's own ops, for `z` (rows, C) and `bias` (G, C) with rows
/// a multiple of G: row r belongs to group r / (rows / G) (G = 1: one bias for every row;
/// G = clouds: a per-cloud term, as TNet's global feature). The fallback of [`dense_relu`] on
/// other devices and dtypes, and the tests' reference.
fn composed_bias_relu(z: &Tensor, bias: &Tensor) -> Result<Tensor> {
    let (rows, c) = z.dims2()?;
    let g = bias.dim(0)?;
    z.reshape((g, rows / g, c))?
        .broadcast_add(&bias.unsqueeze(1)?)?
        .relu()?
        .reshape((rows, c))
}

/// `relu(x·Wᵀ + bias[group])` as one graph node: `x` (rows, in), `w` (out, in), `bias`
/// (G, out), one row per equal, contiguous group of rows (G = 1: one bias for every row).
/// Its backward pass computes `dx`, `dW` and the bias gradient from one masked gradient, so
/// no (rows × out) pre-activation is kept or accumulated.
pub fn dense_relu(x: &Tensor, w: &Tensor, bias: &Tensor) -> Result<Tensor> {
    let (rows, _) = x.dims2()?;
    let (out, _) = w.dims2()?;
    let (g, cb) = bias.dims2()?;
    if cb != out || g == 0 || rows % g != 0 {
        candle_core::bail!(
            "dense_relu: x {:?}, w {:?} and bias {:?} do not fit",
            x.dims(),
            w.dims(),
            bias.dims()
        );
    }
    if fused_path(x) && w.dtype() == DType::F32 && bias.dtype() == DType::F32 {
        x.contiguous()?
            .apply_op3(&w.contiguous()?, &bias.contiguous()?, DenseRelu)
    } else {
        composed_bias_relu(&x.matmul(&w.t()?)?, bias)
    }
}

/// Max over each of `groups` equal, contiguous groups of rows: (rows, C) → (groups, C).
pub fn group_max(x: &Tensor, groups: usize) -> Result<Tensor> {
    let (rows, c) = x.dims2()?;
    if groups == 0 || rows % groups != 0 || rows == 0 {
        candle_core::bail!("group_max: {rows} rows do not split into {groups} groups");
    }
    if fused_path(x) {
        x.contiguous()?.apply_op1(GroupMax { groups })
    } else {
        x.reshape((groups, rows / groups, c))?.max(1)
    }
}

/// `relu(x1·W1ᵀ + x2·W2ᵀ + b)` as one graph node: the layers of two inputs summed before the
/// ReLU (RNet's fusion of colour and point features). `x1` (rows, k1), `x2` (rows, k2), `w1`
/// (out, k1), `w2` (out, k2), `bias` (out) or none. As [`dense_relu`], no (rows × out)
/// product, sum or pre-activation is kept or accumulated; the backward pass skips the
/// gradient of an input that tracks none.
pub fn dense2_relu(
    x1: &Tensor,
    x2: &Tensor,
    w1: &Tensor,
    w2: &Tensor,
    bias: Option<&Tensor>,
) -> Result<Tensor> {
    let (rows, k1) = x1.dims2()?;
    let (rows2, k2) = x2.dims2()?;
    let (out, wk1) = w1.dims2()?;
    let (out2, wk2) = w2.dims2()?;
    let bias_ok = bias.map_or(Ok(true), |b| b.dims1().map(|n| n == out))?;
    if rows != rows2 || wk1 != k1 || wk2 != k2 || out2 != out || !bias_ok {
        candle_core::bail!(
            "dense2_relu: x1 {:?}, x2 {:?}, w1 {:?}, w2 {:?} do not fit",
            x1.dims(),
            x2.dims(),
            w1.dims(),
            w2.dims()
        );
    }
    let bias_col = match bias {
        Some(b) => b.unsqueeze(1)?,
        None => Tensor::zeros((out, 1), w1.dtype(), w1.device())?,
    };
    if [x1, x2, w1, w2, &bias_col].iter().all(|t| fused_path(t)) {
        // The weights and the bias as one small (out, k1 + k2 + 1) tensor: a custom op takes
        // at most three inputs.
        let wb = Tensor::cat(&[w1, w2, &bias_col], 1)?;
        return x1
            .contiguous()?
            .apply_op3(&x2.contiguous()?, &wb, Dense2Relu { k1, k2 });
    }
    (x1.matmul(&w1.t()?)? + x2.matmul(&w2.t()?)?)?
        .broadcast_add(&bias_col.t()?)?
        .relu()
}

/// The mean of each of `groups` equal, contiguous groups of rows: (rows, C) → (groups, C)
/// (RNet's global feature, the average over a cloud's pixels), accumulated in f64; its
/// backward pass spreads each group's gradient over its rows, in parallel.
pub fn group_mean(x: &Tensor, groups: usize) -> Result<Tensor> {
    let (rows, c) = x.dims2()?;
    if groups == 0 || rows % groups != 0 || rows == 0 {
        candle_core::bail!("group_mean: {rows} rows do not split into {groups} groups");
    }
    if fused_path(x) {
        x.contiguous()?.apply_op1(GroupMean { groups })
    } else {
        x.reshape((groups, rows / groups, c))?.mean(1)
    }
}

pub(crate) fn fused_path(t: &Tensor) -> bool {
    t.device().is_cpu() && t.dtype() == DType::F32
}

/// The f32 data of a contiguous CPU tensor.
pub(crate) fn f32_slice<'a>(s: &'a CpuStorage, l: &Layout, op: &str) -> Result<&'a [f32]> {
    let CpuStorage::F32(data) = s else {
        candle_core::bail!("{op}: f32 tensors only");
    };
    match l.contiguous_offsets() {
        Some((a, b)) => Ok(&data[a..b]),
        None => candle_core::bail!("{op}: contiguous tensors only"),
    }
}

/// `z ← relu(z + bias[group(row)])` in place; `z` holds rows × c values.
pub(crate) fn add_bias_relu_in_place(z: &mut [f32], bias: &[f32], c: usize, per_group: usize) {
    z.par_chunks_mut(CHUNK_ROWS * c)
        .enumerate()
        .for_each(|(k, z)| {
            for (i, z) in z.chunks_exact_mut(c).enumerate() {
                let g = (k * CHUNK_ROWS + i) / per_group;
                for (z, b) in z.iter_mut().zip(&bias[g * c..(g + 1) * c]) {
                    *z = (*z + b).max(0.0);
                }
            }
        });
}

struct DenseRelu;

impl CustomOp3 for DenseRelu {
    fn name(&self) -> &'static str {
        "dense-relu"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (rows, k) = l1.shape().dims2()?;
        let (out, _) = l2.shape().dims2()?;
        let bias = f32_slice(s3, l3, self.name())?;
        let per_group = rows / l3.shape().dims2()?.0;
        // x (rows, k) · wᵀ (k, out) with candle's own CPU matmul.
        let z = s1.matmul(s2, (1, rows, out, k), l1, &l2.transpose(0, 1)?)?;
        let CpuStorage::F32(mut z) = z else {
            candle_core::bail!("dense-relu: f32 tensors only");
        };
        add_bias_relu_in_place(&mut z, bias, out, per_group);
        Ok((CpuStorage::F32(z), Shape::from((rows, out))))
    }

    fn bwd(
        &self,
        x: &Tensor,
        w: &Tensor,
        bias: &Tensor,
        res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let dz = grad.contiguous()?.apply_op2_no_bwd(res, &ReluMask)?;
        // The two products are independent; run them side by side (the tall-skinny dW product
        // does not keep both cores busy on its own).
        // No input gradient for data (the first layer's points).
        let (dx, dw) = rayon::join(
            || x.track_op().then(|| dz.matmul(&w.detach())).transpose(),
            || dz.t().and_then(|t| t.matmul(&x.detach())),
        );
        let (dx, dw) = (dx?, dw?);
        let db = dz.apply_op1_no_bwd(&GroupSum {
            groups: bias.dim(0)?,
        })?;
        Ok((dx, Some(dw), Some(db)))
    }
}

/// `grad` where `res` > 0, else 0 (the relu gradient, from the relu's output).
pub(crate) struct ReluMask;

impl CustomOp2 for ReluMask {
    fn name(&self) -> &'static str {
        "relu-mask"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let grad = f32_slice(s1, l1, self.name())?;
        let res = f32_slice(s2, l2, self.name())?;
        if grad.len() != res.len() {
            candle_core::bail!("relu-mask: shapes differ");
        }
        let out: Vec<f32> = grad
            .par_iter()
            .zip(res.par_iter())
            .with_min_len(1 << 14)
            .map(|(g, r)| if *r > 0.0 { *g } else { 0.0 })
            .collect();
        Ok((CpuStorage::F32(out), l1.shape().clone()))
    }
}

/// Column sums per group of rows: (rows, C) → (G, C), accumulated in f64.
pub(crate) struct GroupSum {
    pub(crate) groups: usize,
}

impl CustomOp1 for GroupSum {
    fn name(&self) -> &'static str {
        "group-sum"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let x = f32_slice(s, l, self.name())?;
        let (rows, c) = l.shape().dims2()?;
        let per_group = rows / self.groups;
        // Chunks never straddle two groups.
        let chunk = if self.groups == 1 {
            CHUNK_ROWS
        } else {
            per_group
        }
        .max(1);
        let partial: Vec<(usize, Vec<f64>)> = x
            .par_chunks(chunk * c)
            .enumerate()
            .map(|(k, rows_k)| {
                let mut acc = vec![0f64; c];
                for row in rows_k.chunks_exact(c) {
                    for (a, v) in acc.iter_mut().zip(row) {
                        *a += f64::from(*v);
                    }
                }
                (k * chunk / per_group, acc)
            })
            .collect();
        let mut sums = vec![0f64; self.groups * c];
        for (g, acc) in partial {
            for (s, a) in sums[g * c..(g + 1) * c].iter_mut().zip(acc) {
                *s += a;
            }
        }
        let out = sums.into_iter().map(|v| v as f32).collect();
        Ok((CpuStorage::F32(out), Shape::from((self.groups, c))))
    }
}

struct Dense2Relu {
    k1: usize,
    k2: usize,
}

impl Dense2Relu {
    /// Columns `from..from + k` of the (out, k1 + k2 + 1) weights, as a contiguous (out, k).
    fn block(wb: &[f32], out: usize, from: usize, k: usize) -> Vec<f32> {
        let width = wb.len() / out;
        (0..out)
            .flat_map(|o| wb[o * width + from..o * width + from + k].iter().copied())
            .collect()
    }
}

impl CustomOp3 for Dense2Relu {
    fn name(&self) -> &'static str {
        "dense2-relu"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let (k1, k2) = (self.k1, self.k2);
        let rows = l1.shape().dims2()?.0;
        let (out, _) = l3.shape().dims2()?;
        let wb = f32_slice(s3, l3, self.name())?;
        let product = |s: &CpuStorage, l: &Layout, from: usize, k: usize| -> Result<Vec<f32>> {
            let w = CpuStorage::F32(Self::block(wb, out, from, k));
            let wl = Layout::contiguous((out, k)).transpose(0, 1)?;
            match s.matmul(&w, (1, rows, out, k), l, &wl)? {
                CpuStorage::F32(z) => Ok(z),
                _ => candle_core::bail!("dense2-relu: f32 tensors only"),
            }
        };
        let (z1, z2) = rayon::join(|| product(s1, l1, 0, k1), || product(s2, l2, k1, k2));
        let (mut z, z2) = (z1?, z2?);
        let bias: Vec<f32> = (0..out).map(|o| wb[o * (k1 + k2 + 1) + k1 + k2]).collect();
        z.par_chunks_mut(CHUNK_ROWS * out)
            .zip(z2.par_chunks(CHUNK_ROWS * out))
            .for_each(|(z, z2)| {
                for (z, z2) in z.chunks_exact_mut(out).zip(z2.chunks_exact(out)) {
                    for ((z, z2), b) in z.iter_mut().zip(z2).zip(&bias) {
                        *z = (*z + z2 + b).max(0.0);
                    }
                }
            });
        Ok((CpuStorage::F32(z), Shape::from((rows, out))))
    }

    fn bwd(
        &self,
        x1: &Tensor,
        x2: &Tensor,
        wb: &Tensor,
        res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let (k1, k2) = (self.k1, self.k2);
        let dz = grad.contiguous()?.apply_op2_no_bwd(res, &ReluMask)?;
        let wb = wb.detach();
        let w1 = wb.narrow(1, 0, k1)?.contiguous()?;
        let w2 = wb.narrow(1, k1, k2)?.contiguous()?;
        let dx = |x: &Tensor, w: &Tensor| -> Result<Option<Tensor>> {
            if x.track_op() {
                dz.matmul(w).map(Some)
            } else {
                Ok(None)
            }
        };
        let dw = |x: &Tensor| dz.t().and_then(|t| t.matmul(&x.detach()));
        let ((dx1, dx2), (dw1, dw2)) = rayon::join(
            || rayon::join(|| dx(x1, &w1), || dx(x2, &w2)),
            || rayon::join(|| dw(x1), || dw(x2)),
        );
        let db = dz.apply_op1_no_bwd(&GroupSum { groups: 1 })?.t()?;
        let dwb = Tensor::cat(&[&dw1?, &dw2?, &db], 1)?;
        Ok((dx1?, dx2?, Some(dwb)))
    }
}

struct GroupMean {
    groups: usize,
}

impl CustomOp1 for GroupMean {
    fn name(&self) -> &'static str {
        "group-mean"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let (rows, _) = l.shape().dims2()?;
        let (sums, shape) = GroupSum {
            groups: self.groups,
        }
        .cpu_fwd(s, l)?;
        let CpuStorage::F32(mut sums) = sums else {
            candle_core::bail!("group-mean: f32 tensors only");
        };
        let scale = (1.0 / (rows / self.groups) as f64) as f32;
        for v in &mut sums {
            *v *= scale;
        }
        Ok((CpuStorage::F32(sums), shape))
    }

    fn bwd(&self, arg: &Tensor, _res: &Tensor, grad: &Tensor) -> Result<Option<Tensor>> {
        let (rows, _) = arg.dims2()?;
        Ok(Some(grad.contiguous()?.apply_op1_no_bwd(&GroupSpread {
            per_group: rows / self.groups,
        })?))
    }
}

/// Each group's row of (G, C) divided by `per_group`, repeated over its rows: (G·per_group, C).
struct GroupSpread {
    per_group: usize,
}

impl CustomOp1 for GroupSpread {
    fn name(&self) -> &'static str {
        "group-spread"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let g = f32_slice(s, l, self.name())?;
        let (groups, c) = l.shape().dims2()?;
        let scale = (1.0 / self.per_group as f64) as f32;
        let mut out = vec![0f32; groups * self.per_group * c];
        out.par_chunks_mut(self.per_group * c)
            .zip(g.par_chunks(c))
            .for_each(|(o, g)| {
                let row: Vec<f32> = g.iter().map(|v| v * scale).collect();
                for o in o.chunks_exact_mut(c) {
                    o.copy_from_slice(&row);
                }
            });
        Ok((
            CpuStorage::F32(out),
            Shape::from((groups * self.per_group, c)),
        ))
    }
}

struct GroupMax {
    groups: usize,
}

impl CustomOp1 for GroupMax {
    fn name(&self) -> &'static str {
        "group-max"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let x = f32_slice(s, l, self.name())?;
        let (rows, c) = l.shape().dims2()?;
        let per_group = rows / self.groups;
        let mut out = vec![f32::NEG_INFINITY; self.groups * c];
        out.par_chunks_mut(c)
            .zip(x.par_chunks(per_group * c))
            .for_each(|(m, group)| {
                for row in group.chunks_exact(c) {
                    for (m, v) in m.iter_mut().zip(row) {
                        // NaN propagates, as in candle's max.
                        if *v > *m || v.is_nan() {
                            *m = *v;
                        }
                    }
                }
            });
        Ok((CpuStorage::F32(out), Shape::from((self.groups, c))))
    }

    fn bwd(&self, arg: &Tensor, res: &Tensor, grad: &Tensor) -> Result<Option<Tensor>> {
        Ok(Some(arg.apply_op3_no_bwd(
            res,
            &grad.contiguous()?,
            &MaxScatter,
        )?))
    }
}

/// The max-pool gradient: `grad[g, c]` at every row of group g whose value equals the max
/// (as candle's `max` backward), 0 elsewhere.
struct MaxScatter;

impl CustomOp3 for MaxScatter {
    fn name(&self) -> &'static str {
        "max-scatter"
    }

    fn cpu_fwd(
        &self,
        s1: &CpuStorage,
        l1: &Layout,
        s2: &CpuStorage,
        l2: &Layout,
        s3: &CpuStorage,
        l3: &Layout,
    ) -> Result<(CpuStorage, Shape)> {
        let x = f32_slice(s1, l1, self.name())?;
        let max = f32_slice(s2, l2, self.name())?;
        let grad = f32_slice(s3, l3, self.name())?;
        let (rows, c) = l1.shape().dims2()?;
        let groups = l2.shape().dims2()?.0;
        let per_group = rows / groups;
        let mut out = vec![0f32; x.len()];
        out.par_chunks_mut(per_group * c)
            .zip(x.par_chunks(per_group * c))
            .enumerate()
            .for_each(|(g, (o, x))| {
                let (m, gr) = (&max[g * c..(g + 1) * c], &grad[g * c..(g + 1) * c]);
                for (o, x) in o.chunks_exact_mut(c).zip(x.chunks_exact(c)) {
                    for (((o, x), m), gr) in o.iter_mut().zip(x).zip(m).zip(gr) {
                        if x == m {
                            *o = *gr;
                        }
                    }
                }
            });
        Ok((CpuStorage::F32(out), l1.shape().clone()))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};
    use rand::{Rng, SeedableRng};

    fn random(shape: (usize, usize), seed: u64) -> Var {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let v: Vec<f32> = (0..shape.0 * shape.1)
            .map(|_| rng.gen_range(-1.0..1.0))
            .collect();
        Var::from_tensor(&Tensor::from_vec(v, shape, &Device::Cpu).unwrap()).unwrap()
    }

    fn max_diff(a: &Tensor, b: &Tensor) -> f32 {
        (a - b)
            .unwrap()
            .abs()
            .unwrap()
            .max_all()
            .unwrap()
            .to_scalar()
            .unwrap()
    }

    /// A loss that weights every output differently, so wrong gradients cannot cancel.
    fn weighted_sum(y: &Tensor) -> Tensor {
        let w = Tensor::arange(0f32, y.elem_count() as f32, y.device())
            .unwrap()
            .affine(0.01, -3.0)
            .unwrap()
            .reshape(y.dims())
            .unwrap();
        (y * w).unwrap().sum_all().unwrap()
    }

    /// Gradients of the fused and the composed graph agree, relative to their size (candle
    /// sums the bias gradient in f32, the fused op in f64).
    fn assert_gradients_close(
        fused: &Tensor,
        plain: &Tensor,
        wrt: &[&Tensor],
        tol: f32,
        what: &str,
    ) {
        let gf = weighted_sum(fused).backward().unwrap();
        let gp = weighted_sum(plain).backward().unwrap();
        for t in wrt {
            let (a, p) = (gf.get(t).unwrap(), gp.get(t).unwrap());
            let scale: f32 = p.abs().unwrap().max_all().unwrap().to_scalar().unwrap();
            let d = max_diff(a, p) / scale.max(1.0);
            assert!(d < tol, "{what}: gradient differs by {d} (relative)");
        }
    }

    /// Values and gradients equal candle's matmul + `relu(broadcast_add)`, for one bias and per
    /// group, across chunk boundaries (rows > CHUNK_ROWS, groups not aligned to chunks).
    #[test]
    fn dense_relu_matches_candle_ops() {
        for (rows, groups) in [(1300, 1), (1300, 13), (6, 3)] {
            let x = random((rows, 9), 4);
            let w = random((7, 9), 5);
            let b = random((groups, 7), 6);
            let fused = dense_relu(&x, &w, &b).unwrap();
            let plain = composed_bias_relu(&x.matmul(&w.t().unwrap()).unwrap(), &b).unwrap();
            assert!(max_diff(&fused, &plain) < 1e-6);
            let what = format!("rows {rows} groups {groups}");
            assert_gradients_close(&fused, &plain, &[&x, &w, &b], 1e-5, &what);
        }
    }

    /// The two-input layer: candle's two products, sum, bias and relu; with and without a bias,
    /// and with an input that tracks no gradient (its gradient is skipped, the others agree).
    #[test]
    fn dense2_relu_matches_candle_ops() {
        let x1 = random((1300, 5), 7);
        let x2 = random((1300, 9), 8);
        let w1 = random((6, 5), 9);
        let w2 = random((6, 9), 10);
        let b = Var::from_tensor(&random((1, 6), 11).as_tensor().squeeze(0).unwrap()).unwrap();
        for bias in [Some(b.as_tensor()), None] {
            let fused = dense2_relu(&x1, &x2, &w1, &w2, bias).unwrap();
            let mut z = (x1.matmul(&w1.t().unwrap()).unwrap()
                + x2.matmul(&w2.t().unwrap()).unwrap())
            .unwrap();
            if let Some(b) = bias {
                z = z.broadcast_add(&b.unsqueeze(0).unwrap()).unwrap();
            }
            let plain = z.relu().unwrap();
            assert!(max_diff(&fused, &plain) < 1e-5);
            let mut wrt = vec![
                x1.as_tensor(),
                x2.as_tensor(),
                w1.as_tensor(),
                w2.as_tensor(),
            ];
            wrt.extend(bias);
            assert_gradients_close(&fused, &plain, &wrt, 1e-5, "dense2_relu");
        }
        let data = x2.as_tensor().detach();
        let g = weighted_sum(&dense2_relu(&x1, &data, &w1, &w2, None).unwrap())
            .backward()
            .unwrap();
        assert!(g.get(&data).is_none() && g.get(&x1).is_some() && g.get(&w2).is_some());
    }

    #[test]
    fn group_mean_matches_candle_mean() {
        let x = random((1000, 5), 3);
        let fused = group_mean(&x, 4).unwrap();
        let plain = x.reshape((4, 250, 5)).unwrap().mean(1).unwrap();
        assert!(max_diff(&fused, &plain) < 1e-6);
        assert_gradients_close(&fused, &plain, &[x.as_tensor()], 1e-6, "group_mean");
        assert!(group_mean(&x, 3).is_err());
    }

    #[test]
    fn group_max_matches_candle_max() {
        let x = random((1000, 5), 3);
        let fused = group_max(&x, 4).unwrap();
        let plain = x.reshape((4, 250, 5)).unwrap().max(1).unwrap();
        assert_eq!(max_diff(&fused, &plain), 0.0);
        let gf = weighted_sum(&fused).backward().unwrap();
        let gp = weighted_sum(&plain).backward().unwrap();
        assert_eq!(max_diff(gf.get(&x).unwrap(), gp.get(&x).unwrap()), 0.0);
    }

    #[test]
    fn shapes_that_do_not_fit_are_errors() {
        let z = random((6, 4), 1);
        let w = random((4, 4), 3);
        assert!(dense_relu(&z, &w, &random((4, 4), 2)).is_err());
        assert!(dense_relu(&z, &w, &random((1, 3), 2)).is_err());
        assert!(group_max(&z, 4).is_err());
    }
}
