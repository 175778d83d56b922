//! How a rigid object comes to rest on a table when nothing else is known about it: the
//! stable faces of its convex hull, each with the probability that a random drop ends on it.
//!
//! A hull facet is stable when the centre of mass, projected along the facet's normal, falls
//! inside it. The chance of landing on a facet is estimated quasi-statically (Wiegley et al.
//! 1996; the "solid angle" rule of grasp planners): the solid angle the facet subtends at the
//! centre of mass, plus that of every unstable facet, which topples onto the stable facet whose
//! normal is nearest. The centre of mass is the hull's volume centroid (uniform density).

use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::sample::RestPose;
use synthgen_core::Model;

/// Facet normals closer than this (radians) are one facet.
const COPLANAR_RAD: f64 = 0.5_f64 * std::f64::consts::PI / 180.0;
/// Facets with a smaller share of the drops are left out (numerical slivers).
const MIN_PROBABILITY: f64 = 1e-3;

struct Facet {
    /// Outward unit normal.
    normal: DVec3,
    /// Offset: n·x = d on the facet's plane.
    d: f64,
    /// Its triangles.
    tris: Vec<[DVec3; 3]>,
    /// Solid angle at the centre of mass, steradians.
    solid_angle: f64,
}

/// The stable rest poses of `model` with their probabilities (summing to 1), most likely
/// first. Each rotation turns the model so that its facet lies on the table (the facet's
/// normal down, −z); the yaw about +z is left to the sampler. Empty for a degenerate model.
pub fn stable_rest_poses(model: &Model) -> Vec<RestPose> {
    let points: Vec<rapier3d::parry::math::Vector3> = model
        .positions()
        .map(|p| rapier3d::parry::math::Vector3::new(p.x, p.y, p.z))
        .collect();
    if points.len() < 4 {
        return Vec::new();
    }
    let Ok((verts, tris)) = rapier3d::parry::transformation::try_convex_hull(&points) else {
        return Vec::new();
    };
    let v: Vec<DVec3> = verts
        .iter()
        .map(|p| DVec3::new(f64::from(p.x), f64::from(p.y), f64::from(p.z)))
        .collect();
    let tris: Vec<[DVec3; 3]> = tris
        .iter()
        .map(|t| [v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]])
        .collect();
    let Some(com) = volume_centroid(&tris) else {
        return Vec::new();
    };
    let facets = facets(&tris, com);
    let stable: Vec<usize> = (0..facets.len())
        .filter(|&i| holds(&facets[i], com))
        .collect();
    if stable.is_empty() {
        return Vec::new();
    }
    let mut weight = vec![0.0; facets.len()];
    for (i, f) in facets.iter().enumerate() {
        // An unstable facet topples onto the stable one whose normal is nearest.
        let to = stable
            .iter()
            .copied()
            .max_by(|&a, &b| {
                facets[a]
                    .normal
                    .dot(f.normal)
                    .total_cmp(&facets[b].normal.dot(f.normal))
            })
            .unwrap_or(i);
        weight[to] += f.solid_angle;
    }
    let total: f64 = stable.iter().map(|&i| weight[i]).sum();
    let mut out: Vec<RestPose> = stable
        .iter()
        .map(|&i| RestPose {
            rotation: down_rotation(facets[i].normal),
            probability: weight[i] / total,
        })
        .filter(|r| r.probability >= MIN_PROBABILITY)
        .collect();
    let kept: f64 = out.iter().map(|r| r.probability).sum();
    for r in &mut out {
        r.probability /= kept;
    }
    out.sort_by(|a, b| b.probability.total_cmp(&a.probability));
    out
}

/// The centroid of the solid the (outward-wound) triangles enclose.
fn volume_centroid(tris: &[[DVec3; 3]]) -> Option<DVec3> {
    let (mut vol, mut c) = (0.0, DVec3::ZERO);
    for [a, b, cc] in tris {
        let v = a.dot(b.cross(*cc)) / 6.0;
        vol += v;
        c += v * (*a + *b + *cc) / 4.0;
    }
    (vol.abs() > 1e-15).then(|| c / vol)
}

/// The hull's triangles grouped into planar facets, with their solid angles seen from `com`.
fn facets(tris: &[[DVec3; 3]], com: DVec3) -> Vec<Facet> {
    let mut out: Vec<Facet> = Vec::new();
    for t in tris {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        let area2 = n.length();
        if area2 < 1e-18 {
            continue;
        }
        let mut n = n / area2;
        // Outward: away from the centre of mass.
        if n.dot(t[0] - com) < 0.0 {
            n = -n;
        }
        let d = n.dot(t[0]);
        let omega = solid_angle(t, com);
        match out.iter_mut().find(|f| {
            f.normal.dot(n) > COPLANAR_RAD.cos() && (f.d - d).abs() < 1e-4 * (1.0 + d.abs())
        }) {
            Some(f) => {
                f.tris.push(*t);
                f.solid_angle += omega;
            }
            None => out.push(Facet {
                normal: n,
                d,
                tris: vec![*t],
                solid_angle: omega,
            }),
        }
    }
    out
}

/// The solid angle triangle `t` subtends at `p` (Van Oosterom and Strackee 1983), ≥ 0.
fn solid_angle(t: &[DVec3; 3], p: DVec3) -> f64 {
    let (a, b, c) = (t[0] - p, t[1] - p, t[2] - p);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
    (2.0 * num.atan2(den)).abs()
}

