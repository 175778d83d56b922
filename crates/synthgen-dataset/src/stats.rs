//! `synthgen stats`: counts and distributions of a dataset's annotations.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::Serialize;
use synthgen_core::glam::DVec3;

use std::path::{Path, PathBuf};

use crate::draw::Canvas;
use crate::error::Result;
use crate::io::create_dir_all;
use crate::source::FrameSource;

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
}

/// Reads every frame and computes the statistics.
pub fn compute_stats(source: &dyn FrameSource) -> Result<DatasetStats> {
    let frames = source.frames(&[])?;
    let mut splits: BTreeMap<String, usize> = BTreeMap::new();
    let mut per_obj: BTreeMap<u32, (u64, u64, f64, u64)> = BTreeMap::new();
    let mut visib = Histogram::new(0.0, 1.0, 10);
    let mut any_info = false;
    let (mut distances, mut elevations) = (Vec::new(), Vec::new());
    let world = !frames.is_empty() && frames.iter().all(|f| f.camera.cam_from_world().is_some());
    let mut instances = 0;
    for f in &frames {
        *splits.entry(f.location.split.clone()).or_default() += 1;
        for id in f.object_set() {
            per_obj.entry(id).or_default().1 += 1;
        }
        let cam_from_world = f.camera.cam_from_world();
        for (gt_id, g) in f.gt.iter().enumerate() {
            instances += 1;
            let e = per_obj.entry(g.obj_id).or_default();
            e.0 += 1;
            if let Some(info) = f.gt_info.as_ref().and_then(|i| i.get(gt_id)) {
                any_info = true;
                visib.add(info.visib_fract);
                e.2 += info.visib_fract;
                e.3 += 1;
            }
            let cam_from_obj = g.cam_from_obj();
            distances.push(cam_from_obj.translation_m.length());
            // The camera centre relative to the object, in the frame whose "up" we measure.
            let obj_to_cam = match (world, cam_from_world) {
                (true, Some(cw)) => {
                    let world_from_cam = cw.inverse();
                    let cam_centre = world_from_cam.translation_m;
                    let obj_centre = world_from_cam.transform_point(cam_from_obj.translation_m);
                    cam_centre - obj_centre
                }
                _ => cam_from_obj.inverse().translation_m,
            };
            elevations.push(elevation_deg(obj_to_cam));
        }
    }
    let objects = per_obj
        .into_iter()
        .map(|(obj_id, (instances, frames, sum, n))| ObjectStats {
            obj_id,
            instances,
            frames,
            mean_visib_fract: (n > 0).then(|| sum / n as f64),
        })
        .collect();
    Ok(DatasetStats {
        root: source.root().display().to_string(),
        frames: frames.len(),
        splits,
        instances,
        objects,
        visib_fract: any_info.then_some(visib),
        distance_m: Distribution::of(distances, 10, None),
        elevation_deg: Distribution::of(elevations, 18, Some((-90.0, 90.0))),
        elevation_frame: if world {
            ElevationFrame::World
        } else {
            ElevationFrame::Object
        },
    })
}

fn elevation_deg(v: DVec3) -> f64 {
    let n = v.length();
    if n == 0.0 {
        return f64::NAN;
    }
    (v.z / n).clamp(-1.0, 1.0).asin().to_degrees()
}

fn bar(count: u64, max: u64, width: usize) -> String {
    let n = if max == 0 {
        0
    } else {
        ((count as f64 / max as f64) * width as f64).round() as usize
    };
    "#".repeat(n)
}

/// One line per bin; empty bins before the first and after the last non-empty one are left
/// out (the JSON keeps them all).
fn write_histogram(out: &mut String, h: &Histogram, decimals: usize) {
    let max = h.counts.iter().copied().max().unwrap_or(0);
    let first = h.counts.iter().position(|&c| c > 0).unwrap_or(0);
    let last = h.counts.iter().rposition(|&c| c > 0).unwrap_or(0);
    for (i, &c) in h.counts.iter().enumerate() {
        if i < first || i > last {
            continue;
        }
        let _ = writeln!(
            out,
            "  {:>8.d$} .. {:>8.d$}  {:>7}  {}",
            h.edge(i),
            h.edge(i + 1),
            c,
            bar(c, max, 40),
            d = decimals
        );
    }
}

fn write_distribution(out: &mut String, title: &str, d: &Distribution, decimals: usize) {
    let _ = writeln!(
        out,
        "\n{title}: min {:.d$}, median {:.d$}, mean {:.d$}, max {:.d$}",
        d.min,
        d.median,
        d.mean,
        d.max,
        d = decimals
    );
    write_histogram(out, &d.histogram, decimals);
}

