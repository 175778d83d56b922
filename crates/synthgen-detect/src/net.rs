//! The box detector: where each object class lies in a whole frame, so that the RGB models run
//! without GT boxes. A centre-heatmap detector (CenterNet, Zhou et al. 2019): per cell of a
//! map a quarter of the (downscaled) frame's side and per class, the logit that an object's
//! visible box is centred there, the centre's offset inside the cell and the box's log width
//! and height in cells.
//!
//! The network is the dense RGB model's encoder–decoder without its global feature (so it
//! runs on a frame of any size that is a multiple of 8): three 3×3 stride-2 convolutions
//! (3→32→64→128), two 3×3 ones at 1/8 (128; ~47 px of the input seen by a cell, about an
//! object at the input's scale), a nearest-neighbour ×2 upsampling concatenated with the 1/4
//! map and a 3×3 convolution (→64), and a 1×1 head of [`DET_OUT`] channels per class. All
//! convolutions are `im2col` + a fused dense layer ([`synthgen_nn::im2col`]).
//!
//! With masks (the default of new runs), a mask branch: the decoder's 1/4 map upsampled ×2
//! and concatenated with the 1/2 encoder map (64 + 32), a 3×3 convolution (→32) and a 1×1
//! head of one logit per class: per pixel of a map half the input's side, whether the pixel
//! shows that object (its visible mask). An instance's mask is that map inside its box
//! ([`crate::detector`]): a semantic map cut by the boxes, which is an instance mask as long
//! as two instances of one object do not overlap (BOP's LM-O and YCB-V show each object once).
//!
//! Loss: CenterNet's penalty-reduced focal loss over the heatmaps (Gaussian targets around
//! each box's centre cell), plus the L1 distance of the offset and the log size at the centre
//! cells, each over the number of boxes; with masks, plus the mean binary cross-entropy of
//! the mask logits.

use candle_core::{Result, Tensor};
use candle_nn::VarBuilder;

use synthgen_nn::dense::{dense, Dense};
use synthgen_nn::im2col::Window;
use synthgen_nn::upsample::upsample2_cat;
use synthgen_train::models::rgb_dense::conv;

const ENC: [usize; 3] = [32, 64, 128];
const MID: usize = 128;
const DEC: usize = 64;
/// The mask branch's width.
const MASK_DEC: usize = 32;
/// Outputs per class: the heatmap logit, the centre's offset in the cell (x, y) and the
/// box's log width and height in cells.
pub const DET_OUT: usize = 5;
/// The map's cells per input pixel: a quarter.
pub const DET_STRIDE: u32 = 4;
/// Added to every heatmap logit: a fresh network's scores start near 0.1, not 0.5, so the
/// focal loss of the many empty cells does not swamp the first steps (CenterNet's −2.19).
const HEAT_PRIOR: f64 = -2.19;
const DOWN: Window = Window {
    k: 3,
    stride: 2,
    pad: 1,
};
const SAME: Window = Window {
    k: 3,
    stride: 1,
    pad: 1,
};

/// The detector's network.
pub struct DetectorNet {
    enc: Vec<Dense>,
    mid: [Dense; 2],
    dec: Dense,
    head: Dense,
    /// The mask branch's convolution and head, when the detector gives masks.
    mask: Option<(Dense, Dense)>,
    classes: usize,
}

/// Its output for a batch of (B, H, W, 3) frames: per cell of the (H/4, W/4) map and per
/// class, the heatmap logits (B, h, w, C) and the offset and log size (B, h, w, C, 4); with
/// masks, per pixel of the (H/2, W/2) map and per class the mask logit (B, H/2, W/2, C).
pub struct DetOut {
    pub heat: Tensor,
    pub boxes: Tensor,
    pub mask: Option<Tensor>,
}

impl DetectorNet {
    pub fn new(classes: usize, masks: bool, vb: VarBuilder) -> Result<DetectorNet> {
        if classes == 0 {
            candle_core::bail!("the detector needs at least one object class");
        }
        let mut enc = Vec::with_capacity(ENC.len());
        let mut c_in = 3;
        for (i, &c) in ENC.iter().enumerate() {
            enc.push(dense(9 * c_in, c, vb.pp(format!("enc{}", i + 1)))?);
            c_in = c;
        }
        Ok(DetectorNet {
            enc,
            mid: [
                dense(9 * ENC[2], MID, vb.pp("mid1"))?,
                dense(9 * MID, MID, vb.pp("mid2"))?,
            ],
            dec: dense(9 * (MID + ENC[1]), DEC, vb.pp("dec"))?,
            head: dense(DEC, classes * DET_OUT, vb.pp("head"))?,
            mask: if masks {
                Some((
                    dense(9 * (DEC + ENC[0]), MASK_DEC, vb.pp("mask_dec"))?,
                    dense(MASK_DEC, classes, vb.pp("mask_head"))?,
                ))
            } else {
                None
            },
            classes,
        })
    }

