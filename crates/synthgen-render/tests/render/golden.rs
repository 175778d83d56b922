//! Golden images: a fixed 64x48 scene compared with PNGs in `tests/golden/`, with a tolerance.
//! `SYNTHGEN_BLESS=1 cargo test -p synthgen-render golden` rewrites them.

use std::path::PathBuf;
use std::sync::Arc;

use image::{GrayImage, ImageBuffer, Luma, RgbImage};
use synthgen_core::glam::{DMat3, DVec3, Vec2, Vec3};
use synthgen_core::sample::PointLight;
use synthgen_core::{Intrinsics, Material, Model, Pose, RenderedFrame, Texture};
use synthgen_render::{CpuRenderer, Renderer};

use crate::common::*;

fn golden_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

/// A cube with per-vertex colours and a textured, double-sided quad.
fn models() -> (Vec<Model>, Vec<Arc<Texture>>) {
    let mut cube = Model::cuboid("cube", Vec3::splat(0.1));
    cube.primitives[0].colors = Some(
        cube.primitives[0]
            .positions_m
            .iter()
            .map(|p| [0.5 + p.x * 8.0, 0.5 + p.y * 8.0, 0.5 + p.z * 8.0])
            .collect(),
    );
    cube.primitives[0].material.base_color = [1.0; 3];
    let checker: Vec<u8> = (0..16)
        .flat_map(|i| {
            if (i % 4 + i / 4) % 2 == 0 {
                [230, 200, 40]
            } else {
                [40, 60, 200]
            }
        })
        .collect();
    let tex = Arc::new(Texture {
        width: 4,
        height: 4,
        rgb: checker,
        source: "<checker>".into(),
    });
    let quad = Model {
        name: "quad".into(),
        source: "<quad>".into(),
        primitives: vec![synthgen_core::Primitive {
            positions_m: vec![
                Vec3::new(-0.06, -0.04, 0.0),
                Vec3::new(0.06, -0.04, 0.0),
                Vec3::new(0.06, 0.04, 0.0),
                Vec3::new(-0.06, 0.04, 0.0),
            ],
            uvs: Some(vec![
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 1.0),
                Vec2::new(0.0, 1.0),
            ]),
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            material: Material {
                base_color: [1.0; 3],
                texture: Some(tex),
                double_sided: true,
                ..Default::default()
            },
            ..Default::default()
        }],
    };
    (vec![cube, quad], vec![])
}

fn golden_scene() -> synthgen_core::FrameScene {
    let k = Intrinsics {
        width: 64,
        height: 48,
        fx: 70.0,
        fy: 70.0,
        cx: 31.5,
        cy: 23.5,
    };
    let cube = at(
        DMat3::from_euler(synthgen_core::glam::EulerRot::XYZ, 0.5, 0.7, 0.2),
        -0.05,
        0.0,
        0.5,
    );
    let quad = at(DMat3::from_rotation_y(2.6), 0.08, -0.03, 0.45);
    let mut s = scene(k, vec![instance(0, cube), instance(1, quad)]);
    // A floor 30 cm below the camera, which looks down at it by 30 degrees; its normal
    // (the plane's z axis) points up.
    let plane = Pose::new(
        DMat3::from_rotation_x(120f64.to_radians()),
        DVec3::new(0.0, 0.0, 0.6),
    );
    s.ground = Some(synthgen_core::sample::GroundInstance {
        size_m: 0.7,
        ..ground_facing(plane)
    });
    s.lights.push(PointLight {
        position_cam_m: DVec3::new(-0.4, -0.2, 0.2),
        color: [0.6, 0.7, 1.0],
        intensity: 0.5,
    });
    s
}

fn to_images(f: &RenderedFrame) -> (RgbImage, ImageBuffer<Luma<u16>, Vec<u16>>, GrayImage) {
    let rgb = RgbImage::from_raw(f.width, f.height, f.rgb.clone()).unwrap();
    // Depth in 0.1 mm, instance ids scaled to be visible.
    let depth = ImageBuffer::from_raw(
        f.width,
        f.height,
        f.depth_m
            .iter()
            .map(|d| (d * 10_000.0).round() as u16)
            .collect(),
    )
    .unwrap();
    let inst = GrayImage::from_raw(
        f.width,
        f.height,
        f.instance.iter().map(|&i| (i * 100) as u8).collect(),
    )
    .unwrap();
    (rgb, depth, inst)
}

