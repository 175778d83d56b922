//! What `sensor fit` and `sensor compare` measure on a dataset: every frame's objects
//! rendered at their GT poses (the clean depth, through a [`PoseRenderer`]), and the
//! dataset's own depth readings on those object pixels, summarized as counts and histograms
//! over the features the structured-light model depends on. Everything here adds up frame by
//! frame ([`DepthStats::merge`]), so frames are measured in parallel.

use std::collections::BTreeMap;

use serde::Serialize;
use synthgen_core::depth_features::{
    discontinuities, edge_distance, incidence_map_deg, luminance_map, viewpoint_shadow,
};
use synthgen_core::{Intrinsics, PoseRenderer};

use synthgen_formats::bop::image::{read_depth_m, read_rgb};
use synthgen_formats::source::{FrameLocation, SourceFrame};
use synthgen_formats::{Error, Result};

/// A reading within this of the clean depth is a reading of the object's surface; farther
/// ones read another surface (behind: "far", in front: "near").
pub const SURFACE_TOL_M: f64 = 0.03;
/// The features' depth-edge test: a 4-neighbour empty or off by more than this fraction.
pub const EDGE_REL: f32 = 0.03;
/// Edge distances are binned per pixel up to this; the last bin holds all farther ones.
pub const EDGE_BINS: usize = 17;
/// Incidence bins of 5°.
pub const THETA_BINS: usize = 18;
/// Brightness bins of 0.05.
pub const LUM_BINS: usize = 20;
/// Clean-depth bins of 0.1 m from 0.
pub const Z_BINS: usize = 50;
/// Residual histograms: 0.1 mm bins over ±30 mm.
pub const RESID_BINS: usize = 600;
const RESID_HALF_M: f64 = 0.03;
/// Offset of the nominal second viewpoint that marks the object pixels that some closer
/// surface could shadow (PrimeSense's projector baseline), metres.
pub const ZONE_BASELINE_M: f64 = 0.075;
/// Edge-profile samples per side: 3 outside (s = 1..3), 8 inside (s = 0..7).
pub const PROFILE_LEN: usize = 11;
/// Object-like reading outside the silhouette: within this of the edge's clean depth.
const PROFILE_TOL_M: f64 = 0.015;
/// Shadow-run bins of g = fx (1/z_near − 1/z_far), px per metre of baseline.
pub const RUN_BIN_EDGES: [f64; 7] = [0.0, 5.0, 10.0, 20.0, 40.0, 80.0, 160.0];

/// Pixel counts of one feature cell (or bin).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Cell {
    /// Object pixels.
    pub n: u64,
    /// Of those, no reading.
    pub holes: u64,
    /// A reading more than [`SURFACE_TOL_M`] behind the surface.
    pub far: u64,
    /// A reading more than [`SURFACE_TOL_M`] in front of it.
    pub near: u64,
    /// Sums of the features, for the cell's means.
    pub sum_edge: f64,
    pub sum_theta: f64,
    pub sum_lum: f64,
}

impl Cell {
    fn add(&mut self, o: &Cell) {
        self.n += o.n;
        self.holes += o.holes;
        self.far += o.far;
        self.near += o.near;
        self.sum_edge += o.sum_edge;
        self.sum_theta += o.sum_theta;
        self.sum_lum += o.sum_lum;
    }

    /// Share of pixels without a reading (0 when empty).
    pub fn hole_rate(&self) -> f64 {
        ratio(self.holes, self.n)
    }

    /// Share of pixels reading another surface.
    pub fn off_rate(&self) -> f64 {
        ratio(self.far + self.near, self.n)
    }

    /// Share of pixels without a reading of their own surface: a hole, or a reading more
    /// than [`SURFACE_TOL_M`] off (the surface behind or in front).
    pub fn miss_rate(&self) -> f64 {
        ratio(self.holes + self.far + self.near, self.n)
    }

    pub fn mean_edge(&self) -> f64 {
        self.sum_edge / self.n.max(1) as f64
    }
    pub fn mean_theta(&self) -> f64 {
        self.sum_theta / self.n.max(1) as f64
    }
    pub fn mean_lum(&self) -> f64 {
        self.sum_lum / self.n.max(1) as f64
    }
}

