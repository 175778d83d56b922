#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Cycles against the raster backend on the same sampled scenes: instance masks, depth,
//! camera convention (including fx != fy) and vertex colours. Needs the `blender` feature and
//! the bpy venv; the build script probes for the venv and the tests are ignored (with the
//! reason) without it, or without the feature. With `SYNTHGEN_REQUIRE_BLENDER=1` (CI) they run
//! and a missing bpy is a failure.

#[cfg(not(feature = "blender"))]
#[test]
#[ignore = "needs `--features blender` (Cycles through bpy; docs/blender.md)"]
fn cycles_backend_tests() {}

#[cfg(feature = "blender")]
mod cycles {

    use std::path::Path;
    use std::sync::OnceLock;

    use synthgen_blender::venv::{bpy_site_packages, resolve_venv};
    use synthgen_blender::{BlenderOptions, BlenderRenderer};
    use synthgen_core::glam::{DMat3, DVec3, Vec3};
    use synthgen_core::sample::SceneObject;
    use synthgen_core::{FrameScene, Intrinsics, Model, ObjectInstance, Pose, RenderedFrame};
    use synthgen_core::{SceneSampler, SceneSpec};

    const DRILLER: usize = 0;
    const BOX: usize = 1;
    const RED_BOX: usize = 2;
    const TEXTURED_BOX: usize = 3;

    /// A box whose vertices are all sRGB (0.8, 0.1, 0.1).
    fn red_box() -> Model {
        let mut m = Model::cuboid("red_box", Vec3::new(0.08, 0.06, 0.04));
        for p in &mut m.primitives {
            p.colors = Some(vec![[0.8, 0.1, 0.1]; p.positions_m.len()]);
        }
        m
    }

    /// A white box whose colour comes only from a 4x4 green texture (as an OBJ's map_Kd loads).
    fn textured_box() -> Model {
        let mut m = Model::cuboid("textured_box", Vec3::new(0.08, 0.06, 0.04));
        let texture = std::sync::Arc::new(synthgen_core::Texture {
            width: 4,
            height: 4,
            rgb: [30u8, 200, 40].repeat(16),
            source: "green.png".into(),
        });
        for p in &mut m.primitives {
            p.colors = None;
            p.uvs = Some(
                (0..p.positions_m.len())
                    .map(|i| synthgen_core::glam::Vec2::new((i % 2) as f32, ((i / 2) % 2) as f32))
                    .collect(),
            );
            p.material.base_color = [1.0, 1.0, 1.0];
            p.material.texture = Some(texture.clone());
        }
        m
    }

    fn driller() -> Model {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../datasets/meshes/driller.ply");
        synthgen_assets::load_model(
            &path,
            synthgen_assets::Units::Auto,
            &synthgen_core::NoProgress,
        )
        .unwrap()
        .model
    }

