//! Full: TNet's translation head and RNet's rotation branch on the same point features.
//!
//! Per pixel i the net predicts a centre `t̂_i = x_i + Δx̂_i` (TNet's offset head) and a
//! rotation `R̂_i` with a confidence `c_i` (RNet's branch, fed with TNet's first-layer
//! features). Trained with the per-pixel ADD loss over the object's model points, minimum
//! over its symmetries, confidence-weighted (DenseFusion): (1/N) Σ (d_i c_i − w log c_i).
//! The pose it outputs: the rotation of the most confident pixel and the mean of the
//! per-pixel centres (TNet's estimate). Variable names are TNet's (`l1`, `l2`, `l3`, `h*`)
//! and RNet's (`rot.*`), so either checkpoint initializes its part.

use candle_core::{Result, Tensor};
use candle_nn::VarBuilder;

use super::rnet::{quaternion_to_matrix, RotationBranch, RotationOut};
use super::tnet::TNet;
use crate::losses::{confident_add_loss, symmetric_add_per_pixel};

pub struct Full {
    tnet: TNet,
    rot: RotationBranch,
}

/// Per pixel offsets (B, N, 3, normalized units), quaternions (B, N, 4), confidences (B, N).
pub struct FullOut {
    pub offsets: Tensor,
    pub rotation: RotationOut,
}

impl Full {
    pub fn new(width: usize, vb: VarBuilder) -> Result<Full> {
        Ok(Full {
            tnet: TNet::new(width, 0, vb.clone())?,
            rot: RotationBranch::new(width, vb.pp("rot"))?,
        })
    }

    /// `points`: (B, N, 3) normalized; `crops`: (B, S, S, 3) NHWC; `pixels`: (B·N) u32.
    pub fn forward(&self, points: &Tensor, crops: &Tensor, pixels: &Tensor) -> Result<FullOut> {
        let (b, n, _) = points.dims3()?;
        let (offsets, feat) = self.tnet.forward_with_features(points, None)?;
        let rotation = self.rot.forward(&feat, crops, pixels, b, n)?;
        Ok(FullOut { offsets, rotation })
    }
}

/// Full's loss in metres. Everything in normalized units (centred on the cloud's mean, times
/// `scale`): `points` (B, N, 3) the input cloud, `model_points` (B, M, 3) object-frame model
/// points times `scale`, `targets` (B, K, M, 3) the GT-posed (and symmetry-turned) model
/// points in the normalized frame. Distances are divided by `scale` before weighting.
pub fn full_loss(
    out: &FullOut,
    points: &Tensor,
    model_points: &Tensor,
    targets: &Tensor,
    scale: f64,
    w: f64,
) -> Result<Tensor> {
    let r = quaternion_to_matrix(&out.rotation.quats)?;
    let t = (points + &out.offsets)?;
    let d = (symmetric_add_per_pixel(&r, &t, model_points, targets)? / scale)?;
    confident_add_loss(&d, &out.rotation.conf, w)
}
