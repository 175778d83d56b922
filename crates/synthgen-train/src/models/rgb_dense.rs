//! The dense RGB model: per pixel of a box's colour crop, whether the object is visible there
//! and which point of the object it is (its 3D object coordinates), then the pose by PnP +
//! RANSAC and a non-linear refinement ([`synthgen_core::pnp`]), as correspondence methods do
//! (Brachmann et al. 2014 on Linemod-Occluded, CDPN, GDR-Net).
//!
//! The network is a small encoder–decoder over the NHWC crop: three 3×3 stride-2 convolutions
//! (3→32→64→128) and a 3×3 one at 1/8 (128), then a nearest-neighbour ×2 upsampling,
//! concatenated with the encoder's 1/4 map (skip connection) and a 3×3 convolution (→64), so
//! the output is a quarter of the crop's side ([`dense_out`]); a 1×1 head gives, per class
//! (the detector's class), 4 channels: the coordinates divided by the object's radius (half
//! its diameter: O(1) for every object) and the visibility logit. A cell's convolutions see
//! ~30 px of the crop, less than the object; which side of the object a cell shows is a
//! property of the whole view, so a **global feature** (the 1/8 map flattened through a fully
//! connected layer of `width`, as the direct RGB model's) is added, through its own
//! projection, to every decoder cell, and is trained to hold the view by an auxiliary
//! **rotation head** (per class, the allocentric quaternion, with the direct RGB model's
//! point-matching loss). A **translation head** on the same feature regresses the centre's
//! offset in the box and the scale-invariant depth, as the RGB model's centre + Tz (CDPN's
//! SITE): PnP's depth is its weak direction. All convolutions are `im2col` + a fused dense layer (see
//! [`synthgen_nn::im2col`]).
//!
//! Loss: the mean L1 distance of the coordinates over the visible cells, plus the binary
//! cross-entropy of the visibility over all cells. A symmetric object's target is the
//! coordinates under the one of its equivalent GT poses whose rotation is closest to the
//! identity (largest trace): a function of the pose that every equivalent pose shares, so
//! views that look alike get one target (as Pitteri et al.'s canonical poses).

use candle_core::{Result, Tensor, D};
use candle_nn::VarBuilder;
use synthgen_core::glam::DVec3;
use synthgen_core::Pose;

use super::rgb::{normalize_quaternions, pick_class};
use synthgen_nn::dense::{dense, dense_no_bias, Dense};
use synthgen_nn::im2col::Window;
use synthgen_nn::upsample::upsample2_cat;

/// Encoder channels (three stride-2 layers) and the 1/8 layer's.
const ENC: [usize; 3] = [32, 64, 128];
const MID: usize = 128;
/// Decoder channels after each upsampling.
const DEC: usize = 64;
/// Outputs per class: x, y, z (over the radius) and the visibility logit.
pub const DENSE_OUT: usize = 4;
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

/// The network.
pub struct DenseNet {
    enc: Vec<Dense>,
    mid: Dense,
    global: Dense,
    global2: Dense,
    dec2: Dense,
    head: Dense,
    rot: Dense,
    trans: Dense,
    classes: usize,
}

/// Cells across the model's output for a `crop`-pixel input: a quarter of the side.
pub fn dense_out(crop: u32) -> u32 {
    crop / 4
}

/// Its output for a batch: coordinates over the radius (B, S, S, 3), visibility logits
/// (B, S, S), S = [`dense_out`], the rotation head's allocentric quaternions (B, 4),
/// (w, x, y, z), normalized, and the translation head's centre + Tz targets (B, 3)
/// ([`super::rgb::Translation::CentreTz`]).
pub struct DenseOut {
    pub coords: Tensor,
    pub logits: Tensor,
    pub quats: Tensor,
    pub translation: Tensor,
}

/// A convolution of an NHWC map, ReLU: one fused node ([`Dense::conv_relu`]).
pub fn conv(layer: &Dense, x: &Tensor, win: Window) -> Result<Tensor> {
    layer.conv_relu(x, win, None)
}

pub use synthgen_nn::upsample::upsample2;

