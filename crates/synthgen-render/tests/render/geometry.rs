//! Coverage, depth and culling against analytic references.

use synthgen_core::glam::{DMat3, DVec3, Vec2, Vec3};
use synthgen_core::{annotate, Intrinsics, Material, Model, Pose, Primitive};
use synthgen_render::{CpuRenderer, Renderer};

use crate::common::*;

const CUBE: f32 = 0.1;

fn cube_renderer() -> CpuRenderer {
    CpuRenderer::new(vec![Model::cuboid("cube", Vec3::splat(CUBE))], vec![]).unwrap()
}

#[test]
fn cube_centre_depth_is_analytic() {
    let k = Intrinsics::LINEMOD;
    let r = cube_renderer();
    // A face toward the camera, 45 cm deep; the image centre ray hits it at z = 0.45.
    let f = r
        .render(&scene(
            k,
            vec![instance(0, at(DMat3::IDENTITY, 0.0, 0.0, 0.5))],
        ))
        .unwrap();
    let (cx, cy) = (k.cx.round() as usize, k.cy.round() as usize);
    let i = cy * 640 + cx;
    assert_eq!(f.instance[i], 1);
    assert!((f.depth_m[i] - 0.45).abs() < 1e-4, "{}", f.depth_m[i]);

    // Tilted by 30 degrees about x: the front face is the plane n.p = 0.05 with
    // n = R * (0, 0, -1) (in camera frame, shifted by t); intersect the centre pixel's ray.
    let rot = DMat3::from_rotation_x(30f64.to_radians());
    let pose = at(rot, 0.0, 0.0, 0.6);
    let f = r.render(&scene(k, vec![instance(0, pose)])).unwrap();
    let (u, v) = (cx as f64, cy as f64);
    let d = k.back_project(u, v, 1.0);
    let n = rot * DVec3::new(0.0, 0.0, -1.0);
    let p0 = pose.translation_m + n * 0.05;
    let z = n.dot(p0) / n.dot(d);
    let got = f.depth_m[cy * 640 + cx] as f64;
    assert!((got - z).abs() < 1e-4, "depth {got} vs analytic {z}");
}

#[test]
fn cube_silhouette_matches_projected_hull() {
    let k = Intrinsics::LINEMOD;
    let r = cube_renderer();
    let mut rng = TestRng::new(3);
    for _ in 0..10 {
        let pose = at(
            rng.rotation(),
            rng.range(-0.1, 0.1),
            rng.range(-0.08, 0.08),
            rng.range(0.4, 1.0),
        );
        let f = r.render(&scene(k, vec![instance(0, pose)])).unwrap();
        let hull = convex_hull(projected_box(&k, &pose, Vec3::splat(CUBE)));
        let area = polygon_area(&hull);
        let mut count = 0usize;
        let mut bad = 0usize;
        for y in 0..480 {
            for x in 0..640 {
                let covered = f.instance[y * 640 + x] == 1;
                count += covered as usize;
                let d = inside_distance(&hull, [x as f64, y as f64]);
                // Vertices snap to 1/256 px; only centres that close to the edge may differ.
                if d.abs() > 0.01 && covered != (d > 0.0) {
                    bad += 1;
                }
                assert_eq!(covered, f.depth_m[y * 640 + x] > 0.0);
            }
        }
        assert_eq!(bad, 0, "pixels disagreeing with the hull");
        let rel = (count as f64 - area).abs() / area;
        assert!(rel < 0.02, "count {count} vs area {area:.1}");
    }
}

#[test]
fn cube_points_lie_on_the_surface() {
    let k = Intrinsics::LINEMOD;
    let r = cube_renderer();
    let mut rng = TestRng::new(11);
    let h = DVec3::splat(CUBE as f64 * 0.5);
    for _ in 0..8 {
        let pose = at(
            rng.rotation(),
            rng.range(-0.1, 0.1),
            rng.range(-0.1, 0.1),
            rng.range(0.3, 1.2),
        );
        let f = r.render(&scene(k, vec![instance(0, pose)])).unwrap();
        let obj_from_cam = pose.inverse();
        let mut dists = Vec::new();
        for y in 0..480 {
            for x in 0..640 {
                let i = y * 640 + x;
                if f.instance[i] != 1 {
                    continue;
                }
                let p = k.back_project(x as f64, y as f64, f.depth_m[i] as f64);
                dists.push(box_surface_distance(obj_from_cam.transform_point(p), h));
            }
        }
        assert!(dists.len() > 100);
        let max = dists.iter().cloned().fold(0.0, f64::max);
        assert!(
            median(dists) < 1e-5,
            "median distance to the box surface too large"
        );
        assert!(max < 5e-4, "max distance {max} m");
    }
}