pub(crate) fn ratio(a: u64, b: u64) -> f64 {
    if b == 0 {
        0.0
    } else {
        a as f64 / b as f64
    }
}

/// A histogram of depth residuals (0.1 mm bins over ±30 mm) with the mean clean depth and
/// mean tan² of the incidence of what went in.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualHist {
    #[serde(skip)]
    pub counts: Vec<u64>,
    pub n: u64,
    pub sum_z: f64,
    pub sum_tan2: f64,
}

impl Default for ResidualHist {
    fn default() -> Self {
        ResidualHist {
            counts: vec![0; RESID_BINS],
            n: 0,
            sum_z: 0.0,
            sum_tan2: 0.0,
        }
    }
}

impl ResidualHist {
    fn push(&mut self, e: f64, z: f64, tan2: f64) {
        let b = ((e + RESID_HALF_M) / (2.0 * RESID_HALF_M) * RESID_BINS as f64).floor();
        if b >= 0.0 && b < RESID_BINS as f64 {
            self.counts[b as usize] += 1;
            self.n += 1;
            self.sum_z += z;
            self.sum_tan2 += tan2;
        }
    }

    fn add(&mut self, o: &ResidualHist) {
        for (a, b) in self.counts.iter_mut().zip(&o.counts) {
            *a += b;
        }
        self.n += o.n;
        self.sum_z += o.sum_z;
        self.sum_tan2 += o.sum_tan2;
    }

    /// The centre of bin `i`, metres.
    pub fn centre(i: usize) -> f64 {
        -RESID_HALF_M + (i as f64 + 0.5) * 2.0 * RESID_HALF_M / RESID_BINS as f64
    }

    /// The `q` quantile (0..1), metres, interpolated within the bin; 0 when empty.
    pub fn quantile(&self, q: f64) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        let target = q * self.n as f64;
        let width = 2.0 * RESID_HALF_M / RESID_BINS as f64;
        let mut acc = 0.0;
        for (i, &c) in self.counts.iter().enumerate() {
            let next = acc + c as f64;
            if next >= target && c > 0 {
                let t = (target - acc) / c as f64;
                return -RESID_HALF_M + (i as f64 + t) * width;
            }
            acc = next;
        }
        RESID_HALF_M
    }

    /// Robust spread: 1.4826 × the median absolute deviation from the median, metres.
    pub fn robust_sigma(&self) -> f64 {
        if self.n == 0 {
            return 0.0;
        }
        let med = self.quantile(0.5);
        // The MAD from the histogram: the smallest r with half the mass within med ± r.
        let width = 2.0 * RESID_HALF_M / RESID_BINS as f64;
        let mut lo = 0.0;
        let mut hi = RESID_HALF_M * 2.0;
        for _ in 0..40 {
            let r = 0.5 * (lo + hi);
            let mass: f64 = self
                .counts
                .iter()
                .enumerate()
                .map(|(i, &c)| {
                    let a = -RESID_HALF_M + i as f64 * width;
                    let b = a + width;
                    let overlap = (b.min(med + r) - a.max(med - r)).max(0.0) / width;
                    overlap * c as f64
                })
                .sum();
            if mass >= 0.5 * self.n as f64 {
                hi = r;
            } else {
                lo = r;
            }
        }
        1.4826 * hi
    }

    pub fn mean_z(&self) -> f64 {
        self.sum_z / self.n.max(1) as f64
    }

    pub fn mean_tan2(&self) -> f64 {
        self.sum_tan2 / self.n.max(1) as f64
    }

    /// Wasserstein-1 distance to `other`, metres: the area between the two CDFs.
    pub fn wasserstein1(&self, other: &ResidualHist) -> f64 {
        if self.n == 0 || other.n == 0 {
            return f64::NAN;
        }
        let width = 2.0 * RESID_HALF_M / RESID_BINS as f64;
        let (mut a, mut b, mut w) = (0.0, 0.0, 0.0);
        for (ca, cb) in self.counts.iter().zip(&other.counts) {
            a += *ca as f64 / self.n as f64;
            b += *cb as f64 / other.n as f64;
            w += (a - b).abs() * width;
        }
        w
    }
}

/// Object-like readings at one edge-profile position.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ProfileCell {
    pub n: u64,
    pub object_like: u64,
}

