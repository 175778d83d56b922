//! The same scene gives the same bytes: twice in a row, in a parallel batch, on any number of
//! threads.

use synthgen_core::glam::Vec3;
use synthgen_core::{Model, SceneObject, SceneSampler, SceneSpec};
use synthgen_render::{render_frames, CpuRenderer, Renderer};

fn sampled() -> (CpuRenderer, Vec<synthgen_core::FrameScene>) {
    let models = vec![
        Model::cuboid("a", Vec3::new(0.08, 0.05, 0.06)),
        Model::cuboid("b", Vec3::new(0.04, 0.1, 0.05)),
    ];
    let objects = SceneObject::one_per_model(&models);
    let sampler = SceneSampler::new(SceneSpec::default(), objects, 5).unwrap();
    let scenes = (0..6).map(|i| sampler.sample(i).unwrap()).collect();
    (CpuRenderer::new(models, vec![]).unwrap(), scenes)
}

#[test]
fn same_scene_same_bytes_on_any_thread_count() {
    let (r, scenes) = sampled();
    let single: Vec<_> = scenes.iter().map(|s| r.render(s).unwrap()).collect();
    let again: Vec<_> = scenes.iter().map(|s| r.render(s).unwrap()).collect();
    assert_eq!(single, again);
    for threads in [1, 2, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let batch: Vec<_> = pool
            .install(|| render_frames(&r, &scenes))
            .into_iter()
            .map(|f| f.unwrap())
            .collect();
        assert_eq!(batch, single, "{threads} threads");
    }
    // Sampled frames show objects, ground and noise background.
    for f in &single {
        assert!(f.instance.iter().any(|&v| v > 0));
        assert!(f.depth_m.iter().any(|&d| d > 0.0));
    }
    assert!(single.iter().any(|f| f.depth_m.contains(&0.0)));
}

#[test]
fn render_into_reuses_buffers_and_matches_render() {
    let (r, scenes) = sampled();
    let mut out = synthgen_core::RenderedFrame::default();
    for s in scenes.iter().rev() {
        r.render_into(s, &mut out).unwrap();
        assert_eq!(out, r.render(s).unwrap());
    }
}