    /// One renderer (one bpy interpreter) for the whole test binary. The tests that call it are
    /// ignored where the build script found no bpy venv, so here a missing bpy is a failure.
    fn renderer() -> &'static BlenderRenderer {
        static R: OnceLock<BlenderRenderer> = OnceLock::new();
        R.get_or_init(|| {
        let venv = resolve_venv(None).unwrap();
        if let Err(e) = bpy_site_packages(&venv) {
            panic!("{e} (the venv was there when the tests were built, or SYNTHGEN_REQUIRE_BLENDER=1)");
        }
        let models = vec![
            driller(),
            Model::cuboid("box", Vec3::new(0.08, 0.06, 0.04)),
            red_box(),
            textured_box(),
        ];
        let options = BlenderOptions {
            samples: 8,
            threads: 2,
            ..Default::default()
        };
        // Ground images: wood, tiles; wall images: tiles (frames pick by index).
        let tex = |n: &str| std::sync::Arc::new(synthgen_render::procedural::texture(n).unwrap());
        let ground = vec![tex("wood"), tex("tiles")];
        let walls = vec![tex("tiles")];
        BlenderRenderer::with_surfaces(models, vec![], ground, walls, options).unwrap()
    })
    }

    /// The Linemod camera at a quarter of its size (fx != fy kept).
    fn small_linemod() -> Intrinsics {
        let k = Intrinsics::LINEMOD;
        Intrinsics {
            width: 160,
            height: 120,
            fx: k.fx / 4.0,
            fy: k.fy / 4.0,
            cx: (k.cx + 0.5) / 4.0 - 0.5,
            cy: (k.cy + 0.5) / 4.0 - 0.5,
        }
    }

    /// A 96x72 camera with square pixels (fx = fy = 120) centred on the image.
    fn small_square() -> Intrinsics {
        Intrinsics {
            width: 96,
            height: 72,
            fx: 120.0,
            fy: 120.0,
            cx: 48.0,
            cy: 36.0,
        }
    }

    fn sampler(k: Intrinsics, seed: u64) -> SceneSampler {
        let mut spec = SceneSpec::default();
        spec.camera.width = Some(k.width);
        spec.camera.height = Some(k.height);
        spec.camera.fx = Some(k.fx);
        spec.camera.fy = Some(k.fy);
        spec.camera.cx = Some(k.cx);
        spec.camera.cy = Some(k.cy);
        let objects = SceneObject::one_per_model(&[
            driller(),
            Model::cuboid("box", Vec3::new(0.08, 0.06, 0.04)),
        ]);
        SceneSampler::new(spec, objects, seed).unwrap()
    }

    fn iou(a: &[u16], b: &[u16], id: u16) -> (f64, usize) {
        let (mut inter, mut union, mut n) = (0usize, 0usize, 0usize);
        for (&x, &y) in a.iter().zip(b) {
            let (p, q) = (x == id, y == id);
            inter += usize::from(p && q);
            union += usize::from(p || q);
            n += usize::from(q);
        }
        (
            if union == 0 {
                1.0
            } else {
                inter as f64 / union as f64
            },
            n,
        )
    }

    fn median(mut v: Vec<f64>) -> f64 {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    }

    /// Per object of the frame: (IoU of the instance masks, raster pixel count, median |depth
    /// difference| in metres over pixels both give to the object).
    fn agreement(b: &RenderedFrame, r: &RenderedFrame, objects: usize) -> Vec<(f64, usize, f64)> {
        (1..=objects as u16)
            .map(|id| {
                let (iou, n) = iou(&b.instance, &r.instance, id);
                let diffs: Vec<f64> = (0..b.depth_m.len())
                    .filter(|&p| b.instance[p] == id && r.instance[p] == id)
                    .map(|p| f64::from((b.depth_m[p] - r.depth_m[p]).abs()))
                    .collect();
                let med = if diffs.is_empty() { 0.0 } else { median(diffs) };
                (iou, n, med)
            })
            .collect()
    }

    #[test]
    #[cfg_attr(
        not(has_bpy),
        ignore = "needs the bpy venv: scripts/setup-blender.sh (probed when the crate was built)"
    )]
    fn cycles_masks_and_depth_agree_with_the_raster_backend() {
        let renderer = renderer();
        let s = sampler(small_linemod(), 3);
        let mut checked = 0;
        for i in 0..3 {
            let scene = s.sample(i).unwrap();
            let (b, r) = renderer.render_with_raster(&scene).unwrap();
            for (o, (iou, n, med)) in agreement(&b, &r, scene.objects.len())
                .into_iter()
                .enumerate()
            {
                eprintln!(
                    "frame {i} object {o}: {n} px, IoU {iou:.4}, median |dz| {:.3} mm",
                    med * 1e3
                );
                if n < 200 {
                    continue; // too few pixels for the edge fraction to say anything
                }
                checked += 1;
                // The bar for "annotations are right in both backends".
                assert!(iou >= 0.98, "frame {i} object {o}: IoU {iou}");
                assert!(
                    med < 1e-3,
                    "frame {i} object {o}: median depth difference {med} m"
                );
            }
            // The ground: Cycles' Z pass there agrees as well (it covers most of the image).
            let ground: Vec<f64> = (0..b.depth_m.len())
                .filter(|&p| {
                    b.instance[p] == 0
                        && r.instance[p] == 0
                        && b.depth_m[p] > 0.0
                        && r.depth_m[p] > 0.0
                })
                .map(|p| f64::from((b.depth_m[p] - r.depth_m[p]).abs()))
                .collect();
            assert!(ground.len() > 1000);
            assert!(median(ground) < 1e-3);
        }
        assert!(
            checked >= 3,
            "only {checked} objects were big enough to compare"
        );
    }

    /// A box off to the upper left must land there: a flipped axis or a half-pixel slip of
    /// the camera conversion would move it.
    #[test]
    #[cfg_attr(
        not(has_bpy),
        ignore = "needs the bpy venv: scripts/setup-blender.sh (probed when the crate was built)"
    )]
    fn camera_convention_puts_a_box_where_opencv_projects_it() {
        let renderer = renderer();
        let k = Intrinsics {
            width: 128,
            height: 96,
            fx: 160.0,
            fy: 160.0,
            cx: 60.0,
            cy: 44.0,
        };
        let centre = DVec3::new(-0.06, -0.04, 0.6);
        let scene = FrameScene::bare(
            0,
            k,
            vec![ObjectInstance {
                model_index: BOX,
                obj_id: 2,
                cam_from_obj: Pose::new(DMat3::from_rotation_y(0.3), centre),
                brightness: 1.0,
                specular: 0.2,
                shininess: 32.0,
                tint: [1.0; 3],
                hue_deg: 0.0,
                metallic: 0.0,
            }],
        );
        let (b, r) = renderer.render_with_raster(&scene).unwrap();
        let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
        for (p, &id) in b.instance.iter().enumerate() {
            if id == 1 {
                sx += (p % k.width as usize) as f64;
                sy += (p / k.width as usize) as f64;
                n += 1.0;
            }
        }
        assert!(n > 100.0, "the box covers {n} pixels");
        let (u, v) = k.project(centre).unwrap();
        let (mx, my) = (sx / n, sy / n);
        eprintln!("box centroid ({mx:.2}, {my:.2}), projected centre ({u:.2}, {v:.2})");
        // The centroid of a box's silhouette is near its projected centre (perspective moves it
        // by a fraction of a pixel here); the raster backend's silhouette, same scene, must give
        // the same centroid.
        assert!((mx - u).abs() < 1.0 && (my - v).abs() < 1.0);
        let (iou, _) = iou(&b.instance, &r.instance, 1);
        assert!(iou > 0.95, "IoU with the raster silhouette {iou}");
        // Depth at the centre pixel is the box's near face along the optical axis.
        let p = v.round() as usize * k.width as usize + u.round() as usize;
        assert!((b.depth_m[p] - r.depth_m[p]).abs() < 1e-3);
    }

    /// fx != fy (strongly, to make a wrong fy visible): the model's projected vertices land in
    /// Cycles' mask, and the masks agree with the raster backend's.
    #[test]
    #[cfg_attr(
        not(has_bpy),
        ignore = "needs the bpy venv: scripts/setup-blender.sh (probed when the crate was built)"
    )]
    fn anisotropic_focal_lengths_keep_annotations_right() {
        let renderer = renderer();
        let k = Intrinsics {
            width: 120,
            height: 120,
            fx: 110.0,
            fy: 150.0,
            cx: 58.0,
            cy: 61.5,
        };
        let model = driller();
        let s = sampler(k, 11);
        let mut scene = s.sample(0).unwrap();
        scene.objects.retain(|o| o.model_index == DRILLER);
        let (b, r) = renderer.render_with_raster(&scene).unwrap();
        let pose = &scene.objects[0].cam_from_obj;
        let (w, h) = (k.width as i64, k.height as i64);
        let inside_dilated = |u: f64, v: f64| {
            let (x, y) = (u.round() as i64, v.round() as i64);
            (-1..=1).any(|dy| {
                (-1..=1).any(|dx| {
                    let (xx, yy) = (x + dx, y + dy);
                    xx >= 0
                        && yy >= 0
                        && xx < w
                        && yy < h
                        && b.instance[(yy * w + xx) as usize] == 1
                })
            })
        };
        let (mut hit, mut total) = (0, 0);
        for p in model.positions() {
            if let Some((u, v)) = k.project(pose.transform_point(p.as_dvec3())) {
                if u >= 1.0 && v >= 1.0 && u < (w - 2) as f64 && v < (h - 2) as f64 {
                    total += 1;
                    hit += usize::from(inside_dilated(u, v));
                }
            }
        }
        let frac = hit as f64 / total as f64;
        let (iou, n) = iou(&b.instance, &r.instance, 1);
        eprintln!("{hit}/{total} projected vertices in the mask; IoU {iou:.4} over {n} px");
        assert!(total > 1000);
        assert!(
            frac > 0.99,
            "only {frac} of the projected vertices are in the mask"
        );
        assert!(iou > 0.95);
    }

    /// Vertex colours reach Cycles' principled material: a box with red vertices renders red
    /// (a material without them would be grey), like in the raster backend.
    #[test]
    #[cfg_attr(
        not(has_bpy),
        ignore = "needs the bpy venv: scripts/setup-blender.sh (probed when the crate was built)"
    )]
    fn vertex_colours_and_textures_show_in_cycles() {
        let renderer = renderer();
        let s = sampler(small_linemod(), 5);
        let mut scene = s.sample(0).unwrap();
        scene.objects[1].model_index = RED_BOX;
        let (b, r) = renderer.render_with_raster(&scene).unwrap();
        let mean = |f: &RenderedFrame, id: u16| {
            let mut acc = [0.0f64; 3];
            let mut n = 0.0;
            for (p, &i) in f.instance.iter().enumerate() {
                if i == id {
                    for (a, &v) in acc.iter_mut().zip(&f.rgb[p * 3..p * 3 + 3]) {
                        *a += f64::from(v);
                    }
                    n += 1.0;
                }
            }
            assert!(n > 50.0, "object {id} covers {n} px");
            acc.map(|a| a / n)
        };
        for id in [1, 2] {
            eprintln!(
                "object {id} mean sRGB: cycles {:.1?}, raster {:.1?}",
                mean(&b, id),
                mean(&r, id)
            );
        }
        let red = mean(&b, 2);
        // The same pose with the textured box (same size) in the red box's place.
        let mut textured = scene.clone();
        textured.objects[1].model_index = TEXTURED_BOX;
        let (bt, _) = renderer.render_with_raster(&textured).unwrap();
        let green = mean(&bt, 2);
        eprintln!("textured box mean sRGB: cycles {green:.1?}");
        assert!(
            green[1] > 2.0 * green[0] && green[1] > 2.0 * green[2],
            "texture not shown: {green:?}"
        );
        assert!(
            red[0] > 2.0 * red[1] && red[0] > 2.0 * red[2],
            "not red: {red:?}"
        );
        // The driller's own colours: Cycles' mean within 25 levels of the raster's per channel
        // (the lighting differs, the albedo is the same).
        let (db, dr) = (mean(&b, 1), mean(&r, 1));
        assert!(
            (0..3).all(|c| (db[c] - dr[c]).abs() < 25.0),
            "{db:?} vs {dr:?}"
        );
    }

    /// A distractor in front of the target shows in Cycles' depth, hides the target there, and
    /// has no instance id (pass index 0).
    #[test]
    #[cfg_attr(
        not(has_bpy),
        ignore = "needs the bpy venv: scripts/setup-blender.sh (probed when the crate was built)"
    )]
    fn distractors_render_in_cycles_without_an_instance_id() {
        let renderer = renderer();
        let k = small_square();
        let target = ObjectInstance::new(
            BOX,
            1,
            Pose::new(DMat3::IDENTITY, DVec3::new(0.0, 0.0, 0.8)),
        );
        let distractor = ObjectInstance {
            tint: [0.1, 0.8, 0.1],
            ..ObjectInstance::new(
                BOX,
                0,
                Pose::new(DMat3::IDENTITY, DVec3::new(0.03, 0.0, 0.5)),
            )
        };
        let scene = FrameScene {
            distractors: vec![distractor],
            ..FrameScene::bare(0, k, vec![target])
        };
        let (b, r) = renderer.render_with_raster(&scene).unwrap();
        assert!(b.instance.iter().all(|&i| i <= 1));
        let (u, v) = k.project(DVec3::new(0.03, 0.0, 0.5)).unwrap();
        let p = v.round() as usize * k.width as usize + u.round() as usize;
        assert_eq!(
            b.instance[p], 0,
            "the distractor hides the target at its centre"
        );
        assert!(
            (b.depth_m[p] - r.depth_m[p]).abs() < 2e-3,
            "{} vs {}",
            b.depth_m[p],
            r.depth_m[p]
        );
        let (iou, _) = iou(&b.instance, &r.instance, 1);
        assert!(iou > 0.9, "visible target IoU with the raster {iou}");
    }

    /// The sky/ground environment light reaches Cycles as a world: a box seen from above
    /// (its top face towards the world's up) is brighter under a bright sky than under a
    /// bright ground, by about what the raster's hemisphere probe gives.
    #[test]
    #[cfg_attr(
        not(has_bpy),
        ignore = "needs the bpy venv: scripts/setup-blender.sh (probed when the crate was built)"
    )]
    fn the_environment_light_lights_cycles_as_it_lights_the_raster() {
        let renderer = renderer();
        let k = small_square();
        // Below the optical axis (image y down), so the camera sees the top and the front.
        let target = ObjectInstance::new(
            BOX,
            1,
            Pose::new(DMat3::IDENTITY, DVec3::new(0.0, 0.12, 0.5)),
        );
        let lit = |sky: f32, ground: f32| {
            let scene = FrameScene {
                lights: vec![],
                ambient: 0.5,
                environment: Some([[sky; 3], [ground; 3]]),
                // World up is the camera's -y: world z = camera -y.
                world_from_cam: Pose::new(
                    DMat3::from_rotation_x(-std::f64::consts::FRAC_PI_2),
                    DVec3::ZERO,
                ),
                ..FrameScene::bare(0, k, vec![target.clone()])
            };
            let (b, r) = renderer.render_with_raster(&scene).unwrap();
            let mean = |f: &RenderedFrame| {
                let px: Vec<f64> = (0..f.instance.len())
                    .filter(|&p| f.instance[p] == 1)
                    .map(|p| f64::from(f.rgb[p * 3 + 1]))
                    .collect();
                assert!(px.len() > 100, "{} px", px.len());
                px.iter().sum::<f64>() / px.len() as f64
            };
            (mean(&b), mean(&r))
        };
        let (sky_b, sky_r) = lit(1.8, 0.2);
        let (ground_b, ground_r) = lit(0.2, 1.8);
        eprintln!("bright sky: cycles {sky_b:.1}, raster {sky_r:.1}; bright ground: cycles {ground_b:.1}, raster {ground_r:.1}");
        assert!(sky_r > ground_r + 10.0, "raster {sky_r} vs {ground_r}");
        assert!(sky_b > ground_b + 10.0, "cycles {sky_b} vs {ground_b}");
        assert!(
            (sky_b - sky_r).abs() < 30.0,
            "cycles {sky_b} vs raster {sky_r}"
        );
        assert!(
            (ground_b - ground_r).abs() < 30.0,
            "cycles {ground_b} vs raster {ground_r}"
        );
    }

    /// Pearson correlation of two equally long series.
    fn correlation(a: &[f64], b: &[f64]) -> f64 {
        let n = a.len() as f64;
        let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
        let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
        for (x, y) in a.iter().zip(b) {
            sab += (x - ma) * (y - mb);
            saa += (x - ma) * (x - ma);
            sbb += (y - mb) * (y - mb);
        }
        sab / (saa * sbb).sqrt()
    }

    #[test]
    #[cfg_attr(
        not(has_bpy),
        ignore = "needs the bpy venv: scripts/setup-blender.sh (probed when the crate was built)"
    )]
    fn textured_ground_and_walls_match_the_raster_in_cycles() {
        use synthgen_core::sample::{GroundInstance, SurfaceTexture, WallInstance};
        let renderer = renderer();
        let k = small_linemod();
        // A floor seen at 45 degrees (its z axis towards the camera) and a wall facing the
        // camera 0.75 m away over the left half; both tiled with the 4 x 4 tiles texture.
        let ground = GroundInstance {
            cam_from_plane: Pose::new(
                DMat3::from_rotation_x(135f64.to_radians()),
                DVec3::new(0.0, 0.0, 0.7),
            ),
            size_m: 3.0,
            color: [1.0; 3],
            texture_strength: 0.3,
            texture_seed: 1,
            texture: Some(SurfaceTexture {
                image: 1,
                offset: [0.3, 0.6],
                scale_m: 0.3,
            }),
        };
        let wall = WallInstance {
            cam_from_wall: Pose::new(
                DMat3::from_cols(DVec3::X, -DVec3::Y, -DVec3::Z),
                DVec3::new(-0.5, 0.0, 0.75),
            ),
            width_m: 1.0,
            height_m: 2.0,
            color: [0.9, 0.8, 0.7],
            texture: Some(SurfaceTexture {
                image: 0,
                offset: [0.1, 0.2],
                scale_m: 0.5,
            }),
        };
        let scene = FrameScene {
            ground: Some(ground),
            walls: vec![wall],
            ..FrameScene::bare(0, k, vec![])
        };
        let (b, r) = renderer.render_with_raster(&scene).unwrap();
        assert!(b.instance.iter().all(|&i| i == 0));
        let w = k.width as usize;
        let (mut wall_px, mut ground_px) = (Vec::new(), Vec::new());
        let mut depth_diffs = Vec::new();
        for p in 0..b.depth_m.len() {
            if r.depth_m[p] == 0.0 {
                continue;
            }
            depth_diffs.push(f64::from((b.depth_m[p] - r.depth_m[p]).abs()));
            let x = p % w;
            // Away from the wall's edge (x = 0 in the camera frame, column cx).
            let edge = (x as f64 - k.cx).abs() < 3.0;
            if (r.depth_m[p] - 0.75).abs() < 1e-4 && !edge {
                wall_px.push(p);
            } else if !edge {
                ground_px.push(p);
            }
        }
        let med = median(depth_diffs);
        assert!(med < 2e-3, "median depth difference {med} m");
        assert!(
            wall_px.len() > 1500 && ground_px.len() > 1500,
            "{} wall and {} ground pixels",
            wall_px.len(),
            ground_px.len()
        );
        // The same image, tiling, offset and orientation: the luminance of Cycles and the
        // raster correlate pixel for pixel on both planes.
        let lum = |f: &RenderedFrame, p: usize| {
            let c = &f.rgb[p * 3..p * 3 + 3];
            0.3 * f64::from(c[0]) + 0.6 * f64::from(c[1]) + 0.1 * f64::from(c[2])
        };
        for (name, px) in [("wall", &wall_px), ("ground", &ground_px)] {
            let (lb, lr): (Vec<f64>, Vec<f64>) =
                px.iter().map(|&p| (lum(&b, p), lum(&r, p))).unzip();
            let c = correlation(&lb, &lr);
            assert!(c > 0.6, "{name}: luminance correlation {c}");
        }
    }
}
