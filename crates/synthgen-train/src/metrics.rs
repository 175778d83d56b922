//! Pose error metrics as bop_toolkit (`pose_error.py`) and DenseFusion define them. All
//! inputs and outputs are in metres and radians; BOP files' millimetres are converted by the
//! readers before anything reaches this module. See docs/metrics.md.

use serde::{Deserialize, Serialize};

use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::mesh::Model;
use synthgen_core::Pose;

/// An estimate is correct under ADD(-S) when its error is below this fraction of the
/// object's diameter.
pub const ADD_THRESHOLD_FRACTION: f64 = 0.1;
/// 5cm5°: translation error below 5 cm ...
pub const TE_THRESHOLD_M: f64 = 0.05;
/// ... and rotation error below 5°.
pub const RE_THRESHOLD_DEG: f64 = 5.0;

/// ADD: mean over the model points of ‖(R p + t) − (R̂ p + t̂)‖ (metres).
pub fn add(points_m: &[DVec3], gt: &Pose, est: &Pose) -> f64 {
    if points_m.is_empty() {
        return 0.0;
    }
    let sum: f64 = points_m
        .iter()
        .map(|&p| (gt.transform_point(p) - est.transform_point(p)).length())
        .sum();
    sum / points_m.len() as f64
}

/// ADD-S (bop_toolkit's ADI): mean over the GT-posed points of the distance to the nearest
/// estimate-posed point (metres). O(M²): keep M in the low thousands.
pub fn adi(points_m: &[DVec3], gt: &Pose, est: &Pose) -> f64 {
    if points_m.is_empty() {
        return 0.0;
    }
    let tree = KdTree::new(points_m.iter().map(|&p| est.transform_point(p)).collect());
    let sum: f64 = points_m
        .iter()
        .map(|&p| tree.nearest_sq(gt.transform_point(p)).sqrt())
        .sum();
    sum / points_m.len() as f64
}

/// A k-d tree over points for exact nearest-neighbour distances (ADI): the distances it
/// returns are the brute-force minimum, bit for bit.
struct KdTree {
    /// Points reordered so each subtree is a contiguous range whose middle is its split.
    pts: Vec<DVec3>,
    /// Split axis of the node at each middle index.
    axis: Vec<u8>,
}

/// Ranges at most this long are searched by brute force.
const KD_LEAF: usize = 8;

impl KdTree {
    fn new(mut pts: Vec<DVec3>) -> KdTree {
        let mut axis = vec![0u8; pts.len()];
        let n = pts.len();
        Self::build(&mut pts, &mut axis, 0, n);
        KdTree { pts, axis }
    }

    fn build(pts: &mut [DVec3], axis: &mut [u8], lo: usize, hi: usize) {
        if hi - lo <= KD_LEAF {
            return;
        }
        let (mut min, mut max) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for p in &pts[lo..hi] {
            min = min.min(*p);
            max = max.max(*p);
        }
        let ext = max - min;
        let a = if ext.x >= ext.y && ext.x >= ext.z {
            0
        } else if ext.y >= ext.z {
            1
        } else {
            2
        };
        let mid = (lo + hi) / 2;
        pts[lo..hi].select_nth_unstable_by(mid - lo, |p, q| p[a].total_cmp(&q[a]));
        axis[mid] = a as u8;
        Self::build(pts, axis, lo, mid);
        Self::build(pts, axis, mid + 1, hi);
    }

    #[inline(always)]
    fn dist_sq(q: DVec3, p: DVec3) -> f64 {
        let (dx, dy, dz) = (q.x - p.x, q.y - p.y, q.z - p.z);
        dx * dx + dy * dy + dz * dz
    }

    /// The smallest squared distance from `q` to a point of the tree.
    fn nearest_sq(&self, q: DVec3) -> f64 {
        let mut best = f64::INFINITY;
        self.search(q, 0, self.pts.len(), &mut best);
        best
    }

