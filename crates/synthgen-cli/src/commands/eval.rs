//! `synthgen eval`: score a BOP results CSV, or a trained checkpoint, against a dataset. A skin
//! over `synthgen_jobs::eval`: flags → `EvalRequest`, the tables on stdout, exit
//! 1 when some results rows could not be read.

use anyhow::Result;
use synthgen_jobs::eval::{evaluate_request, EvalRequest};

use crate::cli::{DeviceArg, EvalArgs};
use crate::{ExitStatus, Printer};

pub fn run(args: EvalArgs, printer: &Printer) -> Result<ExitStatus> {
    let request = EvalRequest {
        data: args.data,
        results: args.results,
        checkpoint: args.checkpoint,
        split: args.split,
        min_visib_fract: args.min_visib_fract,
        json: args.json,
        seed: args.seed,
        save_results: args.save_results,
        bop: args.bop,
        targets: args.targets,
        bop_errors: args.bop_errors,
        visib_gt_min: args.visib_gt_min,
        stability: args.stability,
        rotations: args.rotations.into(),
        cuda: args.device == DeviceArg::Cuda,
    };
    let outcome = evaluate_request(&request, printer)?;
    printer.data(&outcome.stdout)?;
    Ok(match outcome.failed {
        Some(why) => {
            printer.error(why);
            ExitStatus::Failure
        }
        None => ExitStatus::Success,
    })
}
