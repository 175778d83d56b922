//! RNet: rotation from colour and points, DenseFusion style.
//!
//! A small CNN over the RGB crop (3→16, 16→32 stride 2, 32→32; 3×3 kernels) gives a colour
//! feature map at half the crop's resolution; each sampled pixel reads the feature at its
//! position. The point branch is TNet's first two layers (3→64→128, the same variable names,
//! so a TNet checkpoint initializes them). Per pixel the colour and point features are fused
//! (`relu(W_c e_i + W_p f_i)`, 128, then a layer to `width`), a global feature average-pooled
//! over the pixels is appended, and a head 128 → 64 → 5 gives per pixel a quaternion
//! (w, x, y, z; normalized) and a confidence (sigmoid). The output is the most confident
//! pixel's quaternion.

use candle_core::{DType, Device, Module, Result, Tensor, D};
use candle_nn::{conv2d, Conv2dConfig, VarBuilder};

pub use crate::quat::quaternion_to_matrix;
use synthgen_nn::conv::conv_bias_relu;
use synthgen_nn::dense::{dense as linear, dense_no_bias as linear_no_bias, Dense as Linear};
use synthgen_nn::fused::group_mean;
use synthgen_nn::im2col::Window;

/// Default side of the square RGB crop, pixels.
pub const DEFAULT_CROP: u32 = 48;
/// Channels of the colour feature.
pub const COLOUR_CHANNELS: usize = 32;
/// The confidence regularizer's weight `w` (DenseFusion's 0.015).
pub const CONFIDENCE_WEIGHT: f64 = 0.015;

/// TNet's first layers: per point 3 → 64 → 128. Shared by RNet and Full.
pub struct PointStem {
    l1: Linear,
    l2: Linear,
}

impl PointStem {
    pub fn new(vb: &VarBuilder) -> Result<PointStem> {
        Ok(PointStem {
            l1: linear(3, 64, vb.pp("l1"))?,
            l2: linear(64, 128, vb.pp("l2"))?,
        })
    }

    /// `x`: (B·N, 3) → (B·N, 128).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        self.l2.forward_relu(&self.l1.forward_relu(x)?)
    }
}

/// The colour CNN: (B, S, S, 3) → (B, S/2, S/2, 32) (S even), NHWC.
///
/// The variables are candle's `conv2d` (`weight` (C_out, C_in, 3, 3), `bias` (C_out); its
/// initialization), so checkpoints of the NCHW network load unchanged; the forward pass runs
/// each layer as one fused convolution + bias + ReLU over the NHWC map
/// ([`conv_bias_relu`], multi-threaded, the patches kept inside the op), the weight viewed
/// as (C_out, 3·3·C_in) in the (ky, kx, c) column order of the patches.
pub struct ColourCnn {
    layers: [ConvLayer; 3],
}

struct ConvLayer {
    weight: Tensor,
    bias: Tensor,
    win: Window,
}

impl ConvLayer {
    fn new(c_in: usize, c_out: usize, stride: usize, vb: VarBuilder) -> Result<ConvLayer> {
        let cfg = Conv2dConfig {
            padding: 1,
            stride,
            ..Default::default()
        };
        let conv = conv2d(c_in, c_out, 3, cfg, vb)?;
        let Some(bias) = conv.bias() else {
            candle_core::bail!("the colour CNN's convolutions have a bias");
        };
        Ok(ConvLayer {
            weight: conv.weight().clone(),
            bias: bias.clone(),
            win: Window {
                k: 3,
                stride,
                pad: 1,
            },
        })
    }

    fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let (c_out, c_in, k, _) = self.weight.dims4()?;
        let w = self
            .weight
            .permute((0, 2, 3, 1))?
            .reshape((c_out, k * k * c_in))?;
        conv_bias_relu(x, &w, &self.bias.unsqueeze(0)?, self.win)
    }
}

impl ColourCnn {
    pub fn new(vb: VarBuilder) -> Result<ColourCnn> {
        Ok(ColourCnn {
            layers: [
                ConvLayer::new(3, 16, 1, vb.pp("c1"))?,
                ConvLayer::new(16, COLOUR_CHANNELS, 2, vb.pp("c2"))?,
                ConvLayer::new(COLOUR_CHANNELS, COLOUR_CHANNELS, 1, vb.pp("c3"))?,
            ],
        })
    }

    /// `x`: (B, S, S, 3) standardized ([`super::rgb::crops_nhwc`]).
    pub fn forward(&self, x: &Tensor) -> Result<Tensor> {
        let mut x = x.clone();
        for layer in &self.layers {
            x = layer.forward(&x)?;
        }
        Ok(x)
    }
}

/// The rotation branch: colour CNN, fusion with the point features, global average pooling,
/// per-pixel quaternion and confidence.
pub struct RotationBranch {
    cnn: ColourCnn,
    fuse_c: Linear,
    fuse_p: Linear,
    fuse2: Linear,
    r1_point: Linear,
    r1_global: Linear,
    r2: Linear,
    r3: Linear,
}

