//! A whole convolution layer `relu(conv(x, W) + b)` over an NHWC map as one graph node.
//!
//! As `im2col` then the fused dense layer ([`crate::fused::dense_relu`]), the patch matrix
//! (B·OH·OW × k·k·C: 56 MB for the dense RGB model's decoder at batch 32) was a node of the
//! graph: kept for the backward pass, and its gradient, as large, was summed by candle's
//! backprop into a freshly zeroed tensor on one thread (a memset and an add of 14 M values
//! per step, 1/4 of the dense model's step on 2 cores, docs/benchmarks.md). Here the patches
//! live only inside the op: the forward pass builds them (in parallel), multiplies and adds
//! the bias and ReLU in place; the backward pass builds them again and returns the gradient
//! of the input map itself (`col2im` of `dz·W`), of `W` (`dzᵀ·patches`) and of the bias. The
//! values are those of `im2col` + `dense_relu` (the same products, the same order).

use std::sync::Mutex;

use candle_core::backend::BackendStorage;
use candle_core::{CpuStorage, CustomOp3, DType, Layout, Result, Shape, Tensor};

use crate::fused::{add_bias_relu_in_place, dense_relu, f32_slice, fused_path, GroupSum, ReluMask};
use crate::im2col::{im2col, im2col_values, Col2Im, Window};

/// `relu(conv(x, w) + bias[group])`: `x` (B, H, W, C), `w` (out, k·k·C) with columns
/// (ky, kx, c) as [`im2col`]'s, `bias` (G, out) with G = 1 or G = B (a term per image);
/// (B, OH, OW, out).
pub fn conv_bias_relu(x: &Tensor, w: &Tensor, bias: &Tensor, win: Window) -> Result<Tensor> {
    let (b, h, wd, c) = x.dims4()?;
    let (out, cols) = w.dims2()?;
    let (g, cb) = bias.dims2()?;
    if cols != win.k * win.k * c || cb != out || !(g == 1 || g == b) {
        candle_core::bail!(
            "conv: x {:?}, w {:?}, bias {:?} do not fit a {}x{} window",
            x.dims(),
            w.dims(),
            bias.dims(),
            win.k,
            win.k
        );
    }
    let (oh, ow) = (win.out(h), win.out(wd));
    if fused_path(x) && w.dtype() == DType::F32 && bias.dtype() == DType::F32 {
        return x.contiguous()?.apply_op3(
            &w.contiguous()?,
            &bias.contiguous()?,
            ConvRelu {
                win,
                patches: Mutex::new(None),
            },
        );
    }
    dense_relu(&im2col(x, win)?, w, bias)?.reshape((b, oh, ow, out))
}

struct ConvRelu {
    win: Window,
    /// The forward pass's patches, kept for the backward pass (which takes them); built again
    /// only when a second backward pass runs on the same graph.
    patches: Mutex<Option<Tensor>>,
}

