//! `synthgen render`: sample scenes, render them, write a BOP, Linemod or YCB-Video dataset.
//! A skin over `synthgen_jobs::render`: flags → `RenderRequest` → the render (its
//! warnings, summary and hints on the printer) → the exit status.

use anyhow::Result;
use synthgen_assets::Units;
use synthgen_core::scene::{BackgroundKind, Orientation};
use synthgen_jobs::render::{render, RenderRequest, SpecOverrides};

use crate::cli::{BackgroundArg, OrientationArg, RenderArgs, UnitsArg};
use crate::commands::render_flags::{check_backend, job_backend, sink_options};
use crate::commands::replay;
use crate::commands::user_error;
use crate::{ExitStatus, Printer};

pub fn run(args: RenderArgs, printer: &Printer) -> Result<ExitStatus> {
    if args.replay.is_some() {
        return replay::run(args, printer);
    }
    if args.replay_models.is_some() || args.replay_lit {
        // clap's `requires` lets them through beside a flag that conflicts with --replay.
        return Err(user_error(
            "--replay-models and --replay-lit apply only to --replay (a replay of real frames)",
            "add --replay REAL_DIR, or drop them",
        ));
    }
    if !args.scenes.is_empty() {
        // clap's `requires` lets it through beside a flag that conflicts with --replay.
        return Err(user_error(
            "--scenes applies only to --replay (the scene ids of the real frames to re-render)",
            "add --replay REAL_DIR, or drop --scenes",
        ));
    }
    check_backend(&args)?;
    let outcome = render(&request(&args)?, printer)?;
    Ok(if outcome.too_many_failed {
        ExitStatus::Failure
    } else {
        ExitStatus::Success
    })
}

/// The render the flags ask for.
fn request(args: &RenderArgs) -> Result<RenderRequest> {
    let image_size = match &args.image_size {
        Some(s) => match s.as_slice() {
            &[w, h] => Some([w, h]),
            _ => {
                return Err(user_error(
                    format!("--image-size needs 2 numbers, got {}", s.len()),
                    "write it as --image-size 640,480",
                ))
            }
        },
        None => None,
    };
    let camera_k =
        match &args.camera_k {
            Some(k) => match k.as_slice() {
                &[fx, fy, cx, cy] => Some([fx, fy, cx, cy]),
                _ => return Err(user_error(
                    format!("--camera-k needs 4 numbers, got {}", k.len()),
                    "write it as --camera-k 572.41,573.57,325.26,242.05 (fx,fy,cx,cy in pixels)",
                )),
            },
            None => None,
        };
    Ok(RenderRequest {
        scene: args.scene.clone(),
        overrides: SpecOverrides {
            camera: args.camera.clone(),
            image_size,
            camera_k,
            distance_m: args.distance_m,
            elevation_deg: args.elevation_deg,
            orientation: args.orientation.map(|o| match o {
                OrientationArg::Upright => Orientation::Upright,
                OrientationArg::Random => Orientation::Random,
            }),
            background: args.background.map(|b| match b {
                BackgroundArg::Color => BackgroundKind::Color,
                BackgroundArg::Noise => BackgroundKind::Noise,
                BackgroundArg::Images => BackgroundKind::Images,
            }),
            background_dir: args.background_dir.clone(),
            sensor: args.sensor.clone(),
        },
        objects: args.objects.clone(),
        obj_ids: args.obj_ids.clone(),
        units: units_of(args.units),
        first_frame: args.first_frame,
        frames: args.frames,
        shard: args.shard.map(|s| [s.index, s.count]),
        seed: args.seed,
        jobs: args.jobs,
        backend: job_backend(args),
        visib_delta_m: args.visib_delta_m,
        out: args.out.clone(),
        force: args.force,
        resume: args.resume,
        fail_fast: args.fail_fast,
        sink: sink_options(args),
        max_failed_fraction: args.max_failed_fraction,
        command_line: std::env::args().collect(),
    })
}

fn units_of(arg: UnitsArg) -> Units {
    match arg {
        UnitsArg::Auto => Units::Auto,
        UnitsArg::Mm => Units::Mm,
        UnitsArg::M => Units::M,
    }
}
