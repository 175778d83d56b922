//! `plot.png`: test error (blue, ±1 std error bars) and train error (grey) in cm against the
//! synthetic fraction 0..1, linear axes from 0; a dashed orange line at the all-real test
//! error + 15% (the target for the all-synthetic row). The `--plus-synth` rows
//! (all the real frames + K× synthetic, at x = K / (K + 1)) are a green series of their own,
//! starting from the all-real row when it has as many real frames. Digits only (the canvas'
//! font): x ticks at 0, 0.25, 0.5, 0.75, 1; y ticks in cm.

use std::path::Path;

use anyhow::Result;
use synthgen_formats::draw::Canvas;

use super::table::{all_real, Line};

const W: u32 = 640;
const H: u32 = 420;
const BLUE: [u8; 3] = [31, 119, 180];
const GREY: [u8; 3] = [150, 150, 150];
const ORANGE: [u8; 3] = [255, 127, 14];
const GREEN: [u8; 3] = [44, 160, 44];
const GRID: [u8; 3] = [225, 225, 225];
const AXIS: [u8; 3] = [60, 60, 60];
/// Labels: the canvas draws text on a dark box.
const TEXT: [u8; 3] = [255, 255, 255];
const X0: f64 = 70.0;
const X1: f64 = 610.0;
const Y0: f64 = 20.0;
const Y1: f64 = 370.0;

/// A "nice" tick step (1, 2 or 5 × 10^k) giving about 5 ticks up to `max`.
fn tick_step(max: f64) -> f64 {
    let raw = (max / 5.0).max(1e-9);
    let p = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * p)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * p)
}

fn label(v: f64, step: f64) -> String {
    let digits = if step >= 1.0 {
        0
    } else {
        (-step.log10().floor()) as usize
    };
    format!("{v:.digits$}")
}

pub fn write(path: &Path, lines: &[Line]) -> Result<()> {
    let mut c = Canvas::new(W, H, [255; 3]);
    let finite = |v: f64| v.is_finite().then_some(v);
    let top = lines
        .iter()
        .flat_map(|l| {
            [
                finite(l.test_cm.mean + l.test_cm.std.max(0.0)),
                finite(l.train_cm.mean),
            ]
        })
        .flatten()
        .chain(all_real(lines).and_then(|l| finite(l.test_cm.mean * 1.15)))
        .fold(0.0f64, f64::max);
    let step = tick_step(if top > 0.0 { top * 1.05 } else { 1.0 });
    let y_max = (top * 1.05 / step).ceil().max(1.0) * step;
    let x = |f: f64| X0 + (X1 - X0) * f;
    let y = |v: f64| Y1 - (Y1 - Y0) * (v / y_max).clamp(0.0, 1.0);

    let mut v = 0.0;
    while v <= y_max + 1e-9 {
        c.line((X0, y(v)), (X1, y(v)), GRID, 1);
        c.line((X0 - 5.0, y(v)), (X0, y(v)), AXIS, 2);
        let s = label(v, step);
        c.text(
            X0 as i64 - 10 - 8 * s.len() as i64,
            y(v) as i64 - 5,
            &s,
            2,
            TEXT,
        );
        v += step;
    }
    for f in [0.0, 0.25, 0.5, 0.75, 1.0] {
        c.line((x(f), Y1), (x(f), Y1 + 5.0), AXIS, 2);
        let s = label(f, 0.01)
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string();
        let s = if s.is_empty() { "0".to_string() } else { s };
        c.text(
            x(f) as i64 - 4 * s.len() as i64,
            Y1 as i64 + 12,
            &s,
            2,
            TEXT,
        );
    }
    c.line((X0, Y0), (X0, Y1), AXIS, 2);
    c.line((X0, Y1), (X1, Y1), AXIS, 2);

    let reference = all_real(lines);
    if let Some(r) = reference {
        let target = y(r.test_cm.mean * 1.15);
        let mut px = X0;
        while px < X1 {
            c.line((px, target), ((px + 8.0).min(X1), target), ORANGE, 2);
            px += 16.0;
        }
    }
    let mut pts: Vec<&Line> = lines.iter().filter(|l| l.plus.is_none()).collect();
    pts.sort_by(|a, b| a.synth_fraction().total_cmp(&b.synth_fraction()));
    let mut plus: Vec<&Line> = lines.iter().filter(|l| l.plus.is_some()).collect();
    plus.sort_by(|a, b| a.synth_fraction().total_cmp(&b.synth_fraction()));
    if let (Some(r), Some(first)) = (reference, plus.first()) {
        if r.real == first.real {
            plus.insert(0, r);
        }
    }
    for (series, colour, pts) in [
        (false, GREY, &pts),
        (true, BLUE, &pts),
        (true, GREEN, &plus),
    ] {
        let val = |l: &Line| {
            if series {
                l.test_cm.mean
            } else {
                l.train_cm.mean
            }
        };
        for w in pts.windows(2) {
            let (a, b) = (val(w[0]), val(w[1]));
            if a.is_finite() && b.is_finite() {
                c.line(
                    (x(w[0].synth_fraction()), y(a)),
                    (x(w[1].synth_fraction()), y(b)),
                    colour,
                    2,
                );
            }
        }
        for l in pts.iter() {
            let m = val(l);
            if !m.is_finite() {
                continue;
            }
            let px = x(l.synth_fraction());
            c.fill_rect(px as i64 - 3, y(m) as i64 - 3, 7, 7, colour);
            if series && l.test_cm.std > 0.0 {
                let (lo, hi) = (y(m - l.test_cm.std), y(m + l.test_cm.std));
                c.line((px, lo), (px, hi), colour, 2);
                c.line((px - 5.0, lo), (px + 5.0, lo), colour, 2);
                c.line((px - 5.0, hi), (px + 5.0, hi), colour, 2);
            }
        }
    }
    c.write_png(path)?;
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn tick_steps_are_nice() {
        assert_eq!(tick_step(5.0), 1.0);
        assert_eq!(tick_step(0.9), 0.2);
        assert_eq!(tick_step(30.0), 10.0);
    }
}
