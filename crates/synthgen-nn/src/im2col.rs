//! Convolutions as matrix products, for the RGB model's CNN on the CPU.
//!
//! candle's CPU `conv2d` backward pass computes the input gradient with a direct
//! `conv_transpose2d` loop; for the RGB model's four stride-2 layers that was ~90% of a
//! training step (495 ms for 32 crops, docs/benchmarks.md). Here a convolution over an NHWC
//! image is `im2col` (each output pixel's k×k×C patch as one row, zeros outside the image)
//! followed by a fused dense layer ([`crate::dense::Dense::forward_relu`]): the forward and
//! both weight and input gradients are then matrix products, and `im2col`'s own gradient is
//! the scatter-add `col2im`. On other devices and dtypes `im2col` composes candle's own ops
//! (zero padding and `index_select`), with the same values and gradients.

use candle_core::{CpuStorage, CustomOp1, Layout, Result, Shape, Tensor};
use rayon::prelude::*;

use crate::fused::{f32_slice, fused_path};

/// A square convolution window: side, stride and zero padding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Window {
    pub k: usize,
    pub stride: usize,
    pub pad: usize,
}

impl Window {
    /// Output side for an input side `n`.
    pub fn out(&self, n: usize) -> usize {
        (n + 2 * self.pad - self.k) / self.stride + 1
    }
}

/// The patches of `x` (B, H, W, C) as rows: (B·OH·OW, k·k·C), row (b, oy, ox), columns
/// (ky, kx, c); zeros where the window leaves the image.
pub fn im2col(x: &Tensor, win: Window) -> Result<Tensor> {
    let (b, h, w, c) = x.dims4()?;
    if win.k == 0 || win.stride == 0 || h + 2 * win.pad < win.k || w + 2 * win.pad < win.k {
        candle_core::bail!("im2col: window {win:?} does not fit a {h}x{w} image");
    }
    if fused_path(x) {
        return x.contiguous()?.apply_op1(Im2Col { win });
    }
    let (oh, ow) = (win.out(h), win.out(w));
    let (hp, wp) = (h + 2 * win.pad, w + 2 * win.pad);
    let padded = x
        .pad_with_zeros(1, win.pad, win.pad)?
        .pad_with_zeros(2, win.pad, win.pad)?
        .reshape((b, hp * wp, c))?;
    let mut idx = Vec::with_capacity(oh * ow * win.k * win.k);
    for oy in 0..oh {
        for ox in 0..ow {
            for ky in 0..win.k {
                for kx in 0..win.k {
                    idx.push(((oy * win.stride + ky) * wp + ox * win.stride + kx) as u32);
                }
            }
        }
    }
    let n = idx.len();
    let idx = Tensor::from_vec(idx, n, x.device())?;
    padded
        .index_select(&idx, 1)?
        .reshape((b * oh * ow, win.k * win.k * c))
}

pub(crate) struct Im2Col {
    pub(crate) win: Window,
}

/// The patches of the NHWC image data `x` (`dims`), as [`im2col`] lays them out; built in
/// parallel, one image per task.
pub(crate) fn im2col_values(
    x: &[f32],
    (b, h, w, c): (usize, usize, usize, usize),
    win: Window,
) -> Vec<f32> {
    let (oh, ow) = (win.out(h), win.out(w));
    let per_image = oh * ow * win.k * win.k * c;
    let mut out = zeros(b * per_image);
    out.par_chunks_mut(per_image)
        .zip(x.par_chunks(h * w * c))
        .for_each(|(o, img)| {
            for_each_span(win, (h, w, c), (oh, ow), |dst, src, len| {
                o[dst..dst + len].copy_from_slice(&img[src..src + len]);
            });
        });
    out
}

