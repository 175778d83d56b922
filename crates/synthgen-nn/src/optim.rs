//! AdamW in one parallel pass per variable.
//!
//! candle's `AdamW` updates each variable with about a dozen tensor operations (scale the
//! moments, add, square, sqrt, divide, ...), each a pass over the variable on one thread:
//! ~4 % of a dense RGB training step on 2 cores (docs/benchmarks.md). [`FusedAdamW`] does the
//! same arithmetic, operation for operation in f32 as candle's ops do it (so the weights come
//! out bit for bit the same), in one pass over chunks of the variable on the worker threads,
//! and keeps its moments as plain vectors. Variables that are not f32 on the CPU go through
//! candle's own `AdamW`.

use candle_core::backprop::GradStore;
use candle_core::{DType, Result, Tensor, Var};
use candle_nn::{AdamW, Optimizer, ParamsAdamW};
use rayon::prelude::*;

/// Values per parallel task of the update.
const CHUNK: usize = 1 << 14;

/// One f32 CPU variable and its moments.
struct Slot {
    var: Var,
    m: Vec<f32>,
    v: Vec<f32>,
}

/// AdamW with candle's `ParamsAdamW` and candle's arithmetic, fused and parallel on the CPU.
pub struct FusedAdamW {
    slots: Vec<Slot>,
    /// The variables on other devices or of other dtypes.
    others: Option<AdamW>,
    params: ParamsAdamW,
    step_t: usize,
}

impl Optimizer for FusedAdamW {
    type Config = ParamsAdamW;

    fn new(vars: Vec<Var>, params: ParamsAdamW) -> Result<Self> {
        let (fused, others): (Vec<Var>, Vec<Var>) = vars
            .into_iter()
            .filter(|v| v.dtype().is_float())
            .partition(|v| v.device().is_cpu() && v.dtype() == DType::F32);
        let slots = fused
            .into_iter()
            .map(|var| {
                let n = var.elem_count();
                Slot {
                    var,
                    m: vec![0.0; n],
                    v: vec![0.0; n],
                }
            })
            .collect();
        let others = if others.is_empty() {
            None
        } else {
            Some(AdamW::new(others, params.clone())?)
        };
        Ok(FusedAdamW {
            slots,
            others,
            params,
            step_t: 0,
        })
    }

    fn learning_rate(&self) -> f64 {
        self.params.lr
    }

    fn set_learning_rate(&mut self, lr: f64) {
        self.params.lr = lr;
        if let Some(o) = self.others.as_mut() {
            o.set_learning_rate(lr);
        }
    }

    fn step(&mut self, grads: &GradStore) -> Result<()> {
        self.step_t += 1;
        let p = &self.params;
        let t = self.step_t as i32;
        // The constants as candle's ops cast them: `tensor * f64` multiplies by the f64 cast
        // to f32 (its affine op), and so does every scalar below.
        let k = Constants {
            beta1: p.beta1 as f32,
            one_minus_beta1: (1.0 - p.beta1) as f32,
            beta2: p.beta2 as f32,
            one_minus_beta2: (1.0 - p.beta2) as f32,
            scale_m: (1.0 / (1.0 - p.beta1.powi(t))) as f32,
            scale_v: (1.0 / (1.0 - p.beta2.powi(t))) as f32,
            decay: (1.0 - p.lr * p.weight_decay) as f32,
            lr: p.lr as f32,
            eps: p.eps as f32,
        };
        for slot in &mut self.slots {
            let Some(g) = grads.get(slot.var.as_tensor()) else {
                continue;
            };
            let g: Vec<f32> = g.flatten_all()?.to_vec1()?;
            let theta: Vec<f32> = slot.var.as_tensor().flatten_all()?.to_vec1()?;
            let mut next = vec![0f32; theta.len()];
            next.par_chunks_mut(CHUNK)
                .zip(slot.m.par_chunks_mut(CHUNK))
                .zip(slot.v.par_chunks_mut(CHUNK))
                .zip(theta.par_chunks(CHUNK).zip(g.par_chunks(CHUNK)))
                .for_each(|(((next, m), v), (theta, g))| {
                    for i in 0..next.len() {
                        next[i] = k.update(&mut m[i], &mut v[i], theta[i], g[i]);
                    }
                });
            let shape = slot.var.shape().clone();
            slot.var
                .set(&Tensor::from_vec(next, shape, slot.var.device())?)?;
        }
        if let Some(o) = self.others.as_mut() {
            o.step(grads)?;
        }
        Ok(())
    }
}

