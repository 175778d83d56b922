//! The render cost of image-textured ground and walls against the plain procedural ground,
//! on the tabletop preset (five Linemod models, 640x480, one thread, render only: no
//! annotation, no files). Variants share the seed, so their frames have the same objects,
//! camera and lights; they run interleaved, round by round, so machine load hits them alike.
//!
//! `cargo run --release -p synthgen-render --example surface_timing [rounds]`
//! (Linemod models from `SYNTHGEN_LMO_DIR`, default ../shared/data/lmo next to the repo.)

mod common;

use std::path::PathBuf;
use std::time::Instant;

use synthgen_core::{RenderedFrame, SceneSampler, SceneSpec};
use synthgen_render::CpuRenderer;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> anyhow::Result<()> {
    let rounds = common::rounds_arg()?;
    let repo = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let (models, objects) = common::lmo_models()?;
    let preset = SceneSpec::from_toml_file(&repo.join("scenes/tabletop.toml"))?;
    let load = |dir: &Option<PathBuf>| -> anyhow::Result<Vec<_>> {
        Ok(match dir {
            Some(d) => synthgen_assets::load_images_in_dir_strict(d)?,
            None => Vec::new(),
        })
    };
    let ground_tex = load(&preset.ground.texture_dir)?;
    let wall_tex = load(&preset.walls.texture_dir)?;
    let renderer =
        CpuRenderer::new(models, vec![])?.with_surface_textures(&ground_tex, &wall_tex)?;

    // (name, spec): the preset's views, then low views where the walls fill the top.
    let mut variants = Vec::new();
    for (view, elevation) in [
        ("preset views", None),
        ("elevation 5-15°", Some([5.0, 15.0])),
    ] {
        let mut full = preset.clone();
        full.placement.mode = synthgen_core::scene::PlacementMode::Sample;
        if let Some(e) = elevation {
            full.camera_pose.elevation_deg = e;
        }
        let mut plain = full.clone();
        plain.ground.texture_dir = None;
        plain.walls.count = [0, 0];
        let mut ground_only = full.clone();
        ground_only.walls.count = [0, 0];
        variants.push((format!("{view}: plain procedural ground"), plain));
        variants.push((format!("{view}: textured ground"), ground_only));
        variants.push((format!("{view}: textured ground + walls"), full));
    }
    let scenes = variants
        .iter()
        .map(|(_, spec)| {
            let s = SceneSampler::new(spec.clone(), objects.clone(), 7)?;
            (0..32).map(|i| s.sample(i)).collect::<Result<Vec<_>, _>>()
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut out = RenderedFrame::default();
    let mut ms: Vec<Vec<f64>> = vec![Vec::new(); variants.len()];
    for _ in 0..rounds {
        for (v, frames) in scenes.iter().enumerate() {
            for s in frames {
                let t0 = Instant::now();
                renderer.render_into(s, &mut out)?;
                ms[v].push(t0.elapsed().as_secs_f64() * 1e3);
            }
        }
    }
    let meds: Vec<f64> = ms.iter_mut().map(|m| median(m)).collect();
    for (v, (name, _)) in variants.iter().enumerate() {
        let base = meds[v / 3 * 3];
        println!(
            "{name}: median {:.2} ms/frame, min {:.2}, ratio to plain {:.2}",
            meds[v],
            ms[v].first().copied().unwrap_or(0.0),
            meds[v] / base
        );
    }
    Ok(())
}