    fn search(&self, q: DVec3, lo: usize, hi: usize, best: &mut f64) {
        if hi - lo <= KD_LEAF {
            for &p in &self.pts[lo..hi] {
                let d = Self::dist_sq(q, p);
                if d < *best {
                    *best = d;
                }
            }
            return;
        }
        let mid = (lo + hi) / 2;
        let p = self.pts[mid];
        let d = Self::dist_sq(q, p);
        if d < *best {
            *best = d;
        }
        let a = self.axis[mid] as usize;
        let diff = q[a] - p[a];
        let (near, far) = if diff < 0.0 {
            ((lo, mid), (mid + 1, hi))
        } else {
            ((mid + 1, hi), (lo, mid))
        };
        self.search(q, near.0, near.1, best);
        if diff * diff <= *best {
            self.search(q, far.0, far.1, best);
        }
    }
}

/// Translation error ‖t − t̂‖ (metres).
pub fn te_m(gt: &Pose, est: &Pose) -> f64 {
    (gt.translation_m - est.translation_m).length()
}

/// Rotation error arccos((tr(R̂ R⁻¹) − 1) / 2) in degrees (0..180), as bop_toolkit's `re`: the
/// inverse, not the transpose, since rotations read from files are only nearly orthonormal
/// (for a proper rotation the two are the same).
pub fn re_deg(gt: &DMat3, est: &DMat3) -> f64 {
    let m = *est * gt.inverse();
    let tr = m.x_axis.x + m.y_axis.y + m.z_axis.z;
    ((tr - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees()
}

/// 5cm5°: translation error < 5 cm and rotation error < 5°.
pub fn is_5cm5deg(gt: &Pose, est: &Pose) -> bool {
    te_m(gt, est) < TE_THRESHOLD_M && re_deg(&gt.rotation, &est.rotation) < RE_THRESHOLD_DEG
}

/// Which rotation matrices ADD(-S), the rotation error and 5cm5° are computed on.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Rotations {
    /// The matrices as the files store them, GT and estimates: what bop_toolkit's
    /// `pose_error` (and PoseCNN's and DenseFusion's evaluations) score, so published numbers
    /// are comparable.
    #[default]
    AsStored,
    /// The nearest proper rotation of each (real annotations are hand-made and stored with ~6
    /// digits: |det R − 1| up to ~1e-2).
    Nearest,
}

/// The errors of one estimate against its GT.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseErrors {
    pub add_m: f64,
    /// ADD-S (ADI).
    pub adi_m: f64,
    /// The error that decides correctness: ADD-S for symmetric objects, ADD otherwise.
    pub add_s_m: f64,
    pub te_m: f64,
    pub re_deg: f64,
}

/// An object's evaluation model: subsampled points (metres), diameter, symmetric or not.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalObject {
    pub points_m: Vec<DVec3>,
    pub diameter_m: f64,
    /// Objects with symmetries in models_info are scored with ADD-S.
    pub symmetric: bool,
}

impl EvalObject {
    pub fn errors(&self, gt: &Pose, est: &Pose) -> PoseErrors {
        let mut e = self.scoring_errors(gt, est);
        if !self.symmetric {
            // ADI ≤ ADD always; computing it for asymmetric objects is only for reporting.
            e.adi_m = adi(&self.points_m, gt, est).min(e.add_m);
        }
        e
    }

    /// What scoring reads (ADD(-S), te, re), as [`errors`](Self::errors) gives it, without
    /// the ADI of an asymmetric object (only reported by `errors`): its `adi_m` is NaN here.
    pub fn scoring_errors(&self, gt: &Pose, est: &Pose) -> PoseErrors {
        let add_m = add(&self.points_m, gt, est);
        let adi_m = if self.symmetric {
            adi(&self.points_m, gt, est)
        } else {
            f64::NAN
        };
        PoseErrors {
            add_m,
            adi_m,
            add_s_m: if self.symmetric { adi_m } else { add_m },
            te_m: te_m(gt, est),
            re_deg: re_deg(&gt.rotation, &est.rotation),
        }
    }

    pub fn add_s_correct(&self, e: &PoseErrors) -> bool {
        e.add_s_m < ADD_THRESHOLD_FRACTION * self.diameter_m
    }
}

impl PoseErrors {
    /// 5cm5° from these errors (what [`is_5cm5deg`] decides from the poses).
    pub fn within_5cm5deg(&self) -> bool {
        self.te_m < TE_THRESHOLD_M && self.re_deg < RE_THRESHOLD_DEG
    }
}

