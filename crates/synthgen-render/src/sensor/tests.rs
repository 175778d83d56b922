use rand::SeedableRng;
use synthgen_core::scene::{D455Spec, TofSpec};
use synthgen_core::Intrinsics;

use super::*;

fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// Mean and standard deviation of the valid pixels' error against `z`, over columns `x0..`.
fn error_stats(depth: &[f32], w: usize, x0: usize, z: f64) -> (f64, f64, usize) {
    let errs: Vec<f64> = depth
        .iter()
        .enumerate()
        .filter(|(i, d)| **d > 0.0 && i % w >= x0)
        .map(|(_, d)| f64::from(*d) - z)
        .collect();
    let n = errs.len() as f64;
    let mean = errs.iter().sum::<f64>() / n;
    let var = errs.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt(), errs.len())
}

#[test]
fn d455_std_over_a_flat_wall_matches_the_formula() {
    let k = Intrinsics::D455_640;
    let (w, h) = (k.width as usize, k.height as usize);
    let spec = D455Spec::default();
    for z in [0.8, 1.5, 3.0, 5.0] {
        let mut depth = vec![z as f32; w * h];
        apply_d455(&spec, k.fx, w, h, &mut depth, &mut rng(7));
        let (mean, std, n) = error_stats(&depth, w, 0, z);
        let want = z * z * spec.subpixel_sigma_px / (k.fx * spec.baseline_m);
        assert!(n > w * h / 2, "only {n} valid pixels at {z} m");
        assert!(
            (std / want - 1.0).abs() < 0.10,
            "z {z} m: std {std} m, formula {want} m"
        );
        assert!(mean.abs() < want * 0.05 + 1e-4, "z {z} m: bias {mean}");
        // Quantized to the 1 mm depth unit.
        assert!(depth
            .iter()
            .all(|d| ((f64::from(*d) * 1000.0) - (f64::from(*d) * 1000.0).round()).abs() < 1e-3));
    }
}

#[test]
fn d455_out_of_range_is_zero() {
    let k = Intrinsics::D455_640;
    let (w, h) = (k.width as usize, k.height as usize);
    let spec = D455Spec::default();
    for z in [0.3f32, 0.55, 6.5, 9.0] {
        let mut depth = vec![z; w * h];
        apply_d455(&spec, k.fx, w, h, &mut depth, &mut rng(1));
        assert!(depth.iter().all(|&d| d == 0.0), "wall at {z} m kept depth");
    }
    // Near the limits, every kept value lies inside the range.
    for z in [0.6f32, 5.99] {
        let mut depth = vec![z; w * h];
        apply_d455(&spec, k.fx, w, h, &mut depth, &mut rng(1));
        assert!(depth.iter().all(|&d| d == 0.0 || (0.6..=6.0).contains(&d)));
        assert!(depth.iter().any(|&d| d > 0.0));
    }
}

#[test]
fn d455_stereo_shadow_left_of_a_box_and_left_band() {
    // A wall at 2 m with a box at 1 m over columns 300..400.
    let (w, h) = (640usize, 4usize);
    let fx = 400.0;
    let spec = D455Spec {
        dropout: 0.0,
        edge_dropout: 0.0,
        subpixel_sigma_px: 0.0,
        ..D455Spec::default()
    };
    let mut depth = vec![2.0f32; w * h];
    for y in 0..h {
        for x in 300..400 {
            depth[y * w + x] = 1.0;
        }
    }
    let clean = depth.clone();
    apply_d455(&spec, fx, w, h, &mut depth, &mut rng(0));
    let fb = fx * spec.baseline_m; // 38 px·m
                                   // Disparity 38 px at 1 m, 19 px at 2 m: the wall is hidden over 19 columns left of the box.
    let row: Vec<f32> = depth[w..2 * w].to_vec();
    for x in 0..w {
        let d_wall = fb / 2.0;
        let want_zero = (x as f64) < d_wall - 0.5 || ((281..300).contains(&x));
        assert_eq!(row[x] == 0.0, want_zero, "column {x}: {}", row[x]);
        if !want_zero {
            assert_eq!(row[x], clean[w + x]);
        }
    }
}

