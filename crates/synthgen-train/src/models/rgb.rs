//! The RGB pose model of seed 001: a 6-DoF pose from the colour crop of a detected box.
//!
//! A detector gives a box (here the GT `bbox_visib`, jittered while training: a trained detector
//! is out of scope); the square crop around it goes through four 3×3 stride-2 convolutions
//! (3→32→64→128→128, ReLU; as `im2col` + a fused dense layer, NHWC, see [`synthgen_nn::im2col`]),
//! a fully connected layer that also takes the box's place in the
//! image ([`box_geometry`]), a second one, and a head per object class (the detector's class)
//! with 7 outputs: three for the translation and a quaternion (w, x, y, z; normalized).
//!
//! The translation is parametrized two ways ([`Translation`]), with the same inputs and the
//! same network:
//! - **centre + Tz** (the seed's, as PoseCNN): the object centre's projection as an offset
//!   inside the box (in box sides) and its depth Tz; then Tx = (cx − px)·Tz/fx and
//!   Ty = (cy − py)·Tz/fy through the intrinsics. Tz is regressed scale-invariantly (as CDPN's
//!   SITE): the target is Tz · side / f, the width in metres the crop spans at the object's
//!   depth, which the crop shows whatever the box's size in pixels.
//! - **direct XYZ** (the seed's baseline): (Tx, Ty, Tz) regressed as they are.
//!
//! The rotation head predicts the allocentric rotation: the object's rotation as seen along the
//! ray through the crop's centre, R_allo = R_rayᵀ · R (R_ray turns the optical axis onto that
//! ray, [`ray_rotation`]); the pose's rotation is R_ray · R̂_allo. A crop cut off the image's
//! centre shows the object from a direction the egocentric `cam_R_m2c` alone does not tell
//! (up to ~25° at the Linemod camera's corners), and the crop's look is what the network sees
//! (as CDPN, GDR-Net). Both translation variants use it; the seed regressed egocentric
//! quaternions.

use candle_core::{DType, Device, Module, Result, Tensor, D};
use candle_nn::VarBuilder;
use serde::{Deserialize, Serialize};
use synthgen_core::glam::{DMat3, DQuat, DVec3};

use synthgen_nn::dense::{dense, dense_no_bias, Dense};
use synthgen_nn::im2col::Window;

/// Default side of the square input crop, pixels.
pub const DEFAULT_RGB_CROP: u32 = 64;
/// Output channels of the four stride-2 convolutions.
const CHANNELS: [usize; 4] = [32, 64, 128, 128];
/// Their window: 3×3, stride 2, zero padding 1 (each halves the side, rounding up).
const CONV: Window = Window {
    k: 3,
    stride: 2,
    pad: 1,
};
/// Regression targets are in decimetres (and offsets in tenths of the box side), so they
/// are O(1).
pub const TARGET_SCALE: f64 = 10.0;
/// Outputs per class: 3 for the translation, 4 for the quaternion.
const HEAD_OUT: usize = 7;

/// How the translation is regressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Translation {
    /// The centre's offset inside the box and the (scale-invariant) depth, back-projected
    /// through the intrinsics.
    CentreTz,
    /// (Tx, Ty, Tz) directly.
    Xyz,
}

