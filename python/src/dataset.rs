//! `synthgen._native.Dataset`: a BOP, Linemod or YCB-Video folder through
//! `synthgen_formats::source` (the layout-independent reader `mix`, `train` and `eval` use):
//! annotations read once, images decoded on request with the GIL released.

use std::path::PathBuf;

use pyo3::prelude::*;
use pyo3::types::PyDict;
use synthgen_formats::bop::image::{read_depth_m, read_rgb};
use synthgen_formats::layout::open_source;
use synthgen_formats::layout::{detect_layout, Layout};
use synthgen_formats::source::{FrameSource, MaskRef, SourceFrame};

use crate::errors::input_error;
use crate::frame::{cam_k, objects_list, stack_masks, Images, ObjectData};
use crate::gil::detached;

#[pyclass(module = "synthgen._native", name = "Dataset", frozen)]
pub struct PyDataset {
    source: Box<dyn FrameSource>,
    frames: Vec<SourceFrame>,
    layout: String,
}

impl PyDataset {
    fn frame(&self, i: usize) -> PyResult<&SourceFrame> {
        self.frames.get(i).ok_or_else(|| {
            pyo3::exceptions::PyIndexError::new_err(format!(
                "frame {i} out of range (dataset has {})",
                self.frames.len()
            ))
        })
    }
}

/// Which of a frame's images to decode.
#[derive(Clone, Copy)]
struct Wanted {
    rgb: bool,
    depth: bool,
    masks: bool,
}

/// The selected instances' masks of one kind, or `None` when any of them has none.
fn read_masks(refs: &[Option<&MaskRef>]) -> synthgen_formats::Result<Option<Vec<Vec<u8>>>> {
    if refs.iter().any(Option::is_none) {
        return Ok(None);
    }
    refs.iter()
        .flatten()
        .map(|m| m.read().map(|p| p.data))
        .collect::<synthgen_formats::Result<Vec<_>>>()
        .map(Some)
}

fn pick<'a>(all: &'a [Option<MaskRef>], gt_ids: &[usize]) -> Vec<Option<&'a MaskRef>> {
    gt_ids
        .iter()
        .map(|&g| all.get(g).and_then(Option::as_ref))
        .collect()
}

fn load_images(
    f: &SourceFrame,
    gt_ids: &[usize],
    want: Wanted,
    size: (u32, u32),
) -> synthgen_formats::Result<Images> {
    let mut im = Images {
        width: size.0 as usize,
        height: size.1 as usize,
        ..Images::default()
    };
    if want.rgb {
        let rgb = read_rgb(&f.rgb)?;
        (im.width, im.height) = (rgb.width as usize, rgb.height as usize);
        im.rgb = Some(rgb.rgb);
    }
    if want.depth {
        if let Some(p) = &f.depth {
            let d = read_depth_m(p, f.camera.depth_scale)?;
            (im.width, im.height) = (d.width as usize, d.height as usize);
            im.depth_m = Some(d.data);
        }
    }
    if want.masks {
        let full = read_masks(&pick(&f.masks, gt_ids))?;
        let visib = read_masks(&pick(&f.masks_visib, gt_ids))?;
        let n_px = im.width * im.height;
        for m in full.iter().chain(&visib).flatten() {
            if m.len() != n_px {
                return Err(synthgen_formats::Error::Malformed {
                    file: "mask".into(),
                    message: format!(
                        "{} pixels, the frame has {}x{}",
                        m.len(),
                        im.width,
                        im.height
                    ),
                    path: f.rgb.clone(),
                });
            }
        }
        // Instance ids from the visible masks (from the full ones where a dataset has no
        // visible masks): `k + 1` for `objects[k]`, as the generator's frames.
        let mut ids = vec![0u16; n_px];
        if let Some(masks) = visib.as_ref().or(full.as_ref()) {
            for (k, m) in masks.iter().enumerate() {
                let id = u16::try_from(k + 1).unwrap_or(u16::MAX);
                for (dst, &v) in ids.iter_mut().zip(m) {
                    if v != 0 {
                        *dst = id;
                    }
                }
            }
        }
        im.instance_ids = Some(ids);
        im.masks = full.map(|m| stack_masks(m.iter().map(Vec::as_slice)));
        im.masks_visib = visib.map(|m| stack_masks(m.iter().map(Vec::as_slice)));
    }
    Ok(im)
}

#[pymethods]
impl PyDataset {
    /// Opens `path` in whichever layout it has; `splits` limits the splits read (all when
    /// empty).
    #[new]
    #[pyo3(signature = (path, splits=Vec::new()))]
    fn new(py: Python<'_>, path: PathBuf, splits: Vec<String>) -> PyResult<PyDataset> {
        if !path.is_dir() {
            return Err(input_error(
                format!("dataset folder not found: {}", path.display()),
                Some("pass a BOP, Linemod or YCB-Video dataset folder"),
            ));
        }
        let layout = match detect_layout(&path) {
            Some(Layout::Linemod) => "linemod",
            Some(Layout::Ycbv) => "ycbv",
            _ => "bop",
        };
        detached(py, || {
            let source = open_source(&path)?;
            let frames = source.frames(&splits)?;
            Ok::<_, synthgen_formats::Error>(PyDataset {
                source,
                frames,
                layout: layout.to_string(),
            })
        })
    }

