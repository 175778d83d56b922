//! The render → object coordinates → PnP chain a correspondence-based RGB model stands on: the
//! per-pixel model coordinates of a rasterized box lie on the box, and PnP on a few hundred of
//! them gives its pose back.

use synthgen_core::glam::{DMat3, DVec2, DVec3, Vec3};
use synthgen_core::pnp::{object_coordinates, ransac, RansacOptions};
use synthgen_core::{Intrinsics, Model};
use synthgen_render::{CpuRenderer, Renderer};

use crate::common::*;

#[test]
fn object_coordinates_of_a_render_give_its_pose_back_through_pnp() {
    let half = Vec3::new(0.04, 0.03, 0.02);
    let r = CpuRenderer::new(vec![Model::cuboid("box", half * 2.0)], vec![]).unwrap();
    let k = Intrinsics {
        width: 320,
        height: 240,
        fx: 300.0,
        fy: 301.0,
        cx: 161.3,
        cy: 118.7,
    };
    let pose = at(
        DMat3::from_euler(synthgen_core::glam::EulerRot::XYZ, 0.6, -0.5, 0.3),
        0.02,
        -0.01,
        0.45,
    );
    let f = r.render(&scene(k, vec![instance(0, pose)])).unwrap();
    let xyz = object_coordinates(&k, &f.depth_m, &f.instance, &[pose]);
    let (mut model, mut pixels) = (Vec::new(), Vec::new());
    let mut on_surface = 0usize;
    for (i, c) in xyz.iter().enumerate() {
        if f.instance[i] == 0 {
            assert!(c.iter().all(|v| v.is_nan()), "background pixel {i}: {c:?}");
        }
        if c[0].is_nan() {
            assert_ne!(f.instance[i], 1, "an object pixel without coordinates");
            continue;
        }
        // On the box: its largest normalized coordinate is 1.
        let m = (c[0].abs() / half.x)
            .max(c[1].abs() / half.y)
            .max(c[2].abs() / half.z);
        assert!(
            (m - 1.0).abs() < 5e-3,
            "pixel {i}: {c:?} is not on the box ({m})"
        );
        on_surface += 1;
        if i % 7 == 0 {
            model.push(DVec3::new(
                f64::from(c[0]),
                f64::from(c[1]),
                f64::from(c[2]),
            ));
            pixels.push(DVec2::new((i % 320) as f64, (i / 320) as f64));
        }
    }
    assert!(on_surface > 2000, "{on_surface} object pixels");
    let sol = ransac(&model, &pixels, &k, &RansacOptions::default()).unwrap();
    let turn = (sol.pose.rotation.transpose() * pose.rotation).to_cols_array();
    let angle = ((turn[0] + turn[4] + turn[8] - 1.0) / 2.0)
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees();
    let te = (sol.pose.translation_m - pose.translation_m).length();
    assert!(angle < 0.05 && te < 2e-4, "{angle} deg, {te} m");
    assert_eq!(
        sol.inliers.len(),
        model.len(),
        "every rendered correspondence is an inlier"
    );
    assert!(sol.rms_px < 0.1, "{} px", sol.rms_px);
}