#[test]
fn truncated_object_keeps_its_whole_silhouette() {
    let k = Intrinsics::LINEMOD;
    let r = cube_renderer();
    // Centre projects to x ~ 0: half the cube is left of the image.
    let x = -k.cx / k.fx * 0.5;
    let f = r
        .render(&scene(
            k,
            vec![instance(0, at(DMat3::IDENTITY, x, 0.0, 0.5))],
        ))
        .unwrap();
    let a = &f.alone[0];
    assert!(a.x0 < 0, "window starts at {}", a.x0);
    let ann = annotate(&k, &f.depth_m, &f.alone, 0.015);
    let info = ann[0].info;
    let in_image = f.instance.iter().filter(|&&v| v == 1).count() as u64;
    assert_eq!(info.px_count_visib, in_image);
    assert!(info.px_count_all as f64 > 1.8 * in_image as f64, "{info:?}");
    assert!(info.bbox_obj[0] < 0);
    assert_eq!(info.bbox_visib[0], 0);
    // The whole silhouette, counted against the projected hull on the 3x canvas.
    let pose = at(DMat3::IDENTITY, x, 0.0, 0.5);
    let hull = convex_hull(projected_box(&k, &pose, Vec3::splat(CUBE)));
    let mut want = 0u64;
    for y in -480..960 {
        for x in -640..1280 {
            want += (inside_distance(&hull, [x as f64, y as f64]) > 0.0) as u64;
        }
    }
    let perimeter = 4.0 * polygon_area(&hull).sqrt();
    assert!(
        (info.px_count_all as f64 - want as f64).abs() < 0.05 * perimeter,
        "{} vs {want}",
        info.px_count_all
    );
}

fn triangle_model(reversed: bool, double_sided: bool) -> Model {
    // Counter-clockwise seen from -z (the camera side when placed at +z in front of it).
    let mut triangles = vec![[0, 1, 2]];
    if reversed {
        triangles = vec![[0, 2, 1]];
    }
    Model {
        name: "tri".into(),
        source: "<tri>".into(),
        primitives: vec![Primitive {
            positions_m: vec![
                Vec3::new(-0.05, -0.05, 0.0),
                Vec3::new(-0.05, 0.05, 0.0),
                Vec3::new(0.05, -0.05, 0.0),
            ],
            triangles,
            material: Material {
                double_sided,
                ..Default::default()
            },
            ..Default::default()
        }],
    }
}

#[test]
fn back_faces_are_culled_unless_double_sided() {
    let k = Intrinsics::LINEMOD;
    let covered = |m: Model| {
        let r = CpuRenderer::new(vec![m], vec![]).unwrap();
        let f = r
            .render(&scene(
                k,
                vec![instance(0, at(DMat3::IDENTITY, 0.0, 0.0, 0.5))],
            ))
            .unwrap();
        f.instance.iter().filter(|&&v| v == 1).count()
    };
    let front = covered(triangle_model(false, false));
    assert!(front > 1000, "front face drew {front} px");
    assert_eq!(covered(triangle_model(true, false)), 0);
    assert_eq!(covered(triangle_model(true, true)), front);
    assert_eq!(covered(triangle_model(false, true)), front);
    // The cuboid's outward faces agree with this convention: seen from inside, nothing.
    let r = cube_renderer();
    let f = r
        .render(&scene(
            k,
            vec![instance(0, at(DMat3::IDENTITY, 0.0, 0.0, 0.02))],
        ))
        .unwrap();
    assert!(f.instance.iter().all(|&v| v == 0));
}

/// A square whose corners and diagonal fall exactly on pixel centres.
fn square_model(split: Option<usize>) -> Model {
    let positions_m = vec![
        Vec3::new(-0.1, -0.1, 0.0),
        Vec3::new(-0.1, 0.1, 0.0),
        Vec3::new(0.1, 0.1, 0.0),
        Vec3::new(0.1, -0.1, 0.0),
    ];
    let all = vec![[0, 1, 2], [0, 2, 3]];
    let triangles = match split {
        Some(i) => vec![all[i]],
        None => all,
    };
    Model {
        name: "square".into(),
        source: "<square>".into(),
        primitives: vec![Primitive {
            positions_m,
            uvs: Some(vec![Vec2::ZERO; 4]),
            triangles,
            ..Default::default()
        }],
    }
}

#[test]
fn top_left_rule_covers_each_pixel_once() {
    let k = Intrinsics {
        width: 64,
        height: 64,
        fx: 100.0,
        fy: 100.0,
        cx: 32.0,
        cy: 32.0,
    };
    // At z = 1 the square spans pixel centres 22..=42 in x and y. Left and top edges are
    // in, right and bottom edges out: exactly 20 x 20 pixels.
    let pose = at(DMat3::IDENTITY, 0.0, 0.0, 1.0);
    let count = |models: Vec<Model>| {
        let n = models.len();
        let r = CpuRenderer::new(models, vec![]).unwrap();
        let objs = (0..n).map(|i| instance(i, pose)).collect();
        let f = r.render(&scene(k, objs)).unwrap();
        let ann = annotate(&k, &f.depth_m, &f.alone, 0.015);
        ann.iter().map(|a| a.info.px_count_all).collect::<Vec<_>>()
    };
    assert_eq!(count(vec![square_model(None)]), vec![400]);
    let halves = count(vec![square_model(Some(0)), square_model(Some(1))]);
    assert_eq!(halves[0] + halves[1], 400, "{halves:?}");
    // The shared diagonal is a right edge of the first triangle, a left edge of the second.
    assert_eq!(halves, vec![190, 210]);
}