impl DenseNet {
    /// For `crop`-pixel inputs (a multiple of 8), a global feature of `width` and `classes`
    /// heads.
    pub fn new(crop: u32, width: usize, classes: usize, vb: VarBuilder) -> Result<DenseNet> {
        if classes == 0 {
            candle_core::bail!("the rgb-dense model needs at least one object class");
        }
        if crop < 16 || !crop.is_multiple_of(8) {
            candle_core::bail!(
                "the rgb-dense model's crop must be a multiple of 8, at least 16 (got {crop})"
            );
        }
        let mut enc = Vec::with_capacity(ENC.len());
        let mut c_in = 3;
        for (i, &c) in ENC.iter().enumerate() {
            enc.push(dense(9 * c_in, c, vb.pp(format!("enc{}", i + 1)))?);
            c_in = c;
        }
        let side = crop as usize / 8;
        Ok(DenseNet {
            enc,
            mid: dense(9 * ENC[2], MID, vb.pp("mid"))?,
            global: dense(side * side * MID, width, vb.pp("global"))?,
            global2: dense_no_bias(width, DEC, vb.pp("global2"))?,
            dec2: dense(9 * (MID + ENC[1]), DEC, vb.pp("dec2"))?,
            head: dense(DEC, classes * DENSE_OUT, vb.pp("head"))?,
            rot: dense(width, classes * 4, vb.pp("rot"))?,
            trans: dense(width, classes * 3, vb.pp("trans"))?,
            classes,
        })
    }

    /// `crops`: (B, S, S, 3) normalized colours; `class`: (B,) u32 head indices.
    pub fn forward(&self, crops: &Tensor, class: &Tensor) -> Result<DenseOut> {
        let e1 = conv(&self.enc[0], crops, DOWN)?;
        let e2 = conv(&self.enc[1], &e1, DOWN)?;
        let e3 = conv(&self.enc[2], &e2, DOWN)?;
        let m = conv(&self.mid, &e3, SAME)?;
        let g = self
            .global
            .forward_relu(&m.flatten_from(1)?.contiguous()?)?;
        let extra = candle_core::Module::forward(&self.global2, &g)?;
        let x = upsample2_cat(&m, &e2)?;
        let d = self.dec2.conv_relu(&x, SAME, Some(&extra))?;
        let (b, s, _, c) = d.dims4()?;
        let out = candle_core::Module::forward(&self.head, &d.reshape((b * s * s, c))?)?
            .reshape((b, s * s, self.classes, DENSE_OUT))?;
        let idx = class
            .reshape((b, 1, 1, 1))?
            .broadcast_as((b, s * s, 1, DENSE_OUT))?
            .contiguous()?;
        let out = out.gather(&idx, 2)?.reshape((b, s, s, DENSE_OUT))?;
        let q = candle_core::Module::forward(&self.rot, &g)?.reshape((b, self.classes, 4))?;
        let quats = normalize_quaternions(&pick_class(&q, class)?)?;
        let t = candle_core::Module::forward(&self.trans, &g)?.reshape((b, self.classes, 3))?;
        let translation = pick_class(&t, class)?;
        Ok(DenseOut {
            coords: out.narrow(3, 0, 3)?,
            logits: out.narrow(3, 3, 1)?.squeeze(3)?,
            quats,
            translation,
        })
    }
}

/// The loss of a batch: `targets` (B, S, S, 3) coordinates over the radius and `visible`
/// (B, S, S) 0/1. Mean L1 over the visible cells (summed over x, y, z) plus the mean binary
/// cross-entropy of the visibility logits.
pub fn dense_loss(out: &DenseOut, targets: &Tensor, visible: &Tensor) -> Result<Tensor> {
    let n_visible = visible.sum_all()?.to_scalar::<f32>()?.max(1.0);
    let l1 = (&out.coords - targets)?
        .abs()?
        .sum(D::Minus1)?
        .mul(visible)?
        .sum_all()?
        .affine(1.0 / f64::from(n_visible), 0.0)?;
    // BCE with logits, stable: max(x, 0) − x·y + log(1 + exp(−|x|)).
    let x = &out.logits;
    let bce = ((x.relu()? - x.mul(visible)?)? + x.abs()?.neg()?.exp()?.affine(1.0, 1.0)?.log()?)?
        .mean_all()?;
    l1 + bce
}

/// The target coordinates of one instance (metres, model frame, NaN where not visible) for
/// the canonical one of its equivalent poses: the symmetry `S` of `symmetries` (identity
/// among them) whose pose `gt · S` has the largest rotation trace, each point mapped by S⁻¹.
pub fn canonical_coords(coords: &mut [[f32; 3]], gt: &Pose, symmetries: &[Pose]) {
    let best = symmetries.iter().max_by(|a, b| {
        let ta = trace(&(gt.rotation * a.rotation));
        let tb = trace(&(gt.rotation * b.rotation));
        ta.total_cmp(&tb)
    });
    let Some(s) = best else { return };
    if *s == Pose::IDENTITY {
        return;
    }
    let inv = s.inverse();
    for c in coords.iter_mut().filter(|c| c[0].is_finite()) {
        let p = inv.transform_point(DVec3::new(c[0].into(), c[1].into(), c[2].into()));
        *c = p.as_vec3().to_array();
    }
}

