//! `synthgen sensor fit` and `synthgen sensor compare`: thin skins over
//! `synthgen_fit::sensor` (measure, fit, compare, plot) with each dataset's own models
//! in an `ObjectRenderer`.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use synthgen_core::scene::{SensorSpec, StructuredLightSpec};
use synthgen_fit::sensor::{compare, plot, Comparison, FitReport};
use synthgen_formats::layout::open_source;

use crate::cli::{SensorCompareArgs, SensorCompareRgbArgs, SensorFitArgs};
use crate::commands::user_error;
use crate::{ExitStatus, Printer};
use synthgen_jobs::fit::{fit_sensor_to_file, measure};

fn thread_pool(jobs: Option<usize>) -> Result<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.unwrap_or(0))
        .build()
        .context("cannot start worker threads")
}

pub fn run_fit(args: SensorFitArgs, printer: &Printer) -> Result<ExitStatus> {
    if !(args.max_frame_residual_mm.is_finite() && args.max_frame_residual_mm > 0.0) {
        return Err(user_error(
            format!(
                "--max-frame-residual-mm must be a positive number of millimetres, got {}",
                args.max_frame_residual_mm
            ),
            "the default, 20, leaves out frames whose GT is obviously off",
        ));
    }
    if args.out.exists() && !args.force {
        return Err(user_error(
            format!("{} exists", args.out.display()),
            "pass --force to overwrite it, or choose another --out",
        ));
    }
    let base = match &args.base {
        Some(p) => {
            let s = SensorSpec::from_toml_file(p)
                .with_context(|| format!("cannot read the base sensor file {}", p.display()))?;
            s.structured_light
        }
        None => StructuredLightSpec::default(),
    };
    let pool = thread_pool(args.jobs)?;
    let report = pool.install(|| {
        fit_sensor_to_file(
            &args.data,
            &args.scenes,
            args.max_frame_residual_mm / 1000.0,
            base,
            &args.out,
            printer,
        )
    })?;
    if let Some(p) = &args.plot {
        plot::write_fit_figure(&report, p)?;
        printer.info(format!("wrote {}", p.display()));
    }
    if args.json {
        printer.data_line(serde_json::to_string_pretty(&report)?)?;
    } else {
        printer.data(format_fit(&report, &args.data))?;
    }
    printer.info(format!("wrote {}", args.out.display()));
    printer.hint(format!(
        "check it on real frames: synthgen render --replay {} --sensor {} --out out/replay, then synthgen sensor compare --real {} --synth out/replay",
        args.data.display(),
        args.out.display(),
        args.data.display()
    ));
    Ok(ExitStatus::Success)
}

fn pct(v: f64) -> String {
    format!("{:.1} %", v * 100.0)
}

fn format_fit(r: &FitReport, data: &Path) -> String {
    let s = &r.spec;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "Fitted a structured-light model to {} frames of {} ({} instances, {} object pixels); {} frame{} left out.",
        r.frames_used,
        data.display(),
        r.instances,
        r.pixels,
        r.frames_excluded.len(),
        if r.frames_excluded.len() == 1 { "" } else { "s" }
    );
    let [l, rr] = &r.shadow;
    let _ = writeln!(
        o,
        "  shadow      on the {} of objects: baseline_m {:+.4} (hole-run slope left {:.4} m, right {:.4} m); second_view_m {:+.4}",
        r.shadow_side, s.baseline_m, l.slope_m, rr.slope_m, s.second_view_m
    );
    let _ = writeln!(
        o,
        "  noise       disparity_sigma_px {:.4}, lateral_sigma_px {:.3}; robust sigma real/fitted by depth: {}",
        s.disparity_sigma_px,
        s.lateral_sigma_px,
        r.noise_by_depth
            .iter()
            .map(|p| format!("{:.2} m {:.2}/{:.2} mm", p.x, p.real * 1000.0, p.fit * 1000.0))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(
        o,
        "  bias        {:+.2} mm (median instance offset)",
        s.bias_m * 1000.0
    );
    let _ = writeln!(
        o,
        "  hole blobs  {:.1} px (mean hole run real {:.2} px, fitted field {:.2} px)\n  holes       real {}, fitted {}; at an edge {:.2} (decay {:.2} px), grazing 50 % at {:.1}° (width {:.1}°), dark {:.2} below {:.2}, bright {:.2} above {:.2}, anywhere {:.3}",
        s.hole_size_px,
        r.hole_run_real,
        r.hole_run_fit,
        pct(r.hole_rate_real),
        pct(r.hole_rate_fit),
        s.edge_dropout,
        s.edge_width_px,
        s.grazing_deg,
        s.grazing_width_deg,
        s.dark_dropout,
        s.dark_luminance,
        s.bright_dropout,
        s.bright_luminance,
        s.dropout
    );
    let _ = writeln!(
        o,
        "  edges       reads the surface behind {:.3} at the edge, fattening {:.2} px, depth shifted {:+.2} px against the colour image",
        s.edge_mix, s.fattening_px, s.shift_px
    );
    for n in &r.notes {
        let _ = writeln!(o, "  note: {n}");
    }
    o
}

