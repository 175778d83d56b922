//! What is drawn where nothing is hit: colour, seeded noise, seeded image crops.

use std::sync::Arc;

use synthgen_core::scene::BackgroundKind;
use synthgen_core::{Intrinsics, Texture};
use synthgen_render::{CpuRenderer, Renderer};

use crate::common::*;

fn solid(rgb: [u8; 3], w: u32, h: u32) -> Arc<Texture> {
    Arc::new(Texture {
        width: w,
        height: h,
        rgb: rgb.repeat((w * h) as usize),
        source: format!("<solid {rgb:?}>").into(),
    })
}

const K: Intrinsics = Intrinsics {
    width: 32,
    height: 24,
    fx: 30.0,
    fy: 30.0,
    cx: 15.5,
    cy: 11.5,
};

#[test]
fn color_background_fills_empty_pixels() {
    let r = CpuRenderer::new(vec![], vec![]).unwrap();
    let mut s = scene(K, vec![]);
    s.background.color = [1.0, 0.0, 0.5];
    let f = r.render(&s).unwrap();
    let want = [255, 0, 128];
    assert!(f.rgb.chunks_exact(3).all(|p| p == want));
    assert!(f.depth_m.iter().all(|&d| d == 0.0));
}

#[test]
fn noise_is_seeded_uniform_and_deterministic() {
    let r = CpuRenderer::new(vec![], vec![]).unwrap();
    let mut s = scene(K, vec![]);
    s.background.kind = BackgroundKind::Noise;
    let a = r.render(&s).unwrap();
    assert_eq!(a, r.render(&s).unwrap());
    s.background.seed += 1;
    let b = r.render(&s).unwrap();
    assert_ne!(a.rgb, b.rgb);
    let mean = a.rgb.iter().map(|&v| v as f64).sum::<f64>() / a.rgb.len() as f64;
    assert!((mean - 127.5).abs() < 10.0, "mean {mean}");
}

#[test]
fn images_are_picked_and_cropped_by_seed() {
    let (red, blue) = ([200, 10, 10], [10, 10, 200]);
    let r = CpuRenderer::new(vec![], vec![solid(red, 40, 30), solid(blue, 13, 50)]).unwrap();
    let mut s = scene(K, vec![]);
    s.background.kind = BackgroundKind::Images;
    let mut seen = [false; 2];
    for seed in 0..20 {
        s.background.seed = seed;
        let f = r.render(&s).unwrap();
        let first = [f.rgb[0], f.rgb[1], f.rgb[2]];
        assert!(
            f.rgb.chunks_exact(3).all(|p| p == first),
            "one image per frame"
        );
        seen[0] |= first == red;
        seen[1] |= first == blue;
        assert_eq!(f, r.render(&s).unwrap());
    }
    assert_eq!(seen, [true, true], "both images get picked");

    // A gradient texture: the crop keeps the output's aspect ratio and stays inside it.
    let grad = Arc::new(Texture {
        width: 256,
        height: 64,
        rgb: (0..64 * 256)
            .flat_map(|i| [(i % 256) as u8, (i / 256) as u8, 0])
            .collect(),
        source: "<gradient>".into(),
    });
    let r = CpuRenderer::new(vec![], vec![grad]).unwrap();
    for seed in 0..10 {
        s.background.seed = seed;
        let f = r.render(&s).unwrap();
        let row0: Vec<u8> = f.rgb[..32 * 3].chunks_exact(3).map(|p| p[0]).collect();
        let span = row0.iter().max().unwrap() - row0.iter().min().unwrap();
        // A crop 64 * 32 / 24 = 85 texels wide at most (and half that at least).
        assert!((40..=90).contains(&span), "seed {seed}: span {span}");
    }
}

#[test]
fn renderer_is_shareable_across_threads() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<CpuRenderer>();
}