fn trace(m: &synthgen_core::glam::DMat3) -> f64 {
    m.x_axis.x + m.y_axis.y + m.z_axis.z
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_core::{DType, Device};
    use candle_nn::VarMap;
    use synthgen_core::glam::DMat3;

    #[test]
    fn shapes_and_the_class_picks_its_head() {
        let dev = Device::Cpu;
        let vm = VarMap::new();
        let net = DenseNet::new(16, 8, 3, VarBuilder::from_varmap(&vm, DType::F32, &dev)).unwrap();
        let crops = Tensor::randn(0f32, 1.0, (2, 16, 16, 3), &dev).unwrap();
        let a = net
            .forward(&crops, &Tensor::new(&[0u32, 0], &dev).unwrap())
            .unwrap();
        let b = net
            .forward(&crops, &Tensor::new(&[0u32, 2], &dev).unwrap())
            .unwrap();
        assert_eq!(a.coords.dims(), [2, 4, 4, 3]);
        assert_eq!(a.logits.dims(), [2, 4, 4]);
        assert_eq!(a.quats.dims(), [2, 4]);
        let row = |t: &Tensor, i: usize| {
            t.get(i)
                .unwrap()
                .flatten_all()
                .unwrap()
                .to_vec1::<f32>()
                .unwrap()
        };
        assert_eq!(row(&a.coords, 0), row(&b.coords, 0));
        assert_ne!(row(&a.coords, 1), row(&b.coords, 1));
        assert!(DenseNet::new(20, 8, 1, VarBuilder::from_varmap(&vm, DType::F32, &dev)).is_err());
    }

    #[test]
    fn the_loss_is_zero_only_at_the_target_and_visibility() {
        let dev = Device::Cpu;
        let t = Tensor::new(&[[[[0.5f32, -0.5, 0.0], [0.1, 0.2, 0.3]]]], &dev).unwrap();
        let vis = Tensor::new(&[[[1f32, 0.0]]], &dev).unwrap();
        let at = |coords: &Tensor, logits: [f32; 2]| {
            let out = DenseOut {
                coords: coords.clone(),
                logits: Tensor::new(&[[logits]], &dev).unwrap(),
                quats: Tensor::zeros((1, 4), DType::F32, &dev).unwrap(),
                translation: Tensor::zeros((1, 3), DType::F32, &dev).unwrap(),
            };
            dense_loss(&out, &t, &vis)
                .unwrap()
                .to_scalar::<f32>()
                .unwrap()
        };
        // The invisible cell's coordinates do not count; confident, right visibility ~ 0.
        let other = Tensor::new(&[[[[0.5f32, -0.5, 0.0], [9.0, 9.0, 9.0]]]], &dev).unwrap();
        assert!(at(&other, [30.0, -30.0]) < 1e-6);
        // L1 over the visible cell: |0.1| + |0.2| off.
        let off = Tensor::new(&[[[[0.6f32, -0.3, 0.0], [0.0, 0.0, 0.0]]]], &dev).unwrap();
        assert!((at(&off, [30.0, -30.0]) - 0.3).abs() < 1e-5);
        // Wrong visibility: BCE of a logit of 0 is ln 2 per cell.
        assert!((at(&t, [0.0, 0.0]) - std::f32::consts::LN_2).abs() < 1e-5);
    }

    #[test]
    fn equivalent_poses_get_one_target() {
        // A 180° symmetry about the model's z axis.
        let flip = Pose::new(DMat3::from_rotation_z(std::f64::consts::PI), DVec3::ZERO);
        let syms = [Pose::IDENTITY, flip];
        let gt = Pose::new(
            DMat3::from_rotation_x(0.3) * DMat3::from_rotation_z(2.5),
            DVec3::new(0.0, 0.0, 0.8),
        );
        let gt_flipped = Pose::new(gt.rotation * flip.rotation, gt.translation_m);
        // The same camera point seen under both poses has model coordinates p and flip⁻¹ p.
        let p = DVec3::new(0.03, -0.01, 0.02);
        let mut a = [p.as_vec3().to_array()];
        let mut b = [flip.inverse().transform_point(p).as_vec3().to_array()];
        canonical_coords(&mut a, &gt, &syms);
        canonical_coords(&mut b, &gt_flipped, &syms);
        for k in 0..3 {
            assert!((a[0][k] - b[0][k]).abs() < 1e-6, "{a:?} {b:?}");
        }
        // NaN (not visible) stays NaN.
        let mut n = [[f32::NAN; 3]];
        canonical_coords(&mut n, &gt, &syms);
        assert!(n[0][0].is_nan());
    }
}
