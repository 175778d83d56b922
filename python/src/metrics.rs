//! `synthgen.metrics`: the pose metrics of `synthgen eval` (`synthgen_train::metrics`) on
//! numpy arrays. Metres and degrees.

use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::Pose;
use synthgen_train::metrics::{self, EvalObject};

use crate::errors::input_error;

fn rotation(name: &str, r: &PyReadonlyArray2<'_, f64>) -> PyResult<DMat3> {
    let a = r.as_array();
    if a.shape() != [3, 3] {
        return Err(input_error(
            format!("{name} must be 3x3, got shape {:?}", a.shape()),
            None,
        ));
    }
    Ok(DMat3::from_cols_array_2d(&[
        [a[[0, 0]], a[[1, 0]], a[[2, 0]]],
        [a[[0, 1]], a[[1, 1]], a[[2, 1]]],
        [a[[0, 2]], a[[1, 2]], a[[2, 2]]],
    ]))
}

fn vector(name: &str, t: &PyReadonlyArray1<'_, f64>) -> PyResult<DVec3> {
    let a = t.as_array();
    if a.len() != 3 {
        return Err(input_error(
            format!("{name} must have 3 elements, got {}", a.len()),
            None,
        ));
    }
    Ok(DVec3::new(a[0], a[1], a[2]))
}

fn points(p: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<DVec3>> {
    let a = p.as_array();
    if a.ncols() != 3 {
        return Err(input_error(
            format!("points must have shape (M, 3), got {:?}", a.shape()),
            None,
        ));
    }
    Ok(a.rows()
        .into_iter()
        .map(|r| DVec3::new(r[0], r[1], r[2]))
        .collect())
}

fn pose(
    which: &str,
    r: &PyReadonlyArray2<'_, f64>,
    t: &PyReadonlyArray1<'_, f64>,
) -> PyResult<Pose> {
    Ok(Pose::new(
        rotation(&format!("R_{which}"), r)?,
        vector(&format!("t_{which}"), t)?,
    ))
}

/// Points (M, 3) as a numpy array.
pub fn points_to_py<'py>(py: Python<'py>, pts: &[DVec3]) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f64> = pts.iter().flat_map(|p| p.to_array()).collect();
    let a = Array2::from_shape_vec((pts.len(), 3), flat)
        .map_err(|e| crate::errors::py_err(crate::errors::Kind::Internal, &e, None))?;
    Ok(a.into_pyarray(py).into_any())
}

/// The arrays of a (points, GT pose, estimated pose) metric read, then `metric` run without
/// the GIL.
#[allow(non_snake_case)]
fn points_and_poses(
    py: Python<'_>,
    points_m: &PyReadonlyArray2<'_, f64>,
    (R_gt, t_gt): (&PyReadonlyArray2<'_, f64>, &PyReadonlyArray1<'_, f64>),
    (R_est, t_est): (&PyReadonlyArray2<'_, f64>, &PyReadonlyArray1<'_, f64>),
    metric: fn(&[DVec3], &Pose, &Pose) -> f64,
) -> PyResult<f64> {
    let (p, gt, est) = (
        points(points_m)?,
        pose("gt", R_gt, t_gt)?,
        pose("est", R_est, t_est)?,
    );
    Ok(py.detach(|| metric(&p, &gt, &est)))
}

/// ADD: mean distance between the model points under both poses (metres).
#[pyfunction]
#[allow(non_snake_case)]
fn add(
    py: Python<'_>,
    points_m: PyReadonlyArray2<'_, f64>,
    R_gt: PyReadonlyArray2<'_, f64>,
    t_gt: PyReadonlyArray1<'_, f64>,
    R_est: PyReadonlyArray2<'_, f64>,
    t_est: PyReadonlyArray1<'_, f64>,
) -> PyResult<f64> {
    points_and_poses(
        py,
        &points_m,
        (&R_gt, &t_gt),
        (&R_est, &t_est),
        metrics::add,
    )
}

