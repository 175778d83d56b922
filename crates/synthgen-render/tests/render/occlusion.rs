//! Occlusion between objects and with the ground: instance, depth and alone renders agree,
//! and `annotate` sees the expected visibility.

use synthgen_core::glam::{DMat3, DVec3, Vec3};
use synthgen_core::{annotate, Intrinsics, Model, Pose};
use synthgen_render::{CpuRenderer, Renderer};

use crate::common::*;

#[test]
fn near_cube_hides_part_of_far_cube() {
    let k = Intrinsics::LINEMOD;
    let (far_size, near_size) = (Vec3::splat(0.1), Vec3::splat(0.05));
    let r = CpuRenderer::new(
        vec![
            Model::cuboid("far", far_size),
            Model::cuboid("near", near_size),
        ],
        vec![],
    )
    .unwrap();
    let far = at(DMat3::from_rotation_y(0.3), 0.0, 0.0, 1.0);
    let near = at(DMat3::from_rotation_z(0.5), 0.03, 0.01, 0.6);
    let f = r
        .render(&scene(k, vec![instance(0, far), instance(1, near)]))
        .unwrap();

    // Per pixel: the nearest alone depth wins, and the frame holds exactly that.
    for y in 0..480i32 {
        for x in 0..640i32 {
            let i = (y * 640 + x) as usize;
            let (a, b) = (f.alone[0].at(x, y), f.alone[1].at(x, y));
            let want = match (a > 0.0, b > 0.0) {
                (false, false) => (0, 0.0),
                (true, false) => (1, a),
                (false, true) => (2, b),
                (true, true) => {
                    if b < a {
                        (2, b)
                    } else {
                        (1, a)
                    }
                }
            };
            assert_eq!((f.instance[i], f.depth_m[i]), want, "pixel ({x}, {y})");
        }
    }

    // Expected visibility of the far cube from the analytic silhouettes.
    let hull_far = convex_hull(projected_box(&k, &far, far_size));
    let hull_near = convex_hull(projected_box(&k, &near, near_size));
    let (mut all, mut vis) = (0.0, 0.0);
    for y in 0..480 {
        for x in 0..640 {
            let p = [x as f64, y as f64];
            if inside_distance(&hull_far, p) > 0.0 {
                all += 1.0;
                if inside_distance(&hull_near, p) <= 0.0 {
                    vis += 1.0;
                }
            }
        }
    }
    let ann = annotate(&k, &f.depth_m, &f.alone, 0.015);
    let info = ann[0].info;
    assert!(
        vis < 0.9 * all && vis > 0.3 * all,
        "test setup: {vis} of {all}"
    );
    let want = vis / all;
    // A pixel-boundary tolerance: the hull perimeters in pixels over the area.
    assert!(
        (info.visib_fract - want).abs() < 0.005,
        "visib_fract {} vs {want}",
        info.visib_fract
    );
    assert_eq!(
        info.px_count_visib,
        f.instance.iter().filter(|&&v| v == 1).count() as u64
    );
    assert_eq!(ann[1].info.visib_fract, 1.0);
    // The occluded part is still in the far cube's full mask.
    let hidden = ann[0]
        .mask
        .iter()
        .zip(&ann[0].mask_visib)
        .filter(|(m, v)| **m == 255 && **v == 0)
        .count();
    assert_eq!(hidden as u64, info.px_count_all - info.px_count_visib);
}

#[test]
fn ground_occludes_and_carries_instance_zero() {
    let k = Intrinsics::LINEMOD;
    let size = Vec3::splat(0.1);
    let r = CpuRenderer::new(vec![Model::cuboid("c", size)], vec![]).unwrap();
    // Camera looking straight at a plane 1 m away; the cube sinks halfway into it.
    let plane = Pose::new(
        DMat3::from_rotation_x(std::f64::consts::PI),
        DVec3::new(0.0, 0.0, 1.0),
    );
    let mut s = scene(k, vec![instance(0, at(DMat3::IDENTITY, 0.0, 0.0, 1.0))]);
    s.ground = Some(ground_facing(plane));
    let f = r.render(&s).unwrap();
    // Every pixel hits the plane (a 3 m square at 1 m fills the view) ...
    assert!(f.depth_m.iter().all(|&d| d > 0.0));
    // ... except where the cube's front half is nearer.
    let c = (242 * 640 + 325) as usize;
    assert_eq!(f.instance[c], 1);
    assert!((f.depth_m[c] - 0.95).abs() < 1e-4);
    let corner = 0usize;
    assert_eq!(f.instance[corner], 0);
    let p = k.back_project(0.0, 0.0, 1.0);
    assert!((f.depth_m[corner] as f64 - p.z).abs() < 1e-5);
    // Behind the plane: the cube is hidden, but its alone render is whole.
    let mut s2 = s.clone();
    s2.objects[0].cam_from_obj = at(DMat3::IDENTITY, 0.0, 0.0, 1.2);
    let f2 = r.render(&s2).unwrap();
    assert!(f2.instance.iter().all(|&v| v == 0));
    let ann = annotate(&k, &f2.depth_m, &f2.alone, 0.015);
    assert!(ann[0].info.px_count_all > 1000);
    assert_eq!(ann[0].info.px_count_visib, 0);
}
