//! `synthgen model align`: a skin over `synthgen_jobs::align` (a scan, or a folder of scans,
//! aligned onto its model and written with an `align.json` report).

use anyhow::Result;
use synthgen_jobs::align::{align_models, AlignRequest};
use synthgen_jobs::Stdout;

use crate::cli::ModelAlignArgs;
use crate::{ExitStatus, Printer};

pub fn run_align(args: ModelAlignArgs, printer: &Printer) -> Result<ExitStatus> {
    let request = AlignRequest {
        scan: args.scan,
        to: args.to,
        scans: args.scans,
        to_dataset: args.to_dataset,
        out: args.out,
        force: args.force,
        rotation_search: args.rotation_search,
        max_median_mm: args.max_median_mm,
        samples: args.samples,
        json: args.json,
    };
    let stdout = Stdout::default();
    let result = align_models(&request, printer, &stdout);
    // The report comes out even when the alignment is refused.
    printer.data(stdout.take())?;
    Ok(if result? {
        ExitStatus::Success
    } else {
        ExitStatus::Failure
    })
}
