//! Seconds per frame of Cycles (this backend) next to the raster backend on the same sampled
//! frames, and the process RSS over a run of frames. Run by benches/blender_vs_raster.sh:
//!
//! `blender_bench --samples 16 --frames 10 --size 640x480 MESH...`
//! `blender_bench --samples 4 --frames 500 --size 160x120 --rss-every 25 MESH...`
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;
use std::time::Instant;

use synthgen_blender::{BlenderOptions, BlenderRenderer};
use synthgen_core::sample::SceneObject;
use synthgen_core::{SceneSampler, SceneSpec};
use synthgen_render::{CpuRenderer, Renderer};

fn rss_mib() -> f64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    let pages: f64 = statm
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.0);
    pages * 4096.0 / (1024.0 * 1024.0)
}

/// CPU seconds of this process, all threads (utime + stime, 100 ticks/s on Linux).
fn cpu_s() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<f64> = after
        .split_whitespace()
        .filter_map(|v| v.parse().ok())
        .collect();
    // Fields 14 and 15 of stat; after the ")" they are the 12th and 13th (the state is not a number).
    f.get(10).copied().unwrap_or(0.0) / 100.0 + f.get(11).copied().unwrap_or(0.0) / 100.0
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let (mut samples, mut frames, mut size, mut rss_every) = (16u32, 10u64, (640u32, 480u32), 0u64);
    let mut meshes: Vec<PathBuf> = Vec::new();
    while let Some(a) = args.next() {
        match a.as_str() {
            "--samples" => samples = args.next().unwrap().parse()?,
            "--frames" => frames = args.next().unwrap().parse()?,
            "--rss-every" => rss_every = args.next().unwrap().parse()?,
            "--size" => {
                let s = args.next().unwrap();
                let (w, h) = s.split_once('x').unwrap();
                size = (w.parse()?, h.parse()?);
            }
            _ => meshes.push(a.into()),
        }
    }
    let models: Vec<_> = meshes
        .iter()
        .map(|p| {
            synthgen_assets::load_model(p, synthgen_assets::Units::Auto, &synthgen_core::NoProgress)
                .map(|l| l.model)
        })
        .collect::<Result<_, _>>()?;
    let mut spec = SceneSpec::default();
    // The Linemod camera scaled to the size asked (fx != fy kept).
    let k = synthgen_core::Intrinsics::LINEMOD;
    let s = f64::from(size.0) / 640.0;
    spec.camera.width = Some(size.0);
    spec.camera.height = Some(size.1);
    spec.camera.fx = Some(k.fx * s);
    spec.camera.fy = Some(k.fy * s);
    spec.camera.cx = Some((k.cx + 0.5) * s - 0.5);
    spec.camera.cy = Some((k.cy + 0.5) * s - 0.5);
    let objects = SceneObject::one_per_model(&models);
    let sampler = SceneSampler::new(spec, objects, 0)?;
    let scenes: Vec<_> = (0..frames)
        .map(|i| sampler.sample(i))
        .collect::<Result<_, _>>()?;

    let raster = CpuRenderer::new(models.clone(), vec![])?;
    let mut raster_s = Vec::new();
    let mut raster_cpu = Vec::new();
    for sc in &scenes {
        let (t, c0) = (Instant::now(), cpu_s());
        let f = raster.render(sc)?;
        synthgen_core::annotate(&sc.intrinsics, &f.depth_m, &f.alone, 0.015);
        raster_s.push(t.elapsed().as_secs_f64());
        raster_cpu.push(cpu_s() - c0);
    }

    let rss_start = rss_mib();
    let t = Instant::now();
    let blender = BlenderRenderer::new(
        models,
        vec![],
        BlenderOptions {
            samples,
            ..Default::default()
        },
    )?;
    let startup_s = t.elapsed().as_secs_f64();
    let mut cycles_s = Vec::new();
    let mut cycles_cpu = Vec::new();
    let mut rss = Vec::new();
    for (i, sc) in scenes.iter().enumerate() {
        let (t, c0) = (Instant::now(), cpu_s());
        let f = blender.render(sc)?;
        synthgen_core::annotate(&sc.intrinsics, &f.depth_m, &f.alone, 0.015);
        cycles_s.push(t.elapsed().as_secs_f64());
        cycles_cpu.push(cpu_s() - c0);
        if rss_every > 0 && ((i as u64).is_multiple_of(rss_every) || i as u64 + 1 == frames) {
            rss.push((i, rss_mib()));
        }
    }
    let (r, c) = (median(raster_s), median(cycles_s));
    let (rc, cc) = (median(raster_cpu), median(cycles_cpu));
    println!(
        "{}x{} {} objects {} frames: raster {:.4} s/frame, cycles {} samples {:.3} s/frame (median; {:.0}x the raster), bpy startup + scene build {:.1} s",
        size.0,
        size.1,
        meshes.len(),
        frames,
        r,
        samples,
        c,
        c / r,
        startup_s
    );
    println!(
        "  cpu seconds per frame (all threads; robust to other load): raster {rc:.3}, cycles {cc:.2} ({:.0}x); load average {}",
        cc / rc.max(0.001),
        std::fs::read_to_string("/proc/loadavg").unwrap_or_default().trim()
    );
    if !rss.is_empty() {
        println!("rss before bpy {rss_start:.0} MiB; after frame (index: MiB):");
        println!(
            "{}",
            rss.iter()
                .map(|(i, m)| format!("{i}: {m:.0}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    Ok(())
}