/// Per pixel quaternions (B, N, 4), unit, (w, x, y, z), and confidences (B, N) in (0, 1).
pub struct RotationOut {
    pub quats: Tensor,
    pub conf: Tensor,
}

impl RotationBranch {
    pub fn new(width: usize, vb: VarBuilder) -> Result<RotationBranch> {
        Ok(RotationBranch {
            cnn: ColourCnn::new(vb.pp("cnn"))?,
            fuse_c: linear(COLOUR_CHANNELS, 128, vb.pp("fuse_c"))?,
            fuse_p: linear_no_bias(128, 128, vb.pp("fuse_p"))?,
            fuse2: linear(128, width, vb.pp("fuse2"))?,
            r1_point: linear(width, 128, vb.pp("r1_point"))?,
            r1_global: linear_no_bias(width, 128, vb.pp("r1_global"))?,
            r2: linear(128, 64, vb.pp("r2"))?,
            r3: linear(64, 5, vb.pp("r3"))?,
        })
    }

    /// `point_feat`: (B·N, 128); `crops`: (B, S, S, 3); `pixels`: (B·N) u32 indices into the
    /// flattened (B, S/2, S/2) feature maps (see [`pixel_indices`]).
    pub fn forward(
        &self,
        point_feat: &Tensor,
        crops: &Tensor,
        pixels: &Tensor,
        b: usize,
        n: usize,
    ) -> Result<RotationOut> {
        let fmap = self.cnn.forward(crops)?; // (B, h, w, C)
        let (_, h, w, c) = fmap.dims4()?;
        let flat = fmap.reshape((b * h * w, c))?;
        let colour = flat.index_select(pixels, 0)?; // (B·N, C)

        // relu(W_c e + b_c + W_p f), one node.
        let fused = self
            .fuse_c
            .forward_relu_with(&colour, &self.fuse_p, point_feat)?;
        let fused = self.fuse2.forward_relu(&fused)?; // (B·N, width)
        let global = group_mean(&fused, b)?; // (B, width)
        let hg = self.r1_global.forward(&global)?; // (B, 128)
        let h = self.r1_point.forward_relu_grouped(&fused, Some(&hg))?; // (B·N, 128)
        let h = self.r2.forward_relu(&h)?;
        let out = self.r3.forward(&h)?.reshape((b, n, 5))?;
        let raw_q = out.narrow(2, 0, 4)?;
        let norm = (raw_q.sqr()?.sum_keepdim(D::Minus1)? + 1e-12)?.sqrt()?;
        let quats = raw_q.broadcast_div(&norm)?;
        let conf = candle_nn::ops::sigmoid(&out.narrow(2, 4, 1)?.squeeze(2)?)?;
        Ok(RotationOut { quats, conf })
    }
}

/// RNet: the point stem and the rotation branch.
pub struct RNet {
    stem: PointStem,
    rot: RotationBranch,
}

impl RNet {
    pub fn new(width: usize, vb: VarBuilder) -> Result<RNet> {
        Ok(RNet {
            stem: PointStem::new(&vb)?,
            rot: RotationBranch::new(width, vb.pp("rot"))?,
        })
    }

    /// `points`: (B, N, 3) normalized; `crops`: (B, S, S, 3) ([`super::rgb::crops_nhwc`]);
    /// `pixels`: (B·N) u32.
    pub fn forward(&self, points: &Tensor, crops: &Tensor, pixels: &Tensor) -> Result<RotationOut> {
        let (b, n, _) = points.dims3()?;
        let f = self.stem.forward(&points.reshape((b * n, 3))?)?;
        self.rot.forward(&f, crops, pixels, b, n)
    }
}

