//! A model alignment as `synthgen model align` runs it: one scan (or a folder of scans, one per
//! object of a dataset) aligned onto its model with `synthgen_physics::align`, refused when
//! the surfaces do not match, written with `synthgen_assets::write_moved_obj` (the moved scan
//! with its materials and textures) beside an `align.json` report.

use anyhow::{Context, Result};
use serde_json::json;
use std::path::{Path, PathBuf};
use synthgen_assets::{load_model, Units};

use synthgen_core::atomic::StagedDir;
use synthgen_formats::layout::open_source;
use synthgen_formats::output::check_apart;
use synthgen_physics::align::{align, AlignOptions, Alignment};

use crate::models::{files_with_extensions, model_name};

use synthgen_core::Progress;

use crate::{user_error, Printer, Stdout};

/// What to align: `synthgen model align`'s arguments as data.
#[derive(Debug, Clone)]
pub struct AlignRequest {
    /// One scan (an OBJ) and the model it is aligned onto...
    pub scan: Option<PathBuf>,
    pub to: Option<PathBuf>,
    /// ...or a folder of scans, one folder per object, and the dataset whose models they
    /// are aligned onto.
    pub scans: Option<PathBuf>,
    pub to_dataset: Option<PathBuf>,
    pub out: PathBuf,
    /// Replace an earlier alignment's folder.
    pub force: bool,
    /// Also try the 24 axis-aligned rotations.
    pub rotation_search: bool,
    /// Refuse an alignment whose median surface distance is above this, mm.
    pub max_median_mm: f64,
    /// Surface samples of the ICP.
    pub samples: usize,
    /// The report as JSON (else a line or a table).
    pub json: bool,
}

/// The report written to `OUT/align.json`.
pub const REPORT_FILE: &str = "align.json";

/// Aligns `req`; messages go to `progress`, the report into `stdout`. Ok(false) when some of a
/// dataset's scans could not be aligned (the others are written).
pub fn align_models(req: &AlignRequest, progress: &dyn Progress, stdout: &Stdout) -> Result<bool> {
    run_align(req, &Printer::new(progress, stdout))
}

fn run_align(args: &AlignRequest, printer: &Printer<'_>) -> Result<bool> {
    if !(args.max_median_mm.is_finite() && args.max_median_mm > 0.0) {
        return Err(user_error(
            format!(
                "--max-median-mm must be a positive number, got {}",
                args.max_median_mm
            ),
            "e.g. --max-median-mm 2",
        ));
    }
    if !(MIN_SAMPLES..=MAX_SAMPLES).contains(&args.samples) {
        return Err(user_error(
            format!(
                "--samples {} is outside {MIN_SAMPLES}..={MAX_SAMPLES} (surface points per mesh)",
                args.samples
            ),
            "the default 4000 aligns the YCB scans to 0.05 mm; a few 10,000 is plenty",
        ));
    }
    let opts = AlignOptions {
        rotation_search: args.rotation_search,
        samples: args.samples,
        ..AlignOptions::default()
    };
    if let (Some(scans), Some(data)) = (&args.scans, &args.to_dataset) {
        check_apart(
            &args.out,
            &[
                ("scans folder", scans.as_path()),
                ("dataset", data.as_path()),
            ],
        )?;
        return align_dataset(args, scans, data, &opts, printer);
    }
    let (Some(scan), Some(to)) = (&args.scan, &args.to) else {
        return Err(user_error(
            "give --scan FILE --to FILE, or --scans DIR --to-dataset DIR",
            "see synthgen model align --help",
        ));
    };
    check_scan_apart(&args.out, scan, to)?;
    check_out(&args.out, args.force)?;
    let done = align_one(args, scan, to, &args.out, &opts, printer)?;
    if args.json {
        printer.data_line(serde_json::to_string_pretty(&done.report)?)?;
    } else {
        printer.data_line(done.line())?;
    }
    printer.info(format!(
        "wrote {} files to {} ({})",
        done.files,
        args.out.display(),
        REPORT_FILE
    ));
    Ok(true)
}

/// One scan aligned and written.
struct Done {
    report: serde_json::Value,
    scan: PathBuf,
    to: PathBuf,
    translation_mm: [f64; 3],
    angle_deg: f64,
    median_mm: f64,
    p95_mm: f64,
    iterations: usize,
    files: usize,
}

