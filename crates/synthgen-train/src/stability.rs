//! Stability of estimates over repeated frames of a static object (`eval --stability`).
//!
//! Frames whose GT pose of an object is the same (to 1e-6 m and 1e-6 in the rotation
//! matrix's entries) form a group: the object stood still while the frames were taken (or
//! the same view was rendered with different noise, lighting or background). Per group and
//! object: the mean and the sample covariance (divided by n − 1) of the estimated translation
//! in millimetres (covariance in mm²), and of the estimated quaternion (w, x, y, z), each
//! sign-aligned to the group's first estimate (q and −q are the same rotation) before
//! averaging; the mean quaternion is the normalized average.

use std::collections::BTreeMap;

use serde::Serialize;
use synthgen_core::glam::{DMat3, DQuat};
use synthgen_core::Pose;

/// One estimate with the GT pose of its instance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub obj_id: u32,
    pub gt: Pose,
    pub est: Pose,
}

/// The spread of one group.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupStability {
    pub obj_id: u32,
    /// Frames in the group.
    pub n: usize,
    pub gt_t_mm: [f64; 3],
    pub mean_t_mm: [f64; 3],
    /// 3×3, row-major, mm².
    pub cov_t_mm2: [[f64; 3]; 3],
    /// GT quaternion (w, x, y, z), w ≥ 0.
    pub gt_q: [f64; 4],
    /// Mean of the sign-aligned estimated quaternions, normalized, sign as the GT's.
    pub mean_q: [f64; 4],
    /// 4×4 covariance of the sign-aligned quaternions.
    pub cov_q: [[f64; 4]; 4],
    /// √(trace cov t): RMS spread of the translation, mm.
    pub t_spread_mm: f64,
    /// Mean angle between each estimate and the mean rotation, degrees.
    pub r_spread_deg: f64,
}

fn quat(r: &DMat3) -> [f64; 4] {
    let q = DQuat::from_mat3(r).normalize();
    let s = if q.w < 0.0 { -1.0 } else { 1.0 };
    [s * q.w, s * q.x, s * q.y, s * q.z]
}

fn mean_cov<const D: usize>(v: &[[f64; D]]) -> ([f64; D], [[f64; D]; D]) {
    let n = v.len() as f64;
    let mut mean = [0.0; D];
    for x in v {
        for i in 0..D {
            mean[i] += x[i] / n;
        }
    }
    let mut cov = [[0.0; D]; D];
    if v.len() > 1 {
        for x in v {
            for i in 0..D {
                for j in 0..D {
                    cov[i][j] += (x[i] - mean[i]) * (x[j] - mean[j]) / (n - 1.0);
                }
            }
        }
    }
    (mean, cov)
}

/// The group key: the GT pose rounded to 1e-6 (metres / matrix entries).
fn key(obj_id: u32, p: &Pose) -> (u32, Vec<i64>) {
    let r = p.rotation_row_major();
    let t = p.translation_m.to_array();
    (
        obj_id,
        r.iter()
            .chain(t.iter())
            .map(|v| (v * 1e6).round() as i64)
            .collect(),
    )
}

/// Groups of ≥ `min_frames` samples with the same object and GT pose, in key order.
pub fn stability(samples: &[Sample], min_frames: usize) -> Vec<GroupStability> {
    let mut groups: BTreeMap<(u32, Vec<i64>), Vec<&Sample>> = BTreeMap::new();
    for s in samples {
        groups.entry(key(s.obj_id, &s.gt)).or_default().push(s);
    }
    groups
        .into_values()
        .filter(|g| g.len() >= min_frames.max(1))
        .map(|g| {
            let ts: Vec<[f64; 3]> = g
                .iter()
                .map(|s| (s.est.translation_m * 1000.0).to_array())
                .collect();
            let (mean_t, cov_t) = mean_cov(&ts);
            let first = quat(&g[0].est.rotation);
            let qs: Vec<[f64; 4]> = g
                .iter()
                .map(|s| {
                    let q = quat(&s.est.rotation);
                    let dot: f64 = q.iter().zip(&first).map(|(a, b)| a * b).sum();
                    if dot < 0.0 {
                        q.map(|v| -v)
                    } else {
                        q
                    }
                })
                .collect();
            let (mq, cov_q) = mean_cov(&qs);
            let norm = mq.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-12);
            let gt_q = quat(&g[0].gt.rotation);
            let mut mean_q = mq.map(|v| v / norm);
            if mean_q.iter().zip(&gt_q).map(|(a, b)| a * b).sum::<f64>() < 0.0 {
                mean_q = mean_q.map(|v| -v);
            }
            let mean_r = DMat3::from_quat(
                DQuat::from_xyzw(mean_q[1], mean_q[2], mean_q[3], mean_q[0]).normalize(),
            );
            let r_spread_deg = g
                .iter()
                .map(|s| synthgen_core::pose::rotation_angle_rad(&s.est.rotation, &mean_r))
                .sum::<f64>()
                .to_degrees()
                / g.len() as f64;
            GroupStability {
                obj_id: g[0].obj_id,
                n: g.len(),
                gt_t_mm: (g[0].gt.translation_m * 1000.0).to_array(),
                mean_t_mm: mean_t,
                cov_t_mm2: cov_t,
                gt_q,
                mean_q,
                cov_q,
                t_spread_mm: (cov_t[0][0] + cov_t[1][1] + cov_t[2][2]).sqrt(),
                r_spread_deg,
            }
        })
        .collect()
}