    /// `frames`: (B, H, W, 3) normalized colours, H and W multiples of 8.
    pub fn forward(&self, frames: &Tensor) -> Result<DetOut> {
        let (_, h, w, _) = frames.dims4()?;
        if h % 8 != 0 || w % 8 != 0 || h == 0 || w == 0 {
            candle_core::bail!(
                "the detector's input must be a multiple of 8 each way (got {w}x{h})"
            );
        }
        let e1 = conv(&self.enc[0], frames, DOWN)?;
        let e2 = conv(&self.enc[1], &e1, DOWN)?;
        let e3 = conv(&self.enc[2], &e2, DOWN)?;
        let m = conv(&self.mid[0], &e3, SAME)?;
        let m = conv(&self.mid[1], &m, SAME)?;
        let x = upsample2_cat(&m, &e2)?;
        let d = conv(&self.dec, &x, SAME)?;
        let (b, s_h, s_w, c) = d.dims4()?;
        let out = candle_core::Module::forward(&self.head, &d.reshape((b * s_h * s_w, c))?)?
            .reshape((b, s_h, s_w, self.classes, DET_OUT))?;
        let mask = match &self.mask {
            Some((dec, head)) => {
                let x = upsample2_cat(&d, &e1)?;
                let m = conv(dec, &x, SAME)?;
                let (b, m_h, m_w, c) = m.dims4()?;
                Some(
                    candle_core::Module::forward(head, &m.reshape((b * m_h * m_w, c))?)?
                        .reshape((b, m_h, m_w, self.classes))?,
                )
            }
            None => None,
        };
        Ok(DetOut {
            heat: (out.narrow(4, 0, 1)?.squeeze(4)? + HEAT_PRIOR)?,
            boxes: out.narrow(4, 1, 4)?,
            mask,
        })
    }
}

/// `log(1 + exp(x))`, stable for large |x|.
fn softplus(x: &Tensor) -> Result<Tensor> {
    x.relu()? + x.abs()?.neg()?.exp()?.log1p()?
}

trait Log1p {
    fn log1p(&self) -> Result<Tensor>;
}

impl Log1p for Tensor {
    fn log1p(&self) -> Result<Tensor> {
        (self + 1.0)?.log()
    }
}

