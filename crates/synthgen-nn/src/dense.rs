//! A fully connected layer whose bias gradient is a matrix product.
//!
//! candle's `Linear` adds its bias with a broadcast; the backward pass then sums the
//! (rows × out) gradient over rows with a strided reduction, which profiling showed to be
//! ~30 % of a TNet training step on the CPU (docs/benchmarks.md). Here the bias is added as
//! `ones(rows, 1) · bias(1, out)`, so its gradient is `onesᵀ · grad`, one gemm call. Same
//! parameters (`weight` (out, in), `bias` (out)), names and initialization as
//! `candle_nn::linear`, so checkpoints are interchangeable.

use candle_core::{Module, Result, Tensor};
use candle_nn::VarBuilder;

use crate::conv::conv_bias_relu;
use crate::fused::dense_relu;
use crate::im2col::Window;

#[derive(Debug, Clone)]
pub struct Dense {
    weight: Tensor,
    bias: Option<Tensor>,
}

/// A layer with bias, initialized as `candle_nn::linear`.
pub fn dense(in_dim: usize, out_dim: usize, vb: VarBuilder) -> Result<Dense> {
    let l = candle_nn::linear(in_dim, out_dim, vb)?;
    Ok(Dense {
        weight: l.weight().clone(),
        bias: l.bias().cloned(),
    })
}

/// A layer without bias, initialized as `candle_nn::linear_no_bias`.
pub fn dense_no_bias(in_dim: usize, out_dim: usize, vb: VarBuilder) -> Result<Dense> {
    let l = candle_nn::linear_no_bias(in_dim, out_dim, vb)?;
    Ok(Dense {
        weight: l.weight().clone(),
        bias: None,
    })
}

impl Dense {
    /// `relu(x·Wᵀ + b)` for `x`: (rows, in), as one fused node on the CPU ([`dense_relu`]).
    pub fn forward_relu(&self, x: &Tensor) -> Result<Tensor> {
        self.forward_relu_grouped(x, None)
    }

    /// `relu(x·Wᵀ + b + extra[group])`: `extra` (G, out) is added to each of G equal,
    /// contiguous groups of rows (TNet's per-cloud global term).
    pub fn forward_relu_grouped(&self, x: &Tensor, extra: Option<&Tensor>) -> Result<Tensor> {
        dense_relu(x, &self.weight, &self.bias_rows(x, extra)?)
    }

    /// The layer as a convolution of the NHWC map `x` (its weight's columns the `k × k × C`
    /// window, as `im2col`'s), ReLU, with `extra` (B, out) added per image:
    /// [`crate::conv::conv_bias_relu`].
    pub fn conv_relu(&self, x: &Tensor, win: Window, extra: Option<&Tensor>) -> Result<Tensor> {
        conv_bias_relu(x, &self.weight, &self.bias_rows(x, extra)?, win)
    }

    /// `relu(x·Wᵀ + b + y·W_oᵀ)`: this layer on `x` plus `other` (its bias ignored) on `y`,
    /// as one node ([`crate::fused::dense2_relu`]).
    pub fn forward_relu_with(&self, x: &Tensor, other: &Dense, y: &Tensor) -> Result<Tensor> {
        crate::fused::dense2_relu(x, y, &self.weight, &other.weight, self.bias.as_ref())
    }

    /// The bias rows (G, out): the layer's bias plus `extra`'s rows (G of them), or alone.
    fn bias_rows(&self, x: &Tensor, extra: Option<&Tensor>) -> Result<Tensor> {
        let out = self.weight.dim(0)?;
        match (&self.bias, extra) {
            (Some(b), Some(e)) => e.broadcast_add(&b.unsqueeze(0)?),
            (Some(b), None) => b.unsqueeze(0),
            (None, Some(e)) => Ok(e.clone()),
            (None, None) => Tensor::zeros((1, out), x.dtype(), x.device()),
        }
    }
}

impl Module for Dense {
    /// `x`: (…, in) → (…, out); leading dimensions are flattened into rows.
    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let dims = x.dims().to_vec();
        let (lead, in_dim) = dims.split_at(dims.len().saturating_sub(1));
        let rows: usize = lead.iter().product();
        let x2 = x.reshape((rows, in_dim.first().copied().unwrap_or(0)))?;
        let mut y = x2.matmul(&self.weight.t()?)?;
        if let Some(b) = &self.bias {
            let ones = Tensor::ones((rows, 1), x.dtype(), x.device())?;
            y = (y + ones.matmul(&b.unsqueeze(0)?)?)?;
        }
        let mut out_dims = lead.to_vec();
        out_dims.push(self.weight.dim(0)?);
        y.reshape(out_dims)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_core::{DType, Device, Var};
    use candle_nn::VarMap;

    /// Same outputs and the same gradients as candle's `Linear` on the same parameters.
    #[test]
    fn matches_candle_linear_values_and_gradients() {
        let dev = Device::Cpu;
        let vm = VarMap::new();
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &dev);
        let d = dense(5, 4, vb.pp("a")).unwrap();
        let lin = candle_nn::Linear::new(d.weight.clone(), d.bias.clone());
        let x = Var::from_tensor(
            &Tensor::arange(0f32, 2.0 * 3.0 * 5.0, &dev)
                .unwrap()
                .affine(0.1, -1.0)
                .unwrap()
                .reshape((2, 3, 5))
                .unwrap(),
        )
        .unwrap();
        let (ya, yb) = (d.forward(&x).unwrap(), lin.forward(&x).unwrap());
        assert_eq!(ya.dims(), [2, 3, 4]);
        let diff = (&ya - &yb).unwrap().abs().unwrap().max_all().unwrap();
        assert!(diff.to_scalar::<f32>().unwrap() < 1e-5);
        let ga = ya.sqr().unwrap().sum_all().unwrap().backward().unwrap();
        let gb = yb.sqr().unwrap().sum_all().unwrap().backward().unwrap();
        for t in [&d.weight, d.bias.as_ref().unwrap(), x.as_tensor()] {
            let (a, b) = (ga.get(t).unwrap(), gb.get(t).unwrap());
            let diff = (a - b).unwrap().abs().unwrap().max_all().unwrap();
            assert!(diff.to_scalar::<f32>().unwrap() < 1e-3, "{diff}");
        }
    }
}
