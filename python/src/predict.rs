//! `synthgen.Predictor`: a detector and a pose model, loaded once, on numpy images with no GT
//! — the library's `synthgen_jobs::predict::Predictor`, which `synthgen predict` runs per
//! frame.

use std::path::PathBuf;

use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use synthgen_core::NoProgress;
use synthgen_formats::bop::{Plane, RgbImage};
use synthgen_jobs::predict::{Predictor, PredictorOptions};
use synthgen_jobs::rgb_refine::refine_options;
use synthgen_jobs::Log;

use crate::errors::{input_error, to_py};
use crate::gil::detached;

#[pyclass(module = "synthgen._native", name = "Predictor", frozen)]
pub struct PyPredictor {
    inner: Predictor,
}

#[pymethods]
impl PyPredictor {
    #[new]
    #[pyo3(signature = (model, detector, *, objects_from=None, min_score=0.05, per_object=1, refine="none", refine_models=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        model: PathBuf,
        detector: PathBuf,
        objects_from: Option<PathBuf>,
        min_score: f64,
        per_object: usize,
        refine: &str,
        refine_models: Option<PathBuf>,
    ) -> PyResult<Self> {
        let options = PredictorOptions {
            model,
            detector,
            objects_from,
            min_score,
            per_object,
            cuda: false,
            refine: refine_options(refine).map_err(to_py)?,
            refine_models,
        };
        let inner = detached(py, || Predictor::load(&options, &Log::new(&NoProgress)))?;
        Ok(PyPredictor { inner })
    }

    /// The pose model's kind ("rgb-dense", "tnet", ...).
    #[getter]
    fn model_kind(&self) -> &'static str {
        self.inner.kind().name()
    }

    /// Whether the pose model reads depth.
    #[getter]
    fn needs_depth(&self) -> bool {
        self.inner.needs_depth()
    }

    #[pyo3(signature = (rgb, K, depth=None))]
    #[allow(non_snake_case)]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        rgb: PyReadonlyArray3<'py, u8>,
        K: PyReadonlyArray2<'py, f64>,
        depth: Option<PyReadonlyArray2<'py, f32>>,
    ) -> PyResult<Bound<'py, PyList>> {
        let shape = rgb.as_array().shape().to_vec();
        if shape[2] != 3 {
            return Err(input_error(
                format!("rgb must be (H, W, 3) uint8, not {shape:?}"),
                Some("give the image as a (height, width, 3) uint8 array"),
            ));
        }
        let (h, w) = (shape[0], shape[1]);
        let image = RgbImage {
            width: w as u32,
            height: h as u32,
            rgb: rgb.as_array().iter().copied().collect(),
        };
        if K.as_array().shape() != [3, 3] {
            return Err(input_error(
                format!("K must be 3x3, not {:?}", K.as_array().shape()),
                Some("give K as a 3x3 array [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]"),
            ));
        }
        let k = K.as_array();
        let cam_k: [f64; 9] = std::array::from_fn(|i| k[[i / 3, i % 3]]);
        let depth = depth.map(|d| Plane {
            width: d.as_array().shape()[1] as u32,
            height: d.as_array().shape()[0] as u32,
            data: d
                .as_array()
                .iter()
                .map(|&v| if v.is_finite() && v > 0.0 { v } else { 0.0 })
                .collect(),
        });
        let found = detached(py, || {
            self.inner
                .predict_image(&image, depth.as_ref(), &cam_k, (0, 0))
        })?;
        let out = PyList::empty(py);
        for o in found.objects {
            let d = PyDict::new(py);
            d.set_item("obj_id", o.obj_id)?;
            d.set_item("score", o.score)?;
            d.set_item("pose_score", o.pose_score)?;
            d.set_item("bbox", Array1::from_vec(o.bbox.to_vec()).into_pyarray(py))?;
            match o.r {
                Some(r) => {
                    let a = Array2::from_shape_vec((3, 3), r.to_vec())
                        .map_err(|e| input_error(e.to_string(), None))?;
                    d.set_item("R", a.into_pyarray(py))?;
                }
                None => d.set_item("R", py.None())?,
            }
            match o.t {
                Some(t) => d.set_item("t", Array1::from_vec(t.to_vec()).into_pyarray(py))?,
                None => d.set_item("t", py.None())?,
            }
            match &o.segmentation {
                Some(m) => {
                    let mask: Vec<bool> = m.decode().into_iter().map(|v| v > 0).collect();
                    let a = Array2::from_shape_vec((h, w), mask)
                        .map_err(|e| input_error(e.to_string(), None))?;
                    d.set_item("mask", a.into_pyarray(py))?;
                }
                None => d.set_item("mask", py.None())?,
            }
            out.append(d)?;
        }
        Ok(out)
    }
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyPredictor>()?;
    Ok(())
}