/// Fraction of values differing by more than `tol`.
fn frac_off(a: &[i64], b: &[i64], tol: i64) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .filter(|(x, y)| (*x - *y).abs() > tol)
        .count() as f64
        / a.len() as f64
}

#[test]
fn golden_64x48() {
    let (models, bgs) = models();
    let r = CpuRenderer::new(models, bgs).unwrap();
    let f = r.render(&golden_scene()).unwrap();
    let (rgb, depth, inst) = to_images(&f);
    let dir = golden_dir();
    // The scene shows what it is meant to.
    for id in [1, 2] {
        assert!(
            f.instance.iter().filter(|&&v| v == id).count() > 50,
            "object {id}"
        );
    }
    assert!(f.depth_m.contains(&0.0), "background visible");
    assert!(
        f.instance
            .iter()
            .zip(&f.depth_m)
            .any(|(&i, &d)| i == 0 && d > 0.0),
        "ground visible"
    );
    if std::env::var_os("SYNTHGEN_BLESS").is_some_and(|v| v == "1") {
        std::fs::create_dir_all(&dir).unwrap();
        rgb.save(dir.join("scene_rgb.png")).unwrap();
        depth.save(dir.join("scene_depth_0.1mm.png")).unwrap();
        inst.save(dir.join("scene_instance.png")).unwrap();
        eprintln!("blessed golden images in {}", dir.display());
        return;
    }
    let want_rgb = image::open(dir.join("scene_rgb.png")).unwrap().to_rgb8();
    let want_depth = image::open(dir.join("scene_depth_0.1mm.png"))
        .unwrap()
        .to_luma16();
    let want_inst = image::open(dir.join("scene_instance.png"))
        .unwrap()
        .to_luma8();
    let wide = |v: &[u8]| v.iter().map(|&x| x as i64).collect::<Vec<_>>();
    let wide16 = |v: &[u16]| v.iter().map(|&x| x as i64).collect::<Vec<_>>();
    // Per pixel the max channel difference.
    let px_off = rgb
        .pixels()
        .zip(want_rgb.pixels())
        .filter(|(a, b)| {
            a.0.iter()
                .zip(b.0)
                .any(|(x, y)| (*x as i32 - y as i32).abs() > 2)
        })
        .count() as f64
        / (64.0 * 48.0);
    assert!(
        px_off <= 0.01,
        "{:.2}% of rgb pixels differ by > 2 levels",
        px_off * 100.0
    );
    let d = frac_off(&wide16(depth.as_raw()), &wide16(want_depth.as_raw()), 1);
    assert!(
        d <= 0.01,
        "{:.2}% of depth pixels differ by > 0.1 mm",
        d * 100.0
    );
    let i = frac_off(&wide(inst.as_raw()), &wide(want_inst.as_raw()), 0);
    assert!(i <= 0.01, "{:.2}% of instance pixels differ", i * 100.0);
}

/// `sky_color = ground_color = [1, 1, 1]` (what `scenes/plain.toml` sets) is the uniform
/// ambient to the byte, on the objects and on the ground: the plain look is reachable from a
/// spec file, where "unset" cannot be written.
#[test]
fn a_white_sky_and_ground_is_no_environment() {
    let (models, bgs) = models();
    let r = CpuRenderer::new(models, bgs).unwrap();
    let mut scene = golden_scene();
    scene.world_from_cam = Pose::new(DMat3::from_rotation_x(-2.0), DVec3::new(0.0, 0.0, 0.3));
    let none = r.render(&scene).unwrap();
    scene.environment = Some([[1.0; 3], [1.0; 3]]);
    let white = r.render(&scene).unwrap();
    assert_eq!(none.rgb, white.rgb);
    scene.environment = Some([[1.3; 3], [0.5; 3]]);
    let coloured = r.render(&scene).unwrap();
    assert_ne!(
        none.rgb, coloured.rgb,
        "the environment light does something"
    );
}