impl ProfileCell {
    pub fn rate(&self) -> f64 {
        ratio(self.object_like, self.n)
    }
}

/// Hole runs just outside silhouettes on one side, by bin of g (see [`RUN_BIN_EDGES`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct RunBin {
    pub n: u64,
    pub sum_run: f64,
    pub sum_g: f64,
}

/// One frame's median |reading − clean| over its object pixels with a reading.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FrameResidual {
    pub location: FrameLocation,
    pub median_abs_m: f64,
    pub pixels: u64,
    /// Left out of the statistics (GT obviously off).
    pub left_out: bool,
}

/// Per scene or per object: pixels, holes and the residual histogram.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct GroupStats {
    pub cell: Cell,
    pub residuals: ResidualHist,
}

impl GroupStats {
    fn add(&mut self, o: &GroupStats) {
        self.cell.add(&o.cell);
        self.residuals.add(&o.residuals);
    }
}

/// Everything measured on a set of frames.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DepthStats {
    pub frames: usize,
    pub instances: usize,
    /// Focal length of the frames (the last one's), pixels: what shadow widths are in.
    pub fx: f64,
    /// Object pixels outside both nominal shadow zones, by (edge, incidence, brightness) cell:
    /// index `(e * THETA_BINS + t) * LUM_BINS + l`.
    #[serde(skip)]
    pub cells: Vec<Cell>,
    /// The same for pixels inside a nominal shadow zone.
    #[serde(skip)]
    pub zone_cells: Vec<Cell>,
    /// Pixels a closer surface would shadow from a viewpoint [`ZONE_BASELINE_M`] to the left
    /// ([0]: shadow on the right of occluders) and to the right ([1]).
    pub zones: [Cell; 2],
    /// Detrended surface residuals of interior pixels (edge ≥ 4 px, incidence < 30°), by
    /// clean depth bin.
    #[serde(skip)]
    pub resid_by_z: Vec<ResidualHist>,
    /// Detrended surface residuals of pixels ≥ 2 px from an edge, by incidence bin.
    #[serde(skip)]
    pub resid_by_theta: Vec<ResidualHist>,
    /// All detrended surface residuals.
    pub resid_all: ResidualHist,
    /// Per instance: the median of reading − clean over its surface readings (metres).
    pub offsets: Vec<f64>,
    /// Edge profile: [left edges, right edges] × [outside s = 3, 2, 1, inside s = 0..7].
    pub profile: [[ProfileCell; PROFILE_LEN]; 2],
    /// Hole runs outside [left, right] silhouette edges against a farther background.
    pub runs: [[RunBin; 6]; 2],
    /// The same per scene: scenes may disagree on the projector's side (another rig).
    #[serde(skip)]
    pub runs_by_scene: BTreeMap<u32, [[RunBin; 6]; 2]>,
    /// Horizontal runs of holes within object pixels: how many, and their pixels.
    pub hole_runs: u64,
    pub hole_run_px: u64,
    pub frame_residuals: Vec<FrameResidual>,
    pub by_scene: BTreeMap<u32, GroupStats>,
    pub by_object: BTreeMap<u32, GroupStats>,
}

impl Default for DepthStats {
    fn default() -> Self {
        let n = EDGE_BINS * THETA_BINS * LUM_BINS;
        DepthStats {
            frames: 0,
            instances: 0,
            fx: 0.0,
            cells: vec![Cell::default(); n],
            zone_cells: vec![Cell::default(); n],
            zones: [Cell::default(); 2],
            resid_by_z: vec![ResidualHist::default(); Z_BINS],
            resid_by_theta: vec![ResidualHist::default(); THETA_BINS],
            resid_all: ResidualHist::default(),
            offsets: Vec::new(),
            profile: [[ProfileCell::default(); PROFILE_LEN]; 2],
            runs: [[RunBin::default(); 6]; 2],
            runs_by_scene: BTreeMap::new(),
            hole_runs: 0,
            hole_run_px: 0,
            frame_residuals: Vec::new(),
            by_scene: BTreeMap::new(),
            by_object: BTreeMap::new(),
        }
    }
}

