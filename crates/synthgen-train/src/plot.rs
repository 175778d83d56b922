//! The training curve as a PNG, drawn on the dataset crate's canvas (no fonts, no system
//! libraries).
//! Top panel: train loss (blue) and val loss (orange), log scale. Bottom panel (green, log
//! scale): validation centre error with a grey line at 1 cm (TNet), or the ADD(-S) error rate
//! with a grey line at 10% (RNet, Full). Grid lines at decades.

use std::path::Path;

use synthgen_formats::draw::Canvas;

use crate::error::Result;
use crate::metrics::EpochMetrics;

const W: u32 = 640;
const H: u32 = 480;
const BLUE: [u8; 3] = [31, 119, 180];
const ORANGE: [u8; 3] = [255, 127, 14];
const GREEN: [u8; 3] = [44, 160, 44];
const GRID: [u8; 3] = [220, 220, 220];
const AXIS: [u8; 3] = [60, 60, 60];

/// A panel: pixel box and a log10 y range.
struct Panel {
    x0: f64,
    x1: f64,
    y0: f64,
    y1: f64,
    lo: f64,
    hi: f64,
    n: usize,
}

impl Panel {
    fn new(top: f64, bottom: f64, values: &[f64], n: usize) -> Panel {
        let logs: Vec<f64> = values
            .iter()
            .filter(|v| **v > 0.0 && v.is_finite())
            .map(|v| v.log10())
            .collect();
        let lo = logs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = logs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let (lo, hi) = if lo.is_finite() {
            (lo.floor(), hi.ceil().max(lo.floor() + 1.0))
        } else {
            (0.0, 1.0)
        };
        Panel {
            x0: 50.0,
            x1: f64::from(W) - 20.0,
            y0: top,
            y1: bottom,
            lo,
            hi,
            n,
        }
    }

    fn x(&self, i: usize) -> f64 {
        let d = (self.n.max(2) - 1) as f64;
        self.x0 + (self.x1 - self.x0) * i as f64 / d
    }

    fn y(&self, v: f64) -> f64 {
        let t = (v.max(1e-12).log10() - self.lo) / (self.hi - self.lo);
        self.y1 - (self.y1 - self.y0) * t
    }

    fn frame(&self, c: &mut Canvas) {
        let mut d = self.lo;
        while d <= self.hi + 1e-9 {
            for m in 1..10 {
                let y = self.y(10f64.powf(d) * f64::from(m));
                if y >= self.y0 - 0.5 && m == 1 {
                    c.line((self.x0, y), (self.x1, y), GRID, 2);
                }
            }
            d += 1.0;
        }
        c.line((self.x0, self.y0), (self.x0, self.y1), AXIS, 2);
        c.line((self.x0, self.y1), (self.x1, self.y1), AXIS, 2);
        for i in 0..self.n {
            let x = self.x(i);
            c.line((x, self.y1), (x, self.y1 + 4.0), AXIS, 2);
        }
    }

    fn series(&self, c: &mut Canvas, v: &[f64], colour: [u8; 3]) {
        for (i, w) in v.windows(2).enumerate() {
            c.line(
                (self.x(i), self.y(w[0])),
                (self.x(i + 1), self.y(w[1])),
                colour,
                2,
            );
        }
        if v.len() == 1 {
            c.line(
                (self.x(0) - 3.0, self.y(v[0])),
                (self.x(0) + 3.0, self.y(v[0])),
                colour,
                2,
            );
        }
    }
}

/// Draws the curve of `epochs` and writes it as a PNG. The bottom panel shows the
/// validation ADD(-S) error rate (1 − accuracy, grey line at 10%) when the run has it (RNet,
/// Full), else the centre error (grey line at 1 cm).
pub fn write_curve(path: &Path, epochs: &[EpochMetrics]) -> Result<()> {
    let mut c = Canvas::new(W, H, [255; 3]);
    let n = epochs.len();
    let train: Vec<f64> = epochs.iter().map(|e| e.train_loss).collect();
    let val: Vec<f64> = epochs.iter().map(|e| e.val_loss).collect();
    let (err, mark): (Vec<f64>, f64) = if epochs.iter().any(|e| e.val_add_s_acc.is_some()) {
        (
            epochs
                .iter()
                .map(|e| 1.0 - e.val_add_s_acc.unwrap_or(0.0))
                .collect(),
            0.1,
        )
    } else {
        (
            epochs
                .iter()
                .map(|e| e.val_centre_error_m.unwrap_or(f64::NAN))
                .collect(),
            0.01,
        )
    };
    let both: Vec<f64> = train.iter().chain(&val).copied().collect();
    let top = Panel::new(20.0, 230.0, &both, n);
    top.frame(&mut c);
    top.series(&mut c, &train, BLUE);
    top.series(&mut c, &val, ORANGE);
    let mut err_range = err.clone();
    err_range.push(mark);
    let bottom = Panel::new(260.0, 450.0, &err_range, n);
    bottom.frame(&mut c);
    let mark_y = bottom.y(mark);
    let mut x = bottom.x0;
    while x < bottom.x1 {
        c.line(
            (x, mark_y),
            ((x + 6.0).min(bottom.x1), mark_y),
            [150, 150, 150],
            2,
        );
        x += 12.0;
    }
    bottom.series(&mut c, &err, GREEN);
    c.write_png(path)?;
    Ok(())
}
