//! `synthgen stats`: counts and distributions of a dataset's annotations (camera distance,
//! elevation, in-plane rotation, visibility), alone or beside another dataset's on shared
//! bins ([`compare_stats`]): what tells a user how to set up the scene sampler to look like
//! their real frames. Text in [`text`], charts in [`plot`].

mod plot;
mod text;

use std::collections::BTreeMap;

use serde::Serialize;
use synthgen_core::glam::DVec3;

use synthgen_formats::source::FrameSource;
use synthgen_formats::Result;

pub use plot::{bar_chart, write_comparison_plots, write_plots};
pub use text::{format_comparison, format_stats};

/// Counts per bin over `[lo, hi]`; the last bin includes `hi`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Histogram {
    pub lo: f64,
    pub hi: f64,
    pub counts: Vec<u64>,
}

impl Histogram {
    pub fn new(lo: f64, hi: f64, bins: usize) -> Histogram {
        Histogram {
            lo,
            hi,
            counts: vec![0; bins.max(1)],
        }
    }

    pub fn add(&mut self, v: f64) {
        let n = self.counts.len();
        let width = self.hi - self.lo;
        let i = if width > 0.0 {
            (((v - self.lo) / width) * n as f64).floor()
        } else {
            0.0
        };
        let i = i.clamp(0.0, (n - 1) as f64) as usize;
        self.counts[i] += 1;
    }

    /// Lower edge of bin `i`.
    pub fn edge(&self, i: usize) -> f64 {
        self.lo + (self.hi - self.lo) * i as f64 / self.counts.len() as f64
    }
}

/// Min, median, mean, max of a sample, with a histogram over [min, max].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Distribution {
    pub count: usize,
    pub min: f64,
    pub median: f64,
    pub mean: f64,
    pub max: f64,
    pub histogram: Histogram,
}

impl Distribution {
    fn of(mut values: Vec<f64>, bins: usize, range: Option<(f64, f64)>) -> Option<Distribution> {
        values.retain(|v| v.is_finite());
        if values.is_empty() {
            return None;
        }
        values.sort_by(f64::total_cmp);
        let (min, max) = (values[0], values[values.len() - 1]);
        let (lo, hi) = range.unwrap_or((min, max));
        let mut histogram = Histogram::new(lo, hi, bins);
        for &v in &values {
            histogram.add(v);
        }
        Some(Distribution {
            count: values.len(),
            min,
            median: values[values.len() / 2],
            mean: values.iter().sum::<f64>() / values.len() as f64,
            max,
            histogram,
        })
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObjectStats {
    pub obj_id: u32,
    /// Object instances over all frames.
    pub instances: u64,
    /// Frames showing the object at least once.
    pub frames: u64,
    /// Mean visib_fract of its instances, when scene_gt_info.json exists.
    pub mean_visib_fract: Option<f64>,
}

/// How the elevation was measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ElevationFrame {
    /// Camera above the world's xy plane, seen from the object (cam_R_w2c/cam_t_w2c present).
    World,
    /// Camera above the object's own xy plane (no world pose in scene_camera.json).
    Object,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DatasetStats {
    pub root: String,
    pub frames: usize,
    /// Frames per split.
    pub splits: BTreeMap<String, usize>,
    pub instances: u64,
    pub objects: Vec<ObjectStats>,
    /// Over all instances, 10 bins over [0, 1]; `None` without scene_gt_info.json.
    pub visib_fract: Option<Histogram>,
    /// Camera-to-object distance ‖cam_t_m2c‖ in metres, per instance.
    pub distance_m: Option<Distribution>,
    /// Camera elevation in degrees, per instance, 18 bins over [-90, 90].
    pub elevation_deg: Option<Distribution>,
    pub elevation_frame: ElevationFrame,
    /// In-plane rotation in degrees, per instance, 24 bins over [-180, 180]: the angle about
    /// the ray to the object between the image's up and the up direction (world z, else the
    /// object's z) seen there; 0 for an upright camera, ±180 upside down.
    pub inplane_deg: Option<Distribution>,
}

/// Per-instance values of a dataset, before binning.
#[derive(Debug, Clone, Default)]
pub struct Samples {
    root: String,
    frames: usize,
    splits: BTreeMap<String, usize>,
    instances: u64,
    per_obj: BTreeMap<u32, (u64, u64, f64, u64)>,
    visib: Option<Histogram>,
    distances: Vec<f64>,
    elevations: Vec<f64>,
    inplane: Vec<f64>,
    world: bool,
}

/// Reads every frame and computes the statistics.
pub fn compute_stats(source: &dyn FrameSource) -> Result<DatasetStats> {
    Ok(collect_samples(source)?.stats(None))
}

/// The statistics of several datasets on the same bins (the distance range spans all of
/// them), for side-by-side tables and charts.
pub fn compare_stats(sources: &[&dyn FrameSource]) -> Result<Vec<DatasetStats>> {
    let samples = sources
        .iter()
        .map(|s| collect_samples(*s))
        .collect::<Result<Vec<_>>>()?;
    let all = samples.iter().flat_map(|s| s.distances.iter().copied());
    let range = all
        .filter(|v| v.is_finite())
        .fold(None, |r: Option<(f64, f64)>, v| {
            Some(r.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))))
        });
    Ok(samples.iter().map(|s| s.stats(range)).collect())
}

