//! `pipeline_640x480`: the 5-object Linemod scene (`scenes/linemod_like.toml`, LMO objects
//! 1, 5, 6, 8, 9; 640x480, ToF depth noise), 8 frames per iteration through the whole
//! pipeline (sample, render, annotate, sensor model): in memory with `frames()` and
//! `frames_batch`, and written as BOP to a fresh temp folder with `write` (PNG encoding,
//! masks, JSON, manifest) — these with every realism option off (`frames_batch`, `write_bop`:
//! Blinn-Phong, uniform ambient, no shadows, no occlusion; the renderer before them);
//! `frames_batch_shadows`, the same frames with `[lights] shadows = true`; and
//! `frames_batch_realistic`, the scene with the defaults (shadows, ambient occlusion 0.6, GGX
//! shading with metallic 0..0.3, the sky/ground environment light). Throughput is in frames;
//! threads: all cores (set `SYNTHGEN_BENCH_THREADS` to pin them).
//!
//! Models come from `$SYNTHGEN_LMO_DIR/models` (default `../shared/data/lmo/models` next to
//! the workspace).

// A benchmark stops loudly on any setup or render failure, like a test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use synthgen_assets::Units;
use synthgen_core::{NoProgress, SceneSpec};
use synthgen_pipeline::{Format, ObjectSource, PreparedJob, RenderJob, SinkOptions, WriteOptions};

const IDS: [u32; 5] = [1, 5, 6, 8, 9];
const FRAMES: u64 = 8;

/// How much of the renderer's realism a bench job turns on.
#[derive(Clone, Copy, PartialEq)]
enum Look {
    Plain,
    Shadows,
    Realistic,
}

fn job(look: Look) -> PreparedJob {
    let manifest_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let root = std::env::var_os("SYNTHGEN_LMO_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| manifest_dir.join("../../../shared/data/lmo"));
    let objects: Vec<ObjectSource> = IDS
        .iter()
        .map(|id| ObjectSource::new(root.join(format!("models/obj_{id:06}.ply")), Units::Mm))
        .collect();
    let mut spec = SceneSpec::from_toml_file(&manifest_dir.join("../../scenes/linemod_like.toml"))
        .expect("scenes/linemod_like.toml");
    // The scene file sets none of the realism options: Realistic is the defaults; Plain
    // turns every one off (the renderer before them); Shadows is Plain with shadows.
    if look != Look::Realistic {
        spec.lights.shadows = look == Look::Shadows;
        spec.lights.ambient_occlusion = 0.0;
        spec.lights.sky_color = None;
        spec.lights.ground_color = None;
        spec.materials.shading = synthgen_core::scene::Shading::Phong;
        spec.materials.metallic = [0.0, 0.0];
    }
    let threads = std::env::var("SYNTHGEN_BENCH_THREADS")
        .ok()
        .and_then(|t| t.parse().ok())
        .unwrap_or(0);
    RenderJob::new(spec)
        .objects(&objects)
        .frames(0..FRAMES)
        .seed(2024)
        .threads(threads)
        .build(&NoProgress)
        .unwrap()
}

fn bench(c: &mut Criterion) {
    let shadowed = job(Look::Shadows);
    let realistic = job(Look::Realistic);
    let job = job(Look::Plain);
    let k = job.intrinsics();
    assert_eq!((k.width, k.height), (640, 480));
    let indices: Vec<u64> = job.frame_range().collect();
    let mut g = c.benchmark_group("pipeline_640x480");
    g.throughput(Throughput::Elements(FRAMES));
    g.sample_size(10);
    g.bench_function("frames_iter", |b| {
        b.iter(|| job.frames().map(Result::unwrap).count())
    });
    g.bench_function("frames_batch", |b| {
        b.iter(|| job.frames_batch(&indices).unwrap().len())
    });
    // The same frames with `[lights] shadows = true` (a shadow map per light).
    g.bench_function("frames_batch_shadows", |b| {
        b.iter(|| shadowed.frames_batch(&indices).unwrap().len())
    });
    g.bench_function("frames_batch_realistic", |b| {
        b.iter(|| realistic.frames_batch(&indices).unwrap().len())
    });
    g.bench_function("write_bop", |b| {
        b.iter_batched(
            || tempfile::tempdir().unwrap(),
            |dir| {
                let options =
                    WriteOptions::new(dir.path().join("out"), SinkOptions::new(Format::Bop));
                let report = job.write(&options, &NoProgress).unwrap();
                assert_eq!(report.written, FRAMES);
                // Dropped, and deleted, outside the timing.
                dir
            },
            BatchSize::PerIteration,
        )
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
