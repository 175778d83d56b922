//! How close two datasets' depth readings are, aspect by aspect, on their object pixels
//! (see [`super::measure`]): usually real frames against their replay through a sensor model.
//!
//! Scored aspects (each divided by its scale, then averaged into the overall score; 0 = the
//! same, lower is closer):
//! - `residual`: Wasserstein-1 distance between the two distributions of surface residuals
//!   (reading − clean depth within ±30 mm, after each instance's own offset and tilt), mm;
//!   scale 1 mm.
//! - `missing`: the difference of the shares of object pixels without a reading of their
//!   own surface — a hole, or a reading more than 30 mm off (of the surface behind, or in
//!   front); scale 0.05. Holes and readings of another surface count together because a
//!   replay renders the annotated objects only: where the real camera reads the table behind
//!   an object's edge, its replay can only have a hole.
//! - `missing_by_incidence`, `missing_by_edge`: the same per incidence bin
//!   (0–15–30–45–60–70–80–90°) and per edge-distance bin (0, 1, 2, 3–4, 5–8, 9–15, 16+ px),
//!   averaged with the first dataset's pixel shares; bins with fewer than 100 pixels on
//!   either side are skipped; scale 0.05.
//! - `edge_profile`: the mean difference of the share of object-like readings along rows
//!   across left and right silhouette edges (3 px outside, 8 inside); scale 0.05.
//!
//! Shown but not scored: holes alone, readings of another surface, missing readings by
//! brightness (real photos and renders of the same object need not agree in brightness), the
//! nominal shadow zones, the mean length of hole runs, and the bias.

use serde::Serialize;

use super::measure::{cell_bins, Cell, DepthStats, GroupStats, ProfileCell};

/// One aspect of the comparison.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Aspect {
    pub name: &'static str,
    /// What `value` is, in words.
    pub what: &'static str,
    pub value: f64,
    pub unit: &'static str,
    /// `value / scale` enters the score.
    pub scale: f64,
    pub scored: bool,
    /// The statistic on each side (a rate, or a spread in mm), for the text line.
    pub first: f64,
    pub second: f64,
    pub bins: Vec<BinDiff>,
}

/// One bin of a per-bin aspect.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BinDiff {
    pub label: String,
    pub n_first: u64,
    pub n_second: u64,
    pub first: f64,
    pub second: f64,
}

/// Per scene or object.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupDiff {
    pub id: u32,
    pub pixels_first: u64,
    pub pixels_second: u64,
    pub holes_first: f64,
    pub holes_second: f64,
    /// W1 of the surface residuals, mm (NaN when a side has none).
    pub residual_w1_mm: f64,
}

/// The comparison of two datasets.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    pub aspects: Vec<Aspect>,
    /// Mean of the scored aspects' value / scale.
    pub score: f64,
    pub frames: [usize; 2],
    pub pixels: [u64; 2],
    pub scenes: Vec<GroupDiff>,
    pub objects: Vec<GroupDiff>,
}

const MIN_BIN: u64 = 100;
const HOLE_SCALE: f64 = 0.05;

fn coarse_theta(t: usize) -> usize {
    match t {
        0..=2 => 0,
        3..=5 => 1,
        6..=8 => 2,
        9..=11 => 3,
        12..=13 => 4,
        14..=15 => 5,
        _ => 6,
    }
}
const THETA_LABELS: [&str; 7] = [
    "0-15°", "15-30°", "30-45°", "45-60°", "60-70°", "70-80°", "80-90°",
];

fn coarse_edge(e: usize) -> usize {
    match e {
        0 => 0,
        1 => 1,
        2 => 2,
        3..=4 => 3,
        5..=8 => 4,
        9..=15 => 5,
        _ => 6,
    }
}
const EDGE_LABELS: [&str; 7] = ["0", "1", "2", "3-4", "5-8", "9-15", "16+ px"];

const LUM_LABELS: [&str; 5] = ["0-0.2", "0.2-0.4", "0.4-0.6", "0.6-0.8", "0.8-1"];

fn all_cells(
    st: &DepthStats,
    key: impl Fn(usize, usize, usize) -> usize,
    bins: usize,
) -> Vec<Cell> {
    let mut out = vec![Cell::default(); bins];
    for (i, (a, b)) in st.cells.iter().zip(&st.zone_cells).enumerate() {
        let (e, t, l) = cell_bins(i);
        let k = key(e, t, l);
        for c in [a, b] {
            let o = &mut out[k];
            o.n += c.n;
            o.holes += c.holes;
            o.far += c.far;
            o.near += c.near;
        }
    }
    out
}

/// Pixel-share-weighted mean |miss-rate difference| over bins both sides populate.
fn per_bin(a: &[Cell], b: &[Cell], labels: &[&str]) -> (f64, Vec<BinDiff>) {
    let mut bins = Vec::new();
    let (mut sum, mut wsum) = (0.0, 0.0);
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        bins.push(BinDiff {
            label: labels[i].to_string(),
            n_first: x.n,
            n_second: y.n,
            first: x.miss_rate(),
            second: y.miss_rate(),
        });
        if x.n >= MIN_BIN && y.n >= MIN_BIN {
            let w = x.n as f64;
            sum += w * (x.miss_rate() - y.miss_rate()).abs();
            wsum += w;
        }
    }
    (if wsum > 0.0 { sum / wsum } else { f64::NAN }, bins)
}

fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

fn groups(
    a: &std::collections::BTreeMap<u32, GroupStats>,
    b: &std::collections::BTreeMap<u32, GroupStats>,
) -> Vec<GroupDiff> {
    let mut ids: Vec<u32> = a.keys().chain(b.keys()).copied().collect();
    ids.sort_unstable();
    ids.dedup();
    let empty = GroupStats::default();
    ids.into_iter()
        .map(|id| {
            let x = a.get(&id).unwrap_or(&empty);
            let y = b.get(&id).unwrap_or(&empty);
            GroupDiff {
                id,
                pixels_first: x.cell.n,
                pixels_second: y.cell.n,
                holes_first: x.cell.hole_rate(),
                holes_second: y.cell.hole_rate(),
                residual_w1_mm: x.residuals.wasserstein1(&y.residuals) * 1000.0,
            }
        })
        .collect()
}

/// Compares `first` (the real frames, usually) with `second` (see the module doc).
pub fn compare(first: &DepthStats, second: &DepthStats) -> Comparison {
    let (ta, tb) = (first.total(), second.total());
    let mut aspects = Vec::new();
    aspects.push(Aspect {
        name: "residual",
        what: "Wasserstein-1 distance of the surface residuals (robust spreads shown)",
        value: first.resid_all.wasserstein1(&second.resid_all) * 1000.0,
        unit: "mm",
        scale: 1.0,
        scored: true,
        first: first.resid_all.robust_sigma() * 1000.0,
        second: second.resid_all.robust_sigma() * 1000.0,
        bins: Vec::new(),
    });
    aspects.push(Aspect {
        name: "missing",
        what: "difference of the shares without a reading of their own surface",
        value: (ta.miss_rate() - tb.miss_rate()).abs(),
        unit: "",
        scale: HOLE_SCALE,
        scored: true,
        first: ta.miss_rate(),
        second: tb.miss_rate(),
        bins: Vec::new(),
    });
    let (v, bins) = per_bin(
        &all_cells(first, |_, t, _| coarse_theta(t), 7),
        &all_cells(second, |_, t, _| coarse_theta(t), 7),
        &THETA_LABELS,
    );
    aspects.push(Aspect {
        name: "missing_by_incidence",
        what: "mean difference of the missing shares per incidence bin",
        value: v,
        unit: "",
        scale: HOLE_SCALE,
        scored: true,
        first: ta.miss_rate(),
        second: tb.miss_rate(),
        bins,
    });
    let (v, bins) = per_bin(
        &all_cells(first, |e, _, _| coarse_edge(e), 7),
        &all_cells(second, |e, _, _| coarse_edge(e), 7),
        &EDGE_LABELS,
    );
    aspects.push(Aspect {
        name: "missing_by_edge",
        what: "mean difference of the missing shares per edge-distance bin",
        value: v,
        unit: "",
        scale: HOLE_SCALE,
        scored: true,
        first: ta.miss_rate(),
        second: tb.miss_rate(),
        bins,
    });
    let (v, bins) = profile_diff(&first.profile, &second.profile);
    aspects.push(Aspect {
        name: "edge_profile",
        what: "mean difference of object-like readings across left/right edges",
        value: v,
        unit: "",
        scale: HOLE_SCALE,
        scored: true,
        first: mean_rate(&first.profile),
        second: mean_rate(&second.profile),
        bins,
    });
    let (v, bins) = per_bin(
        &all_cells(first, |_, _, l| l / 4, 5),
        &all_cells(second, |_, _, l| l / 4, 5),
        &LUM_LABELS,
    );
    aspects.push(Aspect {
        name: "missing_by_brightness",
        what: "mean difference of the missing shares per brightness bin (each side's own colour image)",
        value: v,
        unit: "",
        scale: HOLE_SCALE,
        scored: false,
        first: ta.miss_rate(),
        second: tb.miss_rate(),
        bins,
    });
    aspects.push(Aspect {
        name: "holes",
        what: "difference of the hole rates (no reading at all)",
        value: (ta.hole_rate() - tb.hole_rate()).abs(),
        unit: "",
        scale: HOLE_SCALE,
        scored: false,
        first: ta.hole_rate(),
        second: tb.hole_rate(),
        bins: Vec::new(),
    });
    aspects.push(Aspect {
        name: "other_surface",
        what: "difference of the shares reading another surface (>30 mm off)",
        value: (ta.off_rate() - tb.off_rate()).abs(),
        unit: "",
        scale: HOLE_SCALE,
        scored: false,
        first: ta.off_rate(),
        second: tb.off_rate(),
        bins: Vec::new(),
    });
    let zone_bins: Vec<BinDiff> = ["shadow right of occluders", "shadow left of occluders"]
        .iter()
        .enumerate()
        .map(|(i, l)| BinDiff {
            label: l.to_string(),
            n_first: first.zones[i].n,
            n_second: second.zones[i].n,
            first: first.zones[i].hole_rate(),
            second: second.zones[i].hole_rate(),
        })
        .collect();
    let zone_value = zone_bins
        .iter()
        .filter(|b| b.n_first >= MIN_BIN && b.n_second >= MIN_BIN)
        .map(|b| (b.first - b.second).abs())
        .sum::<f64>()
        / 2.0;
    aspects.push(Aspect {
        name: "shadow_zones",
        what: "mean hole-rate difference where a closer surface could shadow (either side)",
        value: zone_value,
        unit: "",
        scale: HOLE_SCALE,
        scored: false,
        first: first.zones[0].hole_rate(),
        second: second.zones[0].hole_rate(),
        bins: zone_bins,
    });
    aspects.push(Aspect {
        name: "hole_runs",
        what: "difference of the mean horizontal hole-run lengths on the objects",
        value: (first.mean_hole_run() - second.mean_hole_run()).abs(),
        unit: "px",
        scale: 1.0,
        scored: false,
        first: first.mean_hole_run(),
        second: second.mean_hole_run(),
        bins: Vec::new(),
    });
    let (ba, bb) = (
        median(&first.offsets) * 1000.0,
        median(&second.offsets) * 1000.0,
    );
    aspects.push(Aspect {
        name: "bias",
        what: "difference of the median instance offsets",
        value: (ba - bb).abs(),
        unit: "mm",
        scale: 1.0,
        scored: false,
        first: ba,
        second: bb,
        bins: Vec::new(),
    });
    let scored: Vec<f64> = aspects
        .iter()
        .filter(|a| a.scored && a.value.is_finite())
        .map(|a| a.value / a.scale)
        .collect();
    let score = if scored.is_empty() {
        f64::NAN
    } else {
        scored.iter().sum::<f64>() / scored.len() as f64
    };
    Comparison {
        aspects,
        score,
        frames: [first.frames, second.frames],
        pixels: [ta.n, tb.n],
        scenes: groups(&first.by_scene, &second.by_scene),
        objects: groups(&first.by_object, &second.by_object),
    }
}

