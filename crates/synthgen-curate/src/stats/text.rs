//! The statistics as text: one dataset's table, or several side by side.

use std::fmt::Write as _;

use super::{DatasetStats, Distribution, ElevationFrame, Histogram};

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
    if let Some(d) = &s.inplane_deg {
        write_distribution(&mut out, "in-plane rotation (deg)", d, 1);
    }
    out
}

/// One histogram of several datasets side by side, as percentages of each one's instances
/// (datasets differ in size); bins empty in all of them at either end are left out.
fn write_histograms(out: &mut String, title: &str, hs: &[Option<&Histogram>], decimals: usize) {
    let Some(first) = hs.iter().flatten().next() else {
        return;
    };
    // The title, then the dataset numbers over their columns ("  00.0% bars").
    let _ = write!(out, "\n{title}\n{:22}", "");
    for k in 0..hs.len() {
        let _ = write!(out, "  {:<27}", format!("[{}]", k + 1));
    }
    let _ = writeln!(out);
    let bins = first.counts.len();
    let shares: Vec<Vec<f64>> = hs
        .iter()
        .map(|h| match h {
            Some(h) if h.counts.len() == bins => {
                let n = h.counts.iter().sum::<u64>().max(1) as f64;
                h.counts.iter().map(|&c| c as f64 / n).collect()
            }
            _ => vec![f64::NAN; bins],
        })
        .collect();
    let used = |i: usize| shares.iter().any(|s| s[i] > 0.0);
    let lo = (0..bins).find(|&i| used(i)).unwrap_or(0);
    let hi = (0..bins).rfind(|&i| used(i)).unwrap_or(0);
    for i in lo..=hi {
        let _ = write!(
            out,
            "  {:>8.d$} .. {:>8.d$}",
            first.edge(i),
            first.edge(i + 1),
            d = decimals
        );
        for s in &shares {
            let v = s[i];
            if v.is_nan() {
                let _ = write!(out, "  {:>6} {:<20}", "-", "");
            } else {
                let bar = "#".repeat((v * 40.0).round().min(20.0) as usize);
                let _ = write!(out, "  {:>5.1}% {bar:<20}", 100.0 * v);
            }
        }
        let _ = writeln!(out);
    }
}

/// Several datasets' statistics side by side (from [`super::compare_stats`], which puts them
/// on the same bins): counts, then each distribution as the share of each dataset's instances
/// per bin.
pub fn format_comparison(stats: &[DatasetStats]) -> String {
    let mut out = String::new();
    for (k, s) in stats.iter().enumerate() {
        let splits: Vec<String> = s.splits.iter().map(|(k, v)| format!("{k} {v}")).collect();
        let _ = writeln!(
            out,
            "[{}] {}: {} frames ({}), {} objects, {} instances",
            k + 1,
            s.root,
            s.frames,
            splits.join(", "),
            s.objects.len(),
            s.instances
        );
    }

    let medians = |f: &dyn Fn(&DatasetStats) -> Option<f64>, d: usize| {
        stats
            .iter()
            .map(|s| f(s).map_or("-".to_string(), |v| format!("{v:.d$}")))
            .collect::<Vec<_>>()
            .join(" | ")
    };
    let _ = writeln!(
        out,
        "\nmedians [1] | [2] ...: distance m {}; elevation deg {}; in-plane deg {}",
        medians(&|s| s.distance_m.as_ref().map(|d| d.median), 3),
        medians(&|s| s.elevation_deg.as_ref().map(|d| d.median), 1),
        medians(&|s| s.inplane_deg.as_ref().map(|d| d.median), 1),
    );
    let dist = |f: &dyn Fn(&DatasetStats) -> Option<&Distribution>| {
        stats
            .iter()
            .map(|s| f(s).map(|d| &d.histogram))
            .collect::<Vec<_>>()
    };
    write_histograms(
        &mut out,
        "visib_fract (share of instances)",
        &stats
            .iter()
            .map(|s| s.visib_fract.as_ref())
            .collect::<Vec<_>>(),
        2,
    );
    write_histograms(
        &mut out,
        "camera distance (m)",
        &dist(&|s| s.distance_m.as_ref()),
        3,
    );
    write_histograms(
        &mut out,
        "camera elevation (deg)",
        &dist(&|s| s.elevation_deg.as_ref()),
        1,
    );
    write_histograms(
        &mut out,
        "in-plane rotation (deg)",
        &dist(&|s| s.inplane_deg.as_ref()),
        1,
    );
    if stats.iter().any(|s| s.visib_fract.is_none()) {
        let _ = writeln!(
            out,
            "\n(no visib_fract where a dataset has no scene_gt_info.json: `synthgen convert --to bop` or `synthgen annotate` computes it)"
        );
    }
    out
}
