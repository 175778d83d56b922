//! Rigid transforms. A `Pose` named `a_from_b` maps points in frame b to frame a.
//!
//! Rotations read from files are only approximately orthonormal: real BOP annotations store
//! ~6 significant digits of hand-made poses (|det R − 1| up to ~1.4e-2 in LM-O's test GT).
//! Readers accept a rotation whose [`Pose::orthonormality_error`] is within
//! [`rotation_tolerance`] and hand algorithms its [`Pose::orthonormalized`] form.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::{DMat3, DQuat, DVec3};
use serde::{Deserialize, Serialize};

use crate::Error;

/// Default of [`rotation_tolerance`]: covers every instance of the real LM-O, YCB-V and
/// T-LESS test annotations, as bop_toolkit (which checks nothing) reads them all.
pub const DEFAULT_ROTATION_TOLERANCE: f64 = 2e-2;

/// Rotations whose orthonormality error is above this are not exact to the precision of a
/// stored double; `validate` reports them as approximate (a warning, not an error).
pub const EXACT_ROTATION_TOLERANCE: f64 = 1e-5;

// f64 bits of the tolerance; UNSET (a NaN pattern, never stored) means the default.
const UNSET: u64 = u64::MAX;
static ROTATION_TOLERANCE_BITS: AtomicU64 = AtomicU64::new(UNSET);

/// The largest orthonormality error a reader accepts in a rotation read from a file (one
/// setting per process, like the CLI's `--rotation-tolerance`: every reader applies the same
/// rule, so a dataset that `validate` accepts is one every other command reads).
pub fn rotation_tolerance() -> f64 {
    match ROTATION_TOLERANCE_BITS.load(Ordering::Relaxed) {
        UNSET => DEFAULT_ROTATION_TOLERANCE,
        bits => f64::from_bits(bits),
    }
}

/// Sets [`rotation_tolerance`] for this process. Negative or non-finite values are refused.
pub fn set_rotation_tolerance(tol: f64) -> Result<(), Error> {
    if !(tol.is_finite() && tol >= 0.0) {
        return Err(Error::InvalidPose(format!(
            "rotation tolerance must be a finite number >= 0, got {tol}"
        )));
    }
    ROTATION_TOLERANCE_BITS.store(tol.to_bits(), Ordering::Relaxed);
    Ok(())
}

/// The nearest proper rotation to `m` in the Frobenius norm (the polar factor U Vᵀ of its
/// SVD), by Higham's iteration X ← (X + X⁻ᵀ) / 2, which converges quadratically from a
/// near-orthonormal start. `None` when `m` is singular, has det ≤ 0 or is not finite.
pub fn nearest_rotation(m: &DMat3) -> Option<DMat3> {
    let det = m.determinant();
    if !det.is_finite() || det <= 1e-12 {
        return None;
    }
    let mut x = *m;
    for _ in 0..64 {
        let inv_t = x.inverse().transpose();
        let next = (x + inv_t) * 0.5;
        let step = (next - x)
            .to_cols_array()
            .iter()
            .fold(0.0f64, |a, v| a.max(v.abs()));
        x = next;
        if step < 1e-15 {
            break;
        }
    }
    x.to_cols_array().iter().all(|v| v.is_finite()).then_some(x)
}

/// A rigid transform `p_a = rotation * p_b + translation_m` (metres).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub rotation: DMat3,
    pub translation_m: DVec3,
}

impl Default for Pose {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Pose {
    pub const IDENTITY: Pose = Pose {
        rotation: DMat3::IDENTITY,
        translation_m: DVec3::ZERO,
    };

    pub fn new(rotation: DMat3, translation_m: DVec3) -> Self {
        Self {
            rotation,
            translation_m,
        }
    }

    /// Builds a pose from a row-major 3x3 rotation and a translation in millimetres, as BOP and
    /// Linemod files store them (`cam_R_m2c`, `cam_t_m2c`).
    pub fn from_bop(r_row_major: &[f64; 9], t_mm: &[f64; 3]) -> Self {
        let r = r_row_major;
        let rotation = DMat3::from_cols(
            DVec3::new(r[0], r[3], r[6]),
            DVec3::new(r[1], r[4], r[7]),
            DVec3::new(r[2], r[5], r[8]),
        );
        Self::new(rotation, DVec3::from_array(*t_mm) / 1000.0)
    }

    /// Row-major rotation (9 values), as BOP's `cam_R_m2c`.
    pub fn rotation_row_major(&self) -> [f64; 9] {
        // The transpose's column-major storage is the original's row-major order.
        self.rotation.transpose().to_cols_array()
    }

    /// Translation in millimetres, as BOP's `cam_t_m2c`.
    pub fn translation_mm(&self) -> [f64; 3] {
        (self.translation_m * 1000.0).to_array()
    }

    pub fn transform_point(&self, p: DVec3) -> DVec3 {
        self.rotation * p + self.translation_m
    }

    pub fn transform_vector(&self, v: DVec3) -> DVec3 {
        self.rotation * v
    }