impl Translation {
    pub fn name(self) -> &'static str {
        match self {
            Translation::CentreTz => "centre-tz",
            Translation::Xyz => "xyz",
        }
    }

    /// The regression target (scaled by [`TARGET_SCALE`]) of translation `t_m` seen in box `b`.
    pub fn target(self, t_m: DVec3, b: &SquareBox, k: &Pinhole) -> [f64; 3] {
        match self {
            Translation::CentreTz => {
                let u = k.fx * t_m.x / t_m.z + k.cx;
                let v = k.fy * t_m.y / t_m.z + k.cy;
                [
                    (u - b.cx) / b.side * TARGET_SCALE,
                    (v - b.cy) / b.side * TARGET_SCALE,
                    t_m.z * b.side / k.f_mean() * TARGET_SCALE,
                ]
            }
            Translation::Xyz => (t_m * TARGET_SCALE).to_array(),
        }
    }

    /// The translation (metres) that the network's output `pred` for box `b` stands for: the
    /// inverse of [`Translation::target`].
    pub fn translation(self, pred: [f64; 3], b: &SquareBox, k: &Pinhole) -> DVec3 {
        match self {
            Translation::CentreTz => {
                let u = b.cx + pred[0] / TARGET_SCALE * b.side;
                let v = b.cy + pred[1] / TARGET_SCALE * b.side;
                let tz = pred[2] / TARGET_SCALE * k.f_mean() / b.side;
                DVec3::new((u - k.cx) * tz / k.fx, (v - k.cy) * tz / k.fy, tz)
            }
            Translation::Xyz => DVec3::from_array(pred) / TARGET_SCALE,
        }
    }
}

/// A square box in the image: centre and side in pixels, in the intrinsics' coordinates
/// (pixel (u, v)'s centre at (u, v)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SquareBox {
    pub cx: f64,
    pub cy: f64,
    pub side: f64,
}

/// A pinhole camera: focal lengths and principal point, pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Pinhole {
    /// From a row-major `cam_K`.
    pub fn from_cam_k(k: &[f64; 9]) -> Pinhole {
        Pinhole {
            fx: k[0],
            fy: k[4],
            cx: k[2],
            cy: k[5],
        }
    }

    fn f_mean(&self) -> f64 {
        0.5 * (self.fx + self.fy)
    }
}

/// Where the box is, as the network sees it: its centre's direction ((bx − px)/fx,
/// (by − py)/fy) and its angular size side/f. Without it a crop says nothing of where in
/// the image it was cut (direct XYZ could not know Tx, Ty); both variants get it.
pub fn box_geometry(b: &SquareBox, k: &Pinhole) -> [f32; 3] {
    [
        ((b.cx - k.cx) / k.fx) as f32,
        ((b.cy - k.cy) / k.fy) as f32,
        (b.side / k.f_mean()) as f32,
    ]
}

/// The rotation turning the optical axis (0, 0, 1) onto the ray through the box's centre, about
/// their common perpendicular (the identity at the principal point).
pub fn ray_rotation(b: &SquareBox, k: &Pinhole) -> DMat3 {
    let ray = DVec3::new((b.cx - k.cx) / k.fx, (b.cy - k.cy) / k.fy, 1.0).normalize();
    DMat3::from_quat(DQuat::from_rotation_arc(DVec3::Z, ray))
}

/// The network.
pub struct RgbNet {
    /// Weights (C_out, 3·3·C_in), columns in (ky, kx, c) order.
    convs: Vec<Dense>,
    fc1: Dense,
    fc1_geom: Dense,
    fc2: Dense,
    head: Dense,
    classes: usize,
}

/// Per crop the translation output (B, 3; see [`Translation::target`]) and a unit
/// quaternion (B, 4), (w, x, y, z).
pub struct RgbOut {
    pub translation: Tensor,
    pub quats: Tensor,
}

/// Side of the feature map after the four stride-2 convolutions (3×3, padding 1).
fn feature_side(crop: u32) -> usize {
    (0..CHANNELS.len()).fold(crop as usize, |s, _| CONV.out(s))
}

impl RgbNet {
    /// `crop`: the input side; `width`: the fully connected layers' width; `classes`: heads.
    pub fn new(crop: u32, width: usize, classes: usize, vb: VarBuilder) -> Result<RgbNet> {
        if classes == 0 {
            candle_core::bail!("the rgb model needs at least one object class");
        }
        let mut convs = Vec::with_capacity(CHANNELS.len());
        let mut c_in = 3;
        for (i, &c) in CHANNELS.iter().enumerate() {
            // Initialized as a dense layer of fan-in 3·3·C_in: candle's conv2d init.
            convs.push(dense(
                CONV.k * CONV.k * c_in,
                c,
                vb.pp(format!("conv{}", i + 1)),
            )?);
            c_in = c;
        }
        let side = feature_side(crop);
        let flat = c_in * side * side;
        Ok(RgbNet {
            convs,
            fc1: dense(flat, width, vb.pp("fc1"))?,
            fc1_geom: dense_no_bias(3, width, vb.pp("fc1_geom"))?,
            fc2: dense(width, width, vb.pp("fc2"))?,
            head: dense(width, classes * HEAD_OUT, vb.pp("head"))?,
            classes,
        })
    }