/// Reads every frame's annotations into per-instance values.
pub fn collect_samples(source: &dyn FrameSource) -> Result<Samples> {
    let frames = source.frames(&[])?;
    let mut out = Samples {
        root: source.root().display().to_string(),
        frames: frames.len(),
        world: !frames.is_empty() && frames.iter().all(|f| f.camera.cam_from_world().is_some()),
        ..Samples::default()
    };
    let mut visib = Histogram::new(0.0, 1.0, 10);
    let mut any_info = false;
    for f in &frames {
        *out.splits.entry(f.location.split.clone()).or_default() += 1;
        for id in f.object_set() {
            out.per_obj.entry(id).or_default().1 += 1;
        }
        let cam_from_world = f.camera.cam_from_world();
        for (gt_id, g) in f.gt.iter().enumerate() {
            out.instances += 1;
            let e = out.per_obj.entry(g.obj_id).or_default();
            e.0 += 1;
            if let Some(info) = f.gt_info.as_ref().and_then(|i| i.get(gt_id)) {
                any_info = true;
                visib.add(info.visib_fract);
                e.2 += info.visib_fract;
                e.3 += 1;
            }
            let cam_from_obj = g.cam_from_obj();
            out.distances.push(cam_from_obj.translation_m.length());
            // The camera centre relative to the object, and "up", in the frame whose up we
            // measure (the world's when known, else the object's).
            let (obj_to_cam, up_in_cam) = match (out.world, cam_from_world) {
                (true, Some(cw)) => {
                    let world_from_cam = cw.inverse();
                    let cam_centre = world_from_cam.translation_m;
                    let obj_centre = world_from_cam.transform_point(cam_from_obj.translation_m);
                    (cam_centre - obj_centre, cw.transform_vector(DVec3::Z))
                }
                _ => (
                    cam_from_obj.inverse().translation_m,
                    cam_from_obj.transform_vector(DVec3::Z),
                ),
            };
            out.elevations.push(elevation_deg(obj_to_cam));
            out.inplane
                .push(inplane_deg(cam_from_obj.translation_m, up_in_cam));
        }
    }
    out.visib = any_info.then_some(visib);
    Ok(out)
}

