//! A render job: the builder ([`RenderJob`]) and what it prepares ([`PreparedJob`]: models,
//! sampler, physics, renderer, sensor), which renders frames into memory or a dataset folder.

use std::collections::VecDeque;
use std::ops::Range;
use std::sync::Arc;

use rayon::prelude::*;
use synthgen_assets::Units;
use synthgen_core::sample::SceneObject;
use synthgen_core::scene::PlacementMode;
use synthgen_core::{
    FrameScene, Intrinsics, Model, ObjectAnnotation, Progress, RenderedFrame, SceneSampler,
    SceneSpec, Symmetries,
};
use synthgen_render::{CpuRenderer, Renderer, SensorModel, ViewChecker};

use crate::backend::{self, Backend};
use crate::error::{Error, Result};
use crate::extras;
use crate::frame::Frame;
use crate::objects::{self, ObjectSource};

/// What to render: the scene spec, the target objects, the frames and the seed. Nothing is
/// loaded until [`build`](Self::build).
#[derive(Debug, Clone)]
pub struct RenderJob {
    spec: SceneSpec,
    objects: Vec<ObjectSource>,
    units: Units,
    frames: Range<u64>,
    seed: u64,
    threads: usize,
    backend: Backend,
    visib_delta_m: f64,
}

impl RenderJob {
    /// A job over `spec` (validated by the caller, e.g. `SceneSpec::from_toml_file`): frames
    /// 0..100, seed 0, all cores, the CPU renderer, bop_toolkit's 15 mm visibility tolerance.
    pub fn new(spec: SceneSpec) -> RenderJob {
        RenderJob {
            spec,
            objects: Vec::new(),
            units: Units::Auto,
            frames: 0..100,
            seed: 0,
            threads: 0,
            backend: Backend::Cpu,
            visib_delta_m: f64::from(synthgen_core::annotate::DEFAULT_VISIB_DELTA_M),
        }
    }

    /// Target meshes, before the spec's own `[[objects]]` (which are always added).
    pub fn objects(mut self, objects: &[ObjectSource]) -> RenderJob {
        self.objects = objects.to_vec();
        self
    }

    /// Units of the spec's `[[objects]]` that name none (default: auto).
    pub fn units(mut self, units: Units) -> RenderJob {
        self.units = units;
        self
    }

    /// The global frame indices to render.
    pub fn frames(mut self, frames: Range<u64>) -> RenderJob {
        self.frames = frames;
        self
    }

    pub fn seed(mut self, seed: u64) -> RenderJob {
        self.seed = seed;
        self
    }

    /// Worker threads; 0 = all cores. Frames do not depend on it.
    pub fn threads(mut self, threads: usize) -> RenderJob {
        self.threads = threads;
        self
    }

    pub fn backend(mut self, backend: Backend) -> RenderJob {
        self.backend = backend;
        self
    }

    /// How far (metres) an object's surface may lie behind the scene's and still count as
    /// visible (bop19's `delta`).
    pub fn visib_delta_m(mut self, delta_m: f64) -> RenderJob {
        self.visib_delta_m = delta_m;
        self
    }

