//! `synthgen model align`: a thin skin over `synthgen_physics::align` (the alignment) and
//! `synthgen_assets::write_moved_obj` (the moved scan with its materials and textures).

use anyhow::{Context, Result};
use serde_json::json;
use synthgen_assets::{load_model, Units};
use synthgen_physics::align::{align, AlignOptions, Alignment};

use crate::cli::ModelAlignArgs;
use crate::commands::user_error;
use crate::{ExitStatus, Printer};

/// The report written to `OUT/align.json`.
pub const REPORT_FILE: &str = "align.json";

pub fn run_align(args: ModelAlignArgs, printer: &Printer) -> Result<ExitStatus> {
    if !(args.max_median_mm.is_finite() && args.max_median_mm > 0.0) {
        return Err(user_error(
            format!(
                "--max-median-mm must be a positive number, got {}",
                args.max_median_mm
            ),
            "e.g. --max-median-mm 2",
        ));
    }
    let is_obj = args
        .scan
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if !is_obj {
        return Err(user_error(
            format!("the scan must be an OBJ file: {}", args.scan.display()),
            "convert it to OBJ (with its .mtl and textures) first",
        ));
    }
    let written_before = args.out.join(REPORT_FILE).is_file();
    let non_empty = std::fs::read_dir(&args.out).is_ok_and(|mut d| d.next().is_some());
    if non_empty && !(args.force && written_before) {
        return Err(user_error(
            format!("{} is not empty", args.out.display()),
            if written_before {
                "pass --force to replace the earlier alignment there"
            } else {
                "choose an empty or new --out (--force replaces only an earlier alignment's folder)"
            },
        ));
    }
    let scan = load_model(&args.scan, Units::Auto, printer)
        .with_context(|| format!("cannot read the scan {}", args.scan.display()))?;
    let target = load_model(&args.to, Units::Auto, printer)
        .with_context(|| format!("cannot read the model {}", args.to.display()))?;
    let opts = AlignOptions {
        rotation_search: args.rotation_search,
        samples: args.samples.max(100),
        ..AlignOptions::default()
    };
    let a = align(&scan.model, &target.model, &opts)?;
    let report = report_json(&args, &a, scan.units_used);
    let (median_mm, p95_mm) = (a.median_m() * 1e3, a.p95_m() * 1e3);
    if median_mm > args.max_median_mm {
        if args.json {
            printer.data_line(serde_json::to_string_pretty(&report)?)?;
        }
        return Err(user_error(
            format!(
                "the surfaces do not match: after alignment the median distance is {median_mm:.2} mm \
                 and the 95th percentile {p95_mm:.2} mm (over --max-median-mm {}): {} is not the same \
                 shape as {}; nothing written",
                args.max_median_mm,
                args.scan.display(),
                args.to.display()
            ),
            if args.rotation_search {
                "check that the two files are the same object (a remeshed or rescaled model differs)"
            } else {
                "if the files' axes differ, try --rotation-search; else they are not the same object"
            },
        ));
    }
    // The motion in the scan file's own units.
    let scale = match scan.units_used {
        Units::Mm => 1000.0,
        _ => 1.0,
    };
    let mut m = a.matrix();
    m.w_axis.x *= scale;
    m.w_axis.y *= scale;
    m.w_axis.z *= scale;
    if args.out.exists() {
        for e in std::fs::read_dir(&args.out)? {
            let p = e?.path();
            if p.is_file() {
                std::fs::remove_file(&p)
                    .with_context(|| format!("cannot remove {}", p.display()))?;
            }
        }
    }
    let angle_deg = synthgen_core::glam::DQuat::from_mat3(&a.rotation)
        .to_axis_angle()
        .1
        .to_degrees();
    if angle_deg > 1.0 {
        printer.warning(format!(
            "the scan needed a {angle_deg:.1}° rotation as well as a shift to lie on the model (surfaces then {median_mm:.2} mm apart): the files' axes differ; look at a render before trusting it"
        ));
    }
    let written = synthgen_assets::write_moved_obj(&args.scan, &args.out, m)?;
    let report_path = args.out.join(REPORT_FILE);
    std::fs::write(&report_path, serde_json::to_string_pretty(&report)? + "\n")
        .with_context(|| format!("cannot write {}", report_path.display()))?;
    if args.json {
        printer.data_line(serde_json::to_string_pretty(&report)?)?;
    } else {
        let t = a.translation_m * 1e3;
        printer.data_line(format!(
            "{} onto {}: translation ({:.1}, {:.1}, {:.1}) mm, rotation {:.2}°; surface distance median {median_mm:.2} mm, p95 {p95_mm:.2} mm ({} ICP iterations)",
            args.scan.display(),
            args.to.display(),
            t.x,
            t.y,
            t.z,
            angle_deg,
            a.iterations
        ))?;
    }
    printer.info(format!(
        "wrote {} files to {} ({})",
        written.len() + 1,
        args.out.display(),
        REPORT_FILE
    ));
    Ok(ExitStatus::Success)
}

fn report_json(args: &ModelAlignArgs, a: &Alignment, scan_units: Units) -> serde_json::Value {
    let r = a.rotation.transpose().to_cols_array(); // row-major
    let res = |x: &synthgen_physics::align::Residual| {
        json!({
            "median_mm": x.median_m * 1e3,
            "p95_mm": x.p95_m * 1e3,
            "max_mm": x.max_m * 1e3,
            "points": x.points,
        })
    };
    json!({
        "scan": args.scan,
        "model": args.to,
        "scan_units": format!("{scan_units:?}").to_lowercase(),
        "rotation": [[r[0], r[1], r[2]], [r[3], r[4], r[5]], [r[6], r[7], r[8]]],
        "translation_m": a.translation_m.to_array(),
        "scan_to_model": res(&a.scan_to_target),
        "model_to_scan": res(&a.target_to_scan),
        "median_mm": a.median_m() * 1e3,
        "p95_mm": a.p95_m() * 1e3,
        "max_median_mm": args.max_median_mm,
        "rotation_search": args.rotation_search,
        "iterations": a.iterations,
    })
}