/// The cell index of pixel features.
pub fn cell_index(edge: u8, theta_deg: f32, lum: f32) -> usize {
    let e = usize::from(edge).min(EDGE_BINS - 1);
    let t = ((theta_deg / 5.0) as usize).min(THETA_BINS - 1);
    let l = ((lum * LUM_BINS as f32) as usize).min(LUM_BINS - 1);
    (e * THETA_BINS + t) * LUM_BINS + l
}

/// The (edge, incidence, brightness) bins of a cell index.
pub fn cell_bins(i: usize) -> (usize, usize, usize) {
    (
        i / (THETA_BINS * LUM_BINS),
        (i / LUM_BINS) % THETA_BINS,
        i % LUM_BINS,
    )
}

impl DepthStats {
    /// Adds `o` to `self`.
    pub fn merge(&mut self, o: &DepthStats) {
        self.frames += o.frames;
        self.instances += o.instances;
        if o.fx > 0.0 {
            self.fx = o.fx;
        }
        for (a, b) in self.cells.iter_mut().zip(&o.cells) {
            a.add(b);
        }
        for (a, b) in self.zone_cells.iter_mut().zip(&o.zone_cells) {
            a.add(b);
        }
        for (a, b) in self.zones.iter_mut().zip(&o.zones) {
            a.add(b);
        }
        for (a, b) in self.resid_by_z.iter_mut().zip(&o.resid_by_z) {
            a.add(b);
        }
        for (a, b) in self.resid_by_theta.iter_mut().zip(&o.resid_by_theta) {
            a.add(b);
        }
        self.resid_all.add(&o.resid_all);
        self.offsets.extend_from_slice(&o.offsets);
        self.hole_runs += o.hole_runs;
        self.hole_run_px += o.hole_run_px;
        for s in 0..2 {
            for (a, b) in self.profile[s].iter_mut().zip(&o.profile[s]) {
                a.n += b.n;
                a.object_like += b.object_like;
            }
            for (a, b) in self.runs[s].iter_mut().zip(&o.runs[s]) {
                a.n += b.n;
                a.sum_run += b.sum_run;
                a.sum_g += b.sum_g;
            }
        }
        for (scene, runs) in &o.runs_by_scene {
            let mine = self.runs_by_scene.entry(*scene).or_default();
            for s in 0..2 {
                for (a, b) in mine[s].iter_mut().zip(&runs[s]) {
                    a.n += b.n;
                    a.sum_run += b.sum_run;
                    a.sum_g += b.sum_g;
                }
            }
        }
        self.frame_residuals
            .extend(o.frame_residuals.iter().cloned());
        for (k, v) in &o.by_scene {
            self.by_scene.entry(*k).or_default().add(v);
        }
        for (k, v) in &o.by_object {
            self.by_object.entry(*k).or_default().add(v);
        }
    }

    /// Mean length of the horizontal hole runs in object pixels, pixels (0 without holes).
    pub fn mean_hole_run(&self) -> f64 {
        if self.hole_runs == 0 {
            0.0
        } else {
            self.hole_run_px as f64 / self.hole_runs as f64
        }
    }

    /// All object pixels (both cell grids) summed.
    pub fn total(&self) -> Cell {
        let mut c = Cell::default();
        for x in self.cells.iter().chain(&self.zone_cells) {
            c.add(x);
        }
        c
    }

    /// Both cell grids summed by a key of the cell's bins.
    pub fn marginal(&self, key: impl Fn(usize, usize, usize) -> usize, bins: usize) -> Vec<Cell> {
        let mut out = vec![Cell::default(); bins];
        for (i, c) in self.cells.iter().zip(&self.zone_cells).enumerate() {
            let (e, t, l) = cell_bins(i);
            let k = key(e, t, l);
            if k < bins {
                out[k].add(c.0);
                out[k].add(c.1);
            }
        }
        out
    }
}

/// The clean depth, instance ids and features of one frame, and its readings.
pub struct FrameView {
    pub k: Intrinsics,
    pub clean: Vec<f32>,
    pub instance: Vec<u16>,
    pub reading: Vec<f32>,
    pub lum: Vec<f32>,
    pub edge: Vec<u8>,
    pub theta: Vec<f32>,
    /// obj_id per instance (instance i + 1 = gt i).
    pub obj_ids: Vec<u32>,
}

