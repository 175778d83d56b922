//! `synthgen convert`: BOP ⇄ Linemod.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use synthgen_core::Progress;
use synthgen_dataset::convert::{bop_to_linemod, linemod_to_bop, ConvertOptions};
use synthgen_dataset::manifest::{write_manifest, Manifest};
use synthgen_dataset::validate::{detect_layout, Layout};

use crate::cli::{ConvertArgs, FormatArg};
use crate::commands::user_error;
use crate::{ExitStatus, Printer};

/// The layout of `dir`: `--format`/`--from` when given, else detected.
pub fn layout_of(dir: &Path, given: Option<FormatArg>, flag: &str) -> Result<Layout> {
    if let Some(f) = given {
        return Ok(match f {
            FormatArg::Bop => Layout::Bop,
            FormatArg::Linemod => Layout::Linemod,
        });
    }
    if !dir.is_dir() {
        return Err(user_error(
            format!("no such dataset folder: {}", dir.display()),
            "check the path",
        ));
    }
    detect_layout(dir).ok_or_else(|| {
        user_error(
            format!(
                "cannot tell the layout of {}: no camera.json (BOP) and no data/NN/gt.yml (Linemod)",
                dir.display()
            ),
            format!("pass {flag} bop or {flag} linemod"),
        )
    })
}

pub fn run(args: ConvertArgs, printer: &Printer) -> Result<ExitStatus> {
    let started = Instant::now();
    let from = layout_of(&args.input, args.from, "--from")?;
    let to = match args.to {
        FormatArg::Bop => Layout::Bop,
        FormatArg::Linemod => Layout::Linemod,
    };
    if from == to {
        return Err(user_error(
            format!("{} is already a {from} dataset", args.input.display()),
            "pick the other layout with --to, or copy the folder",
        ));
    }
    if let Some(s) = args.depth_scale {
        if !(s.is_finite() && s > 0.0) {
            return Err(user_error(
                format!("--depth-scale must be positive, got {s}"),
                "1.0 stores millimetres, 0.1 tenths of a millimetre",
            ));
        }
    }
    if !(0.0..=1.0).contains(&args.min_visib_fract) {
        return Err(user_error(
            format!(
                "--min-visib-fract must be in 0..1, got {}",
                args.min_visib_fract
            ),
            "0.1 (the default) keeps objects at least 10% visible",
        ));
    }
    if let Ok(mut entries) = std::fs::read_dir(&args.output) {
        if entries.next().is_some() && !args.force {
            return Err(user_error(
                format!("output folder is not empty: {}", args.output.display()),
                "choose another OUT, or pass --force to write into it",
            ));
        }
    }
    let opts = ConvertOptions {
        depth_scale: args.depth_scale,
        min_visib_fract: args.min_visib_fract,
    };
    let summary = match to {
        Layout::Linemod => bop_to_linemod(&args.input, &args.output, &opts, printer),
        Layout::Bop => linemod_to_bop(&args.input, &args.output, &opts, printer),
    }
    .with_context(|| format!("cannot convert {} to {to}", args.input.display()))?;
    printer.finish();

    let mut manifest = Manifest::new(std::env::args().collect(), 0);
    manifest.frames = summary.frames;
    manifest.extra = serde_json::json!({
        "convert": {
            "from": from,
            "to": to,
            "source": args.input,
            "depth_scale": args.depth_scale,
            "min_visib_fract": args.min_visib_fract,
        }
    });
    write_manifest(&args.output, &manifest)?;

    if summary.depth_out_of_range_px > 0 {
        printer.warning(format!(
            "{} depth values did not fit 16 bits at the new depth scale and were written as 0",
            summary.depth_out_of_range_px
        ));
    }
    let note = match (to, summary.instances_without_mask) {
        (_, 0) => String::new(),
        (Layout::Linemod, n) => format!(
            " {n} object instance{} below --min-visib-fract got no folder entry (their poses are kept in the other folders' gt.yml).",
            if n == 1 { "" } else { "s" }
        ),
        (Layout::Bop, n) => format!(
            " {n} object instance{} had no Linemod mask and got an empty mask_visib.",
            if n == 1 { "" } else { "s" }
        ),
    };
    printer.info(format!(
        "Converted {} frames ({} object instances, {} models) from {from} to {to} in {:.1} s: {}.{note}",
        summary.frames,
        summary.instances,
        summary.models,
        started.elapsed().as_secs_f64(),
        args.output.display()
    ));
    printer.hint(format!(
        "check it with `synthgen validate {}`",
        args.output.display()
    ));
    Ok(ExitStatus::Success)
}
