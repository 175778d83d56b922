//! `synthgen predict`: a skin over `synthgen_jobs::predict` (flags → the request → the run;
//! the objects found and the time per stage on stdout).

use anyhow::Result;
use synthgen_jobs::predict::{predict, PredictInput, PredictRequest};
use synthgen_jobs::rgb_refine::refine_options;

use crate::cli::{DeviceArg, PredictArgs};
use crate::{ExitStatus, Printer};

pub fn run(args: PredictArgs, printer: &Printer) -> Result<ExitStatus> {
    let input = match (args.images, args.camera, args.data, args.bag) {
        (Some(dir), Some(camera), None, None) => PredictInput::Images {
            dir,
            camera,
            depth: args.depth,
        },
        (None, None, Some(dir), None) => PredictInput::Data {
            dir,
            split: args.split,
        },
        (None, None, None, Some(path)) => {
            let image_topic = args.image_topic.unwrap_or_default();
            let camera_info_topic =
                args.camera_info_topic
                    .unwrap_or_else(|| match image_topic.rsplit_once('/') {
                        Some((ns, _)) => format!("{ns}/camera_info"),
                        None => "camera_info".to_string(),
                    });
            PredictInput::Bag {
                path,
                image_topic,
                depth_topic: args.depth_topic,
                camera_info_topic,
            }
        }
        // clap's groups leave no other combination.
        _ => anyhow::bail!("give --images DIR --camera FILE, --data DATASET or --bag FILE"),
    };
    let request = PredictRequest {
        model: args.model,
        detector: args.detector,
        input,
        out: args.out.clone(),
        min_score: args.min_score,
        per_object: args.per_object,
        draw: args.draw,
        jobs: args.jobs,
        cuda: args.device == DeviceArg::Cuda,
        refine: refine_options(args.refine.refine.name())?,
        refine_models: args.refine.refine_models,
        force: args.force,
    };
    let s = predict(&request, printer)?;
    let mut table = String::from("| object | found |\n|---|---|\n");
    for (obj, n) in &s.found {
        table.push_str(&format!("| {obj} | {n} |\n"));
    }
    let per = |v: f64| {
        if s.frames == 0 {
            0.0
        } else {
            1000.0 * v / s.frames as f64
        }
    };
    table.push_str(&format!(
        "\n{} frames, {} with objects; {} whole poses in {}; {} detections without a pose (fewer valid depth pixels in the mask than the model's minimum)\n\n| stage | mean ms/frame |\n|---|---|\n| read | {:.1} |\n| detect | {:.1} |\n| instances | {:.1} |\n| pose | {:.1} |\n| refine | {:.1} |\n| total | {:.1} (median {:.1}, p95 {:.1}) |\n",
        s.frames,
        s.frames_with_objects,
        s.results,
        args.out.join(synthgen_jobs::predict::RESULTS_FILE).display(),
        s.without_pose,
        per(s.time.read),
        per(s.time.detect),
        per(s.time.instances),
        per(s.time.pose),
        per(s.time.refine),
        per(s.time.total),
        1000.0 * s.median_frame_s,
        1000.0 * s.p95_frame_s,
    ));
    printer.data(&table)?;
    Ok(ExitStatus::Success)
}
