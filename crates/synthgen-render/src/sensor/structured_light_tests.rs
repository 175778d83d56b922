//! The structured-light model's physics: quantization step vs depth, shadow side vs the sign
//! of the baseline, noise vs the formula, edge holes, fattening, determinism.

use synthgen_core::scene::StructuredLightSpec;
use synthgen_core::Intrinsics;

use super::apply_structured_light;

/// Everything off: only what a test turns on changes the depth.
fn quiet() -> StructuredLightSpec {
    StructuredLightSpec {
        subpixel: 0.0,
        disparity_sigma_px: 0.0,
        lateral_sigma_px: 0.0,
        shadow: false,
        edge_dropout: 0.0,
        edge_mix: 0.0,
        fattening_px: 0.0,
        grazing_deg: 180.0,
        dark_dropout: 0.0,
        bright_dropout: 0.0,
        dropout: 0.0,
        hole_size_px: 1.0,
        depth_unit_m: 0.0,
        ..StructuredLightSpec::default()
    }
}

fn camera(w: u32, h: u32, f: f64) -> Intrinsics {
    Intrinsics {
        width: w,
        height: h,
        fx: f,
        fy: f,
        cx: (w as f64 - 1.0) / 2.0,
        cy: (h as f64 - 1.0) / 2.0,
    }
}

#[test]
fn quantization_step_grows_with_depth_squared() {
    // A slow ramp of depth around z: the output takes values on the disparity grid, whose
    // steps in depth are z² · subpixel / (f |b|).
    let k = camera(2000, 1, 600.0);
    let spec = StructuredLightSpec {
        subpixel: 0.125,
        baseline_m: -0.075,
        ..quiet()
    };
    for z in [0.6f64, 1.0, 2.0, 3.5] {
        let want = spec.depth_step_m(z, k.fx);
        let mut d: Vec<f32> = (0..2000)
            .map(|i| (z + (i as f64 / 2000.0 - 0.5) * 8.0 * want) as f32)
            .collect();
        apply_structured_light(&spec, &k, &[], &mut d, 1);
        let mut levels: Vec<f32> = d.clone();
        levels.dedup();
        assert!(levels.len() >= 7, "z {z}: {} levels", levels.len());
        let steps: Vec<f64> = levels.windows(2).map(|p| f64::from(p[1] - p[0])).collect();
        let mean = steps.iter().sum::<f64>() / steps.len() as f64;
        assert!(
            (mean / want - 1.0).abs() < 0.05,
            "z {z} m: step {mean} m, z² q / (f b) = {want} m"
        );
    }
    // At 1 m with f 600 px, b 7.5 cm, 1/8 px: 2.8 mm (PrimeSense's published ~3 mm).
    assert!((spec.depth_step_m(1.0, 600.0) - 0.002_78).abs() < 1e-4);
}

#[test]
fn shadow_side_follows_the_baseline_sign() {
    // A wall at 2 m, a box at 1 m over columns 300..400, f 500 px: f |b| (1/1 − 1/2) = 18.75
    // px of shadow beside the box.
    let (w, h) = (640usize, 4usize);
    let k = camera(w as u32, h as u32, 500.0);
    let mut wall = vec![2.0f32; w * h];
    for y in 0..h {
        for x in 300..400 {
            wall[y * w + x] = 1.0;
        }
    }
    let holes = |b: f64| {
        let spec = StructuredLightSpec {
            baseline_m: b,
            shadow: true,
            ..quiet()
        };
        let mut d = wall.clone();
        apply_structured_light(&spec, &k, &[], &mut d, 3);
        let row = &d[w..2 * w];
        (0..w).filter(|&x| row[x] == 0.0).collect::<Vec<_>>()
    };
    let right_projector = holes(0.075);
    let left_projector = holes(-0.075);
    assert_eq!(
        right_projector,
        (282..300).collect::<Vec<_>>(),
        "b > 0 → shadow left"
    );
    assert_eq!(
        left_projector,
        (400..418).collect::<Vec<_>>(),
        "b < 0 → shadow right"
    );
}

#[test]
fn noise_matches_the_formula_on_a_flat_wall() {
    let k = camera(640, 480, 570.0);
    let spec = StructuredLightSpec {
        disparity_sigma_px: 0.1,
        ..quiet()
    };
    for z in [0.8f64, 1.5, 3.0] {
        let mut d = vec![z as f32; 640 * 480];
        apply_structured_light(&spec, &k, &[], &mut d, 11);
        let n = d.len() as f64;
        let mean = d.iter().map(|&v| f64::from(v)).sum::<f64>() / n;
        let sd = (d
            .iter()
            .map(|&v| (f64::from(v) - mean).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let want = spec.sigma_m(z, 0.0, k.fx);
        assert!(
            (sd / want - 1.0).abs() < 0.05,
            "z {z}: sd {sd}, formula {want}"
        );
        assert!((mean - z).abs() < 0.05 * want + 1e-5, "z {z}: mean {mean}");
    }
}

#[test]
fn holes_concentrate_at_depth_edges() {
    let (w, h) = (200usize, 200usize);
    let k = camera(w as u32, h as u32, 500.0);
    let spec = StructuredLightSpec {
        edge_dropout: 0.5,
        edge_width_px: 2.0,
        ..quiet()
    };
    let mut d = vec![2.0f32; w * h];
    for y in 50..150 {
        for x in 50..150 {
            d[y * w + x] = 1.0;
        }
    }
    let clean = d.clone();
    apply_structured_light(&spec, &k, &[], &mut d, 5);
    let rate = |pick: &dyn Fn(usize, usize) -> bool| {
        let (mut n, mut holes) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                if pick(x, y) {
                    n += 1;
                    holes += usize::from(d[y * w + x] == 0.0);
                }
            }
        }
        holes as f64 / n as f64
    };
    // The box's own edge column (d = 0) and the column next to it (d = 1): 0.5 and 0.5·e^-½.
    let at_edge = rate(&|x, y| x == 50 && (60..140).contains(&y));
    let one_in = rate(&|x, y| x == 51 && (60..140).contains(&y));
    let interior = rate(&|x, y| (80..120).contains(&x) && (80..120).contains(&y));
    assert!((at_edge - 0.5).abs() < 0.15, "{at_edge}");
    assert!((one_in - 0.5 * (-0.5f64).exp()).abs() < 0.15, "{one_in}");
    assert!(interior < 0.01, "{interior}");
    // Readings that survive are the clean depth (no noise configured).
    assert!(d.iter().zip(&clean).all(|(a, b)| *a == 0.0 || a == b));
}

