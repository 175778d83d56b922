//! `synthgen annotate`: a skin over `synthgen_jobs::annotate` (masks and scene_gt_info.json
//! from the poses, or the comparison with a dataset's own masks).

use anyhow::Result;
use synthgen_jobs::annotate::{annotate, AnnotateRequest};

use crate::cli::AnnotateArgs;
use crate::{ExitStatus, Printer};

pub fn run(args: AnnotateArgs, printer: &Printer) -> Result<ExitStatus> {
    let request = AnnotateRequest {
        dir: args.dir,
        compare: args.compare,
        report: args.report,
        overlay: args.overlay,
        overlay_count: args.overlay_count,
        split: args.split,
        visib_delta_m: args.visib_delta_m,
        fail_fast: args.fail_fast,
    };
    let outcome = annotate(&request, printer)?;
    printer.data(&outcome.stdout)?;
    if outcome.failures.is_empty() {
        return Ok(ExitStatus::Success);
    }
    printer.error(format!("{} frames failed:", outcome.failures.len()));
    for f in &outcome.failures {
        crate::printer::stderr_line(format!("  {f}"));
    }
    Ok(ExitStatus::Failure)
}
