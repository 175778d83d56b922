//! What the viewer holds: the datasets' annotations (no images: those are read on request),
//! the per-frame summaries the grid filters on, the estimates of `--results`, and the
//! thumbnail cache.

use std::collections::{BTreeMap, HashMap, VecDeque};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use serde::Serialize;
use synthgen_formats::bop::ModelInfo;
use synthgen_formats::layout::open_source;
use synthgen_formats::source::{FrameSource, SourceFrame};
use synthgen_train::eval::{evaluate, load_eval_objects, GtInstance};
use synthgen_train::metrics::{PoseErrors, Rotations};
use synthgen_train::results::{read_results_csv, Estimate};

use crate::Error;

/// One dataset given to `synthgen view`.
pub struct Dataset {
    pub name: String,
    /// Canonical root: every file served must lie below it.
    pub root: PathBuf,
    pub source: Box<dyn FrameSource>,
    pub frames: Vec<SourceFrame>,
    pub summaries: Vec<FrameSummary>,
    pub models: BTreeMap<u32, ModelInfo>,
    /// Per frame index and gt id: the matched estimate and its errors (`--results`).
    pub estimates: HashMap<(usize, usize), (Estimate, PoseErrors)>,
}

/// What the grid shows and filters on, per frame.
#[derive(Debug, Clone, Serialize)]
pub struct FrameSummary {
    pub idx: usize,
    pub split: String,
    pub scene_id: u32,
    pub im_id: u32,
    pub instances: Vec<InstanceSummary>,
}

#[derive(Debug, Clone, Copy, Serialize)]
pub struct InstanceSummary {
    pub obj_id: u32,
    /// 1 when the dataset has no scene_gt_info.
    pub visib_fract: f64,
    /// Distance of the object's origin from the camera, metres.
    pub distance_m: f64,
}

/// The grid's filters; an instance must pass all of them for its frame to be listed.
#[derive(Debug, Clone, Default)]
pub struct Filter {
    pub obj: Option<u32>,
    pub scene: Option<u32>,
    pub split: Option<String>,
    pub min_visib: Option<f64>,
    pub max_visib: Option<f64>,
    pub min_dist: Option<f64>,
    pub max_dist: Option<f64>,
}

impl Filter {
    pub fn keeps(&self, f: &FrameSummary) -> bool {
        if self.scene.is_some_and(|s| s != f.scene_id)
            || self
                .split
                .as_ref()
                .is_some_and(|s| !s.is_empty() && *s != f.split)
        {
            return false;
        }
        let any_instance_filter = self.obj.is_some()
            || self.min_visib.is_some()
            || self.max_visib.is_some()
            || self.min_dist.is_some()
            || self.max_dist.is_some();
        !any_instance_filter
            || f.instances.iter().any(|i| {
                self.obj.is_none_or(|o| o == i.obj_id)
                    && self.min_visib.is_none_or(|v| i.visib_fract >= v)
                    && self.max_visib.is_none_or(|v| i.visib_fract <= v)
                    && self.min_dist.is_none_or(|d| i.distance_m >= d)
                    && self.max_dist.is_none_or(|d| i.distance_m <= d)
            })
    }
}

/// A frame: (dataset, index).
type Key = (usize, usize);

/// Thumbnails (JPEG bytes) by (dataset, frame), the oldest dropped beyond `capacity`.
pub struct ThumbCache {
    capacity: usize,
    inner: Mutex<ThumbMap>,
}

#[derive(Default)]
struct ThumbMap {
    bytes: HashMap<Key, std::sync::Arc<Vec<u8>>>,
    order: VecDeque<Key>,
}

impl ThumbCache {
    pub fn new(capacity: usize) -> ThumbCache {
        ThumbCache {
            capacity,
            inner: Mutex::new(ThumbMap::default()),
        }
    }

    pub fn get(&self, key: Key) -> Option<std::sync::Arc<Vec<u8>>> {
        self.inner.lock().ok()?.bytes.get(&key).cloned()
    }

    pub fn put(&self, key: Key, bytes: std::sync::Arc<Vec<u8>>) {
        let Ok(mut g) = self.inner.lock() else { return };
        let ThumbMap { bytes: map, order } = &mut *g;
        if map.insert(key, bytes).is_none() {
            order.push_back(key);
        }
        while order.len() > self.capacity {
            if let Some(old) = order.pop_front() {
                map.remove(&old);
            }
        }
    }
}