    fn __len__(&self) -> usize {
        self.frames.len()
    }

    #[getter]
    fn root(&self) -> PathBuf {
        self.source.root().to_path_buf()
    }

    /// `bop`, `linemod` or `ycbv`.
    #[getter]
    fn layout(&self) -> String {
        self.layout.clone()
    }

    #[getter]
    fn splits(&self) -> Vec<String> {
        self.source.splits()
    }

    /// Per frame, the obj_id of each GT instance in GT order (for filtering without
    /// building frames).
    fn frame_obj_ids(&self) -> Vec<Vec<u32>> {
        self.frames
            .iter()
            .map(|f| f.gt.iter().map(|g| g.obj_id).collect())
            .collect()
    }

    /// Per frame, each instance's `visib_fract` (`None` where the dataset has no
    /// `scene_gt_info`).
    fn frame_visib_fracts(&self) -> Vec<Vec<Option<f64>>> {
        self.frames
            .iter()
            .map(|f| {
                (0..f.gt.len())
                    .map(|g| {
                        f.gt_info
                            .as_ref()
                            .and_then(|i| i.get(g))
                            .map(|i| i.visib_fract)
                    })
                    .collect()
            })
            .collect()
    }

    /// Frame `i`'s annotations for the instances `gt_ids` (all when `None`), as `Frame`
    /// keyword arguments without the images.
    #[pyo3(signature = (i, gt_ids=None))]
    fn annotations<'py>(
        &self,
        py: Python<'py>,
        i: usize,
        gt_ids: Option<Vec<usize>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let f = self.frame(i)?;
        let gt_ids = gt_ids.unwrap_or_else(|| (0..f.gt.len()).collect());
        let mut objects = Vec::with_capacity(gt_ids.len());
        for &g in &gt_ids {
            let gt = f.gt.get(g).ok_or_else(|| {
                pyo3::exceptions::PyIndexError::new_err(format!("no gt id {g} in frame {i}"))
            })?;
            objects.push(ObjectData {
                gt_id: g,
                obj_id: gt.obj_id,
                cam_from_obj: gt.cam_from_obj(),
                info: f.gt_info.as_ref().and_then(|v| v.get(g)).copied(),
            });
        }
        let d = PyDict::new(py);
        d.set_item("index", i)?;
        d.set_item("split", &f.location.split)?;
        d.set_item("scene_id", f.location.scene_id)?;
        d.set_item("im_id", f.location.im_id)?;
        d.set_item("cam_K", cam_k(py, &f.camera.cam_k)?)?;
        d.set_item("depth_scale", f.camera.depth_scale)?;
        d.set_item("rgb_path", &f.rgb)?;
        d.set_item("objects", objects_list(py, &objects)?)?;
        Ok(d)
    }

    /// Decodes frame `i`'s images (those asked for) for the instances `gt_ids`: `rgb`,
    /// `depth` (metres; absent when the frame has no depth image), `instance_ids`, `masks`
    /// and `masks_visib` (absent when the dataset lacks them for one of the instances).
    #[pyo3(signature = (i, gt_ids, rgb=true, depth=true, masks=true))]
    fn images<'py>(
        &self,
        py: Python<'py>,
        i: usize,
        gt_ids: Vec<usize>,
        rgb: bool,
        depth: bool,
        masks: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let f = self.frame(i)?;
        let cam = self.source.camera();
        let want = Wanted { rgb, depth, masks };
        let im = detached(py, || {
            load_images(f, &gt_ids, want, (cam.width, cam.height))
        })?;
        let d = PyDict::new(py);
        im.into_dict(&d)?;
        Ok(d)
    }

    /// Where the model file of an object belongs (present or not), and its units.
    fn model_file(&self, obj_id: u32) -> (PathBuf, String) {
        (
            self.source.model_file(obj_id),
            self.source.model_units().to_string(),
        )
    }

    /// `(points (M, 3) metres, diameter metres, symmetric)`: the evaluation model
    /// `synthgen eval` scores this object with (every vertex, as bop_toolkit does).
    fn eval_model<'py>(
        &self,
        py: Python<'py>,
        obj_id: u32,
    ) -> PyResult<(Bound<'py, PyAny>, f64, bool)> {
        let objects = detached(py, || {
            synthgen_train::eval::load_eval_objects(self.source.as_ref(), [obj_id])
        })?;
        let o = objects
            .get(&obj_id)
            .ok_or_else(|| input_error(format!("no model for object {obj_id}"), None))?;
        let points = crate::metrics::points_to_py(py, &o.points_m)?;
        Ok((points, o.diameter_m, o.symmetric))
    }
}