fn mean_rate(p: &[[ProfileCell; super::measure::PROFILE_LEN]; 2]) -> f64 {
    let (mut k, mut n) = (0, 0);
    for side in p {
        for c in side {
            k += c.object_like;
            n += c.n;
        }
    }
    super::measure::ratio(k, n)
}

fn profile_diff(
    a: &[[ProfileCell; super::measure::PROFILE_LEN]; 2],
    b: &[[ProfileCell; super::measure::PROFILE_LEN]; 2],
) -> (f64, Vec<BinDiff>) {
    let mut bins = Vec::new();
    let (mut sum, mut cnt) = (0.0, 0usize);
    for side in 0..2 {
        for i in 0..super::measure::PROFILE_LEN {
            let s = i as i64 - 3;
            let label = format!(
                "{} edge, {}",
                if side == 0 { "left" } else { "right" },
                if s < 0 {
                    format!("{} px outside", -s)
                } else {
                    format!("{s} px inside")
                }
            );
            let (x, y) = (a[side][i], b[side][i]);
            if x.n >= 50 && y.n >= 50 {
                sum += (x.rate() - y.rate()).abs();
                cnt += 1;
            }
            bins.push(BinDiff {
                label,
                n_first: x.n,
                n_second: y.n,
                first: x.rate(),
                second: y.rate(),
            });
        }
    }
    (if cnt > 0 { sum / cnt as f64 } else { f64::NAN }, bins)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensor::measure::{cell_index, Cell};

    fn stats(holes: u64) -> DepthStats {
        let mut s = DepthStats::default();
        for (e, t) in [(0u8, 10.0f32), (5, 40.0), (16, 75.0)] {
            s.cells[cell_index(e, t, 0.5)] = Cell {
                n: 1000,
                holes,
                ..Cell::default()
            };
        }
        s.frames = 1;
        s
    }

    #[test]
    fn identical_datasets_score_zero_and_differences_show_per_aspect() {
        let a = stats(100);
        let same = compare(&a, &a);
        assert_eq!(same.score, 0.0);
        let c = compare(&a, &stats(150));
        let missing = c.aspects.iter().find(|x| x.name == "missing").unwrap();
        assert!((missing.value - 0.05).abs() < 1e-12);
        assert!((missing.value / missing.scale - 1.0).abs() < 1e-9);
        let by_edge = c
            .aspects
            .iter()
            .find(|x| x.name == "missing_by_edge")
            .unwrap();
        assert!((by_edge.value - 0.05).abs() < 1e-12);
        assert_eq!(by_edge.bins.len(), 7);
        assert!(c.score > 0.0);
    }
}