/// Indices of the sampled pixels into the flattened half-resolution feature maps of a batch:
/// cloud `k`'s pixel at crop position (x, y) reads feature `k·h·w + ⌊y/2⌋·w + ⌊x/2⌋`.
pub fn pixel_indices(crop_xy: &[&[[f32; 2]]], size: u32, device: &Device) -> Result<Tensor> {
    let half = size.div_ceil(2);
    let per_map = half * half;
    let mut v = Vec::new();
    for (k, xy) in crop_xy.iter().enumerate() {
        for p in xy.iter() {
            let x = ((p[0].max(0.0) as u32) / 2).min(half - 1);
            let y = ((p[1].max(0.0) as u32) / 2).min(half - 1);
            v.push(k as u32 * per_map + y * half + x);
        }
    }
    let n = v.len();
    Tensor::from_vec(v, n, device)?.to_dtype(DType::U32)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::{DMat3, DQuat, DVec3};

    #[test]
    fn quaternion_matrix_matches_glam() {
        let r = DMat3::from_axis_angle(DVec3::new(1.0, -2.0, 0.5).normalize(), 1.1);
        let q = DQuat::from_mat3(&r);
        let t = Tensor::from_vec(
            vec![q.w as f32, q.x as f32, q.y as f32, q.z as f32],
            (1, 1, 4),
            &Device::Cpu,
        )
        .unwrap();
        let m: Vec<f32> = quaternion_to_matrix(&t)
            .unwrap()
            .flatten_all()
            .unwrap()
            .to_vec1()
            .unwrap();
        let want = r.transpose().to_cols_array(); // row-major
        for (a, b) in m.iter().zip(want) {
            assert!((f64::from(*a) - b).abs() < 1e-5, "{m:?} vs {want:?}");
        }
    }

    #[test]
    fn pixel_indices_address_the_half_resolution_maps() {
        let a = [[0.0f32, 0.0], [5.0, 3.0]];
        let b = [[7.9f32, 7.9]];
        let t = pixel_indices(&[&a, &b], 8, &Device::Cpu).unwrap();
        let v: Vec<u32> = t.to_vec1().unwrap();
        // 8 px crop → 4×4 maps; (5, 3) → (2, 1) → 1·4 + 2; second map starts at 16.
        assert_eq!(v, vec![0, 6, 16 + 15]);
    }

    /// The NHWC colour CNN computes what candle's NCHW `conv2d` layers of the same variables
    /// compute (checkpoints of the NCHW network keep their meaning), values and gradients.
    #[test]
    fn colour_cnn_is_candles_conv2d_on_nhwc_maps() {
        let dev = Device::Cpu;
        let varmap = candle_nn::VarMap::new();
        let vb = VarBuilder::from_varmap(&varmap, DType::F32, &dev);
        let cnn = ColourCnn::new(vb.pp("cnn")).unwrap();
        let x = Tensor::randn(0f32, 1.0, (4, 48, 48, 3), &dev).unwrap();
        let x = candle_core::Var::from_tensor(&x).unwrap();
        let got = cnn.forward(&x).unwrap(); // (B, 4, 4, 32)
        let mut want = x.permute((0, 3, 1, 2)).unwrap();
        for (name, stride) in [("c1", 1), ("c2", 2), ("c3", 1)] {
            let vars = varmap.data().lock().unwrap();
            let w = vars[&format!("cnn.{name}.weight")].as_tensor().clone();
            let b = vars[&format!("cnn.{name}.bias")].as_tensor().clone();
            want = want
                .conv2d(&w, 1, stride, 1, 1)
                .unwrap()
                .broadcast_add(&b.reshape((1, (), 1, 1)).unwrap())
                .unwrap()
                .relu()
                .unwrap();
        }
        let want = want.permute((0, 2, 3, 1)).unwrap();
        assert_eq!(got.dims(), want.dims());
        let close = |a: &Tensor, b: &Tensor| {
            let d: f32 = (a - b)
                .unwrap()
                .abs()
                .unwrap()
                .max_all()
                .unwrap()
                .to_scalar()
                .unwrap();
            let m: f32 = b.abs().unwrap().max_all().unwrap().to_scalar().unwrap();
            assert!(d <= 1e-5 * m.max(1.0), "max difference {d}, max value {m}");
        };
        close(&got, &want);
        let wsum = Tensor::randn(0f32, 1.0, got.dims(), &dev).unwrap();
        let g1 = (&got * &wsum)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        let g2 = (&want * &wsum)
            .unwrap()
            .sum_all()
            .unwrap()
            .backward()
            .unwrap();
        close(g1.get(&x).unwrap(), g2.get(&x).unwrap());
        for var in varmap.all_vars() {
            close(g1.get(&var).unwrap(), g2.get(&var).unwrap());
        }
    }

    #[test]
    fn rnet_shapes_and_unit_quaternions() {
        let dev = Device::Cpu;
        let varmap = candle_nn::VarMap::new();
        let vb = VarBuilder::from_varmap(&varmap, DType::F32, &dev);
        let net = RNet::new(16, vb).unwrap();
        let (b, n, s) = (2usize, 5usize, 8u32);
        let pts = Tensor::randn(0f32, 1.0, (b, n, 3), &dev).unwrap();
        let crop = vec![128u8; (s * s * 3) as usize];
        let crops = crate::models::rgb::crops_nhwc(&[&crop, &crop], s, &dev).unwrap();
        assert_eq!(crops.dims(), &[2, 8, 8, 3]);
        let xy: Vec<[f32; 2]> = (0..n).map(|i| [i as f32, 7.0 - i as f32]).collect();
        let pix = pixel_indices(&[&xy, &xy], s, &dev).unwrap();
        let out = net.forward(&pts, &crops, &pix).unwrap();
        assert_eq!(out.quats.dims(), &[b, n, 4]);
        assert_eq!(out.conf.dims(), &[b, n]);
        let norms: Vec<Vec<f32>> = out.quats.sqr().unwrap().sum(2).unwrap().to_vec2().unwrap();
        assert!(norms.iter().flatten().all(|v| (v - 1.0).abs() < 1e-4));
        let c: Vec<Vec<f32>> = out.conf.to_vec2().unwrap();
        assert!(c.iter().flatten().all(|v| *v > 0.0 && *v < 1.0));
    }
}