/// Renders a frame's objects at their GT poses and reads its depth and colour images.
/// A frame without a depth image is an error naming it.
pub fn frame_view(
    renderer: &dyn PoseRenderer,
    frame: &SourceFrame,
    width: u32,
    height: u32,
) -> Result<FrameView> {
    let loc = &frame.location;
    let Some(depth_path) = &frame.depth else {
        return Err(Error::InvalidRequest(format!(
            "{}/{:06} image {} has no depth image (looked beside {}); fitting and comparing \
             depth sensors needs the depth readings",
            loc.split,
            loc.scene_id,
            loc.im_id,
            frame.rgb.display()
        )));
    };
    let k = frame.camera.intrinsics(width, height);
    let rendered = synthgen_formats::annotate::render_gt(renderer, frame, &k)?;
    let d = read_depth_m(depth_path, frame.camera.depth_scale)?;
    if (d.width, d.height) != (width, height) {
        return Err(Error::malformed(
            depth_path,
            format!(
                "depth image is {}x{} but the camera is {width}x{height}",
                d.width, d.height
            ),
        ));
    }
    let rgb = read_rgb(&frame.rgb)?;
    if (rgb.width, rgb.height) != (width, height) {
        return Err(Error::malformed(
            &frame.rgb,
            format!(
                "colour image is {}x{} but the camera is {width}x{height}",
                rgb.width, rgb.height
            ),
        ));
    }
    let (w, h) = (width as usize, height as usize);
    let clean = rendered.depth_m;
    let edges = discontinuities(&clean, w, h, EDGE_REL);
    Ok(FrameView {
        edge: edge_distance(&edges, w, h, EDGE_BINS as u8 - 1),
        theta: incidence_map_deg(&clean, EDGE_REL, &k),
        lum: luminance_map(&rgb.rgb),
        k,
        clean,
        instance: rendered.instance,
        reading: d.data,
        obj_ids: frame.gt.iter().map(|g| g.obj_id).collect(),
    })
}

