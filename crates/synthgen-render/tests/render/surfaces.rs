//! Image-textured ground, walls, and the shipped procedural textures.

use std::path::PathBuf;
use std::sync::Arc;

use synthgen_core::glam::{DMat3, DVec3, Vec3};
use synthgen_core::sample::{SurfaceTexture, WallInstance};
use synthgen_core::{Intrinsics, Model, Pose, Texture};
use synthgen_render::procedural::{texture, TEXTURES};
use synthgen_render::{CpuRenderer, Error, Renderer};

use crate::common::{at, ground_facing, instance, scene};

/// A wall facing the camera (its z axis towards the camera) at depth `z`, covering x in
/// [x0, x1] and y in [-h/2, h/2] of the camera frame.
fn wall_facing(z: f64, x0: f64, x1: f64, h: f64, texture: Option<SurfaceTexture>) -> WallInstance {
    // x along camera x, y along camera -y (up), z towards the camera (-z).
    let rot = DMat3::from_cols(DVec3::X, -DVec3::Y, -DVec3::Z);
    WallInstance {
        cam_from_wall: Pose::new(rot, DVec3::new(0.5 * (x0 + x1), 0.0, z)),
        width_m: x1 - x0,
        height_m: h,
        color: [0.8, 0.7, 0.6],
        texture,
    }
}

fn checker(n: u32) -> Arc<Texture> {
    let mut rgb = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let v = if (x / 8 + y / 8) % 2 == 0 { 230 } else { 40 };
            rgb.extend_from_slice(&[v, v / 2, 255 - v]);
        }
    }
    Arc::new(Texture {
        width: n,
        height: n,
        rgb,
        source: PathBuf::from("checker.png"),
    })
}

#[test]
fn walls_occlude_have_depth_and_instance_zero() {
    let k = Intrinsics::LINEMOD;
    let r = CpuRenderer::new(vec![Model::cuboid("c", Vec3::splat(0.1))], vec![]).unwrap();
    let mut s = scene(k, vec![instance(0, at(DMat3::IDENTITY, 0.0, 0.0, 1.0))]);
    // A wall in front of the left half of the cube, and one far behind everything.
    s.walls = vec![
        wall_facing(0.8, -0.5, 0.0, 0.6, None),
        wall_facing(3.0, -5.0, 5.0, 5.0, None),
    ];
    let f = r.render(&s).unwrap();
    let w = k.width as usize;
    let px = |x: usize, y: usize| y * w + x;
    let (cx, cy) = (k.cx.round() as usize, k.cy.round() as usize);
    // Left of the centre: the near wall, instance 0, depth 0.8.
    let l = px(cx - 10, cy);
    assert_eq!(f.instance[l], 0);
    assert!((f.depth_m[l] - 0.8).abs() < 1e-4, "{}", f.depth_m[l]);
    // Right of the centre: the cube's front face.
    let rr = px(cx + 10, cy);
    assert_eq!(f.instance[rr], 1);
    assert!((f.depth_m[rr] - 0.95).abs() < 1e-4, "{}", f.depth_m[rr]);
    // A corner: the far wall, no background left.
    assert!((f.depth_m[px(w - 5, 5)] - 3.0).abs() < 1e-3);
    assert!(f.depth_m.iter().all(|&d| d > 0.0));
    // The cube's alone depth is whole: the wall hides it only in the composite.
    let info = synthgen_core::annotate(&k, &f.depth_m, &f.alone, 0.015);
    assert!(info[0].info.visib_fract < 0.6 && info[0].info.visib_fract > 0.4);
}

/// A floor seen from 0.5 m above at 45 degrees, image-textured.
fn textured_floor_scene(
    texture: Option<SurfaceTexture>,
    color: [f32; 3],
) -> synthgen_core::FrameScene {
    let k = Intrinsics::LINEMOD;
    let mut s = scene(k, vec![]);
    let plane = Pose::new(
        DMat3::from_rotation_x(135f64.to_radians()),
        DVec3::new(0.0, 0.0, 0.7),
    );
    s.ground = Some(synthgen_core::sample::GroundInstance {
        color,
        texture,
        ..ground_facing(plane)
    });
    s
}