#[test]
fn near_plane_clips_instead_of_dropping() {
    // A big square crossing the near plane at a grazing angle: the part beyond the plane is
    // drawn (clipped), the part in front is not, and depths stay >= near.
    let k = Intrinsics::LINEMOD;
    let r = CpuRenderer::new(vec![square_model(None)], vec![]).unwrap();
    let rot = DMat3::from_rotation_x(80f64.to_radians());
    let f = r
        .render(&scene(
            k,
            vec![instance(0, Pose::new(rot, DVec3::new(0.0, 0.0, 0.05)))],
        ))
        .unwrap();
    let n = f.instance.iter().filter(|&&v| v == 1).count();
    assert!(n > 1000, "{n}");
    let min = f
        .depth_m
        .iter()
        .cloned()
        .filter(|&d| d > 0.0)
        .fold(f32::INFINITY, f32::min);
    assert!(min >= 0.0099, "{min}");
    let max = f.depth_m.iter().cloned().fold(0.0f32, f32::max);
    assert!(max <= 0.05 + 0.1 * 80f32.to_radians().sin() + 1e-4, "{max}");
}

#[test]
fn bad_inputs_are_errors() {
    let r = cube_renderer();
    let k = Intrinsics::LINEMOD;
    let e = r
        .render(&scene(k, vec![instance(3, Pose::IDENTITY)]))
        .unwrap_err();
    assert!(e.to_string().contains("model 3"), "{e}");
    let mut s = scene(k, vec![]);
    s.background.kind = synthgen_core::scene::BackgroundKind::Images;
    assert!(r
        .render(&s)
        .unwrap_err()
        .to_string()
        .contains("background image"));
    let mut m = Model::cuboid("c", Vec3::ONE);
    m.primitives[0].triangles.push([0, 1, 99]);
    let e = CpuRenderer::new(vec![m], vec![]).err().unwrap();
    assert!(e.to_string().contains("vertex 99"), "{e}");
}

/// `render_depth_mm`: a 10 cm cube facing the camera at 0.8 m reads 750 mm over its front face,
/// exactly (f64 per pixel, not the rasterizer's snapped depth), over the pixels whose centres
/// it covers; a tilted face's depth matches the plane through it.
#[test]
fn depth_only_render_is_exact_on_a_cube() {
    use synthgen_core::glam::{DMat3, DVec3, Vec3};
    use synthgen_core::{DepthWindowMm, Intrinsics, Model};
    let r = synthgen_render::CpuRenderer::new(vec![Model::cuboid("c", Vec3::splat(0.1))], vec![])
        .unwrap();
    let k = Intrinsics {
        width: 640,
        height: 480,
        fx: 600.0,
        fy: 600.0,
        cx: 320.0,
        cy: 240.0,
    };
    let mut out = DepthWindowMm::default();
    r.render_depth_mm(
        0,
        &DMat3::IDENTITY,
        DVec3::new(0.0, 0.0, 800.0),
        &k,
        &mut out,
    )
    .unwrap();
    // The face spans ±50 mm at 750 mm: ±40 px around the centre; centres exactly on its
    // right and bottom edges are outside (top-left rule): 80 x 80 pixels.
    assert_eq!((out.x0, out.width), (280, 81));
    assert_eq!(out.at(320, 240), 750.0);
    assert_eq!(out.at(280, 200), 750.0);
    assert_eq!(out.at(279, 240), 0.0);
    assert_eq!(out.at(360, 240), 0.0);
    assert!(out.depth_mm.iter().all(|&d| d == 750.0 || d == 0.0));
    assert_eq!(out.depth_mm.iter().filter(|&&d| d > 0.0).count(), 80 * 80);
    // Rotated 30° about y: depth along each pixel's ray on the front face's plane.
    let rot = DMat3::from_rotation_y(30f64.to_radians());
    r.render_depth_mm(0, &rot, DVec3::new(0.0, 0.0, 800.0), &k, &mut out)
        .unwrap();
    let n = rot * DVec3::Z;
    let p0 = rot * DVec3::new(0.0, 0.0, -50.0) + DVec3::new(0.0, 0.0, 800.0);
    let (x, y) = (330, 241);
    let ray = DVec3::new((x as f64 - 320.0) / 600.0, (y as f64 - 240.0) / 600.0, 1.0);
    let want = (-n).dot(p0) / (-n).dot(ray);
    let got = out.at(x, y) as f64;
    assert!((got - want).abs() < 1e-4, "{got} vs {want}");
}