/// Whether the centre of mass, dropped along the facet's normal, lands inside the facet.
fn holds(f: &Facet, com: DVec3) -> bool {
    let p = com - (f.normal.dot(com) - f.d) * f.normal;
    f.tris.iter().any(|t| inside_triangle(t, p, f.normal))
}

fn inside_triangle(t: &[DVec3; 3], p: DVec3, n: DVec3) -> bool {
    // Within a hair of an edge counts: a centre of mass on an edge balances.
    let eps = 1e-9;
    (0..3).all(|i| {
        let (a, b) = (t[i], t[(i + 1) % 3]);
        (b - a).cross(p - a).dot(n) >= -eps * (b - a).length_squared().max(1e-12)
    })
}

/// The rotation that turns `normal` (model frame) to −z: the facet faces the table.
fn down_rotation(normal: DVec3) -> DMat3 {
    let target = DVec3::NEG_Z;
    let n = normal.normalize();
    let axis = n.cross(target);
    let s = axis.length();
    let c = n.dot(target);
    if s < 1e-12 {
        return if c > 0.0 {
            DMat3::IDENTITY
        } else {
            DMat3::from_rotation_x(std::f64::consts::PI)
        };
    }
    DMat3::from_axis_angle(axis / s, s.atan2(c))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::Vec3;

    /// A brick lies on its largest faces most often, on its ends least; every face is stable.
    #[test]
    fn a_brick_rests_on_its_faces_the_largest_most_often() {
        let m = Model::cuboid("brick", Vec3::new(0.2, 0.1, 0.05));
        let poses = stable_rest_poses(&m);
        assert_eq!(poses.len(), 6);
        let sum: f64 = poses.iter().map(|p| p.probability).sum();
        assert!((sum - 1.0).abs() < 1e-9);
        // The two largest faces (normal ±z, 0.2 x 0.1) first, then ±y, then ±x.
        for (i, axis) in [(0, DVec3::Z), (2, DVec3::Y), (4, DVec3::X)] {
            for p in &poses[i..i + 2] {
                let down = p.rotation.transpose() * DVec3::NEG_Z;
                assert!(down.dot(axis).abs() > 0.999, "{i}: {down}");
            }
        }
        assert!(poses[0].probability > poses[2].probability);
        assert!(poses[2].probability > poses[4].probability);
        // Each rotation puts its face's normal down.
        for p in &poses {
            let n = p.rotation.transpose() * DVec3::NEG_Z;
            let lowest = m
                .positions()
                .map(|v| (p.rotation * v.as_dvec3()).z)
                .fold(f64::INFINITY, f64::min);
            let on_face = m
                .positions()
                .filter(|v| ((p.rotation * v.as_dvec3()).z - lowest).abs() < 1e-6)
                .count();
            assert!(on_face >= 4, "{n}: a face, not an edge, lies on the table");
        }
    }

    /// A can: a tall one stands on its ends less often than it lies on its side, a flat one
    /// (a tuna can) the other way round; the probabilities of the side's facets add up.
    #[test]
    fn a_can_lies_on_its_side_or_stands_by_its_shape() {
        let stand = |m: &Model| -> f64 {
            stable_rest_poses(m)
                .iter()
                .filter(|p| (p.rotation.transpose() * DVec3::NEG_Z).z.abs() > 0.999)
                .map(|p| p.probability)
                .sum()
        };
        let tall = synthgen_core::distractor::cylinder("tall", 0.03, 0.2);
        let flat = synthgen_core::distractor::cylinder("flat", 0.05, 0.03);
        let (t, f) = (stand(&tall), stand(&flat));
        assert!(t > 0.0 && t < 0.3, "a tall can stands in {t} of drops");
        assert!(f > 0.7, "a tuna can stands in {f} of drops");
        assert!(
            stable_rest_poses(&tall).len() > 3,
            "the side's facets are rest poses too"
        );
    }

    /// A tetrahedron whose centre of mass overhangs one face cannot rest on it.
    #[test]
    fn a_face_the_centre_of_mass_overhangs_is_not_stable() {
        // A long thin wedge: the face under the overhang is not stable.
        let tri = |a: DVec3, b: DVec3, c: DVec3| [a, b, c];
        let (p0, p1, p2, p3) = (
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.01, 0.0, 0.0),
            DVec3::new(0.0, 0.01, 0.0),
            DVec3::new(0.5, 0.5, 0.01),
        );
        let tris = vec![
            tri(p0, p2, p1),
            tri(p0, p1, p3),
            tri(p1, p2, p3),
            tri(p2, p0, p3),
        ];
        let com = volume_centroid(&tris).unwrap();
        assert!((com - (p0 + p1 + p2 + p3) / 4.0).length() < 1e-12);
        let f = facets(&tris, com);
        assert_eq!(f.len(), 4);
        let total: f64 = f.iter().map(|f| f.solid_angle).sum();
        assert!((total - 4.0 * std::f64::consts::PI).abs() < 1e-6, "{total}");
        let bottom = f.iter().find(|f| f.normal.z < -0.99).unwrap();
        assert!(
            !holds(bottom, com),
            "the small base cannot hold the far centre of mass"
        );
    }
}