/// Up to `max` of the model's vertices, evenly strided over the vertex list (deterministic:
/// the same model always gives the same points).
pub fn subsample_vertices(model: &Model, max: usize) -> Vec<DVec3> {
    let all: Vec<DVec3> = model.positions().map(|p| p.as_dvec3()).collect();
    if all.len() <= max || max == 0 {
        return all;
    }
    (0..max).map(|i| all[i * all.len() / max]).collect()
}

/// One line of `metrics.jsonl`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpochMetrics {
    pub epoch: usize,
    pub train_loss: f64,
    pub val_loss: f64,
    /// Mean ‖centre − ĉ‖ over the validation instances, metres (TNet, Full).
    #[serde(default)]
    pub val_centre_error_m: Option<f64>,
    /// Fraction of validation instances with ADD(-S) below 10% of the diameter (RNet, Full;
    /// RNet's poses use the GT translation).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub val_add_s_acc: Option<f64>,
    /// Mean rotation error over the validation instances, degrees (RNet, Full, RGB).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub val_mean_re_deg: Option<f64>,
    /// Fraction of validation instances within 5 cm and 5° (RGB).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub val_acc_5cm5deg: Option<f64>,
    /// Learning rate at the epoch's last step.
    pub lr: f64,
    pub seconds: f64,
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn adi_equals_brute_force_bit_for_bit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let pts: Vec<DVec3> = (0..777)
            .map(|_| {
                DVec3::new(
                    rng.gen_range(-0.1..0.1),
                    rng.gen_range(-0.05..0.05),
                    rng.gen_range(-0.02..0.02),
                )
            })
            .collect();
        let gt = Pose::new(DMat3::from_rotation_z(0.3), DVec3::new(0.01, 0.0, 0.8));
        let est = Pose::new(DMat3::from_rotation_x(0.2), DVec3::new(0.0, 0.02, 0.81));
        let brute: f64 = pts
            .iter()
            .map(|&p| {
                let g = gt.transform_point(p);
                pts.iter()
                    .map(|&q| {
                        let e = est.transform_point(q);
                        let (dx, dy, dz) = (g.x - e.x, g.y - e.y, g.z - e.z);
                        dx * dx + dy * dy + dz * dz
                    })
                    .fold(f64::INFINITY, f64::min)
                    .sqrt()
            })
            .sum::<f64>()
            / pts.len() as f64;
        assert_eq!(adi(&pts, &gt, &est).to_bits(), brute.to_bits());
    }
    use std::f64::consts::PI;

    /// A thin rod along z: 21 points from −5 cm to 5 cm, symmetric under 180° about x.
    fn rod() -> Vec<DVec3> {
        (0..=20)
            .map(|i| DVec3::new(0.0, 0.0, -0.05 + 0.005 * i as f64))
            .collect()
    }

    /// An asymmetric "L": points along x and along y of different lengths.
    fn ell() -> Vec<DVec3> {
        let mut p: Vec<DVec3> = (0..10)
            .map(|i| DVec3::new(0.01 * i as f64, 0.0, 0.0))
            .collect();
        p.extend((1..5).map(|i| DVec3::new(0.0, 0.01 * i as f64, 0.0)));
        p
    }

    fn pose(r: DMat3, t: [f64; 3]) -> Pose {
        Pose::new(r, DVec3::from_array(t))
    }

    #[test]
    fn identity_estimate_has_zero_errors() {
        let gt = pose(DMat3::from_rotation_y(0.3), [0.1, -0.2, 0.8]);
        let obj = EvalObject {
            points_m: ell(),
            diameter_m: 0.1,
            symmetric: false,
        };
        let e = obj.errors(&gt, &gt);
        assert_eq!(e.add_m, 0.0);
        assert_eq!(e.adi_m, 0.0);
        assert_eq!(e.te_m, 0.0);
        assert!(e.re_deg < 1e-6, "{}", e.re_deg);
        assert!(obj.add_s_correct(&e));
        assert!(is_5cm5deg(&gt, &gt));
    }

    #[test]
    fn pure_translation_offset_is_the_add() {
        let gt = pose(DMat3::IDENTITY, [0.0, 0.0, 1.0]);
        let est = pose(DMat3::IDENTITY, [0.03, 0.04, 1.0]);
        // Every point moves by (3, 4, 0) cm: ADD = 5 cm exactly, re = 0.
        assert!((add(&ell(), &gt, &est) - 0.05).abs() < 1e-12);
        assert!((te_m(&gt, &est) - 0.05).abs() < 1e-12);
        assert!(re_deg(&gt.rotation, &est.rotation) < 1e-9);
    }

    #[test]
    fn rotation_about_origin_hand_computed() {
        // 90° about z moves (x, 0, 0) to (0, x, 0): distance x·√2.
        let pts = vec![DVec3::new(0.1, 0.0, 0.0), DVec3::new(0.2, 0.0, 0.0)];
        let gt = Pose::IDENTITY;
        let est = pose(DMat3::from_rotation_z(PI / 2.0), [0.0; 3]);
        let want = (0.1 + 0.2) / 2.0 * 2f64.sqrt();
        assert!((add(&pts, &gt, &est) - want).abs() < 1e-12);
        assert!((re_deg(&gt.rotation, &est.rotation) - 90.0).abs() < 1e-9);
    }

    #[test]
    fn symmetric_object_rotated_by_its_symmetry() {
        // The rod turned 180° about x is the same set of points: ADD-S 0, ADD large.
        let gt = pose(DMat3::IDENTITY, [0.0, 0.0, 0.7]);
        let est = pose(DMat3::from_rotation_x(PI), [0.0, 0.0, 0.7]);
        let obj = EvalObject {
            points_m: rod(),
            diameter_m: 0.1,
            symmetric: true,
        };
        let e = obj.errors(&gt, &est);
        assert!(e.adi_m < 1e-12, "{}", e.adi_m);
        assert!(e.add_m > 0.02, "{}", e.add_m);
        assert_eq!(e.add_s_m, e.adi_m);
        assert!(obj.add_s_correct(&e));
        // The same estimate for an object scored with ADD is wrong.
        let asym = EvalObject {
            symmetric: false,
            ..obj
        };
        assert!(!asym.add_s_correct(&asym.errors(&gt, &est)));
        assert!((e.re_deg - 180.0).abs() < 1e-6);
    }

    #[test]
    fn five_cm_threshold_is_five_cm_in_metres() {
        let gt = Pose::IDENTITY;
        let just_in = pose(DMat3::IDENTITY, [0.0499, 0.0, 0.0]);
        let just_out = pose(DMat3::IDENTITY, [0.0501, 0.0, 0.0]);
        assert!(is_5cm5deg(&gt, &just_in));
        assert!(!is_5cm5deg(&gt, &just_out));
        let rot_in = pose(DMat3::from_rotation_y(4.9f64.to_radians()), [0.0; 3]);
        let rot_out = pose(DMat3::from_rotation_y(5.1f64.to_radians()), [0.0; 3]);
        assert!(is_5cm5deg(&gt, &rot_in));
        assert!(!is_5cm5deg(&gt, &rot_out));
    }

    #[test]
    fn add_threshold_is_ten_percent_of_diameter() {
        let obj = EvalObject {
            points_m: ell(),
            diameter_m: 0.2,
            symmetric: false,
        };
        let gt = Pose::IDENTITY;
        let e_in = obj.errors(&gt, &pose(DMat3::IDENTITY, [0.0199, 0.0, 0.0]));
        let e_out = obj.errors(&gt, &pose(DMat3::IDENTITY, [0.0201, 0.0, 0.0]));
        assert!(obj.add_s_correct(&e_in));
        assert!(!obj.add_s_correct(&e_out));
    }

    #[test]
    fn adi_never_exceeds_add() {
        let gt = pose(DMat3::from_rotation_x(0.4), [0.0, 0.1, 0.6]);
        let est = pose(DMat3::from_rotation_z(1.1), [0.02, 0.1, 0.65]);
        assert!(adi(&ell(), &gt, &est) <= add(&ell(), &gt, &est) + 1e-12);
    }

    #[test]
    fn subsample_is_deterministic_and_bounded() {
        let m = Model::cuboid("box", synthgen_core::glam::Vec3::new(0.1, 0.2, 0.3));
        let a = subsample_vertices(&m, 3);
        assert_eq!(a.len(), 3.min(m.vertex_count()));
        assert_eq!(a, subsample_vertices(&m, 3));
        assert_eq!(subsample_vertices(&m, 10_000).len(), m.vertex_count());
    }
}