impl Done {
    fn line(&self) -> String {
        let t = self.translation_mm;
        format!(
            "{} onto {}: translation ({:.1}, {:.1}, {:.1}) mm, rotation {:.2}°; surface distance median {:.2} mm, p95 {:.2} mm ({} ICP iterations)",
            self.scan.display(),
            self.to.display(),
            t[0],
            t[1],
            t[2],
            self.angle_deg,
            self.median_mm,
            self.p95_mm,
            self.iterations
        )
    }
}

/// The surface points per mesh `--samples` may ask for: fewer cannot align, more only costs
/// memory (each is a few dozen bytes in several arrays).
pub const MIN_SAMPLES: usize = 100;
pub const MAX_SAMPLES: usize = 2_000_000;

/// `out` may not be, hold or lie inside the scan, its material libraries and textures (as its
/// files name them), or the model: `--force` replaces `out`.
fn check_scan_apart(out: &Path, scan: &Path, to: &Path) -> Result<()> {
    // An unreadable scan is reported by the load that follows, with its own message.
    let mut inputs = synthgen_assets::obj_inputs(scan).unwrap_or_else(|_| vec![scan.to_path_buf()]);
    inputs.push(to.to_path_buf());
    let named: Vec<(&str, &Path)> = inputs
        .iter()
        .enumerate()
        .map(|(i, p)| {
            (
                if i == 0 {
                    "scan"
                } else if p == to {
                    "model"
                } else {
                    "scan's file"
                },
                p.as_path(),
            )
        })
        .collect();
    check_apart(out, &named)?;
    Ok(())
}

/// `out` must be new, empty, or an earlier alignment's folder with --force.
fn check_out(out: &Path, force: bool) -> Result<()> {
    let written_before = out.join(REPORT_FILE).is_file();
    let non_empty = std::fs::read_dir(out).is_ok_and(|mut d| d.next().is_some());
    if non_empty && !(force && written_before) {
        return Err(user_error(
            format!("{} is not empty", out.display()),
            if written_before {
                "pass --force to replace the earlier alignment there"
            } else {
                "choose an empty or new --out (--force replaces only an earlier alignment's folder)"
            },
        ));
    }
    Ok(())
}

fn align_one(
    args: &AlignRequest,
    scan_path: &Path,
    to: &Path,
    out: &Path,
    opts: &AlignOptions,
    printer: &Printer<'_>,
) -> Result<Done> {
    let is_obj = scan_path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if !is_obj {
        return Err(user_error(
            format!("the scan must be an OBJ file: {}", scan_path.display()),
            "convert it to OBJ (with its .mtl and textures) first",
        ));
    }
    let scan = load_model(scan_path, Units::Auto, printer)
        .with_context(|| format!("cannot read the scan {}", scan_path.display()))?;
    let target = load_model(to, Units::Auto, printer)
        .with_context(|| format!("cannot read the model {}", to.display()))?;
    let a = align(&scan.model, &target.model, opts)?;
    let report = report_json(args, scan_path, to, &a, scan.units_used);
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
                scan_path.display(),
                to.display()
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
    let angle_deg = synthgen_core::glam::DQuat::from_mat3(&a.rotation)
        .to_axis_angle()
        .1
        .to_degrees();
    if angle_deg > 1.0 {
        printer.warning(format!(
            "{}: the scan needed a {angle_deg:.1}° rotation as well as a shift to lie on the model (surfaces then {median_mm:.2} mm apart): the files' axes differ; look at a render before trusting it",
            scan_path.display()
        ));
    }
    // Written whole into a temporary sibling, then put in place of `out` (an earlier
    // alignment there is replaced only then): a failed or interrupted run leaves `out` as it was.
    let staged = StagedDir::new(out)
        .with_context(|| format!("cannot create a folder beside {}", out.display()))?;
    let written = synthgen_assets::write_moved_obj(scan_path, staged.path(), m)?;
    let report_path = staged.path().join(REPORT_FILE);
    synthgen_formats::io::atomic_write(
        &report_path,
        (serde_json::to_string_pretty(&report)? + "\n").as_bytes(),
    )?;
    staged
        .commit()
        .with_context(|| format!("cannot put the alignment in place: {}", out.display()))?;
    let t = a.translation_m * 1e3;
    Ok(Done {
        report,
        scan: scan_path.to_path_buf(),
        to: to.to_path_buf(),
        translation_mm: t.to_array(),
        angle_deg,
        median_mm,
        p95_mm,
        iterations: a.iterations,
        files: written.len() + 1,
    })
}

