//! `synthgen.render`, `synthgen.mix`, `synthgen.evaluate`: the library calls behind
//! `synthgen render`, `synthgen mix` and `synthgen eval --results`, with the same checks
//! (output folder, lock, inputs apart) and the outcome as a dict instead of printed lines.

use std::path::{Path, PathBuf};

use pyo3::prelude::*;
use pyo3::types::PyDict;
use synthgen_core::NoProgress;
use synthgen_curate::mix::{MixCounts, MixOptions, SceneRef};
use synthgen_formats::layout::open_source;
use synthgen_formats::output::OutputLock;
use synthgen_pipeline::{error_chain, Format, ImageFormat, SinkOptions, WriteOptions};
use synthgen_render::ObjectRenderer;
use synthgen_train::bop::{load_render_models, prepare_bop, BopOptions};
use synthgen_train::eval::{evaluate as score, load_eval_objects, pick_split, read_gt};
use synthgen_train::metrics::Rotations;
use synthgen_train::results::read_results_csv;

use crate::errors::{input_error, ToPyErr};
use crate::gil::{detached, PyProgress};
use crate::job::{render_job, JobArgs};

fn format_of(text: &str) -> PyResult<Format> {
    match text {
        "bop" => Ok(Format::Bop),
        "linemod" => Ok(Format::Linemod),
        "ycbv" => Ok(Format::Ycbv),
        _ => Err(input_error(
            format!("unknown dataset format {text:?}"),
            Some("use \"bop\", \"linemod\" or \"ycbv\""),
        )),
    }
}

/// As `synthgen render` checks `--out`: empty, absent, or `force`.
fn check_out_dir(out: &Path, force: bool) -> PyResult<()> {
    if out.is_dir() {
        if !synthgen_formats::output::is_empty(out) && !force {
            return Err(input_error(
                format!("output folder is not empty: {}", out.display()),
                Some("choose another out, or pass force=True to replace it"),
            ));
        }
        if force {
            synthgen_formats::output::check_force(out).map_err(|e| e.to_py_err())?;
        }
    } else if out.exists() {
        return Err(input_error(
            format!("output path exists and is not a folder: {}", out.display()),
            Some("choose another out"),
        ));
    }
    Ok(())
}

/// Renders frames `first_frame .. first_frame + frames` into a dataset folder, as
/// `synthgen render` does. Returns what was written; frames that failed are listed in
/// `failures` (the run goes on unless `fail_fast`).
#[pyfunction]
#[pyo3(signature = (objects, out, *, frames=100, first_frame=0, scene=None, camera=None,
                    image_size=None, units="auto".to_string(), obj_ids=None, seed=0, threads=0,
                    format="bop".to_string(), split="train_pbr".to_string(), chunk_size=1000,
                    rgb_format="png".to_string(), jpg_quality=95, depth_scale=None,
                    force=false, fail_fast=false, command_line=Vec::new(), progress=None))]
#[allow(clippy::too_many_arguments)]
fn render<'py>(
    py: Python<'py>,
    objects: Vec<PathBuf>,
    out: PathBuf,
    frames: u64,
    first_frame: u64,
    scene: Option<PathBuf>,
    camera: Option<String>,
    image_size: Option<(u32, u32)>,
    units: String,
    obj_ids: Option<Vec<u32>>,
    seed: u64,
    threads: usize,
    format: String,
    split: String,
    chunk_size: u32,
    rgb_format: String,
    jpg_quality: u8,
    depth_scale: Option<f64>,
    force: bool,
    fail_fast: bool,
    command_line: Vec<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let job = render_job(&JobArgs {
        objects,
        obj_ids,
        scene,
        camera,
        image_size,
        units,
        seed,
        start: first_frame,
        count: frames,
        threads,
    })?;
    let sink = SinkOptions {
        split,
        chunk_size: chunk_size.max(1),
        rgb_format: match rgb_format.as_str() {
            "png" => ImageFormat::Png,
            "jpg" | "jpeg" => ImageFormat::Jpg,
            other => {
                return Err(input_error(
                    format!("unknown rgb_format {other:?}"),
                    Some("use \"png\" or \"jpg\""),
                ))
            }
        },
        jpg_quality: jpg_quality.clamp(1, 100),
        depth_scale,
        ..SinkOptions::new(format_of(&format)?)
    };
    check_out_dir(&out, force)?;
    let progress = PyProgress::new(progress);
    let options = WriteOptions {
        command_line,
        fail_fast,
        ..WriteOptions::new(&out, sink)
    };
    let report = detached(py, || {
        let _lock = OutputLock::acquire(&out).map_err(synthgen_pipeline::Error::from)?;
        if force {
            synthgen_formats::output::clear_output(&out).map_err(synthgen_pipeline::Error::from)?;
        }
        let job = job.build(&progress)?;
        job.write(&options, &progress)
    })?;
    let rendered = report.rendered;
    let n_blank = report.nothing_visible.len();
    if n_blank > 0 && 2 * n_blank as u64 > rendered {
        return Err(input_error(
            format!(
                "most frames show no object ({n_blank} of {rendered}): the dataset in {} is not usable",
                out.display()
            ),
            Some(
                "check the units (units=\"mm\" or \"m\": a model 1000x too large or too small), \
                 the camera distance in the scene against the objects' size, and that the meshes \
                 have faces",
            ),
        ));
    }
    let d = PyDict::new(py);
    d.set_item("out", &out)?;
    d.set_item("written", report.written)?;
    d.set_item("rendered", rendered)?;
    let failures: Vec<(u64, String)> = report
        .failures
        .iter()
        .map(|(i, e)| (*i, error_chain(e)))
        .collect();
    d.set_item("failures", failures)?;
    d.set_item("nothing_visible", report.nothing_visible)?;
    d.set_item("physics_fallbacks", report.physics_fallbacks)?;
    d.set_item("depth_out_of_range_px", report.depth_out_of_range_px)?;
    d.set_item("description", report.description)?;
    Ok(d)
}