impl CustomOp3 for ConvRelu {
    fn name(&self) -> &'static str {
        "conv-relu"
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
        let dims = l1.shape().dims4()?;
        let (b, h, w, _) = dims;
        let (oh, ow) = (self.win.out(h), self.win.out(w));
        let (out, k) = l2.shape().dims2()?;
        let bias = f32_slice(s3, l3, self.name())?;
        let rows = b * oh * ow;
        let per_group = rows / l3.shape().dims2()?.0;
        let cols = im2col_values(x, dims, self.win);
        let cols = Tensor::from_vec(cols, (rows, k), &candle_core::Device::Cpu)?;
        let z = {
            let (storage, layout) = cols.storage_and_layout();
            let candle_core::Storage::Cpu(storage) = &*storage else {
                candle_core::bail!("conv-relu: the patches are not on the CPU");
            };
            // patches (rows, k) · wᵀ (k, out) with candle's own CPU matmul.
            storage.matmul(s2, (1, rows, out, k), layout, &l2.transpose(0, 1)?)?
        };
        let CpuStorage::F32(mut z) = z else {
            candle_core::bail!("conv-relu: f32 tensors only");
        };
        add_bias_relu_in_place(&mut z, bias, out, per_group);
        if let Ok(mut kept) = self.patches.lock() {
            *kept = Some(cols);
        }
        Ok((CpuStorage::F32(z), Shape::from((b, oh, ow, out))))
    }

    fn bwd(
        &self,
        x: &Tensor,
        w: &Tensor,
        bias: &Tensor,
        res: &Tensor,
        grad: &Tensor,
    ) -> Result<(Option<Tensor>, Option<Tensor>, Option<Tensor>)> {
        let dims = x.dims4()?;
        let out = w.dim(0)?;
        let rows = res.elem_count() / out;
        let dz = grad
            .contiguous()?
            .reshape((rows, out))?
            .apply_op2_no_bwd(&res.reshape((rows, out))?, &ReluMask)?;
        let kept = self.patches.lock().ok().and_then(|mut p| p.take());
        let cols = match kept {
            Some(c) => c,
            None => x
                .detach()
                .apply_op1_no_bwd(&crate::im2col::Im2Col { win: self.win })?,
        };
        // An input that needs no gradient (the crops of the first layer) gets none.
        let wants_dx = x.is_variable() || x.track_op();
        // The input's gradient (through the patches) and the weights' are independent.
        let (dx, dw) = rayon::join(
            || {
                wants_dx
                    .then(|| {
                        dz.matmul(&w.detach())?.apply_op1_no_bwd(&Col2Im {
                            win: self.win,
                            dims,
                        })
                    })
                    .transpose()
            },
            || dz.t()?.matmul(&cols),
        );
        let db = dz.apply_op1_no_bwd(&GroupSum {
            groups: bias.dim(0)?,
        })?;
        Ok((dx?, Some(dw?), Some(db)))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};
    use rand::{Rng, SeedableRng};

    fn random(shape: &[usize], seed: u64) -> Var {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let n: usize = shape.iter().product();
        let v: Vec<f32> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
        Var::from_tensor(&Tensor::from_vec(v, shape, &Device::Cpu).unwrap()).unwrap()
    }

    /// The fused layer gives exactly the values and gradients of `im2col` + `dense_relu`,
    /// with one bias and with a bias per image, for strides 1 and 2.
    #[test]
    fn conv_relu_equals_im2col_then_dense_relu() {
        for (shape, win, groups) in [
            (
                (2, 9, 7, 3),
                Window {
                    k: 3,
                    stride: 2,
                    pad: 1,
                },
                1,
            ),
            (
                (3, 6, 6, 4),
                Window {
                    k: 3,
                    stride: 1,
                    pad: 1,
                },
                3,
            ),
            (
                (1, 5, 8, 2),
                Window {
                    k: 1,
                    stride: 1,
                    pad: 0,
                },
                1,
            ),
        ] {
            let x = random(&[shape.0, shape.1, shape.2, shape.3], 1);
            let w = random(&[5, win.k * win.k * shape.3], 2);
            let b = random(&[groups, 5], 3);
            let fused = conv_bias_relu(&x, &w, &b, win).unwrap();
            let cols = im2col(&x, win).unwrap();
            let plain = dense_relu(&cols, &w, &b)
                .unwrap()
                .reshape(fused.dims())
                .unwrap();
            let d = (&fused - &plain).unwrap().abs().unwrap().max_all().unwrap();
            assert_eq!(d.to_scalar::<f32>().unwrap(), 0.0, "{shape:?}");
            let weights = Tensor::arange(0f32, fused.elem_count() as f32, &Device::Cpu)
                .unwrap()
                .affine(0.013, -2.0)
                .unwrap()
                .reshape(fused.dims())
                .unwrap();
            let gf = (&fused * &weights)
                .unwrap()
                .sum_all()
                .unwrap()
                .backward()
                .unwrap();
            let gp = (&plain * &weights)
                .unwrap()
                .sum_all()
                .unwrap()
                .backward()
                .unwrap();
            for t in [x.as_tensor(), w.as_tensor(), b.as_tensor()] {
                let (a, p) = (gf.get(t).unwrap(), gp.get(t).unwrap());
                let d: f32 = (a - p)
                    .unwrap()
                    .abs()
                    .unwrap()
                    .max_all()
                    .unwrap()
                    .to_scalar()
                    .unwrap();
                assert!(d < 1e-5, "{shape:?}: gradient differs by {d}");
            }
        }
    }
}
