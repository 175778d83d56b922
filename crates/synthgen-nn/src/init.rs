//! Seeded weight initialization. candle draws initial weights from its device RNG, which on
//! the CPU is the thread RNG and cannot be seeded, so two runs with the same `--seed` would
//! start from different weights. [`seeded_var_builder`] draws each variable from candle's own
//! distribution (its `Init` hint: Kaiming, uniform, normal, constant) with a ChaCha stream
//! that is a pure function of (seed, variable name), and stores it in the `VarMap` as a
//! trainable variable, as `VarBuilder::from_varmap` would.

use candle_core::{DType, Device, Shape, Tensor, Var};
use candle_nn::init::NormalOrUniform;
use candle_nn::var_builder::SimpleBackend;
use candle_nn::{Init, VarBuilder, VarMap};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use synthgen_core::rng::splitmix64;

/// A `VarBuilder` whose new variables are drawn from `seed` and kept in `varmap`.
pub fn seeded_var_builder(varmap: &VarMap, seed: u64, device: &Device) -> VarBuilder<'static> {
    VarBuilder::from_backend(
        Box::new(SeededInit {
            varmap: varmap.clone(),
            seed,
        }),
        DType::F32,
        device.clone(),
    )
}

struct SeededInit {
    varmap: VarMap,
    seed: u64,
}

/// FNV-1a of a variable name: stable across runs and platforms.
fn name_hash(name: &str) -> u64 {
    name.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// One standard normal draw (Box–Muller).
fn standard_normal(rng: &mut ChaCha8Rng) -> f64 {
    let u1: f64 = 1.0 - rng.gen::<f64>(); // (0, 1]: ln stays finite
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// The values of a new variable: candle's `Init` distributions, drawn from `rng`.
fn init_values(shape: &Shape, init: Init, rng: &mut ChaCha8Rng) -> Vec<f32> {
    let n = shape.elem_count();
    let uniform = |rng: &mut ChaCha8Rng, lo: f64, up: f64| lo + (up - lo) * rng.gen::<f64>();
    let draw: Box<dyn FnMut(&mut ChaCha8Rng) -> f64> = match init {
        Init::Const(c) => Box::new(move |_| c),
        Init::Uniform { lo, up } => Box::new(move |r| uniform(r, lo, up)),
        Init::Randn { mean, stdev } => Box::new(move |r| mean + stdev * standard_normal(r)),
        Init::Kaiming {
            dist,
            fan,
            non_linearity,
        } => {
            let std = non_linearity.gain() / (fan.for_shape(shape) as f64).sqrt();
            match dist {
                NormalOrUniform::Uniform => {
                    let bound = 3f64.sqrt() * std;
                    Box::new(move |r| uniform(r, -bound, bound))
                }
                NormalOrUniform::Normal => Box::new(move |r| std * standard_normal(r)),
            }
        }
    };
    let mut draw = draw;
    (0..n).map(|_| draw(rng) as f32).collect()
}

fn poisoned() -> candle_core::Error {
    candle_core::Error::Msg("the variable map's lock is poisoned".into())
}

impl SimpleBackend for SeededInit {
    fn get(
        &self,
        s: Shape,
        name: &str,
        h: Init,
        dtype: DType,
        dev: &Device,
    ) -> candle_core::Result<Tensor> {
        let data = self.varmap.data();
        let mut vars = data.lock().map_err(|_| poisoned())?;
        if let Some(v) = vars.get(name) {
            if v.shape() != &s {
                return Err(candle_core::Error::UnexpectedShape {
                    msg: format!("shape mismatch for {name}"),
                    expected: s,
                    got: v.shape().clone(),
                }
                .bt());
            }
            return Ok(v.as_tensor().clone());
        }
        let mut rng = ChaCha8Rng::seed_from_u64(splitmix64(self.seed ^ name_hash(name)));
        let values = init_values(&s, h, &mut rng);
        let t = Tensor::from_vec(values, s, dev)?.to_dtype(dtype)?;
        let var = Var::from_tensor(&t)?;
        let out = var.as_tensor().clone();
        vars.insert(name.to_string(), var);
        Ok(out)
    }

    fn get_unchecked(&self, name: &str, dtype: DType, dev: &Device) -> candle_core::Result<Tensor> {
        SimpleBackend::get_unchecked(&self.varmap, name, dtype, dev)
    }

    fn contains_tensor(&self, name: &str) -> bool {
        self.varmap
            .data()
            .lock()
            .map(|v| v.contains_key(name))
            .unwrap_or(false)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn linear_weights(seed: u64) -> Vec<f32> {
        let varmap = VarMap::new();
        let vb = seeded_var_builder(&varmap, seed, &Device::Cpu);
        let l = candle_nn::linear(64, 32, vb.pp("fc")).unwrap();
        assert_eq!(varmap.all_vars().len(), 2);
        l.weight().flatten_all().unwrap().to_vec1().unwrap()
    }

    #[test]
    fn same_seed_same_weights_other_seed_other_weights() {
        let a = linear_weights(3);
        assert_eq!(a, linear_weights(3));
        assert_ne!(a, linear_weights(4));
        // candle's Kaiming normal for a ReLU layer: std = sqrt(2 / fan_in) = 0.177.
        let n = a.len() as f64;
        let mean = a.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let std = (a
            .iter()
            .map(|&v| (f64::from(v) - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        assert!(mean.abs() < 0.02, "{mean}");
        assert!((std - (2.0f64 / 64.0).sqrt()).abs() < 0.02, "{std}");
    }
}
