//! `raster_rgbd_640x480`: five Linemod models (LMO objects 1, 5, 6, 8, 9) in scenes sampled
//! with the default scene spec, rendered single-threaded and as a parallel batch, with and
//! without `synthgen_core::annotate`; and the structured-light sensor model alone on those
//! frames (its cost against the render's). Throughput is in frames.
//!
//! Models come from `$SYNTHGEN_LMO_DIR/models` (default `../shared/data/lmo/models` next to
//! the workspace). `parallel_batch` uses rayon's global pool (all cores; set
//! `RAYON_NUM_THREADS` to pin it).

// A benchmark stops loudly on any setup or render failure, like a test.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::path::PathBuf;

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use synthgen_assets::Units;
use synthgen_core::scene::SensorSpec;
use synthgen_core::{
    annotate, FrameScene, NoProgress, RenderedFrame, SceneObject, SceneSampler, SceneSpec,
};
use synthgen_render::sensor::apply_structured_light;
use synthgen_render::{render_frames, CpuRenderer, Renderer};

const IDS: [u32; 5] = [1, 5, 6, 8, 9];
const SCENES: u64 = 32;

fn setup() -> (CpuRenderer, Vec<FrameScene>) {
    let root = std::env::var_os("SYNTHGEN_LMO_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/lmo")
        });
    let models: Vec<_> = IDS
        .iter()
        .map(|id| {
            let p = root.join(format!("models/obj_{id:06}.ply"));
            synthgen_assets::load_model(&p, Units::Mm, &NoProgress)
                .unwrap_or_else(|e| panic!("cannot read {}: {e}", p.display()))
                .model
        })
        .collect();
    let objects = models
        .iter()
        .enumerate()
        .map(|(i, m)| SceneObject::new(i, IDS[i], m))
        .collect();
    let sampler = SceneSampler::new(SceneSpec::default(), objects, 2024).unwrap();
    let scenes = (0..SCENES).map(|i| sampler.sample(i).unwrap()).collect();
    (CpuRenderer::new(models, vec![]).unwrap(), scenes)
}

fn annotate_frame(s: &FrameScene, f: &RenderedFrame) -> usize {
    annotate(&s.intrinsics, &f.depth_m, &f.alone, 0.015).len()
}

fn bench(c: &mut Criterion) {
    let (r, scenes) = setup();
    let mut g = c.benchmark_group("raster_rgbd_640x480");
    g.throughput(Throughput::Elements(1));
    let mut i = 0usize;
    g.bench_function("single_thread/render", |b| {
        b.iter(|| {
            i = (i + 1) % scenes.len();
            r.render(&scenes[i]).unwrap()
        })
    });
    g.bench_function("single_thread/render_into", |b| {
        let mut out = RenderedFrame::default();
        b.iter(|| {
            i = (i + 1) % scenes.len();
            r.render_into(&scenes[i], &mut out).unwrap();
            out.rgb[0]
        })
    });
    g.bench_function("single_thread/render+annotate", |b| {
        b.iter(|| {
            i = (i + 1) % scenes.len();
            let f = r.render(&scenes[i]).unwrap();
            annotate_frame(&scenes[i], &f)
        })
    });
    // The structured-light model alone on rendered frames (ground plane and objects: every
    // pixel has depth), with the shipped fit to the YCB-Video Xtion (sensors/asus_xtion.toml:
    // both shadows, the shift, hole blobs); the frame's depth is restored each time.
    let rendered: Vec<RenderedFrame> = scenes.iter().map(|s| r.render(s).unwrap()).collect();
    let sl = SensorSpec::from_toml_file(
        &PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../sensors/asus_xtion.toml"),
    )
    .unwrap()
    .structured_light;
    g.bench_function("single_thread/structured_light", |b| {
        let mut depth = Vec::new();
        b.iter(|| {
            i = (i + 1) % scenes.len();
            let f = &rendered[i];
            depth.clone_from(&f.depth_m);
            apply_structured_light(&sl, &scenes[i].intrinsics, &f.rgb, &mut depth, i as u64);
            depth[0]
        })
    });
    g.throughput(Throughput::Elements(SCENES));
    g.bench_function("parallel_batch/render", |b| {
        b.iter(|| render_frames(&r, &scenes))
    });
    g.bench_function("parallel_batch/render+annotate", |b| {
        b.iter(|| {
            use rayon::prelude::*;
            scenes
                .par_iter()
                .map(|s| annotate_frame(s, &r.render(s).unwrap()))
                .sum::<usize>()
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .measurement_time(std::time::Duration::from_secs(5));
    targets = bench
}
criterion_main!(benches);