/// `--scans DIR --to-dataset DATA`: each object of DATA with a scan folder `DIR/<name>/`.
fn align_dataset(
    args: &AlignRequest,
    scans: &Path,
    data: &Path,
    opts: &AlignOptions,
    printer: &Printer<'_>,
) -> Result<bool> {
    let source = open_source(data).with_context(|| format!("cannot open {}", data.display()))?;
    let ids: Vec<u32> = match source.models_info() {
        Some(info) if !info.is_empty() => info.keys().copied().collect(),
        _ => (1..=999)
            .filter(|&id| source.model_path(id).is_some())
            .collect(),
    };
    if ids.is_empty() {
        return Err(user_error(
            format!("{} has no object models", data.display()),
            "give a BOP, Linemod or YCB-Video dataset with its models/",
        ));
    }
    if args.out.exists() && !args.force {
        let non_empty = std::fs::read_dir(&args.out).is_ok_and(|mut d| d.next().is_some());
        if non_empty {
            return Err(user_error(
                format!("{} is not empty", args.out.display()),
                "choose a new --out, or pass --force to replace the alignments there",
            ));
        }
    }
    let mut rows = Vec::new();
    let mut reports = Vec::new();
    let mut refused = 0usize;
    for id in ids {
        let name = model_name(source.as_ref(), id);
        let folder = scans.join(&name);
        let Some(model) = source.model_path(id) else {
            continue;
        };
        // A missing folder: no scan for this object.
        let objs = files_with_extensions(&folder, &["obj"]).unwrap_or_default();
        let [scan] = objs.as_slice() else {
            rows.push(format!(
                "| {id} | {name} | — | — | — | {} |",
                if objs.is_empty() {
                    "no scan".to_string()
                } else {
                    format!("{} OBJ files: skipped", objs.len())
                }
            ));
            continue;
        };
        let out = args.out.join(&name);
        if out.exists() && !out.join(REPORT_FILE).is_file() {
            check_out(&out, args.force)?;
        }
        check_scan_apart(&out, scan, &model)?;
        match align_one(args, scan, &model, &out, opts, printer) {
            Ok(d) => {
                rows.push(format!(
                    "| {id} | {name} | {:.3} | {:.2} | {:.2} | written |",
                    d.median_mm, d.p95_mm, d.angle_deg
                ));
                reports.push(d.report);
            }
            Err(e) => {
                refused += 1;
                printer.warning(format!("{name}: {e:#}"));
                rows.push(format!("| {id} | {name} | — | — | — | refused |"));
            }
        }
    }
    if args.json {
        printer.data_line(serde_json::to_string_pretty(&reports)?)?;
    } else {
        let mut t = String::from(
            "| obj_id | name | median mm | p95 mm | rotation ° | |\n|---:|---|---:|---:|---:|---|\n",
        );
        for r in &rows {
            t.push_str(r);
            t.push('\n');
        }
        printer.data(t)?;
    }
    printer.info(format!(
        "{} aligned into {}, {refused} refused",
        reports.len(),
        args.out.display()
    ));
    if reports.is_empty() && refused == 0 {
        return Err(user_error(
            format!("no scan folder in {} matches an object of {}", scans.display(), data.display()),
            "name each scan's folder as the dataset names the object (e.g. 003_cracker_box, obj_000005)",
        ));
    }
    if refused > 0 {
        printer.hint(format!(
            "render --replay {} --replay-models {} uses the aligned ones and the dataset's models for the rest",
            data.display(),
            args.out.display()
        ));
        return Ok(false);
    }
    printer.hint(format!(
        "a textured replay: synthgen render --replay {} --replay-models {} --out OUT",
        data.display(),
        args.out.display()
    ));
    Ok(true)
}

fn report_json(
    args: &AlignRequest,
    scan: &Path,
    to: &Path,
    a: &Alignment,
    scan_units: Units,
) -> serde_json::Value {
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
        "scan": scan,
        "model": to,
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