/// Everything the server serves from.
pub struct Viewer {
    pub datasets: Vec<Dataset>,
    pub thumbs: ThumbCache,
    pub results: Option<PathBuf>,
    /// The statistics page's numbers, made on first request.
    pub stats: std::sync::OnceLock<Result<serde_json::Value, String>>,
}

fn summarize(idx: usize, f: &SourceFrame) -> FrameSummary {
    FrameSummary {
        idx,
        split: f.location.split.clone(),
        scene_id: f.location.scene_id,
        im_id: f.location.im_id,
        instances: f
            .gt
            .iter()
            .enumerate()
            .map(|(g, e)| InstanceSummary {
                obj_id: e.obj_id,
                visib_fract: f
                    .gt_info
                    .as_ref()
                    .and_then(|v| v.get(g))
                    .map_or(1.0, |i| i.visib_fract),
                distance_m: e.cam_from_obj().translation_m.length(),
            })
            .collect(),
    }
}

impl Dataset {
    /// Opens a dataset of any layout synthgen reads and indexes its annotations.
    pub fn open(root: &Path) -> Result<Dataset, Error> {
        let source = open_source(root).map_err(|e| Error::Open {
            path: root.to_path_buf(),
            message: e.to_string(),
        })?;
        let frames = source.frames(&[]).map_err(|e| Error::Open {
            path: root.to_path_buf(),
            message: e.to_string(),
        })?;
        let summaries = frames
            .iter()
            .enumerate()
            .map(|(i, f)| summarize(i, f))
            .collect();
        let canonical = root.canonicalize().map_err(|e| Error::Open {
            path: root.to_path_buf(),
            message: e.to_string(),
        })?;
        let name = canonical.file_name().map_or_else(
            || canonical.display().to_string(),
            |n| n.to_string_lossy().into(),
        );
        Ok(Dataset {
            name,
            root: canonical,
            models: source.models_info().cloned().unwrap_or_default(),
            source,
            frames,
            summaries,
            estimates: HashMap::new(),
        })
    }

    /// Matches a results CSV's estimates to this dataset's GT (as `synthgen eval` does) and
    /// keeps them per (frame, gt id). Returns how many rows were skipped as unreadable.
    pub fn attach_results(&mut self, csv: &Path) -> Result<usize, Error> {
        let results = read_results_csv(csv).map_err(|e| Error::Open {
            path: csv.to_path_buf(),
            message: e.to_string(),
        })?;
        let mut gts = Vec::new();
        let mut at: HashMap<(u32, u32), usize> = HashMap::new();
        for (idx, f) in self.frames.iter().enumerate() {
            at.insert((f.location.scene_id, f.location.im_id), idx);
            for (gt_id, g) in f.gt.iter().enumerate() {
                gts.push(GtInstance {
                    scene_id: f.location.scene_id,
                    im_id: f.location.im_id,
                    gt_id,
                    obj_id: g.obj_id,
                    pose: g.cam_from_obj(),
                    stored: g.cam_from_obj_as_stored(),
                    visib_fract: 1.0,
                });
            }
        }
        let objects = load_eval_objects(self.source.as_ref(), gts.iter().map(|g| g.obj_id))
            .map_err(|e| Error::Open {
                path: self.root.clone(),
                message: e.to_string(),
            })?;
        let report =
            evaluate(&gts, &results.estimates, &objects, Rotations::default()).map_err(|e| {
                Error::Open {
                    path: csv.to_path_buf(),
                    message: e.to_string(),
                }
            })?;
        for m in report.matches {
            if let (Some(e), Some(&idx)) = (m.estimate, at.get(&(m.gt.scene_id, m.gt.im_id))) {
                self.estimates.insert((idx, m.gt.gt_id), e);
            }
        }
        Ok(results.skipped.len())
    }
}

impl Viewer {
    /// Opens `roots`; `results` (a BOP results CSV) is matched against the first.
    pub fn open(roots: &[PathBuf], results: Option<&Path>) -> Result<Viewer, Error> {
        let mut datasets = roots
            .iter()
            .map(|r| Dataset::open(r))
            .collect::<Result<Vec<_>, _>>()?;
        if let (Some(csv), Some(first)) = (results, datasets.first_mut()) {
            first.attach_results(csv)?;
        }
        Ok(Viewer {
            datasets,
            thumbs: ThumbCache::new(20_000),
            results: results.map(Path::to_path_buf),
            stats: std::sync::OnceLock::new(),
        })
    }

    pub fn frame(&self, ds: usize, idx: usize) -> Option<(&Dataset, &SourceFrame)> {
        let d = self.datasets.get(ds)?;
        Some((d, d.frames.get(idx)?))
    }
}
