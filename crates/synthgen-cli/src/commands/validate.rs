//! `synthgen validate`: every problem of a dataset, each with its file.

use anyhow::{Context, Result};
use synthgen_core::Progress;
use synthgen_formats::validate::{validate, Checks};

use crate::cli::ValidateArgs;
use crate::{ExitStatus, Printer};
use synthgen_jobs::convert::layout_of;

pub fn run(args: ValidateArgs, printer: &Printer) -> Result<ExitStatus> {
    let layout = layout_of(
        &args.dir,
        args.format.map(super::convert::layout),
        "--format",
    )?;
    let checks = Checks::default();
    let report = validate(&args.dir, layout, &checks, printer);
    printer.finish();
    for w in &report.warnings {
        printer.warning(format!("{}: {}", w.path.display(), w.message));
    }
    if args.json {
        let text = serde_json::to_string_pretty(&report).context("cannot write the report")?;
        printer.data_line(text)?;
    } else {
        let cap = if args.max_problems == 0 {
            usize::MAX
        } else {
            args.max_problems
        };
        for p in report.problems.iter().take(cap) {
            printer.data_line(format!("{}: {}", p.path.display(), p.message))?;
        }
        if report.problems.len() > cap {
            printer.data_line(format!(
                "... and {} more (--max-problems 0 prints all)",
                report.problems.len() - cap
            ))?;
        }
    }
    let what = format!(
        "{layout} dataset {}: {} frames, {} object instances, {} images decoded",
        args.dir.display(),
        report.frames,
        report.instances,
        report.images_checked
    );
    if report.problems.is_empty() {
        printer.info(format!("OK: {what}, no problems"));
        Ok(ExitStatus::Success)
    } else {
        let n = report.problems.len();
        printer.error(format!(
            "{n} problem{} in {what}",
            if n == 1 { "" } else { "s" }
        ));
        Ok(ExitStatus::Failure)
    }
}