    /// Loads the models and textures and assembles the sampler, physics, renderer and sensor.
    /// Informational lines (units read, what was loaded) go to `progress.info`.
    pub fn build(self, progress: &dyn Progress) -> Result<PreparedJob> {
        let RenderJob {
            spec,
            objects: mut sources,
            units,
            frames,
            seed,
            threads,
            backend,
            visib_delta_m,
        } = self;
        sources.extend(ObjectSource::from_spec(&spec, units)?);
        if sources.is_empty() {
            return Err(Error::invalid(
                "no objects to render",
                "pass meshes with --objects, e.g. `synthgen render --objects drill.obj`, or list them as [[objects]] in a --scene file",
            ));
        }

        // Models, in the order given; ids explicit, from file names, or 1, 2, ...
        let mut models = Vec::new();
        for s in &sources {
            let loaded = synthgen_assets::load_model(&s.path, s.units, progress).map_err(|e| {
                Error::LoadObject {
                    path: s.path.clone(),
                    source: Box::new(e),
                }
            })?;
            if let Some(note) = &loaded.auto_note {
                progress.info(note);
            }
            models.push(loaded.model);
        }
        objects::name_by_folder_where_stems_repeat(&mut models, &sources);
        let ids = objects::assign_obj_ids(&sources)?;
        let scene_objects = objects::scene_objects(&models, &ids, &sources);
        let n_targets = models.len();
        // Distractor models go after the targets' in the renderer's list.
        let distractors = extras::distractor_pool(&spec, &mut models, progress)?;
        // The bin's two wall models go last.
        let bin_models = spec.bin.enabled.then(|| {
            let first = models.len();
            models.extend(spec.bin.models());
            first
        });

        let backgrounds = extras::backgrounds(&spec, progress)?;
        let (ground_textures, wall_textures) = extras::surface_textures(&spec, progress)?;
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(Error::ThreadPool)?;
        let intrinsics = spec.camera.intrinsics()?;
        let symmetries: Vec<Option<Symmetries>> = sources
            .iter()
            .map(|s| objects::source_symmetries(&s.path, progress))
            .collect::<Result<_>>()?;
        // Written to the dataset's models/; the renderer takes the others.
        let target_models = models[..n_targets].to_vec();

        let mut sampler =
            SceneSampler::new(spec.clone(), scene_objects, seed)?.with_distractors(distractors);
        if let Some(first) = bin_models {
            sampler = sampler.with_bin_models(first);
        }
        if spec.placement.mode == PlacementMode::Physics {
            let p = sampler.distractor_pool();
            let all: Vec<SceneObject> = sampler
                .objects
                .iter()
                .chain(&p.primitives)
                .chain(&p.meshes)
                .cloned()
                .collect();
            let settler =
                synthgen_physics::PhysicsSettler::new(&all, spec.placement.physics.clone())?
                    .with_bin(&if spec.bin.enabled {
                        spec.bin.walls()
                    } else {
                        Vec::new()
                    });
            sampler = sampler.with_settle(Arc::new(settler));
        }
        let renderer: Box<dyn Renderer + Send + Sync> = match &backend {
            Backend::Cpu => {
                let cpu = CpuRenderer::new(models, backgrounds)?
                    .with_surface_textures(&ground_textures, &wall_textures)?;
                if spec.camera.min_visib_fract > 0.0 {
                    // A clone shares the prepared models.
                    let check = ViewChecker::new(cpu.clone(), visib_delta_m as f32);
                    sampler = sampler.with_view_check(Arc::new(check));
                }
                Box::new(cpu)
            }
            Backend::Blender(settings) => {
                if spec.camera.min_visib_fract > 0.0 {
                    // The raster's depth-only pass: the Blender backend's alone depths come
                    // from the same raster.
                    let cpu = CpuRenderer::new(models.clone(), Vec::new())?
                        .with_surface_textures(&ground_textures, &wall_textures)?;
                    let check = ViewChecker::new(cpu, visib_delta_m as f32);
                    sampler = sampler.with_view_check(Arc::new(check));
                }
                let surfaces = [ground_textures, wall_textures];
                backend::blender_renderer(settings, models, backgrounds, surfaces, progress)?
            }
        };
        // Applied after the annotations, so masks and GT come from the clean render.
        let sensor = SensorModel::new(spec.sensor.clone(), seed)?;
        Ok(PreparedJob {
            spec,
            sources,
            ids,
            target_models,
            symmetries,
            intrinsics,
            sampler,
            renderer,
            sensor,
            pool,
            frames,
            seed,
            backend,
            visib_delta_m,
        })
    }
}

