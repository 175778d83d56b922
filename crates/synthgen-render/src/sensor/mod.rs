//! Sensor models applied to a rendered frame after its annotations were computed: a
//! RealSense D455-style stereo depth model, a Kinect/ToF-style depth model, a structured-light
//! (Kinect v1 / PrimeSense / Asus Xtion) model and RGB sensor effects. They change only `RenderedFrame::rgb` and `RenderedFrame::depth_m`; instance ids
//! and alone depths (hence masks and GT) stay those of the clean render. Every draw comes
//! from the frame's `Stream::Sensor` RNG, so a frame's noise depends on (seed, frame index)
//! alone. Formulas and sources: docs/sensors.md.

mod d455;
mod rgb;
mod structured_light;
mod tof;

pub use d455::apply_d455;
pub(crate) use rgb::apply_rgb;
pub use structured_light::apply_structured_light;
pub use tof::{apply_tof, tof_sigma_m};

use rand::{Rng, RngCore};
use rand_chacha::ChaCha8Rng;
use synthgen_core::rng::{frame_rng, Stream};
use synthgen_core::scene::{DepthModel, SensorSpec};
use synthgen_core::{FrameScene, RenderedFrame};

use crate::color::ColorLuts;
use crate::Error;

/// A configured sensor: the spec, the run's seed and the colour tables.
pub struct SensorModel {
    spec: SensorSpec,
    seed: u64,
    luts: ColorLuts,
}

/// RNG streams within the frame's sensor stream.
const DEPTH_STREAM: u64 = 1;
const RGB_STREAM: u64 = 2;

impl SensorModel {
    pub fn new(spec: SensorSpec, seed: u64) -> Result<SensorModel, Error> {
        spec.validate().map_err(|e| Error::InvalidOption {
            name: "sensor",
            reason: e.to_string(),
        })?;
        Ok(SensorModel {
            spec,
            seed,
            luts: ColorLuts::new(),
        })
    }

    pub fn spec(&self) -> &SensorSpec {
        &self.spec
    }

    /// True when `apply` changes nothing.
    pub fn is_identity(&self) -> bool {
        self.spec.is_identity()
    }

    /// Applies the depth model and the RGB effects to `frame` (rendered from `scene`).
    pub fn apply(&self, scene: &FrameScene, frame: &mut RenderedFrame) {
        let k = &scene.intrinsics;
        let (w, h) = (frame.width as usize, frame.height as usize);
        // Defocus blurs by the rendered depth, before the depth model puts holes in it.
        let rgb = &self.spec.rgb;
        let clean_depth = (rgb.enabled && rgb.defocus_px[1] > 0.0 && frame.depth_m.len() == w * h)
            .then(|| frame.depth_m.clone());
        if frame.depth_m.len() == w * h {
            let mut rng = self.rng(scene.frame_index, DEPTH_STREAM);
            match self.spec.depth {
                DepthModel::None => {}
                DepthModel::D455 => {
                    apply_d455(&self.spec.d455, k.fx, w, h, &mut frame.depth_m, &mut rng)
                }
                DepthModel::Tof => apply_tof(&self.spec.tof, k, &mut frame.depth_m, &mut rng),
                DepthModel::StructuredLight => apply_structured_light(
                    &self.spec.structured_light,
                    k,
                    &frame.rgb,
                    &mut frame.depth_m,
                    rng.gen(),
                ),
            }
        }
        if self.spec.rgb.enabled && frame.rgb.len() == w * h * 3 {
            let mut rng = self.rng(scene.frame_index, RGB_STREAM);
            let depth = clean_depth
                .as_deref()
                .map(|d| (d, frame.instance.as_slice()));
            apply_rgb(
                &self.spec.rgb,
                &self.luts,
                w,
                h,
                &mut frame.rgb,
                depth,
                &mut rng,
            );
        }
    }

    fn rng(&self, frame_index: u64, stream: u64) -> ChaCha8Rng {
        let mut rng = frame_rng(self.seed, frame_index, Stream::Sensor);
        rng.set_stream(stream);
        rng
    }
}

/// Standard normal draws (Box-Muller, both values used).
pub(crate) struct Normal {
    spare: Option<f64>,
}

impl Normal {
    pub fn new() -> Normal {
        Normal { spare: None }
    }

    pub fn sample(&mut self, rng: &mut impl RngCore) -> f64 {
        if let Some(v) = self.spare.take() {
            return v;
        }
        // u1 in (0, 1] so ln(u1) is finite.
        let u1 = 1.0 - rng.gen::<f64>();
        let u2: f64 = rng.gen();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (std::f64::consts::TAU * u2).sin_cos();
        self.spare = Some(r * s);
        r * c
    }
}

/// Rounds to a multiple of `unit` (no rounding when `unit` is 0), halves away from zero.
#[inline]
pub(crate) fn quantize(z: f64, unit: f64) -> f64 {
    if unit > 0.0 {
        let q = z / unit;
        // A truncating cast instead of `round` (a libm call on x86-64 without SSE4.1).
        if q.abs() < 1e15 {
            (q + 0.5f64.copysign(q)) as i64 as f64 * unit
        } else {
            q.round() * unit
        }
    } else {
        z
    }
}

#[cfg(test)]
mod tests;