    /// `crops`: (B, S, S, 3) standardized, NHWC ([`crops_nhwc`]); `geometry`: (B, 3)
    /// ([`box_geometry`]); `class`: (B) u32 class indices (into the model's class list).
    pub fn forward(&self, crops: &Tensor, geometry: &Tensor, class: &Tensor) -> Result<RgbOut> {
        let b = crops.dim(0)?;
        let mut x = crops.clone();
        for c in &self.convs {
            x = c.conv_relu(&x, CONV, None)?;
        }
        let flat = x.flatten_from(1)?.contiguous()?;
        let g = self.fc1_geom.forward(geometry)?; // (B, width)
        let h = self.fc1.forward_relu_grouped(&flat, Some(&g))?;
        let h = self.fc2.forward_relu(&h)?;
        let out = self
            .head
            .forward(&h)?
            .reshape((b, self.classes, HEAD_OUT))?;
        let out = pick_class(&out, class)?;
        let translation = out.narrow(1, 0, 3)?;
        let quats = normalize_quaternions(&out.narrow(1, 3, 4)?)?;
        Ok(RgbOut { translation, quats })
    }
}

/// Each row's head of per-class outputs `out` (B, classes, K): the one `class` (B,) u32
/// names, (B, K).
pub fn pick_class(out: &Tensor, class: &Tensor) -> Result<Tensor> {
    let (b, _, k) = out.dims3()?;
    let idx = class
        .reshape((b, 1, 1))?
        .broadcast_as((b, 1, k))?
        .contiguous()?;
    out.gather(&idx, 1)?.reshape((b, k))
}

/// Crops (`S² × 3` bytes each, RGB row-major) as a (B, S, S, 3) tensor, standardized as
/// RNet's ((v/255 − 0.5) / 0.25).
pub fn crops_nhwc(crops: &[&[u8]], size: u32, device: &Device) -> Result<Tensor> {
    let s = size as usize;
    let mut v = Vec::with_capacity(crops.len() * s * s * 3);
    for crop in crops {
        if crop.len() != s * s * 3 {
            candle_core::bail!("crop has {} bytes, expected {}", crop.len(), s * s * 3);
        }
        v.extend(crop.iter().map(|&x| (f32::from(x) / 255.0 - 0.5) / 0.25));
    }
    Tensor::from_vec(v, (crops.len(), s, s, 3), device)
}

/// The quaternion head's raw outputs (B, 4) as unit quaternions. (1, 0, 0, 0) is added first,
/// so that the untrained head starts near the identity instead of normalizing a vector near
/// zero (whose direction the smallest change turns).
pub fn normalize_quaternions(raw: &Tensor) -> Result<Tensor> {
    let b = raw.dim(0)?;
    let identity = Tensor::from_vec(vec![1f32, 0.0, 0.0, 0.0], (1, 4), raw.device())?
        .to_dtype(raw.dtype())?
        .broadcast_as((b, 4))?;
    let q = (raw + identity)?;
    let norm = (q.sqr()?.sum_keepdim(D::Minus1)? + 1e-12)?.sqrt()?;
    q.broadcast_div(&norm)
}

/// A unit quaternion (w, x, y, z) as a rotation matrix; q and −q give the same one.
pub fn quaternion_rotation(q: [f32; 4]) -> DMat3 {
    let [w, x, y, z] = q.map(f64::from);
    DMat3::from_quat(DQuat::from_xyzw(x, y, z, w).normalize())
}