/// The loss of a batch against `heat` (B, h, w, C) Gaussian targets (exactly 1 at each box's
/// centre cell), `reg` (B, h, w, C, 4) offset and log-size targets and `centres`
/// (B, h, w, C) 1 at the centre cells, 0 elsewhere: the focal loss (α 2, β 4) plus the L1 of
/// the regression at the centres, both over the number of boxes (at least 1); with `mask`
/// targets (B, H/2, W/2, C; 1 on the object's visible pixels), plus the mean binary
/// cross-entropy of the mask logits.
pub fn detector_loss(
    out: &DetOut,
    heat: &Tensor,
    reg: &Tensor,
    centres: &Tensor,
    mask_targets: Option<&Tensor>,
) -> Result<Tensor> {
    let n = centres.sum_all()?.to_scalar::<f32>()?.max(1.0);
    let x = &out.heat;
    let p = candle_nn::ops::sigmoid(x)?;
    // log p = −softplus(−x), log(1 − p) = −softplus(x).
    let log_p = softplus(&x.neg()?)?.neg()?;
    let log_q = softplus(x)?.neg()?;
    let one_minus_p = (1.0 - &p)?;
    let pos = ((one_minus_p.sqr()? * log_p)? * centres)?;
    let neg_w = ((1.0 - heat)?.powf(4.0)? * (1.0 - centres)?)?;
    let neg = ((p.sqr()? * log_q)? * neg_w)?;
    let focal = ((pos + neg)?.sum_all()?.neg()? / f64::from(n))?;
    let mask = centres.unsqueeze(4)?.broadcast_as(reg.shape())?;
    let l1 = ((&out.boxes - reg)?.abs()? * mask)?
        .sum_all()?
        .affine(1.0 / f64::from(n), 0.0)?;
    let boxes = (focal + l1)?;
    match (&out.mask, mask_targets) {
        (Some(logits), Some(t)) => {
            // BCE with logits: softplus(x) − x·t.
            let bce = (softplus(logits)? - (logits * t)?)?.mean_all()?;
            boxes + bce
        }
        _ => Ok(boxes),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_core::{DType, Device};
    use candle_nn::VarMap;

    #[test]
    fn the_map_is_a_quarter_of_the_frame_per_class() {
        let vm = VarMap::new();
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu);
        let net = DetectorNet::new(3, true, vb).unwrap();
        let x = Tensor::zeros((2, 32, 48, 3), DType::F32, &Device::Cpu).unwrap();
        let out = net.forward(&x).unwrap();
        assert_eq!(out.heat.dims(), &[2, 8, 12, 3]);
        assert_eq!(out.boxes.dims(), &[2, 8, 12, 3, 4]);
        assert_eq!(out.mask.as_ref().unwrap().dims(), &[2, 16, 24, 3]);
        let vm = VarMap::new();
        let vb = VarBuilder::from_varmap(&vm, DType::F32, &Device::Cpu);
        let boxes_only = DetectorNet::new(3, false, vb).unwrap();
        assert!(boxes_only.forward(&x).unwrap().mask.is_none());
        let odd = Tensor::zeros((1, 30, 48, 3), DType::F32, &Device::Cpu).unwrap();
        assert!(net.forward(&odd).is_err());
    }

    #[test]
    fn the_focal_loss_is_least_when_the_heatmap_is_right() {
        let dev = Device::Cpu;
        let mut heat = vec![0f32; 16];
        heat[5] = 1.0;
        heat[4] = 0.5;
        let mut centres = vec![0f32; 16];
        centres[5] = 1.0;
        let heat_t = Tensor::from_vec(heat.clone(), (1, 4, 4, 1), &dev).unwrap();
        let centres_t = Tensor::from_vec(centres, (1, 4, 4, 1), &dev).unwrap();
        let reg = Tensor::zeros((1, 4, 4, 1, 4), DType::F32, &dev).unwrap();
        let loss = |logits: Vec<f32>| {
            let out = DetOut {
                heat: Tensor::from_vec(logits, (1, 4, 4, 1), &dev).unwrap(),
                boxes: Tensor::zeros((1, 4, 4, 1, 4), DType::F32, &dev).unwrap(),
                mask: None,
            };
            detector_loss(&out, &heat_t, &reg, &centres_t, None)
                .unwrap()
                .to_scalar::<f32>()
                .unwrap()
        };
        let right: Vec<f32> = (0..16).map(|i| if i == 5 { 6.0 } else { -6.0 }).collect();
        let wrong: Vec<f32> = (0..16).map(|i| if i == 10 { 6.0 } else { -6.0 }).collect();
        let flat = vec![0f32; 16];
        let (r, w, f) = (loss(right), loss(wrong), loss(flat));
        assert!(r < 0.05, "{r}");
        assert!(r < f && f < w, "{r} {f} {w}");
    }

    #[test]
    fn the_mask_loss_is_least_when_the_mask_is_right() {
        let dev = Device::Cpu;
        let target: Vec<f32> = (0..8).map(|i| f32::from(u8::from(i % 3 == 0))).collect();
        let t = Tensor::from_vec(target.clone(), (1, 2, 4, 1), &dev).unwrap();
        let zeros = |shape: &[usize]| Tensor::zeros(shape, DType::F32, &dev).unwrap();
        let loss = |logits: Vec<f32>| {
            let out = DetOut {
                heat: zeros(&[1, 1, 1, 1]),
                boxes: zeros(&[1, 1, 1, 1, 4]),
                mask: Some(Tensor::from_vec(logits, (1, 2, 4, 1), &dev).unwrap()),
            };
            let with = detector_loss(
                &out,
                &zeros(&[1, 1, 1, 1]),
                &zeros(&[1, 1, 1, 1, 4]),
                &zeros(&[1, 1, 1, 1]),
                Some(&t),
            );
            let without = detector_loss(
                &out,
                &zeros(&[1, 1, 1, 1]),
                &zeros(&[1, 1, 1, 1, 4]),
                &zeros(&[1, 1, 1, 1]),
                None,
            );
            with.unwrap().to_scalar::<f32>().unwrap() - without.unwrap().to_scalar::<f32>().unwrap()
        };
        let right: Vec<f32> = target
            .iter()
            .map(|&v| if v > 0.0 { 8.0 } else { -8.0 })
            .collect();
        let wrong: Vec<f32> = right.iter().map(|v| -v).collect();
        let (r, f, w) = (loss(right), loss(vec![0.0; 8]), loss(wrong));
        assert!(r < 1e-3, "{r}");
        assert!((f - std::f32::consts::LN_2).abs() < 1e-5, "{f}");
        assert!(w > 7.9, "{w}");
    }
}
