//! Quick timing without criterion: renders the benchmark scenes repeatedly on one thread and
//! prints the median and minimum time per frame (minimum = least disturbed by other load),
//! and the mean over scenes of each scene's fastest round (robust to load from other
//! processes, which only ever adds time).
//!
//! `cargo run --release -p synthgen-render --example frame_timing [rounds]`

mod common;

use std::time::Instant;

use synthgen_core::{annotate, RenderedFrame, SceneSampler, SceneSpec};
use synthgen_render::CpuRenderer;

fn main() -> anyhow::Result<()> {
    let rounds = common::rounds_arg()?;
    let (models, objects) = common::lmo_models()?;
    let sampler = SceneSampler::new(SceneSpec::default(), objects, 2024)?;
    let scenes = (0..32)
        .map(|i| sampler.sample(i))
        .collect::<Result<Vec<_>, _>>()?;
    let r = CpuRenderer::new(models, vec![])?;
    let mut out = RenderedFrame::default();
    let (mut render_ms, mut ann_ms) = (Vec::new(), Vec::new());
    for _ in 0..rounds {
        for s in &scenes {
            let t0 = Instant::now();
            r.render_into(s, &mut out)?;
            let t1 = Instant::now();
            std::hint::black_box(annotate(&s.intrinsics, &out.depth_m, &out.alone, 0.015));
            let t2 = Instant::now();
            render_ms.push((t1 - t0).as_secs_f64() * 1e3);
            ann_ms.push((t2 - t1).as_secs_f64() * 1e3);
        }
    }
    let (mut obj_px, mut ground_px, mut bg_px, mut alone_px) = (0usize, 0usize, 0usize, 0usize);
    for s in &scenes {
        r.render_into(s, &mut out)?;
        for (&d, &i) in out.depth_m.iter().zip(&out.instance) {
            match (d > 0.0, i) {
                (false, _) => bg_px += 1,
                (true, 0) => ground_px += 1,
                _ => obj_px += 1,
            }
        }
        alone_px += out.alone.iter().map(|a| a.depth_m.len()).sum::<usize>();
    }
    let n = scenes.len();
    println!(
        "per frame: {} object px, {} ground px, {} background px, {} alone window px",
        obj_px / n,
        ground_px / n,
        bg_px / n,
        alone_px / n
    );
    for (name, v) in [("render", &render_ms), ("annotate", &ann_ms)] {
        let best = (0..n)
            .map(|i| {
                v.iter()
                    .skip(i)
                    .step_by(n)
                    .copied()
                    .fold(f64::MAX, f64::min)
            })
            .sum::<f64>()
            / n as f64;
        println!("{name:>9}: mean of per-scene best {best:.3} ms");
    }
    for (name, mut v) in [("render", render_ms), ("annotate", ann_ms)] {
        v.sort_by(|a, b| a.total_cmp(b));
        println!(
            "{name:>9}: median {:.3} ms, min {:.3} ms, p90 {:.3} ms ({} frames)",
            v[v.len() / 2],
            v[0],
            v[v.len() * 9 / 10],
            v.len()
        );
    }
    Ok(())
}