/// Measures one frame. `max_median_abs_m`: a frame whose median |reading − clean| over its
/// object pixels is larger (GT obviously off) adds nothing but its [`FrameResidual`]; the
/// bool says whether it was left out.
pub fn measure_frame(
    v: &FrameView,
    location: &FrameLocation,
    max_median_abs_m: f64,
) -> (DepthStats, bool) {
    let mut st = DepthStats {
        fx: v.k.fx,
        ..DepthStats::default()
    };
    let (w, h) = (v.k.width as usize, v.k.height as usize);
    let n = w * h;

    // The frame's median |residual| decides whether its GT can be trusted.
    let mut abs: Vec<f32> = (0..n)
        .filter(|&i| v.instance[i] > 0 && v.reading[i] > 0.0)
        .map(|i| (v.reading[i] - v.clean[i]).abs())
        .collect();
    let median = if abs.is_empty() {
        0.0
    } else {
        let mid = abs.len() / 2;
        let (_, m, _) = abs.select_nth_unstable_by(mid, f32::total_cmp);
        f64::from(*m)
    };
    st.frame_residuals.push(FrameResidual {
        location: location.clone(),
        median_abs_m: median,
        pixels: abs.len() as u64,
        left_out: median > max_median_abs_m,
    });
    if median > max_median_abs_m {
        return (st, false);
    }
    st.frames = 1;

    // Per instance: the offset along the ray and a robust affine trend (GT poses are off by a
    // few mm; the sensor's noise is what is left).
    let n_inst = v.obj_ids.len();
    let trends: Vec<Trend> = (1..=n_inst).map(|inst| fit_trend(v, inst as u16)).collect();
    for t in &trends {
        if let Some(off) = t.offset {
            st.offsets.push(off);
            st.instances += 1;
        }
    }

    let fb = v.k.fx * ZONE_BASELINE_M;
    let zone_l = viewpoint_shadow(&v.clean, w, h, -fb, false);
    let zone_r = viewpoint_shadow(&v.clean, w, h, fb, false);
    let scene = st.by_scene.entry(location.scene_id).or_default();
    let mut scene_stats = std::mem::take(scene);
    let mut objects: BTreeMap<u32, GroupStats> = BTreeMap::new();
    for i in 0..n {
        let inst = v.instance[i];
        if inst == 0 {
            continue;
        }
        let z = f64::from(v.clean[i]);
        let r = f64::from(v.reading[i]);
        let mut c = Cell {
            n: 1,
            sum_edge: f64::from(v.edge[i]),
            sum_theta: f64::from(v.theta[i]),
            sum_lum: f64::from(v.lum[i]),
            ..Cell::default()
        };
        let mut surface = None;
        if r <= 0.0 {
            c.holes = 1;
        } else if r > z + SURFACE_TOL_M {
            c.far = 1;
        } else if r < z - SURFACE_TOL_M {
            c.near = 1;
        } else {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            surface = Some(r - z - trends[usize::from(inst) - 1].at(x, y));
        }
        let idx = cell_index(v.edge[i], v.theta[i], v.lum[i]);
        let in_zone = zone_l[i] || zone_r[i];
        if in_zone {
            st.zone_cells[idx].add(&c);
        } else {
            st.cells[idx].add(&c);
        }
        if zone_l[i] {
            st.zones[0].add(&c);
        }
        if zone_r[i] {
            st.zones[1].add(&c);
        }
        let obj = objects.entry(v.obj_ids[usize::from(inst) - 1]).or_default();
        obj.cell.add(&c);
        scene_stats.cell.add(&c);
        if let Some(e) = surface {
            let tan = f64::from(v.theta[i]).min(85.0).to_radians().tan();
            let tan2 = tan * tan;
            st.resid_all.push(e, z, tan2);
            obj.residuals.push(e, z, tan2);
            scene_stats.residuals.push(e, z, tan2);
            if v.edge[i] >= 4 && v.theta[i] < 30.0 {
                let zb = ((z / 0.1) as usize).min(Z_BINS - 1);
                st.resid_by_z[zb].push(e, z, tan2);
            }
            if v.edge[i] >= 2 {
                let tb = ((v.theta[i] / 5.0) as usize).min(THETA_BINS - 1);
                st.resid_by_theta[tb].push(e, z, tan2);
            }
        }
    }
    st.by_scene.insert(location.scene_id, scene_stats);
    st.by_object = objects;
    for y in 0..h {
        let mut inside = false;
        for x in 0..w {
            let i = y * w + x;
            let hole = v.instance[i] > 0 && v.reading[i] <= 0.0;
            if hole {
                st.hole_run_px += 1;
                if !inside {
                    st.hole_runs += 1;
                }
            }
            inside = hole;
        }
    }
    scan_rows(v, &mut st);
    st.runs_by_scene.insert(location.scene_id, st.runs);
    (st, true)
}

/// The residual trend of one instance: offset + a u + b v.
struct Trend {
    offset: Option<f64>,
    coef: [f64; 3],
}

impl Trend {
    fn at(&self, x: f64, y: f64) -> f64 {
        self.coef[0] + self.coef[1] * x + self.coef[2] * y
    }
}

