//! Fitting the structured-light model to measured frames ([`DepthStats`] of a real dataset).
//!
//! In order, each from its own statistic:
//! 1. **Shadow**: the hole run just outside every left and right silhouette edge that has a
//!    read background behind it, against g = fx (1/z_edge − 1/z_background). A shadow of a
//!    viewpoint b metres to the side is b·g pixels wide, so per side the run is fitted as
//!    a + k·g (least squares on bin means): the side with the larger slope is the projector's
//!    shadow (`baseline_m` = ±k, the sign putting the shadow there), a clear slope on the other
//!    side becomes `second_view_m`.
//! 2. **Holes**: a maximum-likelihood (Bernoulli) fit of `StructuredLightSpec::hole_probability`
//!    over the pixels binned by edge distance, incidence and brightness (pixels that a closer
//!    surface could shadow are left out), by Nelder–Mead.
//! 3. **Edge mixing**: the share of readings from behind the surface by edge distance,
//!    least squares on the hole fit's decay.
//! 4. **Noise**: the robust spread (1.4826 MAD) of the residuals after each instance's own
//!    offset and tilt were removed (GT poses are off by millimetres), by depth on interior
//!    pixels seen head-on → `disparity_sigma_px` after the quantization's and the output
//!    unit's share; by incidence → `lateral_sigma_px`.
//! 5. **Bias**: the median of the instances' offsets. **Fattening**: the share of
//!    foreground-like readings 1–3 px outside an edge against a far background, summed.
//!
//! `focal_px`, `subpixel`, `range_m`, `edge_jump_rel` and `depth_unit_m` are not identifiable
//! from registered depth and are kept from the base spec.

use serde::Serialize;
use synthgen_core::scene::StructuredLightSpec;

use super::measure::{
    cell_bins, Cell, DepthStats, FrameResidual, ResidualHist, EDGE_BINS, LUM_BINS, THETA_BINS,
};
use super::optimize::nelder_mead;
use synthgen_formats::{Error, Result};

/// How to fit.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FitOptions {
    /// Start values and the parameters the fit does not touch.
    pub base: StructuredLightSpec,
}

/// One point of a curve: the statistic on the real frames and what the fitted model gives.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CurvePoint {
    /// The bin's mean feature value (pixels, degrees, brightness or metres).
    pub x: f64,
    pub n: u64,
    pub real: f64,
    pub fit: f64,
}

/// One point of an edge profile.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ProfilePoint {
    /// "left" or "right".
    pub side: &'static str,
    /// Pixels into the object from its silhouette edge (negative: outside).
    pub x: f64,
    pub n: u64,
    pub real: f64,
    pub fit: f64,
}

/// The hole-run regression of one side.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SideFit {
    /// Run length per g, metres (the width of that side's shadow per px·m).
    pub slope_m: f64,
    pub intercept_px: f64,
    /// Per g bin: mean g (x), edges (n), mean run (real), fitted run (fit).
    pub bins: Vec<CurvePoint>,
}

/// What the fit found and how well the model reproduces it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FitReport {
    pub spec: StructuredLightSpec,
    pub frames_used: usize,
    /// Frames left out because their GT is obviously off.
    pub frames_excluded: Vec<FrameResidual>,
    pub instances: usize,
    pub pixels: u64,
    pub hole_rate_real: f64,
    pub hole_rate_fit: f64,
    /// Mean length of horizontal hole runs on the objects, pixels: real, and what a field of
    /// the fitted `hole_size_px` gives at the real hole rate.
    pub hole_run_real: f64,
    pub hole_run_fit: f64,
    /// "left" or "right": where the projector's shadow falls.
    pub shadow_side: String,
    /// [left edges, right edges].
    pub shadow: [SideFit; 2],
    pub noise_by_depth: Vec<CurvePoint>,
    pub noise_by_incidence: Vec<CurvePoint>,
    pub holes_by_edge: Vec<CurvePoint>,
    pub holes_by_incidence: Vec<CurvePoint>,
    pub holes_by_luminance: Vec<CurvePoint>,
    pub far_by_edge: Vec<CurvePoint>,
    /// Object-like readings across left and right silhouette edges (x: position, negative
    /// outside), real and as the fitted edge terms, fattening and shift predict them.
    pub edge_profile: Vec<ProfilePoint>,
    /// Hole rates in the nominal shadow zones [viewpoint left, viewpoint right].
    pub zone_hole_rates: [f64; 2],
    /// What was kept from the base spec or could not be measured.
    pub notes: Vec<String>,
    /// Per scene, the projector side its own shadows give (scenes with enough edges).
    pub shadow_by_scene: Vec<SceneShadow>,
    /// What the user should know about the fit: weak or contradicting evidence.
    pub warnings: Vec<String>,
}