/// A markdown table: one row per group.
pub fn to_markdown(groups: &[GroupStability]) -> String {
    let mut s = String::from(
        "| object | n | mean t mm | GT t mm | σ t mm (x, y, z) | t spread mm | mean q (w, x, y, z) | σ q (w, x, y, z) | R spread ° |\n\
         |---|---:|---|---|---|---:|---|---|---:|\n",
    );
    let f3 = |v: [f64; 3], d: usize| format!("{:.d$}, {:.d$}, {:.d$}", v[0], v[1], v[2]);
    let f4 =
        |v: [f64; 4], d: usize| format!("{:.d$}, {:.d$}, {:.d$}, {:.d$}", v[0], v[1], v[2], v[3]);
    for g in groups {
        let sd_t = [0, 1, 2].map(|i| g.cov_t_mm2[i][i].sqrt());
        let sd_q = [0, 1, 2, 3].map(|i| g.cov_q[i][i].sqrt());
        s += &format!(
            "| {} | {} | {} | {} | {} | {:.2} | {} | {} | {:.2} |\n",
            g.obj_id,
            g.n,
            f3(g.mean_t_mm, 1),
            f3(g.gt_t_mm, 1),
            f3(sd_t, 2),
            g.t_spread_mm,
            f4(g.mean_q, 4),
            f4(sd_q, 4),
            g.r_spread_deg
        );
    }
    s
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::DVec3;

    #[test]
    fn groups_by_gt_pose_and_measures_spread() {
        let gt = Pose::new(DMat3::from_rotation_z(0.5), DVec3::new(0.0, 0.0, 1.0));
        let other = Pose::new(DMat3::IDENTITY, DVec3::new(0.1, 0.0, 1.0));
        // Translations 1 mm either side of the GT along x; rotations ±1° about z.
        let mk = |dx: f64, da: f64| Sample {
            obj_id: 8,
            gt,
            est: Pose::new(
                DMat3::from_rotation_z(0.5 + da.to_radians()),
                gt.translation_m + DVec3::new(dx, 0.0, 0.0),
            ),
        };
        let mut samples = vec![mk(-0.001, -1.0), mk(0.001, 1.0)];
        // A q / −q flip must not matter: the same estimate with the quaternion's sign flipped
        // is the same rotation, so it is built from the matrix.
        samples.push(mk(0.0, 0.0));
        // A lone frame of another pose is no group.
        samples.push(Sample {
            obj_id: 8,
            gt: other,
            est: other,
        });
        let g = stability(&samples, 2);
        assert_eq!(g.len(), 1);
        let g = &g[0];
        assert_eq!(g.n, 3);
        for i in 0..3 {
            assert!((g.mean_t_mm[i] - g.gt_t_mm[i]).abs() < 1e-9);
        }
        // Sample variance of (−1, 1, 0) mm is 1 mm².
        assert!((g.cov_t_mm2[0][0] - 1.0).abs() < 1e-9, "{:?}", g.cov_t_mm2);
        assert!(g.cov_t_mm2[1][1].abs() < 1e-12);
        assert!((g.t_spread_mm - 1.0).abs() < 1e-9);
        for i in 0..4 {
            assert!(
                (g.mean_q[i] - g.gt_q[i]).abs() < 1e-9,
                "{:?} {:?}",
                g.mean_q,
                g.gt_q
            );
        }
        // Angles −1°, 1°, 0° from the mean: mean 2/3°.
        assert!(
            (g.r_spread_deg - 2.0 / 3.0).abs() < 1e-6,
            "{}",
            g.r_spread_deg
        );
        let md = to_markdown(std::slice::from_ref(g));
        assert!(md.contains("| 8 | 3 |"), "{md}");
    }

    #[test]
    fn opposite_quaternion_signs_are_aligned() {
        // A rotation near 180° where the canonical quaternion's w is ~0: estimates on either
        // side flip sign; aligned, the spread stays small.
        let axis = DVec3::Z;
        let gt = Pose::new(DMat3::from_axis_angle(axis, std::f64::consts::PI), DVec3::Z);
        let samples: Vec<Sample> = [-0.5f64, 0.5]
            .iter()
            .map(|d| Sample {
                obj_id: 1,
                gt,
                est: Pose::new(
                    DMat3::from_axis_angle(axis, std::f64::consts::PI + d.to_radians()),
                    DVec3::Z,
                ),
            })
            .collect();
        let g = &stability(&samples, 2)[0];
        let tr: f64 = (0..4).map(|i| g.cov_q[i][i]).sum();
        assert!(tr < 1e-4, "{tr}");
        assert!((g.r_spread_deg - 0.5).abs() < 1e-6);
    }
}