/// Calls `f(row_offset, pixel_offset, len)` for every run of window positions of one output
/// pixel and one window row whose input pixels lie inside the image: they are `len` values
/// at `row_offset` in the output pixel's row and at `pixel_offset` in one image of
/// `h × w × c` values (a window row's in-image positions are consecutive pixels, so one copy
/// moves `k · c` values where a copy per position moved `c`).
fn for_each_span(
    win: Window,
    (h, w, c): (usize, usize, usize),
    (oh, ow): (usize, usize),
    mut f: impl FnMut(usize, usize, usize),
) {
    let row_len = win.k * win.k * c;
    for oy in 0..oh {
        for ox in 0..ow {
            let row = (oy * ow + ox) * row_len;
            // The window's columns inside the image: kx in kx0..kx1.
            let x0 = ox * win.stride;
            let kx0 = win.pad.saturating_sub(x0);
            let kx1 = win.k.min((w + win.pad).saturating_sub(x0));
            if kx0 >= kx1 {
                continue;
            }
            let ix0 = x0 + kx0 - win.pad;
            for ky in 0..win.k {
                let Some(iy) = (oy * win.stride + ky)
                    .checked_sub(win.pad)
                    .filter(|&y| y < h)
                else {
                    continue;
                };
                f(
                    row + (ky * win.k + kx0) * c,
                    (iy * w + ix0) * c,
                    (kx1 - kx0) * c,
                );
            }
        }
    }
}

/// `n` zeros, written by the worker threads (a large `vec![0.0; n]` is one thread's memset).
pub(crate) fn zeros(n: usize) -> Vec<f32> {
    let mut v = Vec::with_capacity(n);
    v.par_extend(rayon::iter::repeat_n(0f32, n).with_min_len(1 << 16));
    v
}

impl CustomOp1 for Im2Col {
    fn name(&self) -> &'static str {
        "im2col"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let x = f32_slice(s, l, self.name())?;
        let (b, h, w, c) = l.shape().dims4()?;
        let (oh, ow) = (self.win.out(h), self.win.out(w));
        let out = im2col_values(x, (b, h, w, c), self.win);
        let shape = Shape::from((b * oh * ow, self.win.k * self.win.k * c));
        Ok((CpuStorage::F32(out), shape))
    }

    fn bwd(&self, arg: &Tensor, _res: &Tensor, grad: &Tensor) -> Result<Option<Tensor>> {
        let (b, h, w, c) = arg.dims4()?;
        Ok(Some(grad.contiguous()?.apply_op1_no_bwd(&Col2Im {
            win: self.win,
            dims: (b, h, w, c),
        })?))
    }
}

/// `im2col`'s gradient: every row's values added back onto the pixels they were read from.
pub(crate) struct Col2Im {
    pub(crate) win: Window,
    pub(crate) dims: (usize, usize, usize, usize),
}

