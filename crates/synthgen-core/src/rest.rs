//! How an upright object stands: which model axis points up (`[[objects]] up`) and how far it
//! may tilt away from that rest pose (`tilt_deg`).

use glam::{DMat3, DVec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

/// The model axis that points up, away from the table, when an object stands.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
pub enum UpAxis {
    #[serde(rename = "+x")]
    PlusX,
    #[serde(rename = "-x")]
    MinusX,
    #[serde(rename = "+y")]
    PlusY,
    #[serde(rename = "-y")]
    MinusY,
    /// As scanned (default).
    #[default]
    #[serde(rename = "+z")]
    PlusZ,
    #[serde(rename = "-z")]
    MinusZ,
    /// Unknown: each instance stands on one of the six axes, drawn uniformly (for objects
    /// whose rest pose no real frame showed; every face it might lie on is covered).
    #[serde(rename = "any")]
    Any,
    /// Unknown: each instance rests on a stable face of the model's convex hull, drawn with
    /// the probability that a random drop ends there (`SceneObject::rest_poses`, computed
    /// from the mesh by synthgen-physics). Without rest poses, as `any`.
    #[serde(rename = "stable")]
    Stable,
}

impl UpAxis {
    pub const ALL: [UpAxis; 6] = [
        UpAxis::PlusX,
        UpAxis::MinusX,
        UpAxis::PlusY,
        UpAxis::MinusY,
        UpAxis::PlusZ,
        UpAxis::MinusZ,
    ];

    /// The axis as a unit vector of the model frame (`any`: +z, as scanned; instances draw
    /// their own axis with [`UpAxis::resolve`]).
    pub fn model_axis(self) -> DVec3 {
        match self {
            UpAxis::PlusX => DVec3::X,
            UpAxis::MinusX => DVec3::NEG_X,
            UpAxis::PlusY => DVec3::Y,
            UpAxis::MinusY => DVec3::NEG_Y,
            UpAxis::PlusZ | UpAxis::Any | UpAxis::Stable => DVec3::Z,
            UpAxis::MinusZ => DVec3::NEG_Z,
        }
    }

    /// A concrete axis: itself, or for `any` (and `stable` without rest poses) one of the six
    /// drawn from `rng`.
    pub fn resolve(self, rng: &mut ChaCha8Rng) -> UpAxis {
        match self {
            UpAxis::Any | UpAxis::Stable => UpAxis::ALL[rng.gen_range(0..UpAxis::ALL.len())],
            up => up,
        }
    }

    /// The axis closest to a direction given in the model frame (largest |component|, its
    /// sign), and the angle between them in radians.
    pub fn nearest(dir_in_model: DVec3) -> (UpAxis, f64) {
        let d = dir_in_model.normalize_or_zero();
        let a = d.abs();
        let (axis, c) = if a.x >= a.y && a.x >= a.z {
            (
                if d.x >= 0.0 {
                    UpAxis::PlusX
                } else {
                    UpAxis::MinusX
                },
                a.x,
            )
        } else if a.y >= a.z {
            (
                if d.y >= 0.0 {
                    UpAxis::PlusY
                } else {
                    UpAxis::MinusY
                },
                a.y,
            )
        } else {
            (
                if d.z >= 0.0 {
                    UpAxis::PlusZ
                } else {
                    UpAxis::MinusZ
                },
                a.z,
            )
        };
        (axis, c.clamp(-1.0, 1.0).acos())
    }

    /// `world_from_rest`: the rotation that maps this model axis onto world +z (a quarter or
    /// half turn about a model axis; the yaw about +z is drawn afterwards anyway).
    pub fn rest_rotation(self) -> DMat3 {
        use std::f64::consts::{FRAC_PI_2, PI};
        match self {
            UpAxis::PlusX => DMat3::from_rotation_y(-FRAC_PI_2),
            UpAxis::MinusX => DMat3::from_rotation_y(FRAC_PI_2),
            UpAxis::PlusY => DMat3::from_rotation_x(FRAC_PI_2),
            UpAxis::MinusY => DMat3::from_rotation_x(-FRAC_PI_2),
            UpAxis::PlusZ | UpAxis::Any | UpAxis::Stable => DMat3::IDENTITY,
            UpAxis::MinusZ => DMat3::from_rotation_x(PI),
        }
    }

    /// `"+x"`, `"-y"`, ... as written in a scene spec.
    pub fn as_str(self) -> &'static str {
        match self {
            UpAxis::PlusX => "+x",
            UpAxis::MinusX => "-x",
            UpAxis::PlusY => "+y",
            UpAxis::MinusY => "-y",
            UpAxis::PlusZ => "+z",
            UpAxis::MinusZ => "-z",
            UpAxis::Any => "any",
            UpAxis::Stable => "stable",
        }
    }
}