/// ADD-S (bop_toolkit's ADI): mean distance from each GT-posed point to the nearest
/// estimate-posed point (metres). O(M^2).
#[pyfunction]
#[allow(non_snake_case)]
fn add_s(
    py: Python<'_>,
    points_m: PyReadonlyArray2<'_, f64>,
    R_gt: PyReadonlyArray2<'_, f64>,
    t_gt: PyReadonlyArray1<'_, f64>,
    R_est: PyReadonlyArray2<'_, f64>,
    t_est: PyReadonlyArray1<'_, f64>,
) -> PyResult<f64> {
    points_and_poses(
        py,
        &points_m,
        (&R_gt, &t_gt),
        (&R_est, &t_est),
        metrics::adi,
    )
}

/// Rotation error arccos((tr(R_est R_gt^-1) - 1) / 2) in degrees, as bop_toolkit's `re`.
#[pyfunction]
#[allow(non_snake_case)]
fn re(R_gt: PyReadonlyArray2<'_, f64>, R_est: PyReadonlyArray2<'_, f64>) -> PyResult<f64> {
    Ok(metrics::re_deg(
        &rotation("R_gt", &R_gt)?,
        &rotation("R_est", &R_est)?,
    ))
}

/// Translation error |t_gt - t_est| in metres.
#[pyfunction]
fn te(t_gt: PyReadonlyArray1<'_, f64>, t_est: PyReadonlyArray1<'_, f64>) -> PyResult<f64> {
    let at = |t: DVec3| Pose::new(DMat3::IDENTITY, t);
    Ok(metrics::te_m(
        &at(vector("t_gt", &t_gt)?),
        &at(vector("t_est", &t_est)?),
    ))
}

/// 5cm5°: translation error below 5 cm and rotation error below 5°.
#[pyfunction]
#[allow(non_snake_case)]
fn within_5cm5deg(
    R_gt: PyReadonlyArray2<'_, f64>,
    t_gt: PyReadonlyArray1<'_, f64>,
    R_est: PyReadonlyArray2<'_, f64>,
    t_est: PyReadonlyArray1<'_, f64>,
) -> PyResult<bool> {
    Ok(metrics::is_5cm5deg(
        &pose("gt", &R_gt, &t_gt)?,
        &pose("est", &R_est, &t_est)?,
    ))
}

/// All errors of one estimate as `synthgen eval` scores it: `add`, `add_s` (ADI), `add_or_s`
/// (the one that decides: ADD-S for symmetric objects), `te`, `re`, `correct` (ADD(-S) below
/// 10% of the diameter) and `within_5cm5deg`.
#[pyfunction]
#[allow(non_snake_case, clippy::too_many_arguments)]
fn pose_errors<'py>(
    py: Python<'py>,
    points_m: PyReadonlyArray2<'_, f64>,
    diameter_m: f64,
    symmetric: bool,
    R_gt: PyReadonlyArray2<'_, f64>,
    t_gt: PyReadonlyArray1<'_, f64>,
    R_est: PyReadonlyArray2<'_, f64>,
    t_est: PyReadonlyArray1<'_, f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let obj = EvalObject {
        points_m: points(&points_m)?,
        diameter_m,
        symmetric,
    };
    let (gt, est) = (pose("gt", &R_gt, &t_gt)?, pose("est", &R_est, &t_est)?);
    let e = py.detach(|| obj.errors(&gt, &est));
    let d = PyDict::new(py);
    d.set_item("add", e.add_m)?;
    d.set_item("add_s", e.adi_m)?;
    d.set_item("add_or_s", e.add_s_m)?;
    d.set_item("te", e.te_m)?;
    d.set_item("re", e.re_deg)?;
    d.set_item("correct", obj.add_s_correct(&e))?;
    d.set_item("within_5cm5deg", metrics::is_5cm5deg(&gt, &est))?;
    Ok(d)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(add, m)?)?;
    m.add_function(wrap_pyfunction!(add_s, m)?)?;
    m.add_function(wrap_pyfunction!(re, m)?)?;
    m.add_function(wrap_pyfunction!(te, m)?)?;
    m.add_function(wrap_pyfunction!(within_5cm5deg, m)?)?;
    m.add_function(wrap_pyfunction!(pose_errors, m)?)?;
    m.add("ADD_THRESHOLD_FRACTION", metrics::ADD_THRESHOLD_FRACTION)?;
    m.add("TE_THRESHOLD_M", metrics::TE_THRESHOLD_M)?;
    m.add("RE_THRESHOLD_DEG", metrics::RE_THRESHOLD_DEG)?;
    Ok(())
}