impl CustomOp1 for Col2Im {
    fn name(&self) -> &'static str {
        "col2im"
    }

    fn cpu_fwd(&self, s: &CpuStorage, l: &Layout) -> Result<(CpuStorage, Shape)> {
        let g = f32_slice(s, l, self.name())?;
        let (b, h, w, c) = self.dims;
        let (oh, ow) = (self.win.out(h), self.win.out(w));
        let per_image = oh * ow * self.win.k * self.win.k * c;
        if g.len() != b * per_image {
            candle_core::bail!("col2im: {} values for {:?}", g.len(), self.dims);
        }
        let mut out = zeros(b * h * w * c);
        out.par_chunks_mut(h * w * c)
            .zip(g.par_chunks(per_image))
            .for_each(|(img, rows)| {
                for_each_span(self.win, (h, w, c), (oh, ow), |src, dst, len| {
                    for (o, v) in img[dst..dst + len].iter_mut().zip(&rows[src..src + len]) {
                        *o += v;
                    }
                });
            });
        Ok((CpuStorage::F32(out), Shape::from((b, h, w, c))))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_core::{DType, Device, Var, D};

    fn ramp(shape: (usize, usize, usize, usize), dtype: DType) -> Tensor {
        let n = shape.0 * shape.1 * shape.2 * shape.3;
        Tensor::arange(0f32, n as f32, &Device::Cpu)
            .unwrap()
            .affine(0.37, -3.0)
            .unwrap()
            .sin()
            .unwrap()
            .reshape(shape)
            .unwrap()
            .to_dtype(dtype)
            .unwrap()
    }

    /// The fused CPU op (f32) and candle's composed ops (f64 takes that path) agree in
    /// values and gradients, for odd sizes and every padding.
    #[test]
    fn fused_and_composed_agree() {
        for (shape, win) in [
            (
                (2, 7, 5, 3),
                Window {
                    k: 3,
                    stride: 2,
                    pad: 1,
                },
            ),
            (
                (1, 6, 6, 2),
                Window {
                    k: 3,
                    stride: 1,
                    pad: 0,
                },
            ),
            (
                (3, 4, 9, 1),
                Window {
                    k: 2,
                    stride: 3,
                    pad: 2,
                },
            ),
        ] {
            let x32 = Var::from_tensor(&ramp(shape, DType::F32)).unwrap();
            let x64 = Var::from_tensor(&ramp(shape, DType::F64)).unwrap();
            let a = im2col(x32.as_tensor(), win).unwrap();
            let b = im2col(x64.as_tensor(), win).unwrap();
            assert_eq!(a.dims(), b.dims());
            let diff = (a.to_dtype(DType::F64).unwrap() - &b)
                .unwrap()
                .abs()
                .unwrap()
                .max_all()
                .unwrap()
                .to_scalar::<f64>()
                .unwrap();
            assert!(diff < 1e-6, "{diff}");
            // A loss that weighs every column differently.
            let weights = |t: &Tensor| {
                let cols = t.dim(D::Minus1).unwrap();
                Tensor::arange(0f32, cols as f32, &Device::Cpu)
                    .unwrap()
                    .to_dtype(t.dtype())
                    .unwrap()
            };
            let grads = |t: &Tensor| {
                t.broadcast_mul(&weights(t))
                    .unwrap()
                    .sqr()
                    .unwrap()
                    .sum_all()
                    .unwrap()
                    .backward()
                    .unwrap()
            };
            let (ga, gb) = (grads(&a), grads(&b));
            let (ga, gb) = (ga.get(&x32).unwrap(), gb.get(&x64).unwrap());
            let rel = ((ga.to_dtype(DType::F64).unwrap() - gb)
                .unwrap()
                .abs()
                .unwrap())
            .max_all()
            .unwrap()
            .to_scalar::<f64>()
            .unwrap()
                / (1.0
                    + gb.abs()
                        .unwrap()
                        .max_all()
                        .unwrap()
                        .to_scalar::<f64>()
                        .unwrap());
            assert!(rel < 1e-5, "{shape:?} {win:?}: {rel}");
        }
    }

    /// im2col followed by a matrix product is candle's conv2d (NCHW, weights (Co, Ci, k, k)).
    #[test]
    fn im2col_matmul_is_a_convolution() {
        let (b, h, w, ci, co) = (2, 9, 8, 3, 4);
        let x = ramp((b, h, w, ci), DType::F32);
        let k = ramp((co, ci, 3, 3), DType::F32);
        let win = Window {
            k: 3,
            stride: 2,
            pad: 1,
        };
        let ours = im2col(&x, win)
            .unwrap()
            .matmul(
                &k.permute((0, 2, 3, 1))
                    .unwrap()
                    .reshape((co, 9 * ci))
                    .unwrap()
                    .t()
                    .unwrap(),
            )
            .unwrap()
            .reshape((b, win.out(h), win.out(w), co))
            .unwrap();
        let theirs = x
            .permute((0, 3, 1, 2))
            .unwrap()
            .conv2d(&k, 1, 2, 1, 1)
            .unwrap()
            .permute((0, 2, 3, 1))
            .unwrap();
        let diff = (ours - theirs)
            .unwrap()
            .abs()
            .unwrap()
            .max_all()
            .unwrap()
            .to_scalar::<f32>()
            .unwrap();
        assert!(diff < 1e-4, "{diff}");
    }
}