fn canonical(what: &str, path: &Path) -> PyResult<PathBuf> {
    path.canonicalize().map_err(|_| {
        input_error(
            format!("{what} dataset folder not found: {}", path.display()),
            Some("check the path"),
        )
    })
}

/// Draws a reproducible mix of a real and a synthetic dataset into `out` (a BOP dataset with
/// `train/`, `test/` and per-frame provenance), as `synthgen mix` does.
#[pyfunction]
#[pyo3(signature = (real, synth, out, *, real_count, synth_count, test_count=None, seed=0,
                    force=false, exclude_shared=false, test_scenes=Vec::new(),
                    command_line=Vec::new(), progress=None))]
#[allow(clippy::too_many_arguments)]
fn mix<'py>(
    py: Python<'py>,
    real: PathBuf,
    synth: PathBuf,
    out: PathBuf,
    real_count: usize,
    synth_count: usize,
    test_count: Option<usize>,
    seed: u64,
    force: bool,
    exclude_shared: bool,
    test_scenes: Vec<String>,
    command_line: Vec<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyDict>> {
    let real = canonical("real", &real)?;
    let synth = canonical("synthetic", &synth)?;
    let test_scenes = test_scenes
        .iter()
        .map(|s| s.parse::<SceneRef>().map_err(|e| input_error(e, None)))
        .collect::<PyResult<Vec<_>>>()?;
    let opts = MixOptions {
        counts: MixCounts {
            real: real_count,
            synth: synth_count,
            test: test_count,
        },
        seed,
        command_line,
        force,
        exclude_shared,
        test_scenes,
    };
    let progress = PyProgress::new(progress);
    let report = detached(py, || {
        synthgen_jobs::mix::mix_datasets(&real, &synth, &out, &opts, &progress)
    })?;
    let d = PyDict::new(py);
    d.set_item("out", &out)?;
    d.set_item("train_real", report.train_real)?;
    d.set_item("train_synth", report.train_synth)?;
    d.set_item("test", report.test)?;
    d.set_item("linked", report.linked)?;
    d.set_item("copied", report.copied)?;
    d.set_item("completed", report.completed)?;
    d.set_item("excluded_shared", report.excluded_shared)?;
    d.set_item("duplicate_train", report.duplicate_train)?;
    d.set_item("warnings", report.warnings)?;
    Ok(d)
}