/// Median offset and an iteratively reweighted (Huber) least-squares plane through the
/// surface residuals of instance `inst`; a plain offset with fewer than 50 pixels.
fn fit_trend(v: &FrameView, inst: u16) -> Trend {
    let w = v.k.width as usize;
    let mut pts: Vec<(f64, f64, f64)> = Vec::new();
    for (i, (&id, (&z, &r))) in v
        .instance
        .iter()
        .zip(v.clean.iter().zip(&v.reading))
        .enumerate()
    {
        if id != inst || r <= 0.0 {
            continue;
        }
        let e = f64::from(r) - f64::from(z);
        if e.abs() <= SURFACE_TOL_M {
            pts.push(((i % w) as f64, (i / w) as f64, e));
        }
    }
    if pts.is_empty() {
        return Trend {
            offset: None,
            coef: [0.0; 3],
        };
    }
    let mut es: Vec<f64> = pts.iter().map(|p| p.2).collect();
    let mid = es.len() / 2;
    let (_, m, _) = es.select_nth_unstable_by(mid, f64::total_cmp);
    let median = *m;
    if pts.len() < 50 {
        return Trend {
            offset: Some(median),
            coef: [median, 0.0, 0.0],
        };
    }
    // Centre the coordinates for conditioning.
    let n = pts.len() as f64;
    let cx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let cy = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let mut coef = [median, 0.0, 0.0];
    for _ in 0..6 {
        let resid: Vec<f64> = pts
            .iter()
            .map(|p| p.2 - coef[0] - coef[1] * (p.0 - cx) - coef[2] * (p.1 - cy))
            .collect();
        let mut a: Vec<f64> = resid.iter().map(|r| r.abs()).collect();
        let mid = a.len() / 2;
        let (_, mad, _) = a.select_nth_unstable_by(mid, f64::total_cmp);
        let c = (1.4826 * *mad * 1.5).max(2e-4);
        let mut ata = [[0.0f64; 3]; 3];
        let mut atb = [0.0f64; 3];
        for (p, r) in pts.iter().zip(&resid) {
            let wgt = if r.abs() <= c { 1.0 } else { c / r.abs() };
            let row = [1.0, p.0 - cx, p.1 - cy];
            for i in 0..3 {
                atb[i] += wgt * row[i] * p.2;
                for j in 0..3 {
                    ata[i][j] += wgt * row[i] * row[j];
                }
            }
        }
        match solve3(ata, atb) {
            Some(s) => coef = s,
            None => break,
        }
    }
    Trend {
        offset: Some(median),
        coef: [coef[0] - coef[1] * cx - coef[2] * cy, coef[1], coef[2]],
    }
}

/// Solves a 3x3 system by Cramer's rule; `None` when singular.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(&a);
    if d.abs() < 1e-12 * (a[0][0] * a[1][1] * a[2][2]).abs().max(1e-300) {
        return None;
    }
    let mut out = [0.0; 3];
    for (c, o) in out.iter_mut().enumerate() {
        let mut m = a;
        for r in 0..3 {
            m[r][c] = b[r];
        }
        *o = det(&m) / d;
    }
    Some(out)
}

/// Row scans at the left and right ends of every run of object pixels: the edge profile,
/// and hole runs against a farther background.
fn scan_rows(v: &FrameView, st: &mut DepthStats) {
    let (w, h) = (v.k.width as usize, v.k.height as usize);
    let obj = |x: usize, y: usize| v.instance[y * w + x] > 0;
    for y in 0..h {
        let mut x = 0;
        while x < w {
            if !obj(x, y) {
                x += 1;
                continue;
            }
            let x0 = x;
            while x < w && obj(x, y) {
                x += 1;
            }
            let x1 = x - 1;
            if x1 - x0 + 1 < 8 {
                continue;
            }
            // side 0: the left end, looking left (dir −1); side 1: the right end.
            for (side, edge_x, dir) in [(0usize, x0, -1isize), (1, x1, 1)] {
                scan_edge(v, st, y, edge_x, dir, side);
            }
        }
    }
}

