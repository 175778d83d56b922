//! `synthgen render --replay REAL_DIR`: a skin over `synthgen_jobs::replay` (the
//! synthetic twin of an annotated dataset).

use anyhow::Result;
use synthgen_jobs::replay::{replay, ReplayRequest};

use crate::cli::RenderArgs;
use crate::commands::render_flags::{check_backend, job_backend, sink_options};
use crate::commands::user_error;
use crate::{ExitStatus, Printer};

pub fn run(args: RenderArgs, printer: &Printer) -> Result<ExitStatus> {
    let Some(real) = args.replay.clone() else {
        anyhow::bail!("internal error: replay without --replay");
    };
    check_args(&args)?;
    let request = ReplayRequest {
        real,
        scenes: args.scenes.clone(),
        sensor: args.sensor.clone(),
        models: args.replay_models.clone(),
        lit: args.replay_lit,
        seed: args.seed,
        visib_delta_m: args.visib_delta_m,
        out: args.out.clone(),
        force: args.force,
        resume: args.resume,
        fail_fast: args.fail_fast,
        jobs: args.jobs,
        backend: job_backend(&args),
        split: args.split.clone(),
        sink: sink_options(&args),
        command_line: std::env::args().collect(),
    };
    let outcome = replay(&request, printer)?;
    Ok(if outcome.failures.is_empty() {
        ExitStatus::Success
    } else {
        ExitStatus::Failure
    })
}

/// What `--replay` refuses beyond clap's conflicts (flags whose message needs a hint).
fn check_args(args: &RenderArgs) -> Result<()> {
    if args.scene.is_some() {
        return Err(user_error(
            "--scene does not apply to --replay: the real frames give the camera, the poses and the objects",
            "choose the depth sensor with --sensor none|d455|tof|structured_light|FILE (a sensor file holds the keys of a scene's [sensor] section)",
        ));
    }
    check_backend(args)
}