/// Scores a BOP results CSV against a dataset's GT, as `synthgen eval --results` does:
/// returns the per-object scores and the `all` row (as `--json` writes them), the markdown
/// table, and the rows of the CSV that could not be read. With `bop`, also BOP's Average
/// Recall (VSD, MSSD, MSPD) as `eval --bop` computes it, under `"bop"`.
#[pyfunction]
#[pyo3(signature = (data, results, *, split=None, min_visib_fract=0.1, bop=false, targets=None, visib_gt_min=-1.0, rotations="as_stored"))]
// pyo3 cannot write a negative default into the generated signature (it writes `...`,
// which mypy.stubtest rejects against the stub's -1.0), so the signature is spelled out.
#[pyo3(
    text_signature = "(data, results, *, split=None, min_visib_fract=0.1, bop=False, targets=None, visib_gt_min=-1.0, rotations='as_stored')"
)]
#[allow(clippy::too_many_arguments)]
fn evaluate<'py>(
    py: Python<'py>,
    data: PathBuf,
    results: PathBuf,
    split: Option<String>,
    min_visib_fract: f64,
    bop: bool,
    targets: Option<PathBuf>,
    visib_gt_min: f64,
    rotations: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let rotations = match rotations {
        "as_stored" => Rotations::AsStored,
        "nearest" => Rotations::Nearest,
        other => {
            return Err(crate::errors::input_error(
                format!("rotations must be \"as_stored\" or \"nearest\", not {other:?}"),
                None,
            ))
        }
    };
    let (report, bop_json, markdown, skipped, n_estimates, split) = detached(py, || {
        let ds = open_source(&data)?;
        let split = pick_split(ds.as_ref(), split.as_deref())?;
        let gts = read_gt(ds.as_ref(), &split, min_visib_fract)?;
        let file = read_results_csv(&results)?;
        let objects = load_eval_objects(ds.as_ref(), gts.iter().map(|g| g.obj_id))?;
        let report = score(&gts, &file.estimates, &objects, rotations)?;
        let markdown = report.to_markdown(&objects);
        let bop_json = if bop {
            let opts = BopOptions {
                visib_gt_min,
                ..BopOptions::default()
            };
            let setup = prepare_bop(ds.as_ref(), &split, targets.as_deref(), &opts)?;
            let renderer = ObjectRenderer::new(load_render_models(ds.as_ref(), setup.obj_ids())?)
                .map_err(|e| synthgen_train::Error::InvalidOption(e.to_string()))?;
            let r = setup.evaluate(&file.estimates, Some(&renderer), &opts, &NoProgress)?;
            Some(serde_json::to_string(&r).map_err(|e| {
                synthgen_train::Error::InvalidOption(format!("BOP report as JSON: {e}"))
            })?)
        } else {
            None
        };
        Ok::<_, synthgen_train::Error>((
            report,
            bop_json,
            markdown,
            file.skipped,
            file.estimates.len(),
            split,
        ))
    })?;
    let json = serde_json::to_string(&report.to_json())
        .map_err(|e| crate::errors::py_err(crate::errors::Kind::Internal, &e, None))?;
    let loads = py.import("json")?.getattr("loads")?;
    let d = PyDict::new(py);
    d.set_item("split", split)?;
    d.set_item("scores", loads.call1((json,))?)?;
    match bop_json {
        Some(b) => d.set_item("bop", loads.call1((b,))?)?,
        None => d.set_item("bop", py.None())?,
    }
    d.set_item("markdown", markdown)?;
    d.set_item("estimates", n_estimates)?;
    d.set_item("unmatched_estimates", report.unmatched_estimates)?;
    let skipped: Vec<(usize, String)> = skipped.into_iter().map(|p| (p.line, p.message)).collect();
    d.set_item("skipped_rows", skipped)?;
    Ok(d)
}

/// Scores a BOP detections file (boxes, and masks as COCO RLE where it has them) against a
/// dataset's GT as bop_toolkit's `eval_bop22_coco.py` does, as `synthgen detector eval` does:
/// the scores as `detector eval --out` writes them.
#[pyfunction]
#[pyo3(signature = (data, detections, *, split=None, targets=None, all_frames=false, bbox_type="amodal"))]
fn evaluate_detections<'py>(
    py: Python<'py>,
    data: PathBuf,
    detections: PathBuf,
    split: Option<String>,
    targets: Option<PathBuf>,
    all_frames: bool,
    bbox_type: &str,
) -> PyResult<Bound<'py, PyAny>> {
    use synthgen_jobs::detect_eval::{detection_eval_run, BboxType, DetectionEvalRequest};
    let bbox_type = match bbox_type {
        "amodal" => BboxType::Amodal,
        "modal" => BboxType::Modal,
        other => {
            return Err(crate::errors::input_error(
                format!("bbox_type must be \"amodal\" or \"modal\", not {other:?}"),
                None,
            ))
        }
    };
    let request = DetectionEvalRequest {
        data,
        split,
        detections,
        targets,
        all_frames,
        bbox_type,
        ..DetectionEvalRequest::default()
    };
    let scores = detached(py, || detection_eval_run(&request, &NoProgress))?;
    let json = serde_json::to_string(&scores)
        .map_err(|e| crate::errors::py_err(crate::errors::Kind::Internal, &e, None))?;
    py.import("json")?.getattr("loads")?.call1((json,))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(evaluate_detections, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(mix, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate, m)?)?;
    Ok(())
}
