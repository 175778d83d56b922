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
        let (dx, dw) = rayon::join(
            || dz.matmul(&w.detach()),
            || dz.t().and_then(|t| t.matmul(&x.detach())),
        );
        let (dx, dw) = (dx?, dw?);
        let db = dz.apply_op1_no_bwd(&GroupSum {
            groups: bias.dim(0)?,
        })?;
        Ok((Some(dx), Some(dw), Some(db)))
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