/// The statistics as a readable text table.
pub fn format_stats(s: &DatasetStats) -> String {
    let mut out = String::new();
    let _ = writeln!(out, "dataset    {}", s.root);
    let splits: Vec<String> = s.splits.iter().map(|(k, v)| format!("{k} {v}")).collect();
    let _ = writeln!(out, "frames     {} ({})", s.frames, splits.join(", "));
    let _ = writeln!(out, "objects    {}", s.objects.len());
    let _ = writeln!(out, "instances  {}", s.instances);
    let _ = writeln!(out, "\n  obj_id  instances   frames  mean visib_fract");
    for o in &s.objects {
        let v = o
            .mean_visib_fract
            .map_or("-".to_string(), |v| format!("{v:.3}"));
        let _ = writeln!(
            out,
            "  {:>6}  {:>9}  {:>7}  {:>16}",
            o.obj_id, o.instances, o.frames, v
        );
    }
    if let Some(h) = &s.visib_fract {
        let _ = writeln!(out, "\nvisib_fract (instances)");
        write_histogram(&mut out, h, 2);
    }
    if let Some(d) = &s.distance_m {
        write_distribution(&mut out, "camera distance (m)", d, 3);
    }
    if let Some(d) = &s.elevation_deg {
        let frame = match s.elevation_frame {
            ElevationFrame::World => "above the world xy plane",
            ElevationFrame::Object => "above the object's xy plane",
        };
        write_distribution(&mut out, &format!("camera elevation (deg, {frame})"), d, 1);
    }
    out
}

/// A bar chart of `counts` with the range's ends written under the axis (digits only: the
/// file name says what is plotted).
pub fn bar_chart(counts: &[u64], lo: &str, hi: &str) -> Canvas {
    let (w, h, margin) = (480u32, 240u32, 24i64);
    let mut c = Canvas::new(w, h, [255, 255, 255]);
    let max = counts.iter().copied().max().unwrap_or(0).max(1);
    let n = counts.len().max(1) as i64;
    let plot_w = w as i64 - 2 * margin;
    let plot_h = h as i64 - 2 * margin;
    for (i, &v) in counts.iter().enumerate() {
        let x0 = margin + plot_w * i as i64 / n;
        let x1 = margin + plot_w * (i as i64 + 1) / n;
        let bh = (plot_h as f64 * v as f64 / max as f64).round() as i64;
        c.fill_rect(
            x0 + 1,
            margin + plot_h - bh,
            (x1 - x0 - 2).max(1),
            bh,
            [70, 120, 200],
        );
    }
    let base = (margin + plot_h) as f64;
    c.line(
        (margin as f64, base),
        ((margin + plot_w) as f64, base),
        [0, 0, 0],
        1,
    );
    c.line(
        (margin as f64, margin as f64),
        (margin as f64, base),
        [0, 0, 0],
        1,
    );
    c.text(margin, base as i64 + 6, lo, 2, [255, 255, 255]);
    let hi_w = hi.chars().count() as i64 * 8;
    c.text(
        margin + plot_w - hi_w,
        base as i64 + 6,
        hi,
        2,
        [255, 255, 255],
    );
    c.text(margin + 4, 6, &max.to_string(), 2, [255, 255, 255]);
    c
}

/// Writes `visib_fract.png`, `distance_m.png`, `elevation_deg.png` and
/// `instances_per_object.png` (those with data) into `dir`; returns their paths.
pub fn write_plots(s: &DatasetStats, dir: &Path) -> Result<Vec<PathBuf>> {
    create_dir_all(dir)?;
    let mut charts = Vec::new();
    if let Some(h) = &s.visib_fract {
        charts.push(("visib_fract.png", bar_chart(&h.counts, "0", "1")));
    }
    for (name, d, decimals) in [
        ("distance_m.png", &s.distance_m, 2),
        ("elevation_deg.png", &s.elevation_deg, 0),
    ] {
        if let Some(d) = d {
            let h = &d.histogram;
            let lo = format!("{:.p$}", h.lo, p = decimals);
            let hi = format!("{:.p$}", h.hi, p = decimals);
            charts.push((name, bar_chart(&h.counts, &lo, &hi)));
        }
    }
    if !s.objects.is_empty() {
        let counts: Vec<u64> = s.objects.iter().map(|o| o.instances).collect();
        let first = s.objects.first().map_or(0, |o| o.obj_id).to_string();
        let last = s.objects.last().map_or(0, |o| o.obj_id).to_string();
        charts.push((
            "instances_per_object.png",
            bar_chart(&counts, &first, &last),
        ));
    }
    let mut paths = Vec::new();
    for (name, canvas) in charts {
        let p = dir.join(name);
        canvas.write_png(&p)?;
        paths.push(p);
    }
    Ok(paths)
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
