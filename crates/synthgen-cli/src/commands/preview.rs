//! `synthgen preview`: a contact sheet PNG with the ground-truth poses drawn over the RGB.

use anyhow::{Context, Result};
use synthgen_curate::preview::{contact_sheet, PreviewOptions};
use synthgen_formats::layout::open_source;

use crate::cli::PreviewArgs;
use crate::commands::user_error;
use crate::{ExitStatus, Printer};

pub fn run(args: PreviewArgs, printer: &Printer) -> Result<ExitStatus> {
    if args.count == 0 {
        return Err(user_error("--count must be at least 1", "try --count 16"));
    }
    let source = open_source(&args.dir)
        .with_context(|| format!("cannot open dataset {}", args.dir.display()))?;
    let opts = PreviewOptions {
        count: args.count,
        seed: args.seed,
        tile_width: args.tile_width,
        splits: args.split.clone().into_iter().collect(),
    };
    let (sheet, frames) = contact_sheet(source.as_ref(), &opts, printer)?;
    if let Some(parent) = args.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        synthgen_formats::io::create_dir_all(parent)?;
    }
    sheet.write_png(&args.out)?;
    printer.info(format!(
        "wrote {} ({} frames, {}x{})",
        args.out.display(),
        frames.len(),
        sheet.width,
        sheet.height
    ));
    for f in &frames {
        printer.info(format!("  {}/{:06}/{:06}", f.split, f.scene_id, f.im_id));
    }
    Ok(ExitStatus::Success)
}