pub fn run_compare(args: SensorCompareArgs, printer: &Printer) -> Result<ExitStatus> {
    let pool = thread_pool(args.jobs)?;
    let (cmp, frames) = pool.install(|| -> Result<(Comparison, [usize; 2])> {
        let (_, a) = measure(&args.real, &args.scenes, f64::INFINITY, printer)?;
        let (_, b) = measure(&args.synth, &args.scenes, f64::INFINITY, printer)?;
        let frames = [a.frames, b.frames];
        Ok((compare(&a, &b), frames))
    })?;
    if frames[0] != frames[1] {
        printer.warning(format!(
            "the datasets have {} and {} frames with GT: a replay has as many as its source",
            frames[0], frames[1]
        ));
    }
    if let Some(p) = &args.plot {
        plot::write_compare_figure(&cmp, p)?;
        printer.info(format!("wrote {}", p.display()));
    }
    if args.json {
        printer.data_line(serde_json::to_string_pretty(&cmp)?)?;
    } else {
        printer.data(format_compare(&cmp, &args.real, &args.synth))?;
    }
    Ok(ExitStatus::Success)
}

fn format_compare(c: &Comparison, a: &Path, b: &Path) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "first:  {} ({} frames, {} object pixels)",
        a.display(),
        c.frames[0],
        c.pixels[0]
    );
    let _ = writeln!(
        o,
        "second: {} ({} frames, {} object pixels)",
        b.display(),
        c.frames[1],
        c.pixels[1]
    );
    let _ = writeln!(
        o,
        "{:<20} {:>10} {:>10} {:>12} {:>7}",
        "aspect", "first", "second", "difference", "scaled"
    );
    for asp in &c.aspects {
        let (fa, fb, diff) = if asp.unit.is_empty() {
            (
                pct(asp.first),
                pct(asp.second),
                format!("{:.1} pts", asp.value * 100.0),
            )
        } else {
            (
                format!("{:.2} {}", asp.first, asp.unit),
                format!("{:.2} {}", asp.second, asp.unit),
                format!("{:.3} {}", asp.value, asp.unit),
            )
        };
        let scaled = if asp.scored {
            format!("{:.2}", asp.value / asp.scale)
        } else {
            "-".into()
        };
        let _ = writeln!(
            o,
            "{:<20} {fa:>10} {fb:>10} {diff:>12} {scaled:>7}",
            asp.name
        );
    }
    let _ = writeln!(
        o,
        "score {:.3}  (mean of the scaled aspects; 0 = the same, lower = closer)",
        c.score
    );
    for (title, groups) in [("scene", &c.scenes), ("object", &c.objects)] {
        let _ = writeln!(
            o,
            "{:<8} {:>9} {:>9} {:>8} {:>8} {:>9}",
            title, "px first", "px second", "holes 1", "holes 2", "W1 mm"
        );
        for g in groups.iter() {
            let _ = writeln!(
                o,
                "{:<8} {:>9} {:>9} {:>8} {:>8} {:>9.3}",
                g.id,
                g.pixels_first,
                g.pixels_second,
                pct(g.holes_first),
                pct(g.holes_second),
                g.residual_w1_mm
            );
        }
    }
    o
}

/// `synthgen sensor compare-rgb`: a thin skin over `synthgen_fit::rgb_compare`.
pub fn run_compare_rgb(args: SensorCompareRgbArgs, printer: &Printer) -> Result<ExitStatus> {
    let real =
        open_source(&args.real).with_context(|| format!("cannot open {}", args.real.display()))?;
    let synth = open_source(&args.synth)
        .with_context(|| format!("cannot open {}", args.synth.display()))?;
    let opts = synthgen_fit::rgb_compare::RgbCompareOptions {
        scenes: args.scenes.clone(),
        min_pixels: args.min_pixels,
    };
    let c = synthgen_fit::rgb_compare::compare_rgb(real.as_ref(), synth.as_ref(), &opts)?;
    if c.frames_not_twins > 0 {
        let msg = format!(
            "{} frames of {} share their scene and image ids with {}'s but show something else ({}): not its replay{}",
            c.frames_not_twins,
            args.synth.display(),
            args.real.display(),
            c.not_twins.join("; "),
            if c.frames == 0 { "" } else { "; those frames are not compared" }
        );
        if c.frames == 0 {
            return Err(user_error(
                msg,
                format!(
                    "compare a replay of the real frames: `synthgen render --replay {} --out DIR`",
                    args.real.display()
                ),
            ));
        }
        printer.warning(msg);
    }
    if c.frames == 0 {
        return Err(user_error(
            format!(
                "no frame of {} has a twin in {} (frames are matched by scene and image id)",
                args.real.display(),
                args.synth.display()
            ),
            format!(
                "make the twins with `synthgen render --replay {} --out DIR`",
                args.real.display()
            ),
        ));
    }
    if c.frames_without_twin > 0 {
        printer.warning(format!(
            "{} real frames have no twin in {} and are not compared",
            c.frames_without_twin,
            args.synth.display()
        ));
    }
    if args.json {
        printer.data_line(serde_json::to_string_pretty(&c)?)?;
        return Ok(ExitStatus::Success);
    }
    let mut t = String::new();
    let _ = writeln!(
        t,
        "{} frames, {} instances (real visible masks eroded by 1 px, render not black; gains fitted per frame)",
        c.frames, c.all.instances
    );
    let _ = writeln!(t, "| object | n | ncc_int | ncc_grad | hist |");
    let _ = writeln!(t, "|---:|---:|---:|---:|---:|");
    for (id, m) in &c.objects {
        let _ = writeln!(
            t,
            "| {id} | {} | {:.3} | {:.3} | {:.3} |",
            m.instances, m.ncc_intensity, m.ncc_gradient, m.hist_distance
        );
    }
    let _ = writeln!(
        t,
        "| all | {} | {:.3} | {:.3} | {:.3} |",
        c.all.instances, c.all.ncc_intensity, c.all.ncc_gradient, c.all.hist_distance
    );
    printer.data(t)?;
    Ok(ExitStatus::Success)
}