#[test]
fn textured_ground_is_lit_tinted_deterministic_and_needs_its_images() {
    let tex = SurfaceTexture {
        image: 0,
        offset: [0.25, 0.5],
        scale_m: 0.2,
    };
    let plain = CpuRenderer::new(vec![], vec![]).unwrap();
    let r = CpuRenderer::new(vec![], vec![])
        .unwrap()
        .with_surface_textures(&[checker(64)], &[])
        .unwrap();
    let s = textured_floor_scene(Some(tex.clone()), [1.0; 3]);
    let a = r.render(&s).unwrap();
    assert_eq!(a.rgb, r.render(&s).unwrap().rgb);
    // The plane has depth everywhere it covers and instance 0.
    let covered = a.depth_m.iter().filter(|&&d| d > 0.0).count();
    assert!(covered > 100_000, "{covered}");
    assert!(a.instance.iter().all(|&i| i == 0));
    // The checker's two colours show: red-heavy and blue-heavy pixels near the camera.
    let w = 640usize;
    let (mut red, mut blue) = (0, 0);
    for y in 400..480 {
        for x in 0..w {
            let p = &a.rgb[(y * w + x) * 3..][..3];
            red += (p[0] as i32 > p[2] as i32 + 40) as u32;
            blue += (p[2] as i32 > p[0] as i32 + 40) as u32;
        }
    }
    assert!(red > 5000 && blue > 5000, "red {red} blue {blue}");
    // A checker square of 2.5 mm is smaller than a pixel's footprint in the top rows (about
    // 6 mm): the mip levels average the squares there, so neighbouring pixels differ far
    // less than the checker's contrast (nearest texel of level 0 would jump at random).
    let fine = SurfaceTexture {
        scale_m: 0.02,
        ..tex.clone()
    };
    let f = r
        .render(&textured_floor_scene(Some(fine), [1.0; 3]))
        .unwrap();
    let top: Vec<&[u8]> = f.rgb[..w * 3 * 40].chunks_exact(3).collect();
    let jumps = top
        .windows(2)
        .map(|p| (p[0][0] as i32 - p[1][0] as i32).abs())
        .filter(|&d| d > 60)
        .count();
    let hit_top = f.depth_m[..w * 40].iter().filter(|&&d| d > 0.0).count();
    assert!(
        hit_top > 1000 && jumps < hit_top / 100,
        "{jumps} jumps in {hit_top} px"
    );
    // The colour multiplies: half the colour, darker everywhere the plane is.
    let dark = r
        .render(&textured_floor_scene(Some(tex.clone()), [0.5; 3]))
        .unwrap();
    let sum = |f: &synthgen_core::RenderedFrame| f.rgb.iter().map(|&v| v as u64).sum::<u64>();
    assert!(sum(&dark) < sum(&a) * 8 / 10);
    // Without its images the renderer refuses the frame.
    match plain.render(&s) {
        Err(Error::NoSurfaceTextures { what: "ground" }) => {}
        other => panic!("{:?}", other.map(|_| ())),
    }
    // A texture-less ground is the procedural one, unchanged.
    let p = textured_floor_scene(None, [1.0; 3]);
    assert_eq!(plain.render(&p).unwrap().rgb, r.render(&p).unwrap().rgb);
}

#[test]
fn shipped_textures_equal_the_generator_output() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../textures");
    for (folder, name) in TEXTURES {
        let path = root.join(folder).join(format!("{name}.png"));
        let img = image::open(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .to_rgb8();
        let want = texture(name).unwrap();
        assert_eq!(
            (img.width(), img.height()),
            (256, 256),
            "{}",
            path.display()
        );
        assert!(
            img.as_raw() == &want.rgb,
            "{} differs from the generator: run `cargo run -p synthgen-render --example make_textures -- textures`",
            path.display()
        );
        let size = std::fs::metadata(&path).unwrap().len();
        assert!(size < 100_000, "{} is {size} bytes", path.display());
    }
}