    /// `self * other`: if self is `a_from_b` and other is `b_from_c`, the result is `a_from_c`.
    pub fn compose(&self, other: &Pose) -> Pose {
        Pose {
            rotation: self.rotation * other.rotation,
            translation_m: self.rotation * other.translation_m + self.translation_m,
        }
    }

    /// The inverse transform (`b_from_a` for `a_from_b`). Assumes an orthonormal rotation.
    pub fn inverse(&self) -> Pose {
        let rt = self.rotation.transpose();
        Pose {
            rotation: rt,
            translation_m: -(rt * self.translation_m),
        }
    }

    /// Unit quaternion of the rotation, stored as (w, x, y, z).
    pub fn quaternion_wxyz(&self) -> [f64; 4] {
        let q = DQuat::from_mat3(&self.rotation).normalize();
        [q.w, q.x, q.y, q.z]
    }

    /// How far the rotation is from a proper rotation: max(|det R − 1|, max |R Rᵀ − I|).
    /// NaN when a value is not finite.
    pub fn orthonormality_error(&self) -> f64 {
        let det = self.rotation.determinant();
        let rrt = self.rotation * self.rotation.transpose();
        let dev = (rrt - DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        if det.is_finite() && dev.is_finite() {
            (det - 1.0).abs().max(dev)
        } else {
            f64::NAN
        }
    }

    /// The same pose with its rotation replaced by the nearest proper rotation
    /// ([`nearest_rotation`]); unchanged when there is none (det ≤ 0), which `validate`
    /// rejects anyway.
    pub fn orthonormalized(&self) -> Pose {
        match nearest_rotation(&self.rotation) {
            Some(rotation) => Pose::new(rotation, self.translation_m),
            None => *self,
        }
    }

    /// Checks that the rotation is orthonormal with determinant +1 within `tol` and that all
    /// values are finite; a determinant ≤ 0 (a reflection or a degenerate matrix) is an error
    /// at any tolerance.
    pub fn validate(&self, tol: f64) -> Result<(), Error> {
        let vals = self
            .rotation
            .to_cols_array()
            .into_iter()
            .chain(self.translation_m.to_array());
        if vals.into_iter().any(|v| !v.is_finite()) {
            return Err(Error::InvalidPose("non-finite value".into()));
        }
        let det = self.rotation.determinant();
        if det <= 0.0 {
            return Err(Error::InvalidPose(format!(
                "rotation determinant {det:.6} <= 0 (a reflection or a degenerate matrix)"
            )));
        }
        if (det - 1.0).abs() > tol {
            return Err(Error::InvalidPose(format!(
                "rotation determinant {det:.6} != 1 (tolerance {tol})"
            )));
        }
        let rrt = self.rotation * self.rotation.transpose();
        let dev = (rrt - DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        if dev > tol {
            return Err(Error::InvalidPose(format!(
                "rotation not orthonormal (max |R Rᵀ - I| = {dev:.2e}, tolerance {tol})"
            )));
        }
        Ok(())
    }

    /// Camera pose looking from `eye` at `target` in a world with `up`, in the OpenCV camera
    /// convention (x right, y down, z forward). Returns `world_from_cam`.
    pub fn world_from_cam_look_at(eye: DVec3, target: DVec3, up: DVec3) -> Pose {
        let forward = (target - eye).normalize();
        let mut right = forward.cross(up);
        if right.length_squared() < 1e-12 {
            // Looking straight along `up`: any perpendicular works.
            right = forward.any_orthonormal_vector();
        }
        let right = right.normalize();
        let down = forward.cross(right);
        Pose::new(DMat3::from_cols(right, down, forward), eye)
    }
}

/// Geodesic angle between two rotations in radians: arccos((tr(Ra Rbᵀ) - 1) / 2).
pub fn rotation_angle_rad(a: &DMat3, b: &DMat3) -> f64 {
    let m = *a * b.transpose();
    let tr = m.x_axis.x + m.y_axis.y + m.z_axis.z;
    ((tr - 1.0) / 2.0).clamp(-1.0, 1.0).acos()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn arb_pose() -> impl Strategy<Value = Pose> {
        (
            -1.0f64..1.0,
            -1.0f64..1.0,
            -1.0f64..1.0,
            0.0f64..std::f64::consts::PI,
            prop::array::uniform3(-2.0f64..2.0),
        )
            .prop_filter_map("axis non-zero", |(x, y, z, a, t)| {
                let axis = DVec3::new(x, y, z);
                (axis.length() > 1e-3).then(|| {
                    Pose::new(
                        DMat3::from_axis_angle(axis.normalize(), a),
                        DVec3::from_array(t),
                    )
                })
            })
    }

    proptest! {
        #[test]
        fn compose_with_inverse_is_identity(p in arb_pose(), q in prop::array::uniform3(-1.0f64..1.0)) {
            let q = DVec3::from_array(q);
            let back = p.inverse().compose(&p).transform_point(q);
            prop_assert!((back - q).length() < 1e-9);
        }

        #[test]
        fn compose_is_associative_on_points(a in arb_pose(), b in arb_pose(), q in prop::array::uniform3(-1.0f64..1.0)) {
            let q = DVec3::from_array(q);
            let lhs = a.compose(&b).transform_point(q);
            let rhs = a.transform_point(b.transform_point(q));
            prop_assert!((lhs - rhs).length() < 1e-9);
        }

        #[test]
        fn bop_round_trip(p in arb_pose()) {
            let r = p.rotation_row_major();
            let t = p.translation_mm();
            let back = Pose::from_bop(&r, &t);
            prop_assert!(rotation_angle_rad(&back.rotation, &p.rotation) < 1e-6);
            prop_assert!((back.translation_m - p.translation_m).length() < 1e-12);
            prop_assert!(back.validate(1e-6).is_ok());
        }
    }

    #[test]
    fn row_major_layout_matches_bop() {
        // 90° about z: x -> y. Row-major [[0,-1,0],[1,0,0],[0,0,1]].
        let p = Pose::new(
            DMat3::from_rotation_z(std::f64::consts::FRAC_PI_2),
            DVec3::ZERO,
        );
        let r = p.rotation_row_major();
        let want = [0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0];
        for (a, b) in r.iter().zip(want) {
            assert!((a - b).abs() < 1e-12, "{r:?}");
        }
    }

    #[test]
    fn look_at_is_opencv() {
        // Camera above the origin looking down (-z world), world y as "up" hint.
        let w = Pose::world_from_cam_look_at(DVec3::new(0.0, 0.0, 1.0), DVec3::ZERO, DVec3::Y);
        // The optical axis (camera +z) points down in the world.
        assert!((w.transform_vector(DVec3::Z) - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
        // The target lies on the optical axis at depth 1.
        let t_cam = w.inverse().transform_point(DVec3::ZERO);
        assert!((t_cam - DVec3::new(0.0, 0.0, 1.0)).length() < 1e-12);
        assert!(w.validate(1e-9).is_ok());
        // Image "down" (camera +y) must point away from the up hint.
        assert!(w.transform_vector(DVec3::Y).dot(DVec3::Y) < 0.0);
    }

    /// A rotation rounded to 6 digits and scaled so that det R = 1.0144, as the worst real
    /// LM-O annotation: accepted at the default tolerance, its nearest rotation is proper and
    /// within 1e-2 of it, and a reflection is refused at any tolerance.
    #[test]
    fn real_world_rotations_are_accepted_and_projected() {
        let r = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 1.2);
        let scaled = DMat3::from_cols_array(
            &(r * 1.0144f64.cbrt())
                .to_cols_array()
                .map(|v| (v * 1e6).round() / 1e6),
        );
        let p = Pose::new(scaled, DVec3::new(0.1, 0.0, 0.5));
        assert!(p.validate(1e-3).is_err());
        assert!(p.validate(DEFAULT_ROTATION_TOLERANCE).is_ok());
        let e = p.orthonormality_error();
        assert!(e > 1e-2 && e < 2e-2, "{e}");
        let q = p.orthonormalized();
        assert!(q.orthonormality_error() < 1e-14);
        assert!(rotation_angle_rad(&q.rotation, &r) < 1e-5);
        assert_eq!(q.translation_m, p.translation_m);
        let mirror = Pose::new(
            DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0)),
            DVec3::ZERO,
        );
        assert!(mirror.validate(10.0).is_err());
        assert!(nearest_rotation(&mirror.rotation).is_none());
    }

    proptest! {
        /// The polar factor of a perturbed rotation is the nearest rotation: no other rotation
        /// near it (a few small turns) is closer in the Frobenius norm.
        #[test]
        fn nearest_rotation_is_nearest(p in arb_pose(), noise in prop::array::uniform9(-0.01f64..0.01)) {
            let m = DMat3::from_cols_array(&noise) + p.rotation;
            let r = nearest_rotation(&m).unwrap();
            let dist = |a: DMat3| (a - m).to_cols_array().iter().map(|v| v * v).sum::<f64>();
            let best = dist(r);
            for axis in [DVec3::X, DVec3::Y, DVec3::Z, DVec3::ONE.normalize()] {
                for angle in [-1e-3, 1e-3] {
                    prop_assert!(dist(r * DMat3::from_axis_angle(axis, angle)) >= best - 1e-15);
                }
            }
            prop_assert!((r.determinant() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn the_tolerance_is_settable() {
        assert!(set_rotation_tolerance(-1.0).is_err());
        assert!(set_rotation_tolerance(f64::NAN).is_err());
    }

    #[test]
    fn validate_rejects_nan_and_scaled() {
        let mut p = Pose::IDENTITY;
        p.translation_m.x = f64::NAN;
        assert!(p.validate(1e-6).is_err());
        let s = Pose::new(DMat3::from_diagonal(DVec3::splat(1.1)), DVec3::ZERO);
        assert!(s.validate(1e-6).is_err());
    }
}