#[test]
fn d455_same_seed_same_noise() {
    let k = Intrinsics::D455_640;
    let (w, h) = (k.width as usize, k.height as usize);
    let wall: Vec<f32> = (0..w * h).map(|i| 1.0 + (i % w) as f32 * 1e-3).collect();
    let run = |seed| {
        let mut d = wall.clone();
        apply_d455(&D455Spec::default(), k.fx, w, h, &mut d, &mut rng(seed));
        d
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}

#[test]
fn d455_discontinuities_get_holes() {
    let (w, h) = (64usize, 64usize);
    let spec = D455Spec {
        edge_dropout: 1.0,
        dropout: 0.0,
        stereo_shadow: false,
        ..D455Spec::default()
    };
    let mut depth = vec![2.0f32; w * h];
    for y in 20..40 {
        for x in 20..40 {
            depth[y * w + x] = 1.0;
        }
    }
    apply_d455(&spec, 400.0, w, h, &mut depth, &mut rng(0));
    // Both sides of the step are holes, the inside of the box is not.
    assert_eq!(depth[30 * w + 19], 0.0);
    assert_eq!(depth[30 * w + 20], 0.0);
    assert_eq!(depth[19 * w + 30], 0.0);
    assert!(depth[30 * w + 30] > 0.0 && depth[30 * w + 10] > 0.0);
}

#[test]
fn tof_std_over_a_flat_wall_matches_the_formula() {
    let k = Intrinsics::LINEMOD;
    let (w, h) = (k.width as usize, k.height as usize);
    let spec = TofSpec {
        lateral_jitter: 0.0,
        depth_unit_m: 0.0,
        ..TofSpec::default()
    };
    for z in [0.6, 1.2, 2.5, 3.5] {
        let mut depth = vec![z as f32; w * h];
        apply_tof(&spec, &k, &mut depth, &mut rng(11));
        // Off-axis pixels see the wall at up to ~30°, where the angle term adds < 1e-5 m.
        let (mean, std, n) = error_stats(&depth, w, 0, z);
        let want = tof_sigma_m(&spec, z, 0.0);
        assert!(n > w * h * 9 / 10);
        assert!(
            (std / want - 1.0).abs() < 0.10,
            "z {z} m: std {std} m, formula {want} m"
        );
        assert!(mean.abs() < want * 0.05);
    }
    for z in [0.3f32, 4.5] {
        let mut depth = vec![z; w * h];
        apply_tof(&spec, &k, &mut depth, &mut rng(1));
        assert!(depth.iter().all(|&d| d == 0.0), "wall at {z} m kept depth");
    }
}

#[test]
fn tof_noise_grows_with_incidence_and_grazing_is_invalid() {
    let k = Intrinsics::LINEMOD;
    let (w, h) = (k.width as usize, k.height as usize);
    let spec = TofSpec {
        lateral_jitter: 0.0,
        depth_unit_m: 0.0,
        ..TofSpec::default()
    };
    // A plane through (0, 0, 1.5) tilted about the camera's y axis by `deg`: z = 1.5 + x tanα
    // in camera coordinates, i.e. per pixel z = 1.5 / (1 − tanα (u − cx) / fx).
    let plane = |deg: f64| -> Vec<f32> {
        let t = deg.to_radians().tan();
        (0..w * h)
            .map(|i| {
                let u = (i % w) as f64;
                (1.5 / (1.0 - t * (u - k.cx) / k.fx)) as f32
            })
            .collect()
    };
    let central_std = |d: &[f32], clean: &[f32]| {
        let errs: Vec<f64> = (0..w * h)
            .filter(|i| (i % w).abs_diff(w / 2) < 20 && d[*i] > 0.0)
            .map(|i| f64::from(d[i] - clean[i]))
            .collect();
        let m = errs.iter().sum::<f64>() / errs.len() as f64;
        (errs.iter().map(|e| (e - m).powi(2)).sum::<f64>() / errs.len() as f64).sqrt()
    };
    let clean0 = plane(0.0);
    let clean70 = plane(70.0);
    let mut d0 = clean0.clone();
    let mut d70 = clean70.clone();
    apply_tof(&spec, &k, &mut d0, &mut rng(2));
    apply_tof(&spec, &k, &mut d70, &mut rng(2));
    let s0 = central_std(&d0, &clean0);
    let s70 = central_std(&d70, &clean70);
    let want70 = tof_sigma_m(&spec, 1.5, 70f64.to_radians());
    assert!(s70 > s0 * 1.1, "{s0} vs {s70}");
    assert!(
        (s70 / want70 - 1.0).abs() < 0.15,
        "{s70} vs formula {want70}"
    );
    let mut d85 = plane(85.0);
    apply_tof(&spec, &k, &mut d85, &mut rng(2));
    assert!(d85[240 * w + 320] == 0.0);
}

#[test]
fn sensor_model_touches_only_rgb_and_depth_and_is_deterministic() {
    use synthgen_core::glam::DMat3;
    use synthgen_core::sample::{BackgroundSample, ObjectInstance};
    use synthgen_core::scene::BackgroundKind;
    use synthgen_core::{FrameScene, Model, Pose};

    use crate::{CpuRenderer, Renderer};

    let renderer = CpuRenderer::new(
        vec![Model::cuboid("box", synthgen_core::glam::Vec3::splat(0.2))],
        vec![],
    )
    .unwrap();
    let scene = FrameScene {
        frame_index: 3,
        intrinsics: Intrinsics::D455_640,
        world_from_cam: Pose::IDENTITY,
        objects: vec![ObjectInstance {
            model_index: 0,
            obj_id: 1,
            cam_from_obj: Pose::new(
                DMat3::from_rotation_y(0.4),
                synthgen_core::glam::DVec3::new(0.0, 0.0, 1.0),
            ),
            brightness: 1.0,
            specular: 0.2,
            shininess: 32.0,
            tint: [1.0; 3],
            hue_deg: 0.0,
            metallic: 0.0,
        }],
        distractors: vec![],
        lights: vec![],
        ambient: 0.8,
        shadows: false,
        ambient_occlusion: 0.0,
        shading: Default::default(),
        environment: None,
        ground: None,
        walls: vec![],
        background: BackgroundSample {
            kind: BackgroundKind::Noise,
            color: [0.0; 3],
            seed: 1,
        },
    };
    let clean = renderer.render(&scene).unwrap();
    let mut spec = SensorSpec {
        depth: DepthModel::D455,
        ..SensorSpec::default()
    };
    spec.rgb.enabled = true;
    let model = SensorModel::new(spec.clone(), 9).unwrap();
    let mut a = clean.clone();
    model.apply(&scene, &mut a);
    let mut b = clean.clone();
    model.apply(&scene, &mut b);
    assert_eq!(a, b);
    assert_eq!(a.instance, clean.instance);
    assert_eq!(a.alone, clean.alone);
    assert_ne!(a.depth_m, clean.depth_m);
    assert_ne!(a.rgb, clean.rgb);
    let mut c = clean.clone();
    SensorModel::new(spec, 10).unwrap().apply(&scene, &mut c);
    assert_ne!(a.depth_m, c.depth_m);
}

#[test]
fn quantize_rounds_as_round_does() {
    for unit in [0.001, 0.0001, 0.00025] {
        for i in -20_000..20_000 {
            let z = f64::from(i) * 0.000_037_3;
            assert_eq!(
                super::quantize(z, unit),
                (z / unit).round() * unit,
                "z {z} unit {unit}"
            );
        }
        // Exact halves go away from zero, as `round` does.
        assert_eq!(super::quantize(2.5 * unit, unit), 3.0 * unit);
        assert_eq!(super::quantize(-2.5 * unit, unit), -3.0 * unit);
    }
    assert_eq!(super::quantize(0.123, 0.0), 0.123);
}

#[test]
fn normal_draws_have_mean_0_variance_1_and_normal_tails() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut n = super::Normal::new();
    let v: Vec<f64> = (0..200_000).map(|_| n.sample(&mut rng)).collect();
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / v.len() as f64;
    let beyond_2 = v.iter().filter(|x| x.abs() > 2.0).count() as f64 / v.len() as f64;
    assert!(mean.abs() < 0.01, "mean {mean}");
    assert!((var - 1.0).abs() < 0.01, "variance {var}");
    // P(|z| > 2) = 0.0455 for a standard normal.
    assert!((beyond_2 - 0.0455).abs() < 0.002, "{beyond_2}");
}