/// A job ready to render: any frame, in any order, on its thread pool.
pub struct PreparedJob {
    pub(crate) spec: SceneSpec,
    pub(crate) sources: Vec<ObjectSource>,
    pub(crate) ids: Vec<u32>,
    pub(crate) target_models: Vec<Model>,
    pub(crate) symmetries: Vec<Option<Symmetries>>,
    pub(crate) intrinsics: Intrinsics,
    pub(crate) sampler: SceneSampler,
    renderer: Box<dyn Renderer + Send + Sync>,
    sensor: SensorModel,
    pub(crate) pool: rayon::ThreadPool,
    pub(crate) frames: Range<u64>,
    pub(crate) seed: u64,
    pub(crate) backend: Backend,
    pub(crate) visib_delta_m: f64,
}

impl PreparedJob {
    /// The global frame indices of the job.
    pub fn frame_range(&self) -> Range<u64> {
        self.frames.clone()
    }

    pub fn spec(&self) -> &SceneSpec {
        &self.spec
    }

    pub fn seed(&self) -> u64 {
        self.seed
    }

    pub fn backend(&self) -> &Backend {
        &self.backend
    }

    pub fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    /// The target objects: their sources and assigned obj_ids, in the same order.
    pub fn objects(&self) -> (&[ObjectSource], &[u32]) {
        (&self.sources, &self.ids)
    }

    /// The target models' names (their folder's where file stems repeat), one per source.
    pub fn object_names(&self) -> Vec<String> {
        self.target_models.iter().map(|m| m.name.clone()).collect()
    }

    /// `placement.objects_per_frame`, clamped to the number of object instances.
    pub fn objects_per_frame(&self) -> Option<[usize; 2]> {
        self.spec.placement.objects_per_frame.map(|[lo, hi]| {
            let n = self.sampler.objects.len();
            [(lo as usize).min(n), (hi as usize).min(n)]
        })
    }

    /// Worker threads of the job's pool.
    pub fn threads(&self) -> usize {
        self.pool.current_num_threads()
    }

    /// Frames whose physics did not settle and kept the non-physics placement, with why,
    /// among all sampled so far.
    pub fn physics_fallbacks(&self) -> Vec<(u64, String)> {
        self.sampler.physics_fallbacks()
    }

    /// Frame `index` (any global index, inside the job's range or not): the same arrays
    /// whatever the thread count and whichever frames were rendered before.
    pub fn frame(&self, index: u64) -> Result<Frame> {
        let (scene, frame, ann) = self.pool.install(|| self.render(index))?;
        Ok(Frame::new(&scene, frame, ann))
    }

    /// Several frames rendered in parallel, returned in the order of `indices`; the first
    /// failure (in that order) is the error.
    pub fn frames_batch(&self, indices: &[u64]) -> Result<Vec<Frame>> {
        self.pool.install(|| {
            indices
                .par_iter()
                .map(|&i| {
                    let (scene, frame, ann) = self.render(i)?;
                    Ok(Frame::new(&scene, frame, ann))
                })
                .collect()
        })
    }

    /// The job's frames in order, rendered a few per thread at a time. A frame that fails is
    /// an `Err` item; the others still come.
    pub fn frames(&self) -> Frames<'_> {
        Frames {
            job: self,
            next: self.frames.start,
            end: self.frames.end,
            ready: VecDeque::new(),
        }
    }

    /// Samples and renders frame `index`: the scene, the frame after the sensor model, and
    /// the annotations of the clean render.
    pub(crate) fn render(
        &self,
        index: u64,
    ) -> Result<(FrameScene, RenderedFrame, Vec<ObjectAnnotation>)> {
        let scene = self.sampler.sample(index)?;
        let (frame, ann) = render_annotated(
            self.renderer.as_ref(),
            &scene,
            &self.sensor,
            self.visib_delta_m as f32,
        )?;
        Ok((scene, frame, ann))
    }
}

/// The frames of a [`PreparedJob`], in order.
pub struct Frames<'a> {
    job: &'a PreparedJob,
    next: u64,
    end: u64,
    ready: VecDeque<Result<Frame>>,
}