impl std::fmt::Display for UpAxis {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The orientation of an upright object with a yaw `yaw_rad` already drawn: Rz(yaw) · T · R_rest,
/// where T tilts by a uniform angle in 0..=`tilt_deg` about a uniformly random horizontal axis.
/// `any` first draws the axis. Draws from `rng` only for `any` and when there is a tilt, and
/// returns Rz(yaw) itself for `+z` without tilt, so specs without these fields sample exactly
/// as before.
pub fn upright_rotation(yaw_rad: f64, up: UpAxis, tilt_deg: f64, rng: &mut ChaCha8Rng) -> DMat3 {
    let up = up.resolve(rng);
    let yaw = DMat3::from_rotation_z(yaw_rad);
    let tilt = if tilt_deg > 0.0 {
        let angle = rng.gen_range(0.0..=tilt_deg).to_radians();
        let dir = rng.gen_range(0.0..std::f64::consts::TAU);
        Some(DMat3::from_axis_angle(
            DVec3::new(dir.cos(), dir.sin(), 0.0),
            angle,
        ))
    } else {
        None
    };
    match (up, tilt) {
        (UpAxis::PlusZ, None) => yaw,
        (_, None) => yaw * up.rest_rotation(),
        (_, Some(t)) => yaw * t * up.rest_rotation(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn rest_rotation_maps_the_axis_to_world_up() {
        for up in UpAxis::ALL {
            let r = up.rest_rotation();
            assert!((r * up.model_axis() - DVec3::Z).length() < 1e-12, "{up}");
            assert!((r.determinant() - 1.0).abs() < 1e-12);
            assert_eq!(UpAxis::nearest(up.model_axis()), (up, 0.0));
        }
    }

    #[test]
    fn nearest_axis_and_its_angle() {
        let (a, t) = UpAxis::nearest(DVec3::new(-0.9, 0.1, 0.3));
        assert_eq!(a, UpAxis::MinusX);
        assert!((t - (0.9 / DVec3::new(-0.9, 0.1, 0.3).length()).acos()).abs() < 1e-12);
        let (a, _) = UpAxis::nearest(DVec3::new(0.2, -0.5, 0.1));
        assert_eq!(a, UpAxis::MinusY);
    }

    #[test]
    fn tilt_stays_within_its_bound_and_parses() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut largest: f64 = 0.0;
        for i in 0..500 {
            let r = upright_rotation(f64::from(i), UpAxis::MinusX, 12.0, &mut rng);
            let up = r * DVec3::NEG_X;
            let tilt = up.z.clamp(-1.0, 1.0).acos().to_degrees();
            assert!(tilt <= 12.0 + 1e-9, "{tilt}");
            largest = largest.max(tilt);
        }
        assert!(largest > 10.0, "tilts reach the bound: {largest}");
        #[derive(Deserialize)]
        struct W {
            up: UpAxis,
        }
        let w: W = toml::from_str("up = \"-y\"").unwrap();
        assert_eq!(w.up, UpAxis::MinusY);
        assert!(toml::from_str::<W>("up = \"y\"").is_err());
        assert_eq!(toml::from_str::<W>("up = \"any\"").unwrap().up, UpAxis::Any);
    }

    #[test]
    fn any_draws_every_axis() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut seen = std::collections::BTreeSet::new();
        for _ in 0..200 {
            let r = upright_rotation(0.0, UpAxis::Any, 0.0, &mut rng);
            // The model axis now pointing up is one of the six.
            let up_in_model = r.transpose() * DVec3::Z;
            let (axis, angle) = UpAxis::nearest(up_in_model);
            assert!(angle < 1e-9);
            seen.insert(axis);
        }
        assert_eq!(seen.len(), 6, "{seen:?}");
    }
}
