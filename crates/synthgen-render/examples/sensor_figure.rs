//! Writes docs/sensor_depth.png: one frame of the robot_chest_d455 preset (the driller and
//! two Linemod-sized boxes on a table), its clean depth, the D455 model's depth and the ToF
//! model's depth, colour-mapped over the objects' depth range (black = 0, invalid).
//!
//! `cargo run -p synthgen-render --example sensor_figure -- docs/sensor_depth.png 5`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::Path;

use synthgen_assets::Units;
use synthgen_core::glam::Vec3;
use synthgen_core::sample::SceneObject;
use synthgen_core::scene::DepthModel;
use synthgen_core::{Model, NoProgress, SceneSampler, SceneSpec};
use synthgen_render::{CpuRenderer, Renderer, SensorModel};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let out = args.get(1).map_or("docs/sensor_depth.png", String::as_str);
    let frame: u64 = args.get(2).map_or(Ok(0), |s| s.parse())?;
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let spec = SceneSpec::from_toml_file(&root.join("scenes/robot_chest_d455.toml"))?;
    let driller = synthgen_assets::load_model(
        &root.join("datasets/meshes/driller.ply"),
        Units::Auto,
        &NoProgress,
    )?
    .model;
    let models = vec![
        driller,
        Model::cuboid("box", Vec3::new(0.1, 0.07, 0.12)),
        Model::cuboid("flat", Vec3::new(0.16, 0.12, 0.03)),
    ];
    let objects = SceneObject::one_per_model(&models);
    let seed = 3;
    let sampler = SceneSampler::new(spec.clone(), objects, seed)?;
    let renderer = CpuRenderer::new(models, vec![])?;
    let scene = sampler.sample(frame)?;
    let clean = renderer.render(&scene)?;
    let mut panels = vec![clean.depth_m.clone()];
    for model in [DepthModel::D455, DepthModel::Tof] {
        let mut s = spec.sensor.clone();
        s.depth = model;
        s.rgb.enabled = false;
        let mut f = clean.clone();
        SensorModel::new(s, seed)?.apply(&scene, &mut f);
        panels.push(f.depth_m);
    }
    let (w, h) = (clean.width as usize, clean.height as usize);
    // The colour range spans the objects, so that their noise is visible.
    let objs = clean
        .depth_m
        .iter()
        .zip(&clean.instance)
        .filter(|(_, i)| **i > 0)
        .map(|(d, _)| *d);
    let lo = objs.clone().fold(f32::INFINITY, f32::min) - 0.03;
    let hi = objs.fold(0.0f32, f32::max) + 0.1;
    let gap = 8;
    let mut img = image::RgbImage::from_pixel(
        (w * 4 + gap * 3) as u32,
        h as u32,
        image::Rgb([255, 255, 255]),
    );
    for (x, y, p) in image::RgbImage::from_raw(w as u32, h as u32, clean.rgb.clone())
        .unwrap()
        .enumerate_pixels()
    {
        img.put_pixel(x, y, *p);
    }
    for (k, d) in panels.iter().enumerate() {
        let x0 = (k + 1) * (w + gap);
        for y in 0..h {
            for x in 0..w {
                img.put_pixel((x0 + x) as u32, y as u32, colormap(d[y * w + x], lo, hi));
            }
        }
    }
    // Half size keeps the PNG small; nearest keeps holes visible.
    let img = image::imageops::resize(
        &img,
        img.width() / 2,
        img.height() / 2,
        image::imageops::FilterType::Nearest,
    );
    img.save(out)?;
    println!("wrote {out}: rgb | clean depth | d455 | tof, {lo:.2}..{hi:.2} m");
    Ok(())
}

/// Turbo-like ramp from blue (near) to red (far); 0 (invalid) is black.
fn colormap(z: f32, lo: f32, hi: f32) -> image::Rgb<u8> {
    if z <= 0.0 {
        return image::Rgb([0, 0, 0]);
    }
    let t = ((z - lo) / (hi - lo)).clamp(0.0, 1.0);
    let r = (1.5 - (4.0 * t - 3.0).abs()).clamp(0.0, 1.0);
    let g = (1.5 - (4.0 * t - 2.0).abs()).clamp(0.0, 1.0);
    let b = (1.5 - (4.0 * t - 1.0).abs()).clamp(0.0, 1.0);
    image::Rgb([(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8])
}