/// The projector baseline one scene's shadows give.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SceneShadow {
    pub scene_id: u32,
    /// Shadow runs measured beside [left, right] silhouette edges.
    pub edges: [u64; 2],
    /// Run growth per (px·m) beside [left, right] edges.
    pub slope_m: [f64; 2],
    /// `None` where neither side shows a shadow.
    pub baseline_m: Option<f64>,
}

/// A shadow grows by at least this (metres of baseline) to count as the projector's.
const MIN_SHADOW_SLOPE_M: f64 = 0.002;
/// Fewer edges than this on the projector's side of a scene say little about it.
const MIN_SIDE_EDGES: u64 = 100;

/// The baseline the shadows on `[left, right]` edges give (its sign: the projector's side), or
/// `None` without a shadow.
fn projector_baseline(shadow: &[SideFit; 2]) -> Option<f64> {
    let main = if shadow[0].slope_m >= shadow[1].slope_m {
        0
    } else {
        1
    };
    // A shadow on the left (side 0) means the projector is to the right (+x).
    let sign = if main == 0 { 1.0 } else { -1.0 };
    (shadow[main].slope_m > MIN_SHADOW_SLOPE_M)
        .then(|| sign * shadow[main].slope_m.clamp(0.001, 1.0))
}

/// Warnings about the projector side: scenes that contradict each other, or evidence too weak
/// to tell the projector from the second view.
fn projector_warnings(
    shadow: &[SideFit; 2],
    scenes: &[SceneShadow],
    baseline_m: f64,
) -> Vec<String> {
    let mut out = Vec::new();
    let decided: Vec<&SceneShadow> = scenes
        .iter()
        .filter(|s| s.baseline_m.is_some() && s.edges.iter().sum::<u64>() >= MIN_SIDE_EDGES)
        .collect();
    let side = |b: f64| if b > 0.0 { "left" } else { "right" };
    let list = |v: &[&&SceneShadow]| -> String {
        v.iter()
            .map(|s| format!("{} ({:+.3})", s.scene_id, s.baseline_m.unwrap_or(0.0)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let pos: Vec<&&SceneShadow> = decided
        .iter()
        .filter(|s| s.baseline_m > Some(0.0))
        .collect();
    let neg: Vec<&&SceneShadow> = decided
        .iter()
        .filter(|s| s.baseline_m < Some(0.0))
        .collect();
    if !pos.is_empty() && !neg.is_empty() {
        out.push(format!(
            "the scenes disagree on the projector's side: scenes {} give a positive baseline_m (shadows on the {} of objects), scenes {} a negative one (shadows on the {}); the fit over all of them uses {baseline_m:+.3}. Fit each rig apart (--scenes), or check the odd scenes' depth registration",
            list(&pos),
            side(1.0),
            list(&neg),
            side(-1.0)
        ));
    }
    let (l, r) = (shadow[0].slope_m, shadow[1].slope_m);
    let (hi, lo) = (l.max(r), l.min(r));
    let edges: u64 = shadow[if l >= r { 0 } else { 1 }]
        .bins
        .iter()
        .map(|b| b.n)
        .sum();
    if hi > MIN_SHADOW_SLOPE_M && (lo > 0.75 * hi || edges < MIN_SIDE_EDGES) {
        out.push(format!(
            "the projector's side is uncertain: shadow runs grow {l:.4} m (left edges) and {r:.4} m (right edges) per px·m over {edges} edges on the stronger side; baseline_m ({baseline_m:+.4}) and second_view_m may be swapped"
        ));
    }
    out
}

/// Fits the structured-light model to `st` (measured on frames with real depth).
pub fn fit(st: &DepthStats, options: &FitOptions) -> Result<FitReport> {
    let total = st.total();
    if st.frames == 0 || total.n == 0 {
        return Err(Error::InvalidRequest(
            "no usable frame to fit to: every frame was left out or shows no object".into(),
        ));
    }
    if total.holes == total.n {
        return Err(Error::InvalidRequest(format!(
            "no depth readings: all {} object pixels of the {} frames read 0, so there is nothing to fit (are the depth images empty, or stored at a scale that rounds them to 0?)",
            total.n, st.frames
        )));
    }
    let mut spec = options.base.clone();
    let mut notes = Vec::new();
    let fx = st.fx;

    // 1. Shadow sides and widths.
    let shadow = [side_fit(&st.runs[0]), side_fit(&st.runs[1])];
    let (main, other) = if shadow[0].slope_m >= shadow[1].slope_m {
        (0, 1)
    } else {
        (1, 0)
    };
    // A shadow on the left (side 0) means the projector is to the right (+x).
    let sign = |side: usize| if side == 0 { 1.0 } else { -1.0 };
    if let Some(b) = projector_baseline(&shadow) {
        spec.baseline_m = b;
    } else {
        notes.push(format!(
            "no shadow beside the objects could be measured (fewer than two populated bins or \
             no slope); baseline_m kept at {}",
            spec.baseline_m
        ));
    }
    spec.second_view_m = if shadow[other].slope_m > 0.005 && shadow[main].slope_m > 0.002 {
        sign(other) * shadow[other].slope_m
    } else {
        0.0
    };
    let shadow_side = if spec.baseline_m > 0.0 {
        "left"
    } else {
        "right"
    }
    .to_string();

    // 2. Holes, and how blob-like they are.
    fit_holes(&st.cells, &mut spec);
    let hole_run_real = st.mean_hole_run();
    if st.hole_runs >= 100 {
        spec.hole_size_px = fit_hole_size(hole_run_real, total.hole_rate());
    } else {
        notes.push(format!(
            "too few holes to measure their size; hole_size_px kept at {}",
            spec.hole_size_px
        ));
    }

    // 3. Edge mixing, fattening and the registration shift, from the edge profiles.
    let by_edge = marginal(&st.cells, |e, _, _| e, EDGE_BINS);
    let edge_profile = fit_edge_profile(st, &mut spec, &mut notes);

    // 4. Noise (needs |baseline|).
    fit_noise(st, &mut spec, fx, &mut notes);

    // 5. Bias.
    if !st.offsets.is_empty() {
        let mut o = st.offsets.clone();
        o.sort_by(f64::total_cmp);
        spec.bias_m = o[o.len() / 2].clamp(-0.05, 0.05);
    }
    notes.push(
        "focal_px, subpixel, range_m, edge_jump_rel and depth_unit_m come from the base spec \
         (not identifiable from depth registered to a colour camera)"
            .into(),
    );

    let shadow_by_scene: Vec<SceneShadow> = st
        .runs_by_scene
        .iter()
        .map(|(&scene_id, runs)| {
            let sides = [side_fit(&runs[0]), side_fit(&runs[1])];
            SceneShadow {
                scene_id,
                edges: [0, 1].map(|s| runs[s].iter().map(|b| b.n).sum()),
                slope_m: [sides[0].slope_m, sides[1].slope_m],
                baseline_m: projector_baseline(&sides),
            }
        })
        .collect();
    let warnings = projector_warnings(&shadow, &shadow_by_scene, spec.baseline_m);
    let report = FitReport {
        frames_used: st.frames,
        frames_excluded: excluded(st),
        instances: st.instances,
        pixels: total.n,
        hole_rate_real: marginal(&st.cells, |_, _, _| 0, 1)[0].hole_rate(),
        hole_rate_fit: mean_hole_probability(&st.cells, &spec, |_, _, _| true),
        hole_run_real,
        hole_run_fit: simulated_run(spec.hole_size_px, total.hole_rate()),
        shadow_side,
        shadow,
        noise_by_depth: noise_curve(&st.resid_by_z, &spec, fx, false),
        noise_by_incidence: noise_curve(&st.resid_by_theta, &spec, fx, true),
        holes_by_edge: hole_curve(&st.cells, &spec, EDGE_BINS, |e, _, _| e, Cell::mean_edge),
        holes_by_incidence: hole_curve(&st.cells, &spec, THETA_BINS, |_, t, _| t, Cell::mean_theta),
        holes_by_luminance: hole_curve(&st.cells, &spec, LUM_BINS, |_, _, l| l, Cell::mean_lum),
        far_by_edge: by_edge
            .iter()
            .enumerate()
            .filter(|(_, c)| c.n > 0)
            .map(|(d, c)| {
                let keep = 1.0 - mean_hole_probability(&st.cells, &spec, |e, _, _| e == d);
                CurvePoint {
                    x: c.mean_edge(),
                    n: c.n,
                    real: super::measure::ratio(c.far, c.n),
                    fit: spec.mix_probability(c.mean_edge()) * keep,
                }
            })
            .collect(),
        edge_profile,
        zone_hole_rates: [st.zones[0].hole_rate(), st.zones[1].hole_rate()],
        notes,
        shadow_by_scene,
        warnings,
        spec,
    };
    Ok(report)
}

/// The frames left out because their GT is obviously off.
fn excluded(st: &DepthStats) -> Vec<FrameResidual> {
    st.frame_residuals
        .iter()
        .filter(|f| f.left_out)
        .cloned()
        .collect()
}

fn marginal(cells: &[Cell], key: impl Fn(usize, usize, usize) -> usize, bins: usize) -> Vec<Cell> {
    let mut out = vec![Cell::default(); bins];
    for (i, c) in cells.iter().enumerate() {
        let (e, t, l) = cell_bins(i);
        let k = key(e, t, l);
        if k < bins {
            let o = &mut out[k];
            o.n += c.n;
            o.holes += c.holes;
            o.far += c.far;
            o.near += c.near;
            o.sum_edge += c.sum_edge;
            o.sum_theta += c.sum_theta;
            o.sum_lum += c.sum_lum;
        }
    }
    out
}

/// Pixel-weighted mean hole probability of the model over the cells `pick` selects.
fn mean_hole_probability(
    cells: &[Cell],
    spec: &StructuredLightSpec,
    pick: impl Fn(usize, usize, usize) -> bool,
) -> f64 {
    let (mut p, mut n) = (0.0, 0.0);
    for (i, c) in cells.iter().enumerate() {
        let (e, t, l) = cell_bins(i);
        if c.n == 0 || !pick(e, t, l) {
            continue;
        }
        p += c.n as f64 * spec.hole_probability(c.mean_edge(), c.mean_theta(), c.mean_lum());
        n += c.n as f64;
    }
    if n > 0.0 {
        p / n
    } else {
        0.0
    }
}

fn hole_curve(
    cells: &[Cell],
    spec: &StructuredLightSpec,
    bins: usize,
    key: impl Fn(usize, usize, usize) -> usize + Copy,
    x: fn(&Cell) -> f64,
) -> Vec<CurvePoint> {
    let m = marginal(cells, key, bins);
    m.iter()
        .enumerate()
        .filter(|(_, c)| c.n > 0)
        .map(|(b, c)| CurvePoint {
            x: x(c),
            n: c.n,
            real: c.hole_rate(),
            fit: mean_hole_probability(cells, spec, |e, t, l| key(e, t, l) == b),
        })
        .collect()
}

fn side_fit(bins: &[super::measure::RunBin; 6]) -> SideFit {
    let pts: Vec<(f64, f64, f64)> = bins
        .iter()
        .filter(|b| b.n >= 30)
        .map(|b| (b.sum_g / b.n as f64, b.sum_run / b.n as f64, b.n as f64))
        .collect();
    let (mut a, mut k) = (0.0, 0.0);
    if pts.len() >= 2 {
        let sw: f64 = pts.iter().map(|p| p.2).sum();
        let mx = pts.iter().map(|p| p.2 * p.0).sum::<f64>() / sw;
        let my = pts.iter().map(|p| p.2 * p.1).sum::<f64>() / sw;
        let sxx: f64 = pts.iter().map(|p| p.2 * (p.0 - mx).powi(2)).sum();
        let sxy: f64 = pts.iter().map(|p| p.2 * (p.0 - mx) * (p.1 - my)).sum();
        if sxx > 0.0 {
            k = (sxy / sxx).max(0.0);
            a = my - k * mx;
        }
    }
    SideFit {
        slope_m: k,
        intercept_px: a,
        bins: pts
            .iter()
            .map(|p| CurvePoint {
                x: p.0,
                n: p.2 as u64,
                real: p.1,
                fit: a + k * p.0,
            })
            .collect(),
    }
}

/// The maximum-likelihood hole parameters (see the module doc), in place.
fn fit_holes(cells: &[Cell], spec: &mut StructuredLightSpec) {
    let used: Vec<&Cell> = cells.iter().filter(|c| c.n > 0).collect();
    if used.is_empty() {
        return;
    }
    let sig = |v: f64| 1.0 / (1.0 + (-v).exp());
    let logit = |p: f64| {
        let p = p.clamp(1e-6, 1.0 - 1e-6);
        (p / (1.0 - p)).ln()
    };
    let base = spec.clone();
    let decode = |x: &[f64]| -> StructuredLightSpec {
        StructuredLightSpec {
            dropout: sig(x[0]),
            edge_dropout: sig(x[1]),
            edge_width_px: x[2].exp().clamp(0.1, 50.0),
            grazing_deg: 40.0 + 50.0 * sig(x[3]),
            grazing_width_deg: x[4].exp().clamp(0.01, 90.0),
            dark_luminance: 0.5 * sig(x[5]),
            dark_dropout: sig(x[6]),
            bright_luminance: 0.5 + 0.5 * sig(x[7]),
            bright_dropout: sig(x[8]),
            ..base.clone()
        }
    };
    let x0 = [
        logit(base.dropout),
        logit(base.edge_dropout),
        base.edge_width_px.ln(),
        logit(((base.grazing_deg - 40.0) / 50.0).clamp(0.01, 0.99)),
        base.grazing_width_deg.ln(),
        logit((base.dark_luminance / 0.5).clamp(0.01, 0.99)),
        logit(base.dark_dropout),
        logit(((base.bright_luminance - 0.5) / 0.5).clamp(0.01, 0.99)),
        logit(base.bright_dropout),
    ];
    let nll = |x: &[f64]| -> f64 {
        let s = decode(x);
        let mut v = 0.0;
        for c in &used {
            let p = s
                .hole_probability(c.mean_edge(), c.mean_theta(), c.mean_lum())
                .clamp(1e-9, 1.0 - 1e-9);
            let h = c.holes as f64;
            v -= h * p.ln() + (c.n as f64 - h) * (1.0 - p).ln();
        }
        // A weak pull towards the start keeps parameters the data says nothing about (no dark
        // pixels, say) where they were.
        v + x.iter().zip(&x0).map(|(a, b)| (a - b).powi(2)).sum::<f64>()
    };
    let mut best = nelder_mead(&nll, &x0, 0.5, 3000);
    // A threshold parked where the likelihood is flat (a ramp pushed past the data) is a local
    // optimum Nelder–Mead cannot leave: a grid over each parameter in turn, then Nelder–Mead
    // again from the best point, until nothing improves.
    for _ in 0..3 {
        let before = best.1;
        for i in 0..best.0.len() {
            for step in -12..=12 {
                let mut x = best.0.clone();
                x[i] = x0[i] + f64::from(step) * 0.5;
                let v = nll(&x);
                if v < best.1 {
                    best = (x, v);
                }
            }
        }
        let next = nelder_mead(&nll, &best.0, 0.25, 3000);
        if next.1 < best.1 {
            best = next;
        }
        if best.1 > before - 1e-6 * before.abs().max(1.0) {
            break;
        }
    }
    *spec = decode(&best.0);
}

/// Disparity and lateral noise from the robust spreads (see the module doc), in place.
fn fit_noise(st: &DepthStats, spec: &mut StructuredLightSpec, fx: f64, notes: &mut Vec<String>) {
    let fb = spec.focal_baseline(fx);
    let unit_var = spec.depth_unit_m * spec.depth_unit_m / 12.0;
    let quant_var = |z: f64, s: &StructuredLightSpec| {
        let q = s.depth_step_m(z, fx);
        q * q / 12.0
    };
    let z_bins: Vec<&ResidualHist> = st.resid_by_z.iter().filter(|h| h.n >= 500).collect();
    let t_bins: Vec<(usize, &ResidualHist)> = st
        .resid_by_theta
        .iter()
        .enumerate()
        .filter(|(t, h)| *t >= 6 && h.n >= 500)
        .collect();
    if z_bins.is_empty() {
        notes.push(format!(
            "too few interior pixels to measure the noise; disparity_sigma_px kept at {}",
            spec.disparity_sigma_px
        ));
        return;
    }
    let mut lateral = 0.0f64;
    for _ in 0..3 {
        // σ_d² from the depth bins, minus quantization, unit and lateral shares.
        let (mut num, mut den) = (0.0, 0.0);
        for h in &z_bins {
            let z = h.mean_z();
            let s = h.robust_sigma();
            let lat = (lateral * z / fx).powi(2) * h.mean_tan2();
            let rest = s * s - quant_var(z, spec) - unit_var - lat;
            let g = (fb / (z * z)).powi(2);
            num += h.n as f64 * rest.max(0.0) * g;
            den += h.n as f64;
        }
        spec.disparity_sigma_px = (num / den).sqrt();
        // σ_lat² from the incidence bins past 30°.
        let (mut num, mut den) = (0.0, 0.0);
        for (_, h) in &t_bins {
            let z = h.mean_z();
            let s = h.robust_sigma();
            let axial = z * z * spec.disparity_sigma_px / fb;
            let rest = s * s - axial * axial - quant_var(z, spec) - unit_var;
            let a = (z / fx).powi(2) * h.mean_tan2();
            num += h.n as f64 * rest.max(0.0) * a;
            den += h.n as f64 * a * a;
        }
        if den > 0.0 {
            lateral = (num / den).sqrt().min(20.0);
        }
    }
    if t_bins.is_empty() {
        notes.push(format!(
            "too few pixels past 30° incidence to measure lateral noise; kept {} px",
            spec.lateral_sigma_px
        ));
    } else {
        spec.lateral_sigma_px = lateral;
    }
}

fn noise_curve(
    hists: &[ResidualHist],
    spec: &StructuredLightSpec,
    fx: f64,
    by_theta: bool,
) -> Vec<CurvePoint> {
    let unit_var = spec.depth_unit_m * spec.depth_unit_m / 12.0;
    hists
        .iter()
        .enumerate()
        .filter(|(_, h)| h.n >= 200)
        .map(|(b, h)| {
            let z = h.mean_z();
            let theta = h.mean_tan2().sqrt().atan().to_degrees();
            let q = spec.depth_step_m(z, fx);
            let model = (spec.sigma_m(z, theta, fx).powi(2) + q * q / 12.0 + unit_var).sqrt();
            CurvePoint {
                x: if by_theta { b as f64 * 5.0 + 2.5 } else { z },
                n: h.n,
                real: h.robust_sigma(),
                fit: model,
            }
        })
        .collect()
}

/// The object-like share the model predicts at position `t` (pixels into the object from the
/// silhouette edge; negative outside) of an edge whose content is displaced outwards by `m`
/// pixels, before any displacement given by `inside` (t = 0..7) and `outside` (t = −1..−3).
fn profile_at(inside: &[f64; 8], outside: &[f64; 3], t: f64) -> f64 {
    let at = |k: i64| -> f64 {
        match k {
            k if k >= 7 => inside[7],
            k if k >= 0 => inside[k as usize],
            -3..=-1 => outside[(-k - 1) as usize],
            _ => 0.0,
        }
    };
    let k = t.floor();
    let f = t - k;
    let k = k as i64;
    at(k) * (1.0 - f) + at(k + 1) * f
}

/// Fits `edge_mix`, `fattening_px` and `shift_px` to the left and right edge profiles by a
/// grid search (least squares, pixel-weighted), given the hole parameters: inside, a pixel d
/// from the edge reads the surface with (1 − p_hole(d)) (1 − p_mix(d)); outside, s pixels
/// out, it reads the foreground with min(1, max(0, F − s + 1)) (1 − p_hole(s − 1)); a shift m
/// moves the left edge's content outwards by −m and the right edge's inwards.
fn fit_edge_profile(
    st: &DepthStats,
    spec: &mut StructuredLightSpec,
    notes: &mut Vec<String>,
) -> Vec<ProfilePoint> {
    let p = &st.profile;
    let populated = p.iter().flatten().filter(|c| c.n >= 50).count();
    let hole =
        |d: usize| mean_hole_probability(&st.cells, spec, |e, _, _| e == d.min(EDGE_BINS - 1));
    let keep_in: Vec<f64> = (0..8).map(|d| 1.0 - hole(d)).collect();
    let keep_out: Vec<f64> = (0..3)
        .map(|d| 1.0 - spec.hole_probability(d as f64, 0.0, 0.5))
        .collect();
    let predict = |mix: f64, fat: f64, shift: f64, side: usize, t: f64| -> f64 {
        let mut inside = [0.0; 8];
        for (d, v) in inside.iter_mut().enumerate() {
            *v = keep_in[d] * (1.0 - mix * (-(d as f64) / spec.edge_width_px).exp());
        }
        let mut outside = [0.0; 3];
        for (s, v) in outside.iter_mut().enumerate() {
            *v = (fat - s as f64).clamp(0.0, 1.0) * keep_out[s];
        }
        // Left edge: content displaced outwards by −shift; right edge: by +shift.
        let out = if side == 0 { -shift } else { shift };
        profile_at(&inside, &outside, t + out)
    };
    let cells: Vec<(usize, f64, f64, f64)> = (0..2)
        .flat_map(|side| {
            (0..super::measure::PROFILE_LEN).filter_map(move |i| {
                let c = p[side][i];
                (c.n >= 50).then(|| (side, i as f64 - 3.0, c.rate(), c.n as f64))
            })
        })
        .collect();
    if populated < 8 {
        notes.push(format!(
            "too few silhouette edges to fit the edge profile; edge_mix {}, fattening_px {}, shift_px {} kept",
            spec.edge_mix, spec.fattening_px, spec.shift_px
        ));
    } else {
        let sse = |mix: f64, fat: f64, shift: f64| -> f64 {
            cells
                .iter()
                .map(|&(side, t, r, n)| n * (predict(mix, fat, shift, side, t) - r).powi(2))
                .sum()
        };
        let mut best = (
            f64::INFINITY,
            spec.edge_mix,
            spec.fattening_px,
            spec.shift_px,
        );
        for mi in 0..=25 {
            let mix = mi as f64 * 0.02;
            for fi in 0..=40 {
                let fat = fi as f64 * 0.05;
                for si in -40..=40 {
                    let shift = si as f64 * 0.05;
                    let v = sse(mix, fat, shift);
                    if v < best.0 {
                        best = (v, mix, fat, shift);
                    }
                }
            }
        }
        (spec.edge_mix, spec.fattening_px, spec.shift_px) = (best.1, best.2, best.3);
    }
    let (mix, fat, shift) = (spec.edge_mix, spec.fattening_px, spec.shift_px);
    (0..2)
        .flat_map(|side| (0..super::measure::PROFILE_LEN).map(move |i| (side, i)))
        .map(|(side, i)| {
            let c = p[side][i];
            let t = i as f64 - 3.0;
            ProfilePoint {
                side: if side == 0 { "left" } else { "right" },
                x: t,
                n: c.n,
                real: c.rate(),
                fit: predict(mix, fat, shift, side, t),
            }
        })
        .collect()
}

/// Mean horizontal run of a smooth field of blob size `size` thresholded at `p` (a fixed
/// 512 x 512 field).
fn simulated_run(size: f64, p: f64) -> f64 {
    let f = synthgen_core::depth_features::smooth_uniform_field(512, 512, size, 0x686f_6c65);
    synthgen_core::depth_features::mean_run_below(&f, 512, p as f32)
}

/// The blob size whose field, thresholded at the real hole rate `p`, gives runs as long as
/// the real ones (`run`): interpolated between sizes 1..24 px.
fn fit_hole_size(run: f64, p: f64) -> f64 {
    const SIZES: [f64; 12] = [
        1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 12.0, 16.0, 24.0,
    ];
    let runs: Vec<f64> = SIZES.iter().map(|&s| simulated_run(s, p)).collect();
    if run <= runs[0] {
        return SIZES[0];
    }
    for i in 1..SIZES.len() {
        if run <= runs[i] {
            let t = (run - runs[i - 1]) / (runs[i] - runs[i - 1]).max(1e-9);
            return SIZES[i - 1] + t * (SIZES[i] - SIZES[i - 1]);
        }
    }
    SIZES[SIZES.len() - 1]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::measure::RunBin;

    /// Shadow runs growing `left` and `right` m per px·m beside left and right edges.
    fn runs(left: f64, right: f64) -> [[RunBin; 6]; 2] {
        let mut r = [[RunBin::default(); 6]; 2];
        for (s, k) in [(0, left), (1, right)] {
            for (b, g) in [(1, 7.0), (2, 15.0), (3, 30.0)] {
                r[s][b] = RunBin {
                    n: 100,
                    sum_g: 100.0 * g,
                    sum_run: 100.0 * (0.5 + k * g),
                };
            }
        }
        r
    }

    /// Issue 26: one scene's shadows gave baseline -0.11 m, two gave +0.02 m, silently.
    #[test]
    fn scenes_that_disagree_on_the_projector_side_are_named() {
        let scenes = [
            (0, runs(0.0, 0.11)),
            (1, runs(0.02, 0.0)),
            (2, runs(0.021, 0.0)),
        ];
        let mut pooled = [[RunBin::default(); 6]; 2];
        let shadow_by_scene: Vec<SceneShadow> = scenes
            .iter()
            .map(|(id, r)| {
                for s in 0..2 {
                    for (a, b) in pooled[s].iter_mut().zip(&r[s]) {
                        a.n += b.n;
                        a.sum_g += b.sum_g;
                        a.sum_run += b.sum_run;
                    }
                }
                let sides = [side_fit(&r[0]), side_fit(&r[1])];
                SceneShadow {
                    scene_id: *id,
                    edges: [300, 300],
                    slope_m: [sides[0].slope_m, sides[1].slope_m],
                    baseline_m: projector_baseline(&sides),
                }
            })
            .collect();
        assert!((shadow_by_scene[0].baseline_m.unwrap() + 0.11).abs() < 1e-9);
        assert!((shadow_by_scene[1].baseline_m.unwrap() - 0.02).abs() < 1e-9);
        let shadow = [side_fit(&pooled[0]), side_fit(&pooled[1])];
        let b = projector_baseline(&shadow).unwrap();
        let w = projector_warnings(&shadow, &shadow_by_scene, b).join("\n");
        assert!(
            w.contains("disagree on the projector's side")
                && w.contains("scenes 1 (+0.020), 2 (+0.021)")
                && w.contains("scenes 0 (-0.110)"),
            "{w}"
        );
        // One scene alone: no disagreement, and a clear side is not "uncertain".
        let one = &shadow_by_scene[1..2];
        let s1 = [side_fit(&scenes[1].1[0]), side_fit(&scenes[1].1[1])];
        assert!(projector_warnings(&s1, one, 0.02).is_empty());
        // Shadows as wide on both sides: which is the projector is uncertain.
        let both = runs(0.019, 0.018);
        let s2 = [side_fit(&both[0]), side_fit(&both[1])];
        let w = projector_warnings(&s2, &[], 0.019).join("\n");
        assert!(w.contains("projector's side is uncertain"), "{w}");
    }

    #[test]
    fn edge_profile_interpolates_and_ends_at_zero_outside() {
        let inside = [0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.9, 0.9];
        let outside = [0.3, 0.1, 0.0];
        assert_eq!(profile_at(&inside, &outside, 0.0), 0.5);
        assert!((profile_at(&inside, &outside, 0.5) - 0.55).abs() < 1e-12);
        assert!((profile_at(&inside, &outside, -0.5) - 0.4).abs() < 1e-12);
        assert_eq!(profile_at(&inside, &outside, -5.0), 0.0);
        assert_eq!(profile_at(&inside, &outside, 30.0), 0.9);
    }

    #[test]
    fn hole_size_calibration_is_monotone() {
        let small = fit_hole_size(simulated_run(2.0, 0.08), 0.08);
        let large = fit_hole_size(simulated_run(8.0, 0.08), 0.08);
        assert!((small - 2.0).abs() < 0.3, "{small}");
        assert!((large - 8.0).abs() < 1.0, "{large}");
        assert_eq!(fit_hole_size(0.0, 0.08), 1.0);
    }

    #[test]
    fn no_frames_is_an_error() {
        assert!(fit(&DepthStats::default(), &FitOptions::default()).is_err());
    }
}