/// `q` with w ≥ 0: the one of q, −q that predictions report.
pub fn canonical_sign(q: [f32; 4]) -> [f32; 4] {
    if q[0] < 0.0 {
        q.map(|v| -v)
    } else {
        q
    }
}

/// Class indices of object ids in `classes` (sorted ids) as a (B) u32 tensor; `None` for an
/// id the model has no head for.
pub fn class_indices(obj_ids: &[u32], classes: &[u32], device: &Device) -> Result<Tensor> {
    let idx: Vec<u32> = obj_ids
        .iter()
        .map(|id| {
            classes
                .iter()
                .position(|c| c == id)
                .map(|i| i as u32)
                .ok_or_else(|| {
                    candle_core::Error::Msg(format!(
                        "object {id} is not one of the model's classes {classes:?}"
                    ))
                })
        })
        .collect::<Result<_>>()?;
    Tensor::from_vec(idx, obj_ids.len(), device)?.to_dtype(DType::U32)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use candle_nn::VarMap;

    fn camera() -> Pinhole {
        // fx ≠ fy, the principal point off the image centre.
        Pinhole {
            fx: 600.0,
            fy: 480.0,
            cx: 330.5,
            cy: 236.25,
        }
    }

    #[test]
    fn centre_tz_back_projection_inverts_the_intrinsics() {
        let k = camera();
        let b = SquareBox {
            cx: 401.0,
            cy: 190.0,
            side: 96.0,
        };
        for t in [
            DVec3::new(0.11, -0.07, 0.83),
            DVec3::new(-0.25, 0.2, 1.4),
            DVec3::new(0.0, 0.0, 0.4),
        ] {
            for v in [Translation::CentreTz, Translation::Xyz] {
                let back = v.translation(v.target(t, &b, &k), &b, &k);
                assert!((back - t).length() < 1e-12, "{v:?}: {t} -> {back}");
            }
            // The centre target is the projection through fx and fy separately.
            let p = Translation::CentreTz.target(t, &b, &k);
            let u = b.cx + p[0] / TARGET_SCALE * b.side;
            let v = b.cy + p[1] / TARGET_SCALE * b.side;
            assert!((u - (600.0 * t.x / t.z + 330.5)).abs() < 1e-9);
            assert!((v - (480.0 * t.y / t.z + 236.25)).abs() < 1e-9);
        }
        // Tx, Ty from the centre through the intrinsics: a centre at the principal point is
        // on the optical axis whatever Tz; one fx pixels to the right is at Tx = Tz.
        let on_axis = SquareBox {
            cx: k.cx,
            cy: k.cy,
            side: 50.0,
        };
        let t = Translation::CentreTz.translation([0.0, 0.0, 7.0], &on_axis, &k);
        assert!(t.x.abs() < 1e-12 && t.y.abs() < 1e-12);
        assert!((t.z - 0.7 * k.f_mean() / 50.0).abs() < 1e-12);
        let right = SquareBox {
            cx: k.cx + k.fx,
            cy: k.cy - k.fy,
            side: 50.0,
        };
        let t = Translation::CentreTz.translation([0.0, 0.0, 7.0], &right, &k);
        assert!((t.x - t.z).abs() < 1e-12 && (t.y + t.z).abs() < 1e-12);
    }

    #[test]
    fn ray_rotation_points_the_axis_at_the_box() {
        let k = camera();
        let centred = SquareBox {
            cx: k.cx,
            cy: k.cy,
            side: 40.0,
        };
        assert!(ray_rotation(&centred, &k).abs_diff_eq(DMat3::IDENTITY, 1e-12));
        let b = SquareBox {
            cx: 520.0,
            cy: 40.0,
            side: 40.0,
        };
        let r = ray_rotation(&b, &k);
        assert!((r.determinant() - 1.0).abs() < 1e-12);
        // The optical axis turned by it projects onto the box centre, through fx and fy.
        let d = r * DVec3::Z;
        assert!((k.fx * d.x / d.z + k.cx - 520.0).abs() < 1e-9);
        assert!((k.fy * d.y / d.z + k.cy - 40.0).abs() < 1e-9);
        // Allocentric and back.
        let ego = DMat3::from_rotation_y(0.7) * DMat3::from_rotation_x(-0.3);
        let allo = r.transpose() * ego;
        assert!((r * allo).abs_diff_eq(ego, 1e-12));
    }

    #[test]
    fn depth_target_is_scale_invariant() {
        // The same object twice as far spans half the pixels: the same target.
        let k = camera();
        let near = Translation::CentreTz.target(
            DVec3::new(0.0, 0.0, 0.5),
            &SquareBox {
                cx: k.cx,
                cy: k.cy,
                side: 120.0,
            },
            &k,
        );
        let far = Translation::CentreTz.target(
            DVec3::new(0.0, 0.0, 1.0),
            &SquareBox {
                cx: k.cx,
                cy: k.cy,
                side: 60.0,
            },
            &k,
        );
        assert!((near[2] - far[2]).abs() < 1e-12);
    }

    #[test]
    fn quaternion_head_is_unit_and_sign_free() {
        let raw = Tensor::from_vec(
            vec![
                0.3f32, -2.0, 0.5, 1.0, -1.9, 0.2, 0.1, -0.4, -1.0, 0.0, 0.0, 0.0,
            ],
            (3, 4),
            &Device::Cpu,
        )
        .unwrap();
        let q: Vec<Vec<f32>> = normalize_quaternions(&raw).unwrap().to_vec2().unwrap();
        for v in &q[..2] {
            let n: f32 = v.iter().map(|x| x * x).sum::<f32>().sqrt();
            assert!((n - 1.0).abs() < 1e-6, "{v:?}");
        }
        // The third row cancels the identity offset: (0, 0, 0, 0) normalizes to ~0, not NaN.
        assert!(q[2].iter().all(|v| v.is_finite()));
        let a = [q[0][0], q[0][1], q[0][2], q[0][3]];
        let neg = a.map(|v| -v);
        assert_eq!(canonical_sign(neg), canonical_sign(a));
        assert!(canonical_sign(neg)[0] >= 0.0);
        let (ra, rn) = (quaternion_rotation(a), quaternion_rotation(neg));
        assert!(ra.abs_diff_eq(rn, 1e-12));
        assert!((ra.determinant() - 1.0).abs() < 1e-9);
    }

    #[test]
    fn forward_shapes_and_class_heads() {
        let dev = Device::Cpu;
        let vm = VarMap::new();
        let vb = synthgen_nn::init::seeded_var_builder(&vm, 3, &dev);
        let net = RgbNet::new(20, 16, 2, vb).unwrap();
        assert_eq!(feature_side(20), 2);
        let crops = Tensor::randn(0f32, 1.0, (3, 20, 20, 3), &dev).unwrap();
        let geom = Tensor::zeros((3, 3), DType::F32, &dev).unwrap();
        let classes = [5u32, 9];
        let idx = class_indices(&[5, 9, 5], &classes, &dev).unwrap();
        let out = net.forward(&crops, &geom, &idx).unwrap();
        assert_eq!(out.translation.dims(), [3, 3]);
        assert_eq!(out.quats.dims(), [3, 4]);
        // The same crop through the other class's head gives other outputs.
        let one = crops.narrow(0, 0, 1).unwrap();
        let g1 = geom.narrow(0, 0, 1).unwrap();
        let translation_of = |class: u32| -> Vec<f32> {
            net.forward(&one, &g1, &class_indices(&[class], &classes, &dev).unwrap())
                .unwrap()
                .translation
                .flatten_all()
                .unwrap()
                .to_vec1()
                .unwrap()
        };
        assert_ne!(translation_of(5), translation_of(9));
        assert!(class_indices(&[7], &classes, &dev).is_err());
    }
}
