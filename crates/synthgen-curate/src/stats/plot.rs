//! The statistics as PNG bar charts, alone or several datasets' bars side by side.

use std::path::{Path, PathBuf};

use super::{DatasetStats, Histogram};
use synthgen_formats::draw::Canvas;
use synthgen_formats::io::create_dir_all;
use synthgen_formats::Result;

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
    axes(&mut c, (margin, plot_w, plot_h), lo, hi, &max.to_string());
    c
}

/// The x and y axes of a chart whose plot area starts at `margin` and is `plot_w` x `plot_h`,
/// the range's ends under the x axis and `top` (the tallest bar's value) above the y axis.
fn axes(c: &mut Canvas, (margin, plot_w, plot_h): (i64, i64, i64), lo: &str, hi: &str, top: &str) {
    let base = (margin + plot_h) as f64;
    let black = [0, 0, 0];
    c.line(
        (margin as f64, base),
        ((margin + plot_w) as f64, base),
        black,
        1,
    );
    c.line(
        (margin as f64, margin as f64),
        (margin as f64, base),
        black,
        1,
    );
    let white = [255, 255, 255];
    c.text(margin, base as i64 + 6, lo, 2, white);
    let hi_w = hi.chars().count() as i64 * 8;
    c.text(margin + plot_w - hi_w, base as i64 + 6, hi, 2, white);
    c.text(margin + 4, 6, top, 2, white);
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
        ("inplane_deg.png", &s.inplane_deg, 0),
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

/// Colours of the datasets in comparison charts, in order.
pub const SERIES_COLOURS: [[u8; 3]; 4] = [
    [70, 120, 200],
    [230, 140, 40],
    [60, 170, 90],
    [190, 60, 160],
];

/// Grouped bars: per bin, one bar per series (its share of its own total), in
/// [`SERIES_COLOURS`].
pub fn grouped_bar_chart(series: &[Vec<f64>], lo: &str, hi: &str) -> Canvas {
    let (w, h, margin) = (560u32, 260u32, 24i64);
    let mut c = Canvas::new(w, h, [255, 255, 255]);
    let bins = series.iter().map(Vec::len).max().unwrap_or(0).max(1) as i64;
    let max = series
        .iter()
        .flatten()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max)
        .max(1e-12);
    let plot_w = w as i64 - 2 * margin;
    let plot_h = h as i64 - 2 * margin;
    let k = series.len().max(1) as i64;
    for (s, values) in series.iter().enumerate() {
        let colour = SERIES_COLOURS[s % SERIES_COLOURS.len()];
        for (i, &v) in values.iter().enumerate() {
            if !v.is_finite() {
                continue;
            }
            let x0 = margin + plot_w * i as i64 / bins;
            let x1 = margin + plot_w * (i as i64 + 1) / bins;
            let bw = ((x1 - x0 - 2) / k).max(1);
            let bh = (plot_h as f64 * v / max).round() as i64;
            c.fill_rect(x0 + 1 + s as i64 * bw, margin + plot_h - bh, bw, bh, colour);
        }
    }
    // The peak share in percent.
    let top = format!("{:.0}", 100.0 * max);
    axes(&mut c, (margin, plot_w, plot_h), lo, hi, &top);
    c
}

fn shares(h: &Histogram) -> Vec<f64> {
    let n = h.counts.iter().sum::<u64>().max(1) as f64;
    h.counts.iter().map(|&c| c as f64 / n).collect()
}

/// Writes `visib_fract.png`, `distance_m.png`, `elevation_deg.png` and `inplane_deg.png`
/// with the datasets' bars side by side (shares of each one's instances, colours in
/// [`SERIES_COLOURS`] order) into `dir`; returns their paths.
pub fn write_comparison_plots(stats: &[DatasetStats], dir: &Path) -> Result<Vec<PathBuf>> {
    create_dir_all(dir)?;
    type Pick = fn(&DatasetStats) -> Option<&Histogram>;
    let charts: [(&str, Pick, usize); 4] = [
        ("visib_fract.png", |s| s.visib_fract.as_ref(), 1),
        (
            "distance_m.png",
            |s| s.distance_m.as_ref().map(|d| &d.histogram),
            2,
        ),
        (
            "elevation_deg.png",
            |s| s.elevation_deg.as_ref().map(|d| &d.histogram),
            0,
        ),
        (
            "inplane_deg.png",
            |s| s.inplane_deg.as_ref().map(|d| &d.histogram),
            0,
        ),
    ];
    let mut paths = Vec::new();
    for (name, pick, decimals) in charts {
        let hs: Vec<Option<&Histogram>> = stats.iter().map(pick).collect();
        let Some(first) = hs.iter().flatten().next() else {
            continue;
        };
        let series: Vec<Vec<f64>> = hs
            .iter()
            .map(|h| h.map_or(vec![f64::NAN; first.counts.len()], shares))
            .collect();
        let lo = format!("{:.p$}", first.lo, p = decimals);
        let hi = format!("{:.p$}", first.hi, p = decimals);
        let p = dir.join(name);
        grouped_bar_chart(&series, &lo, &hi).write_png(&p)?;
        paths.push(p);
    }
    Ok(paths)
}
