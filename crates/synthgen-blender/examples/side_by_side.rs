//! One sampled frame rendered by both backends, side by side: raster | Cycles | Cycles with
//! the visible masks (from Cycles' depth, bop19 rule) tinted per object. Writes OUT.png.
//!
//! `side_by_side OUT.png SEED SAMPLES MESH...`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use synthgen_blender::{BlenderOptions, BlenderRenderer};
use synthgen_core::sample::SceneObject;
use synthgen_core::{SceneSampler, SceneSpec};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (out, seed, samples) = (&args[0], args[1].parse::<u64>()?, args[2].parse::<u32>()?);
    let models: Vec<_> = args[3..]
        .iter()
        .map(|p| {
            synthgen_assets::load_model(
                p.as_ref(),
                synthgen_assets::Units::Auto,
                &synthgen_core::NoProgress,
            )
            .map(|l| l.model)
        })
        .collect::<Result<_, _>>()?;
    let objects = SceneObject::one_per_model(&models);
    let sampler = SceneSampler::new(SceneSpec::default(), objects, seed)?;
    let scene = sampler.sample(0)?;
    let r = BlenderRenderer::new(
        models,
        vec![],
        BlenderOptions {
            samples,
            ..Default::default()
        },
    )?;
    let (b, raster) = r.render_with_raster(&scene)?;
    let ann = synthgen_core::annotate(&scene.intrinsics, &b.depth_m, &b.alone, 0.015);
    let (w, h) = (b.width as usize, b.height as usize);
    let tints = [
        [255u8, 60, 60],
        [60, 255, 60],
        [60, 120, 255],
        [255, 220, 40],
        [255, 60, 255],
    ];
    let mut overlay = b.rgb.clone();
    for (i, a) in ann.iter().enumerate() {
        let t = tints[i % tints.len()];
        for (p, &m) in a.mask_visib.iter().enumerate() {
            if m > 0 {
                for c in 0..3 {
                    overlay[p * 3 + c] =
                        ((u16::from(overlay[p * 3 + c]) + u16::from(t[c])) / 2) as u8;
                }
            }
        }
    }
    // Half size (2x2 box filter) keeps the PNG small.
    let (hw, hh) = (w / 2, h / 2);
    let mut img = image::RgbImage::new((hw * 3) as u32, hh as u32);
    for (k, src) in [&raster.rgb, &b.rgb, &overlay].iter().enumerate() {
        for y in 0..hh {
            for x in 0..hw {
                let px = std::array::from_fn(|c| {
                    let s: u32 = [(0, 0), (1, 0), (0, 1), (1, 1)]
                        .iter()
                        .map(|(dx, dy)| u32::from(src[((2 * y + dy) * w + 2 * x + dx) * 3 + c]))
                        .sum();
                    ((s + 2) / 4) as u8
                });
                img.put_pixel((k * hw + x) as u32, y as u32, image::Rgb(px));
            }
        }
    }
    img.save(out)?;
    println!("wrote {out}: raster | cycles {samples} samples | cycles + mask_visib");
    Ok(())
}