fn scan_edge(v: &FrameView, st: &mut DepthStats, y: usize, edge_x: usize, dir: isize, side: usize) {
    let w = v.k.width as usize;
    let at = |s: isize| -> Option<usize> {
        let x = edge_x as isize + dir * s;
        (x >= 0 && (x as usize) < w).then(|| y * w + x as usize)
    };
    let z_edge = f64::from(v.clean[y * w + edge_x]);
    if z_edge <= 0.0 {
        return;
    }
    // Outside: up to 12 pixels that are not object pixels.
    let mut outside: Vec<usize> = Vec::new();
    for s in 1..=12 {
        match at(s) {
            Some(j) if v.instance[j] == 0 => outside.push(j),
            _ => break,
        }
    }
    // Inside profile (s = 0..7 into the object, same surface run).
    for s in 0..8isize {
        let Some(j) = at(-s) else { break };
        if v.instance[j] == 0 {
            break;
        }
        let z = f64::from(v.clean[j]);
        let r = f64::from(v.reading[j]);
        let cell = &mut st.profile[side][3 + s as usize];
        cell.n += 1;
        if r > 0.0 && (r - z).abs() <= SURFACE_TOL_M {
            cell.object_like += 1;
        }
    }
    if outside.len() < 8 {
        return;
    }
    let reading = |j: usize| f64::from(v.reading[j]);
    // What lies beyond (s = 4..8): the first reading there, if any.
    let beyond = outside[3..8].iter().map(|&j| reading(j)).find(|&r| r > 0.0);
    let far_background = beyond.is_none_or(|r| r > z_edge + SURFACE_TOL_M);
    if far_background {
        for s in 1..=3usize {
            let r = reading(outside[s - 1]);
            let cell = &mut st.profile[side][3 - s];
            cell.n += 1;
            if r > 0.0 && (r - z_edge).abs() <= PROFILE_TOL_M {
                cell.object_like += 1;
            }
        }
    }
    // Shadow runs need a background that was read: past any foreground-like readings (the
    // edge spread outwards), the run of holes, then the first reading, farther away.
    let mut k = 0usize;
    while k < outside.len() && {
        let r = reading(outside[k]);
        r > 0.0 && (r - z_edge).abs() <= PROFILE_TOL_M
    } {
        k += 1;
    }
    let mut run = 0usize;
    while k + run < outside.len() && reading(outside[k + run]) <= 0.0 {
        run += 1;
    }
    let Some(&bg_px) = outside.get(k + run) else {
        return;
    };
    let z_bg = reading(bg_px);
    if z_bg <= z_edge + 0.02 {
        return;
    }
    let g = v.k.fx * (1.0 / z_edge - 1.0 / z_bg);
    if let Some(b) = RUN_BIN_EDGES.windows(2).position(|e| g >= e[0] && g < e[1]) {
        let bin = &mut st.runs[side][b];
        bin.n += 1;
        bin.sum_run += run as f64;
        bin.sum_g += g;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hist(values: impl Iterator<Item = f64>) -> ResidualHist {
        let mut h = ResidualHist::default();
        for v in values {
            h.push(v, 1.0, 0.0);
        }
        h
    }

    /// A deterministic Gaussian sample: the normal quantiles of an even grid of
    /// probabilities (Tukey's lambda approximation of the probit, within 1 %).
    fn gaussian(sigma: f64, mean: f64, n: usize) -> Vec<f64> {
        (1..n)
            .map(|i| {
                let p = i as f64 / n as f64;
                // Probit approximation (Tukey lambda 0.14): error < 1 %.
                let z = (p.powf(0.14) - (1.0 - p).powf(0.14)) / 0.1975;
                mean + sigma * z
            })
            .collect()
    }

    #[test]
    fn histogram_quantiles_spread_and_distance() {
        let h = hist(gaussian(0.002, 0.001, 20000).into_iter());
        assert!(
            (h.quantile(0.5) - 0.001).abs() < 1e-4,
            "{}",
            h.quantile(0.5)
        );
        let s = h.robust_sigma();
        assert!((s / 0.002 - 1.0).abs() < 0.05, "{s}");
        // W1 of two distributions shifted by 1 mm is 1 mm; of one with itself, 0.
        let g = hist(gaussian(0.002, 0.002, 20000).into_iter());
        assert!(
            (h.wasserstein1(&g) - 0.001).abs() < 1e-4,
            "{}",
            h.wasserstein1(&g)
        );
        assert_eq!(h.wasserstein1(&h), 0.0);
        // Outside ±30 mm nothing is counted.
        assert_eq!(hist([0.05, -0.04].into_iter()).n, 0);
        assert!(ResidualHist::default().wasserstein1(&h).is_nan());
    }

    #[test]
    fn cells_index_and_merge() {
        let i = cell_index(3, 47.0, 0.51);
        assert_eq!(cell_bins(i), (3, 9, 10));
        assert_eq!(
            cell_bins(cell_index(200, 100.0, 2.0)),
            (EDGE_BINS - 1, THETA_BINS - 1, LUM_BINS - 1)
        );
        let mut a = DepthStats::default();
        a.cells[i] = Cell {
            n: 10,
            holes: 2,
            far: 1,
            ..Cell::default()
        };
        a.hole_runs = 2;
        a.hole_run_px = 6;
        let mut b = DepthStats::default();
        b.merge(&a);
        b.merge(&a);
        assert_eq!(b.total().n, 20);
        assert_eq!(b.total().hole_rate(), 0.2);
        assert_eq!(b.total().miss_rate(), 0.3);
        assert_eq!(b.mean_hole_run(), 3.0);
    }
}
