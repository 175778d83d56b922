//! `synthgen._native.RenderJob`: a prepared render job (`synthgen_pipeline::PreparedJob`)
//! whose frames come back as numpy arrays; `synthgen.Generator` wraps it.

use std::path::PathBuf;
use std::time::Instant;

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use synthgen_assets::Units;
use synthgen_core::SceneSpec;
use synthgen_pipeline::{ObjectSource, PreparedJob, RenderJob};

use crate::errors::{input_error, to_py};
use crate::frame::{cam_k, Rendered};
use crate::gil::{detached, PyProgress};

/// What `Generator(...)` and `render(...)` take to describe a job, as the CLI's flags do.
pub struct JobArgs {
    pub objects: Vec<PathBuf>,
    pub obj_ids: Option<Vec<u32>>,
    pub scene: Option<PathBuf>,
    pub camera: Option<String>,
    pub image_size: Option<(u32, u32)>,
    pub units: String,
    pub seed: u64,
    pub start: u64,
    pub count: u64,
    pub threads: usize,
}

/// The scene spec: defaults, then the scene file, then the camera preset and image size.
fn build_spec(a: &JobArgs) -> PyResult<SceneSpec> {
    let mut spec = match &a.scene {
        Some(path) => SceneSpec::from_toml_file(path).map_err(to_py)?,
        None => SceneSpec::default(),
    };
    if let Some(name) = &a.camera {
        spec.camera.preset = name.clone();
    }
    if let Some((w, h)) = a.image_size {
        spec.camera.set_image_size(w, h).map_err(to_py)?;
    }
    spec.validate().map_err(to_py)?;
    Ok(spec)
}

fn units(text: &str) -> PyResult<Units> {
    text.parse::<Units>().map_err(|_| {
        input_error(
            format!("unknown units {text:?}"),
            Some("use \"mm\", \"m\" or \"auto\""),
        )
    })
}

/// A [`RenderJob`] from the arguments; nothing loaded yet.
pub fn render_job(a: &JobArgs) -> PyResult<RenderJob> {
    let spec = build_spec(a)?;
    let units = units(&a.units)?;
    if let Some(ids) = &a.obj_ids {
        if ids.len() != a.objects.len() {
            return Err(input_error(
                format!(
                    "obj_ids has {} ids but objects has {} meshes",
                    ids.len(),
                    a.objects.len()
                ),
                Some("give one id per mesh, in the same order"),
            ));
        }
    }
    let sources: Vec<ObjectSource> = a
        .objects
        .iter()
        .enumerate()
        .map(|(i, p)| ObjectSource {
            obj_id: a.obj_ids.as_ref().map(|ids| ids[i]),
            ..ObjectSource::new(p.clone(), units)
        })
        .collect();
    let end = a.start.checked_add(a.count).ok_or_else(|| {
        input_error(
            format!("frames {}..{}+{} overflow", a.start, a.start, a.count),
            None,
        )
    })?;
    Ok(RenderJob::new(spec)
        .objects(&sources)
        .units(units)
        .frames(a.start..end)
        .seed(a.seed)
        .threads(a.threads))
}

/// A prepared render job. Frames are rendered with the GIL released, several in parallel
/// on the job's own thread pool; frame `i` depends only on the scene, objects, seed and `i`.
#[pyclass(module = "synthgen._native", name = "RenderJob", frozen)]
pub struct PyRenderJob {
    job: PreparedJob,
}

#[pymethods]
impl PyRenderJob {
    #[new]
    #[pyo3(signature = (objects, *, obj_ids=None, scene=None, camera=None, image_size=None,
                        units="auto".to_string(), seed=0, start=0, count=100, threads=0,
                        progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        objects: Vec<PathBuf>,
        obj_ids: Option<Vec<u32>>,
        scene: Option<PathBuf>,
        camera: Option<String>,
        image_size: Option<(u32, u32)>,
        units: String,
        seed: u64,
        start: u64,
        count: u64,
        threads: usize,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PyRenderJob> {
        let args = JobArgs {
            objects,
            obj_ids,
            scene,
            camera,
            image_size,
            units,
            seed,
            start,
            count,
            threads,
        };
        let job = render_job(&args)?;
        let progress = PyProgress::new(progress);
        let job = detached(py, || job.build(&progress))?;
        Ok(PyRenderJob { job })
    }

    /// The job's first global frame index and its frame count.
    #[getter]
    fn frame_range(&self) -> (u64, u64) {
        let r = self.job.frame_range();
        (r.start, r.end - r.start)
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.job.seed()
    }

    #[getter]
    fn threads(&self) -> usize {
        self.job.threads()
    }

    /// `(width, height)` in pixels.
    #[getter]
    fn image_size(&self) -> (u32, u32) {
        let k = self.job.intrinsics();
        (k.width, k.height)
    }

    #[getter]
    #[allow(non_snake_case)]
    fn cam_K<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        cam_k(py, &self.job.intrinsics().k_row_major())
    }

    /// The target objects: `(obj_id, name, path)` in the order given.
    #[getter]
    fn objects(&self) -> Vec<(u32, String, PathBuf)> {
        let (sources, ids) = self.job.objects();
        sources
            .iter()
            .zip(ids)
            .zip(self.job.object_names())
            .map(|((s, &id), name)| (id, name, s.path.clone()))
            .collect()
    }

    /// The scene spec as TOML.
    fn spec_toml(&self) -> String {
        self.job.spec().to_toml()
    }

    /// Frame `index` (a global frame index) as `Frame` keyword arguments.
    fn frame<'py>(&self, py: Python<'py>, index: u64) -> PyResult<Bound<'py, PyDict>> {
        let r = detached(py, || self.job.frame(index).map(Rendered::new))?;
        r.into_dict(py)
    }

    /// Several frames rendered in parallel, in the order of `indices`.
    fn frames_batch<'py>(
        &self,
        py: Python<'py>,
        indices: Vec<u64>,
    ) -> PyResult<Bound<'py, PyList>> {
        // Converted on this thread: rayon's global pool is not used anywhere in the module,
        // so a forked DataLoader worker never waits on threads that did not survive the fork.
        let rendered = detached(py, || {
            self.job
                .frames_batch(&indices)
                .map(|frames| frames.into_iter().map(Rendered::new).collect::<Vec<_>>())
        })?;
        let list = PyList::empty(py);
        for r in rendered {
            list.append(r.into_dict(py)?)?;
        }
        Ok(list)
    }

    /// Seconds to render the job's frames in memory in Rust (`PreparedJob::frames`, no
    /// numpy): the benchmark's reference figure.
    fn time_in_memory(&self, py: Python<'_>) -> PyResult<f64> {
        detached(py, || {
            let t = Instant::now();
            for f in self.job.frames() {
                std::hint::black_box(f?);
            }
            Ok::<_, synthgen_pipeline::Error>(t.elapsed().as_secs_f64())
        })
    }
}
