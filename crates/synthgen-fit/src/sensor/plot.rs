//! The fit's and the comparison's figures: small line charts on the dataset crate's canvas
//! (real: dots, blue; fitted or second dataset: line, orange).

use std::path::Path;

use super::compare::{Aspect, Comparison};
use super::fit::{CurvePoint, FitReport};
use synthgen_formats::draw::Canvas;
use synthgen_formats::Result;

const PANEL_W: i64 = 420;
const PANEL_H: i64 = 270;
const BLUE: [u8; 3] = [31, 119, 180];
const ORANGE: [u8; 3] = [230, 110, 10];
const GREEN: [u8; 3] = [44, 160, 44];
const GRID: [u8; 3] = [225, 225, 225];
const AXIS: [u8; 3] = [60, 60, 60];
const INK: [u8; 3] = [20, 20, 20];

/// One series of a panel.
pub struct Series {
    pub points: Vec<(f64, f64)>,
    pub color: [u8; 3],
    /// Joined by a line (else dots).
    pub line: bool,
}

/// A panel: title, axis names and series, drawn at (x, y) on `c`.
pub fn panel(
    c: &mut Canvas,
    x: i64,
    y: i64,
    title: &str,
    x_name: &str,
    y_name: &str,
    series: &[Series],
) {
    let (l, r, t, b) = (x + 56, x + PANEL_W - 14, y + 30, y + PANEL_H - 40);
    let all: Vec<(f64, f64)> = series.iter().flat_map(|s| s.points.clone()).collect();
    let finite = |v: &f64| v.is_finite();
    let xs: Vec<f64> = all.iter().map(|p| p.0).filter(finite).collect();
    let ys: Vec<f64> = all.iter().map(|p| p.1).filter(finite).collect();
    let (mut x0, mut x1) = (
        xs.iter().copied().fold(f64::INFINITY, f64::min),
        xs.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    );
    if !x0.is_finite() {
        (x0, x1) = (0.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let mut y1 = ys.iter().copied().fold(0.0, f64::max);
    if y1 <= 0.0 || !y1.is_finite() {
        y1 = 1.0;
    }
    y1 *= 1.1;
    let px = |v: f64| l as f64 + (v - x0) / (x1 - x0) * (r - l) as f64;
    let py = |v: f64| b as f64 - v / y1 * (b - t) as f64;
    for k in 1..=4 {
        let yy = py(y1 / 1.1 * k as f64 / 4.0);
        c.line((l as f64, yy), (r as f64, yy), GRID, 1);
    }
    c.line((l as f64, t as f64), (l as f64, b as f64), AXIS, 2);
    c.line((l as f64, b as f64), (r as f64, b as f64), AXIS, 2);
    for s in series {
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .filter(|p| p.0.is_finite() && p.1.is_finite())
            .map(|p| (px(p.0), py(p.1)))
            .collect();
        if s.line {
            for w in pts.windows(2) {
                c.line(w[0], w[1], s.color, 2);
            }
        } else {
            for p in &pts {
                c.fill_rect(p.0 as i64 - 3, p.1 as i64 - 3, 7, 7, s.color);
            }
        }
    }
    c.label(x + 8, y + 8, title, 2, INK);
    c.label(l - 50, t - 4, &short(y1 / 1.1), 2, INK);
    c.label(l - 50, b - 10, "0", 2, INK);
    c.label(l, b + 8, &short(x0), 2, INK);
    let hi = short(x1);
    c.label(r - hi.chars().count() as i64 * 8, b + 8, &hi, 2, INK);
    let name_w = x_name.chars().count() as i64 * 8;
    c.label((l + r) / 2 - name_w / 2, b + 22, x_name, 2, INK);
    c.label(x + 8, y + PANEL_H - 14, y_name, 1, INK);
}

fn short(v: f64) -> String {
    let a = v.abs();
    if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

fn real_and_fit(pts: &[CurvePoint], scale: f64) -> [Series; 2] {
    [
        Series {
            points: pts.iter().map(|p| (p.x, p.real * scale)).collect(),
            color: BLUE,
            line: false,
        },
        Series {
            points: pts.iter().map(|p| (p.x, p.fit * scale)).collect(),
            color: ORANGE,
            line: true,
        },
    ]
}

/// The fit's figure: nine panels, real statistics as blue dots, the fitted model as orange
/// lines.
pub fn fit_figure(r: &FitReport) -> Canvas {
    let mut c = Canvas::new(3 * PANEL_W as u32, 3 * PANEL_H as u32 + 40, [255, 255, 255]);
    c.label(
        10,
        12,
        "SENSOR FIT: REAL (BLUE DOTS) VS FITTED MODEL (ORANGE)",
        2,
        INK,
    );
    let at = |k: i64| ((k % 3) * PANEL_W, 40 + (k / 3) * PANEL_H);
    let [l, rr] = &r.shadow;
    let mut shadow = Vec::new();
    for (side, color) in [(l, BLUE), (rr, GREEN)] {
        shadow.push(Series {
            points: side.bins.iter().map(|p| (p.x, p.real)).collect(),
            color,
            line: false,
        });
        shadow.push(Series {
            points: side.bins.iter().map(|p| (p.x, p.fit)).collect(),
            color,
            line: true,
        });
    }
    let profile = |side: &str| -> Vec<CurvePoint> {
        r.edge_profile
            .iter()
            .filter(|p| p.side == side)
            .map(|p| CurvePoint {
                x: p.x,
                n: p.n,
                real: p.real,
                fit: p.fit,
            })
            .collect()
    };
    let panels: [(&str, &str, &str, [Series; 2]); 8] = [
        (
            "NOISE SIGMA VS DEPTH",
            "DEPTH M",
            "MM, INTERIOR, HEAD-ON",
            real_and_fit(&r.noise_by_depth, 1000.0),
        ),
        (
            "NOISE SIGMA VS INCIDENCE",
            "DEG",
            "MM, 2+ PX FROM EDGES",
            real_and_fit(&r.noise_by_incidence, 1000.0),
        ),
        (
            "HOLES VS EDGE DISTANCE",
            "PX",
            "HOLE RATE",
            real_and_fit(&r.holes_by_edge, 1.0),
        ),
        (
            "HOLES VS INCIDENCE",
            "DEG",
            "HOLE RATE",
            real_and_fit(&r.holes_by_incidence, 1.0),
        ),
        (
            "HOLES VS BRIGHTNESS",
            "LUMINANCE",
            "HOLE RATE",
            real_and_fit(&r.holes_by_luminance, 1.0),
        ),
        (
            "READINGS FROM BEHIND VS EDGE DIST.",
            "PX",
            "SHARE",
            real_and_fit(&r.far_by_edge, 1.0),
        ),
        (
            "LEFT EDGES: OBJECT READINGS",
            "PX INTO THE OBJECT",
            "SHARE",
            real_and_fit(&profile("left"), 1.0),
        ),
        (
            "RIGHT EDGES: OBJECT READINGS",
            "PX INTO THE OBJECT",
            "SHARE",
            real_and_fit(&profile("right"), 1.0),
        ),
    ];
    for (k, (title, x_name, y_name, series)) in panels.iter().enumerate() {
        let (x, y) = at(k as i64);
        panel(&mut c, x, y, title, x_name, y_name, series);
    }
    let (x, y) = at(8);
    panel(
        &mut c,
        x,
        y,
        "HOLE RUN OUTSIDE: LEFT BLUE, RIGHT GREEN",
        "G = FX(1/ZN-1/ZF) PX/M",
        "RUN PX",
        &shadow,
    );
    c
}

/// Writes [`fit_figure`] as a PNG.
pub fn write_fit_figure(r: &FitReport, path: &Path) -> Result<()> {
    fit_figure(r).write_png(path)
}

fn bins_series(a: &Aspect) -> [Series; 2] {
    [
        Series {
            points: a
                .bins
                .iter()
                .enumerate()
                .map(|(i, b)| (i as f64, b.first))
                .collect(),
            color: BLUE,
            line: false,
        },
        Series {
            points: a
                .bins
                .iter()
                .enumerate()
                .map(|(i, b)| (i as f64, b.second))
                .collect(),
            color: ORANGE,
            line: true,
        },
    ]
}

/// The comparison's figure: hole rates by incidence, by edge distance and by brightness, and
/// the edge profile, first dataset blue dots, second orange lines. "Missing": no reading of
/// the pixel's own surface.
pub fn compare_figure(cmp: &Comparison) -> Canvas {
    let mut c = Canvas::new(2 * PANEL_W as u32, 2 * PANEL_H as u32 + 40, [255, 255, 255]);
    c.label(
        10,
        12,
        &format!(
            "SENSOR COMPARE: FIRST (BLUE) VS SECOND (ORANGE), SCORE {:.2}",
            cmp.score
        ),
        2,
        INK,
    );
    let find = |name: &str| cmp.aspects.iter().find(|a| a.name == name);
    let layout = [
        (
            "missing_by_incidence",
            "MISSING BY INCIDENCE BIN",
            "0-15 ... 80-90 DEG",
        ),
        (
            "missing_by_edge",
            "MISSING BY EDGE DISTANCE BIN",
            "0 1 2 3-4 5-8 9-15 16+ PX",
        ),
        (
            "missing_by_brightness",
            "MISSING BY BRIGHTNESS BIN",
            "0 ... 1 IN 0.2",
        ),
        (
            "edge_profile",
            "OBJECT READINGS ACROSS EDGES",
            "LEFT -3..7, RIGHT -3..7",
        ),
    ];
    for (k, (name, title, x_name)) in layout.iter().enumerate() {
        if let Some(a) = find(name) {
            let (x, y) = ((k as i64 % 2) * PANEL_W, 40 + (k as i64 / 2) * PANEL_H);
            panel(&mut c, x, y, title, x_name, "RATE", &bins_series(a));
        }
    }
    c
}

/// Writes [`compare_figure`] as a PNG.
pub fn write_compare_figure(cmp: &Comparison, path: &Path) -> Result<()> {
    compare_figure(cmp).write_png(path)
}