impl Samples {
    /// Bins the samples; `distance_range` (metres) replaces the data's own min..max.
    pub fn stats(&self, distance_range: Option<(f64, f64)>) -> DatasetStats {
        let objects = self
            .per_obj
            .iter()
            .map(|(&obj_id, &(instances, frames, sum, n))| ObjectStats {
                obj_id,
                instances,
                frames,
                mean_visib_fract: (n > 0).then(|| sum / n as f64),
            })
            .collect();
        DatasetStats {
            root: self.root.clone(),
            frames: self.frames,
            splits: self.splits.clone(),
            instances: self.instances,
            objects,
            visib_fract: self.visib.clone(),
            distance_m: Distribution::of(self.distances.clone(), 10, distance_range),
            elevation_deg: Distribution::of(self.elevations.clone(), 18, Some((-90.0, 90.0))),
            elevation_frame: if self.world {
                ElevationFrame::World
            } else {
                ElevationFrame::Object
            },
            inplane_deg: Distribution::of(self.inplane.clone(), 24, Some((-180.0, 180.0))),
        }
    }
}

/// The signed angle (degrees) about the ray to `centre` (camera frame) from the image's up
/// (−y) to `up`, both seen in the plane perpendicular to the ray. NaN when either lies along
/// the ray.
fn inplane_deg(centre: DVec3, up: DVec3) -> f64 {
    let r = centre.normalize_or_zero();
    let on_plane = |v: DVec3| v - v.dot(r) * r;
    let (a, b) = (on_plane(-DVec3::Y), on_plane(up));
    if r == DVec3::ZERO || a.length_squared() < 1e-18 || b.length_squared() < 1e-18 {
        return f64::NAN;
    }
    r.dot(a.cross(b)).atan2(a.dot(b)).to_degrees()
}

fn elevation_deg(v: DVec3) -> f64 {
    let n = v.length();
    if n == 0.0 {
        return f64::NAN;
    }
    (v.z / n).clamp(-1.0, 1.0).asin().to_degrees()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn histogram_bins() {
        let mut h = Histogram::new(0.0, 1.0, 10);
        for v in [0.0, 0.05, 0.1, 0.95, 1.0, -3.0, 7.0] {
            h.add(v);
        }
        assert_eq!(h.counts, vec![3, 1, 0, 0, 0, 0, 0, 0, 0, 3]);
        assert!((h.edge(3) - 0.3).abs() < 1e-12);
    }

    #[test]
    fn inplane_rotation_of_a_rolled_camera() {
        let ahead = DVec3::new(0.0, 0.0, 1.0);
        // Up seen as the image's up: 0; rolled 90° about the optical axis one way or the other.
        assert!(inplane_deg(ahead, -DVec3::Y).abs() < 1e-9);
        assert!((inplane_deg(ahead, DVec3::X) - 90.0).abs() < 1e-9);
        assert!((inplane_deg(ahead, -DVec3::X) + 90.0).abs() < 1e-9);
        assert!((inplane_deg(ahead, DVec3::Y).abs() - 180.0).abs() < 1e-9);
        // Off-axis, the part of up along the ray does not count.
        let off = DVec3::new(0.3, 0.0, 1.0);
        assert!(inplane_deg(off, -DVec3::Y + off).abs() < 1e-9);
        assert!(inplane_deg(ahead, ahead).is_nan());
    }

    #[test]
    fn elevation_of_a_camera_straight_above() {
        assert!((elevation_deg(DVec3::new(0.0, 0.0, 2.0)) - 90.0).abs() < 1e-9);
        assert!(elevation_deg(DVec3::new(1.0, 0.0, 0.0)).abs() < 1e-9);
    }

    #[test]
    fn distribution_summary() {
        let d = Distribution::of(vec![3.0, 1.0, 2.0, f64::NAN], 2, None).unwrap();
        assert_eq!((d.count, d.min, d.median, d.max), (3, 1.0, 2.0, 3.0));
        assert_eq!(d.histogram.counts, vec![1, 2]);
        assert!(Distribution::of(vec![], 2, None).is_none());
    }
}
