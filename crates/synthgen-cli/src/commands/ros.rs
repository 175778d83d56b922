//! `synthgen ros`: a skin over `synthgen_jobs::ros` (flags → the request → the node until
//! Ctrl-C, --max-frames or --duration; a summary on stdout).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use anyhow::Result;
use synthgen_jobs::predict::PredictorOptions;
use synthgen_jobs::rgb_refine::refine_options;
use synthgen_jobs::ros::{run_node, NodeConfig, RosRequest};

use crate::cli::{DeviceArg, RosArgs};
use crate::{ExitStatus, Printer};

pub fn run(args: RosArgs, printer: &Printer) -> Result<ExitStatus> {
    let camera_info_topic =
        args.camera_info_topic
            .clone()
            .unwrap_or_else(|| match args.image_topic.rsplit_once('/') {
                Some((ns, _)) => format!("{ns}/camera_info"),
                None => "camera_info".to_string(),
            });
    let domain_id = match args.domain_id {
        Some(d) => d,
        None => match std::env::var("ROS_DOMAIN_ID") {
            Ok(v) if !v.trim().is_empty() => match v.trim().parse::<u16>() {
                Ok(d) if d <= 232 => d,
                _ => {
                    return Err(synthgen_jobs::user_error(
                        format!("ROS_DOMAIN_ID={v:?} is not a DDS domain (0 to 232)"),
                        "set it to one, or give --domain-id",
                    ))
                }
            },
            _ => 0,
        },
    };
    let request = RosRequest {
        predictor: PredictorOptions {
            model: args.model,
            detector: args.detector,
            objects_from: None,
            min_score: args.min_score,
            per_object: args.per_object,
            cuda: args.device == DeviceArg::Cuda,
            refine: refine_options(args.refine.refine.name())?,
            refine_models: args.refine.refine_models.clone(),
        },
        node: NodeConfig {
            domain_id,
            namespace: args.namespace,
            name: args.node_name,
            image_topic: args.image_topic,
            depth_topic: args.depth_topic,
            camera_info_topic,
            detections_topic: args.detections_topic,
            detections_2d_topic: args.detections_2d_topic,
        },
        record: args.record.clone(),
        force: args.force,
        max_frames: args.max_frames,
        duration: args.duration,
        status_every: args.status_every,
        jobs: args.jobs,
    };
    let stop = Arc::new(AtomicBool::new(false));
    let flag = stop.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst))?;
    let s = run_node(&request, printer, &stop)?;
    let mut table = format!(
        "{} frames in {:.1} s ({:.2} Hz), {} poses published; latency from arrival to publication median {:.0} ms, p95 {:.0} ms; {} images replaced by a newer one before they were processed\nmemory {:.0} MiB after the first frame, {:.0} MiB at the end\n",
        s.frames,
        s.seconds,
        if s.seconds > 0.0 { s.frames as f64 / s.seconds } else { 0.0 },
        s.poses,
        s.latency_median_s * 1000.0,
        s.latency_p95_s * 1000.0,
        s.replaced,
        s.rss_first_mib,
        s.rss_end_mib,
    );
    if !s.skipped.is_empty() {
        table.push_str("\n| skipped | messages |\n|---|---|\n");
        for (why, n) in &s.skipped {
            table.push_str(&format!("| {why} | {n} |\n"));
        }
    }
    if let Some(r) = &args.record {
        table.push_str(&format!("\nrecorded: {}\n", r.display()));
    }
    printer.data(&table)?;
    Ok(ExitStatus::Success)
}