#[derive(Clone, Copy)]
struct Constants {
    beta1: f32,
    one_minus_beta1: f32,
    beta2: f32,
    one_minus_beta2: f32,
    scale_m: f32,
    scale_v: f32,
    decay: f32,
    lr: f32,
    eps: f32,
}

impl Constants {
    /// One element's update, in candle's `AdamW` order of f32 operations (each tensor op
    /// rounds): moments, bias correction, decoupled weight decay, step.
    #[inline]
    fn update(&self, m: &mut f32, v: &mut f32, theta: f32, g: f32) -> f32 {
        let next_m = *m * self.beta1 + g * self.one_minus_beta1;
        let next_v = *v * self.beta2 + (g * g) * self.one_minus_beta2;
        *m = next_m;
        *v = next_v;
        let m_hat = next_m * self.scale_m;
        let v_hat = next_v * self.scale_v;
        let adjusted = m_hat / (v_hat.sqrt() + self.eps);
        theta * self.decay - adjusted * self.lr
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_core::Device;
    use rand::{Rng, SeedableRng};

    /// The fused optimizer's weights equal candle's AdamW's bit for bit, over steps with
    /// changing gradients and learning rates, for variables larger than a chunk.
    #[test]
    fn equals_candle_adamw_bit_for_bit() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut draw =
            |n: usize| -> Vec<f32> { (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect() };
        let shapes = [(3usize, 5usize), (200, 100), (1, 7)];
        let dev = Device::Cpu;
        let make = |vals: &[Vec<f32>]| -> Vec<Var> {
            vals.iter()
                .zip(shapes)
                .map(|(v, s)| {
                    Var::from_tensor(&Tensor::from_vec(v.clone(), s, &dev).unwrap()).unwrap()
                })
                .collect()
        };
        let init: Vec<Vec<f32>> = shapes.iter().map(|(a, b)| draw(a * b)).collect();
        let (ours, theirs) = (make(&init), make(&init));
        let params = ParamsAdamW {
            lr: 3e-3,
            weight_decay: 0.05,
            ..Default::default()
        };
        let mut a = FusedAdamW::new(ours.clone(), params.clone()).unwrap();
        let mut b = AdamW::new(theirs.clone(), params).unwrap();
        for step in 0..5 {
            let targets: Vec<Tensor> = shapes
                .iter()
                .map(|&s| Tensor::from_vec(draw(s.0 * s.1), s, &dev).unwrap())
                .collect();
            let loss = |vars: &[Var]| {
                let mut l = Tensor::zeros((), DType::F32, &dev).unwrap();
                for (v, t) in vars.iter().zip(&targets) {
                    l = (l
                        + (v.as_tensor() - t)
                            .unwrap()
                            .sqr()
                            .unwrap()
                            .sum_all()
                            .unwrap())
                    .unwrap();
                }
                l
            };
            a.set_learning_rate(3e-3 / f64::from(step + 1));
            b.set_learning_rate(3e-3 / f64::from(step + 1));
            a.backward_step(&loss(&ours)).unwrap();
            b.backward_step(&loss(&theirs)).unwrap();
            for (x, y) in ours.iter().zip(&theirs) {
                let x: Vec<f32> = x.flatten_all().unwrap().to_vec1().unwrap();
                let y: Vec<f32> = y.flatten_all().unwrap().to_vec1().unwrap();
                assert!(
                    x.iter().zip(&y).all(|(p, q)| p.to_bits() == q.to_bits()),
                    "step {step}: the weights differ from candle's AdamW"
                );
            }
        }
    }
}
