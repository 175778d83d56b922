//! Frames handed to Python: buffers filled with the GIL released (rendered, decoded, masks
//! stacked), then moved into numpy arrays without a copy.

use numpy::ndarray::{Array1, Array2, Array3};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use synthgen_core::{GtInfo, Pose};

use crate::errors::{py_err, Kind};

/// One annotated object: its pose (metres, OpenCV camera frame) and, when known, BOP's
/// `scene_gt_info` entry.
pub struct ObjectData {
    /// Index in the frame's GT list (BOP's gt id).
    pub gt_id: usize,
    pub obj_id: u32,
    pub cam_from_obj: Pose,
    pub info: Option<GtInfo>,
}

/// A frame's images as owned buffers, row-major, `height x width`.
#[derive(Default)]
pub struct Images {
    pub width: usize,
    pub height: usize,
    pub rgb: Option<Vec<u8>>,
    pub depth_m: Option<Vec<f32>>,
    pub instance_ids: Option<Vec<u16>>,
    /// `n x height x width`, one per object in order.
    pub masks: Option<(usize, Vec<bool>)>,
    pub masks_visib: Option<(usize, Vec<bool>)>,
}

/// Masks of 0/255 (or any non-zero) bytes stacked into one `n x h x w` bool buffer.
pub fn stack_masks<'a>(masks: impl ExactSizeIterator<Item = &'a [u8]>) -> (usize, Vec<bool>) {
    let n = masks.len();
    let mut out = Vec::new();
    for m in masks {
        out.extend(m.iter().map(|&v| v != 0));
    }
    (n, out)
}

fn shape_err(e: impl std::error::Error + 'static) -> PyErr {
    py_err(Kind::Internal, &e, None)
}

impl Images {
    /// Sets `rgb`, `depth`, `instance_ids`, `masks`, `masks_visib` in `d` (those present).
    pub fn into_dict(self, d: &Bound<'_, PyDict>) -> PyResult<()> {
        let py = d.py();
        let (h, w) = (self.height, self.width);
        if let Some(rgb) = self.rgb {
            let a = Array3::from_shape_vec((h, w, 3), rgb).map_err(shape_err)?;
            d.set_item("rgb", a.into_pyarray(py))?;
        }
        if let Some(depth) = self.depth_m {
            let a = Array2::from_shape_vec((h, w), depth).map_err(shape_err)?;
            d.set_item("depth", a.into_pyarray(py))?;
        }
        if let Some(ids) = self.instance_ids {
            let a = Array2::from_shape_vec((h, w), ids).map_err(shape_err)?;
            d.set_item("instance_ids", a.into_pyarray(py))?;
        }
        for (key, masks) in [("masks", self.masks), ("masks_visib", self.masks_visib)] {
            if let Some((n, m)) = masks {
                let a = Array3::from_shape_vec((n, h, w), m).map_err(shape_err)?;
                d.set_item(key, a.into_pyarray(py))?;
            }
        }
        Ok(())
    }
}

/// `cam_K` as a 3x3 float64 array.
pub fn cam_k<'py>(py: Python<'py>, k_row_major: &[f64; 9]) -> PyResult<Bound<'py, PyAny>> {
    let a = Array2::from_shape_vec((3, 3), k_row_major.to_vec()).map_err(shape_err)?;
    Ok(a.into_pyarray(py).into_any())
}

/// The frame's `objects`: a list of dicts in GT order.
pub fn objects_list<'py>(py: Python<'py>, objects: &[ObjectData]) -> PyResult<Bound<'py, PyList>> {
    let list = PyList::empty(py);
    for o in objects {
        let d = PyDict::new(py);
        d.set_item("obj_id", o.obj_id)?;
        let r = Array2::from_shape_vec((3, 3), o.cam_from_obj.rotation_row_major().to_vec())
            .map_err(shape_err)?;
        d.set_item("R", r.into_pyarray(py))?;
        let t = Array1::from_vec(o.cam_from_obj.translation_m.to_array().to_vec());
        d.set_item("t", t.into_pyarray(py))?;
        match &o.info {
            Some(i) => {
                d.set_item("bbox_obj", i.bbox_obj.to_vec())?;
                d.set_item("bbox_visib", i.bbox_visib.to_vec())?;
                d.set_item("visib_fract", i.visib_fract)?;
                d.set_item("px_count_all", i.px_count_all)?;
                d.set_item("px_count_valid", i.px_count_valid)?;
                d.set_item("px_count_visib", i.px_count_visib)?;
            }
            None => {
                for key in [
                    "bbox_obj",
                    "bbox_visib",
                    "visib_fract",
                    "px_count_all",
                    "px_count_valid",
                    "px_count_visib",
                ] {
                    d.set_item(key, py.None())?;
                }
            }
        }
        d.set_item("gt_id", o.gt_id)?;
        list.append(d)?;
    }
    Ok(list)
}

/// A frame the pipeline rendered, as buffers: everything but the numpy wrapping, which needs
/// the GIL.
pub struct Rendered {
    pub index: u64,
    pub cam_k: [f64; 9],
    pub objects: Vec<ObjectData>,
    pub images: Images,
}

impl Rendered {
    pub fn new(f: synthgen_pipeline::Frame) -> Rendered {
        let (masks, masks_visib) = (
            stack_masks(f.objects.iter().map(|o| o.mask.as_slice())),
            stack_masks(f.objects.iter().map(|o| o.mask_visib.as_slice())),
        );
        let objects = f
            .objects
            .iter()
            .enumerate()
            .map(|(gt_id, o)| ObjectData {
                gt_id,
                obj_id: o.obj_id,
                cam_from_obj: o.cam_from_obj,
                info: Some(o.info),
            })
            .collect();
        Rendered {
            index: f.index,
            cam_k: f.cam_k(),
            objects,
            images: Images {
                width: f.width as usize,
                height: f.height as usize,
                rgb: Some(f.rgb),
                depth_m: Some(f.depth_m),
                instance_ids: Some(f.instance_ids),
                masks: Some(masks),
                masks_visib: Some(masks_visib),
            },
        }
    }

    /// The keyword arguments of Python's `Frame`.
    pub fn into_dict(self, py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("index", self.index)?;
        d.set_item("cam_K", cam_k(py, &self.cam_k)?)?;
        d.set_item("objects", objects_list(py, &self.objects)?)?;
        self.images.into_dict(&d)?;
        Ok(d)
    }
}