impl Iterator for Frames<'_> {
    type Item = Result<Frame>;

    fn next(&mut self) -> Option<Result<Frame>> {
        if self.ready.is_empty() && self.next < self.end {
            // Two frames per thread: every thread busy, memory bounded.
            let batch = (2 * self.job.threads() as u64)
                .max(1)
                .min(self.end - self.next);
            let indices = self.next..self.next + batch;
            self.next += batch;
            let job = self.job;
            let frames: Vec<Result<Frame>> = job.pool.install(|| {
                indices
                    .into_par_iter()
                    .map(|i| {
                        let (scene, frame, ann) = job.render(i)?;
                        Ok(Frame::new(&scene, frame, ann))
                    })
                    .collect()
            });
            self.ready.extend(frames);
        }
        self.ready.pop_front()
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        let n = usize::try_from(self.end - self.next)
            .unwrap_or(usize::MAX)
            .saturating_add(self.ready.len());
        (n, Some(n))
    }
}

impl ExactSizeIterator for Frames<'_> {}

/// Renders `scene`, annotates the clean render, then applies the sensor model to the frame's
/// RGB and depth (masks and GT stay those of the clean render): the step every rendered
/// frame goes through, sampled or replayed.
pub fn render_annotated(
    renderer: &(dyn Renderer + Sync),
    scene: &FrameScene,
    sensor: &SensorModel,
    delta_m: f32,
) -> Result<(RenderedFrame, Vec<ObjectAnnotation>)> {
    let mut frame = renderer.render(scene)?;
    let ann = synthgen_core::annotate(&scene.intrinsics, &frame.depth_m, &frame.alone, delta_m);
    if !sensor.is_identity() {
        sensor.apply(scene, &mut frame);
    }
    Ok((frame, ann))
}

#[cfg(test)]
mod tests {
    use crate::test_support::job;

    #[test]
    fn frames_do_not_depend_on_the_thread_count() {
        let one: Vec<_> = job(0..5, 1).frames().map(Result::unwrap).collect();
        let two: Vec<_> = job(0..5, 2).frames().map(Result::unwrap).collect();
        assert_eq!(one.len(), 5);
        assert_eq!(one, two);
        // Something was rendered.
        assert!(one.iter().all(|f| f.objects.len() == 2));
        assert!(one
            .iter()
            .any(|f| f.objects.iter().any(|o| o.info.px_count_visib > 0)));
    }

    #[test]
    fn one_frame_and_batches_equal_the_iterator() {
        let j = job(3..8, 2);
        let all: Vec<_> = j.frames().map(Result::unwrap).collect();
        assert_eq!(
            all.iter().map(|f| f.index).collect::<Vec<_>>(),
            vec![3, 4, 5, 6, 7]
        );
        // Out of order, after other frames: frame i is still frame i.
        assert_eq!(j.frame(6).unwrap(), all[3]);
        assert_eq!(j.frame(3).unwrap(), all[0]);
        let batch = j.frames_batch(&[7, 4, 5]).unwrap();
        assert_eq!(batch, vec![all[4].clone(), all[1].clone(), all[2].clone()]);
    }

    #[test]
    fn prepared_job_is_send_and_sync() {
        // Bindings hand it to other threads (a Python object, a DataLoader worker).
        fn check<T: Send + Sync>() {}
        check::<super::PreparedJob>();
    }

    #[test]
    fn masks_and_counts_agree() {
        for f in job(0..4, 2).frames().map(Result::unwrap) {
            let n = (f.width * f.height) as usize;
            assert_eq!(
                (f.rgb.len(), f.depth_m.len(), f.instance_ids.len()),
                (3 * n, n, n)
            );
            for (k, o) in f.objects.iter().enumerate() {
                let visib = o.mask_visib.iter().filter(|&&v| v == 255).count() as u64;
                assert_eq!(visib, o.info.px_count_visib);
                // The visible part lies inside the full mask, which holds the instance's pixels.
                assert!(o
                    .mask_visib
                    .iter()
                    .zip(&o.mask)
                    .all(|(&v, &m)| v == 0 || m == 255));
                let id = k as u16 + 1;
                assert!(f
                    .instance_ids
                    .iter()
                    .zip(&o.mask)
                    .all(|(&i, &m)| i != id || m == 255));
            }
        }
    }
}