#[test]
fn fattening_spreads_the_closer_surface_along_rows() {
    let (w, h) = (100usize, 3usize);
    let k = camera(w as u32, h as u32, 500.0);
    let spec = StructuredLightSpec {
        fattening_px: 2.0,
        ..quiet()
    };
    let mut d = vec![2.0f32; w * h];
    for y in 0..h {
        for x in 40..60 {
            d[y * w + x] = 1.0;
        }
    }
    apply_structured_light(&spec, &k, &[], &mut d, 2);
    let row = &d[w..2 * w];
    assert_eq!(
        &row[38..62],
        &[1.0f32; 24][..],
        "two pixels each side read the box"
    );
    assert_eq!(row[37], 2.0);
    assert_eq!(row[62], 2.0);
}

#[test]
fn dark_and_bright_surfaces_lose_readings() {
    let k = camera(100, 100, 500.0);
    let spec = StructuredLightSpec {
        dark_luminance: 0.2,
        dark_dropout: 0.6,
        bright_luminance: 0.8,
        bright_dropout: 0.4,
        ..quiet()
    };
    let rate = |grey: u8| {
        let mut d = vec![1.0f32; 100 * 100];
        let rgb = vec![grey; 100 * 100 * 3];
        apply_structured_light(&spec, &k, &rgb, &mut d, 4);
        d.iter().filter(|&&v| v == 0.0).count() as f64 / d.len() as f64
    };
    assert!((rate(0) - 0.6).abs() < 0.03, "{}", rate(0));
    assert!(rate(128) < 1e-9);
    assert!((rate(255) - 0.4).abs() < 0.03, "{}", rate(255));
}

#[test]
fn same_seed_same_depth() {
    let k = camera(320, 240, 300.0);
    let wall: Vec<f32> = (0..320 * 240)
        .map(|i| 1.0 + (i % 320) as f32 * 1e-3)
        .collect();
    let run = |seed| {
        let mut d = wall.clone();
        apply_structured_light(&StructuredLightSpec::default(), &k, &[], &mut d, seed);
        d
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}

#[test]
fn shift_displaces_the_depth_image() {
    let (w, h) = (50usize, 2usize);
    let k = camera(w as u32, h as u32, 500.0);
    let mut d = vec![0f32; w * h];
    for y in 0..h {
        for x in 20..30 {
            d[y * w + x] = 1.0;
        }
    }
    let run = |shift: f64| {
        let mut out = d.clone();
        let spec = StructuredLightSpec {
            shift_px: shift,
            ..quiet()
        };
        apply_structured_light(&spec, &k, &[], &mut out, 9);
        (0..w).filter(|&x| out[x] > 0.0).collect::<Vec<_>>()
    };
    assert_eq!(
        run(-2.0),
        (18..28).collect::<Vec<_>>(),
        "negative = to the left"
    );
    assert_eq!(run(3.0), (23..33).collect::<Vec<_>>());
    // Half a pixel: each edge pixel goes either way.
    let half = run(-0.5);
    assert!(
        half.len() >= 9 && half.len() <= 11 && half[0] >= 19,
        "{half:?}"
    );
}

#[test]
fn holes_come_in_blobs_of_the_configured_size() {
    let k = camera(400, 300, 500.0);
    let mean_run = |size: f64| {
        let spec = StructuredLightSpec {
            dropout: 0.1,
            hole_size_px: size,
            ..quiet()
        };
        let mut d = vec![1.0f32; 400 * 300];
        apply_structured_light(&spec, &k, &[], &mut d, 8);
        let holes: Vec<f32> = d
            .iter()
            .map(|&v| if v == 0.0 { 0.0 } else { 1.0 })
            .collect();
        let share = holes.iter().filter(|&&v| v == 0.0).count() as f64 / holes.len() as f64;
        assert!(
            (share - 0.1).abs() < 0.02,
            "size {size}: hole share {share}"
        );
        synthgen_core::depth_features::mean_run_below(&holes, 400, 0.5)
    };
    let (one, four) = (mean_run(1.0), mean_run(4.0));
    assert!(one < 1.3, "{one}");
    assert!(four > 2.0 * one, "blobs of 4 px: mean run {four} vs {one}");
}
