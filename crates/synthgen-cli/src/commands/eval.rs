//! `synthgen eval`: score a BOP results CSV, or a trained checkpoint, against a dataset. A skin
//! over `synthgen_jobs::eval`: flags → `EvalRequest`, the tables on stdout, exit
//! 1 when some results rows could not be read.

use anyhow::Result;
use synthgen_jobs::eval::{evaluate_request, EvalRequest};

use crate::cli::{DeviceArg, EvalArgs, RgbRefineArg, VisibleBoxArg};
use crate::{ExitStatus, Printer};
use synthgen_fit::edge_refine::EdgeRefineOptions;

pub fn run(args: EvalArgs, printer: &Printer) -> Result<ExitStatus> {
    // Flags that only --refine views reads, and what each sets there.
    let views_only = [
        (
            args.view_candidates.is_some(),
            "--view-candidates",
            "sets how many view-search poses --refine views refines",
        ),
        (
            args.region_weight.is_some(),
            "--region-weight",
            "sets how much the colour regions weigh in --refine views",
        ),
        (
            args.photometric_weight.is_some(),
            "--photometric-weight",
            "sets how much the model's colours weigh in --refine views",
        ),
        (
            args.restart_deg.is_some(),
            "--restart-deg",
            "sets how far --refine views turns its winning end to refine again",
        ),
        (
            args.refine_models.is_some(),
            "--refine-models",
            "gives the colours that --refine views compares with the image",
        ),
    ];
    if args.refine != RgbRefineArg::Views {
        if let Some((_, flag, what)) = views_only.iter().find(|(given, _, _)| *given) {
            return Err(synthgen_jobs::user_error(
                format!("{flag} {what}"),
                format!("add --refine views, or drop {flag}"),
            ));
        }
    }
    if args.box_gap_weight.is_some() && args.visible_box == VisibleBoxArg::None {
        return Err(synthgen_jobs::user_error(
            "--box-gap-weight sets what a gap between the visible box and the outline costs, and no box is given",
            "add --visible-box gt, or drop --box-gap-weight",
        ));
    }
    if args.refine == RgbRefineArg::None && args.visible_box != VisibleBoxArg::None {
        return Err(synthgen_jobs::user_error(
            "--visible-box is what the refinement keeps to, and nothing is refined",
            "add --refine views (or edges), or drop --visible-box",
        ));
    }
    if args.visible_box == VisibleBoxArg::Detected && args.detections.is_none() {
        return Err(synthgen_jobs::user_error(
            "--visible-box detected reads the boxes of --detections, and none is given",
            "add --detections FILE (written by `synthgen detector run`), or use --visible-box gt",
        ));
    }
    if args.detections.is_some()
        && args.checkpoint.is_none()
        && args.visible_box != VisibleBoxArg::Detected
    {
        return Err(synthgen_jobs::user_error(
            "--detections gives a checkpoint its crops or the refinement its boxes, and neither reads them here",
            "add --checkpoint FILE, or --refine views --visible-box detected",
        ));
    }
    let mut refine = match args.refine {
        RgbRefineArg::None => None,
        RgbRefineArg::Edges => Some(EdgeRefineOptions::default()),
        RgbRefineArg::Views => {
            let mut opts = EdgeRefineOptions::with_view_search();
            if let (Some(v), Some(n)) = (opts.view_search.as_mut(), args.view_candidates) {
                v.candidates = n as usize;
            }
            if let Some(w) = args.region_weight {
                opts.region_weight_px = w;
            }
            if let Some(w) = args.photometric_weight {
                opts = opts.with_photometric_weight(w);
            }
            if let Some(d) = args.restart_deg {
                opts.restart_deg = d;
            }
            Some(opts)
        }
    };
    if let (Some(o), Some(w)) = (refine.as_mut(), args.box_gap_weight) {
        o.box_gap_weight = w;
    }
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
        refine,
        refine_models: args.refine_models,
        visible_boxes: args.visible_box.into(),
        detections: args.detections,
        detector: args.detector,
    };
    if request.save_results.is_some() && request.checkpoint.is_none() && request.refine.is_none() {
        return Err(synthgen_jobs::user_error(
            "--save-results writes a checkpoint's estimates, or the refined ones of --results",
            "add --checkpoint FILE, or --refine edges to write the refined estimates",
        ));
    }
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
