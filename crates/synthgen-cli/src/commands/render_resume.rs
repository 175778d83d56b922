//! Shards and resume for `synthgen render`: which frames this process renders and the
//! command line recorded in the manifest. The run plan that lets `--resume` check it
//! continues the same run is the pipeline's (`synthgen_pipeline::RUN_PLAN`).

use std::ops::Range;

use anyhow::Result;

use crate::cli::{FormatArg, RenderArgs};
use crate::commands::user_error;

/// `--shard` and `--resume` need the BOP writer's global numbering and journals.
pub fn check_supported(args: &RenderArgs) -> Result<()> {
    if args.format != FormatArg::Bop && (args.shard.is_some() || args.resume) {
        return Err(user_error(
            "--shard and --resume work with --format bop only",
            "render BOP and convert the merged dataset with `synthgen convert --to linemod`",
        ));
    }
    Ok(())
}

/// The frames this process renders: all of `--first-frame .. +--frames`, or its shard.
pub fn frame_range(args: &RenderArgs) -> Result<Range<u64>> {
    if args.first_frame.checked_add(args.frames).is_none() {
        return Err(user_error(
            "--first-frame + --frames is beyond the last frame index (2^64 - 1)",
            "use smaller frame numbers",
        ));
    }
    Ok(match args.shard {
        Some(s) => s.range(args.first_frame, args.frames),
        None => args.first_frame..args.first_frame + args.frames,
    })
}

/// The command line for the manifest: `--resume` does not change what is written, so it is
/// left out and a resumed dataset is byte-identical to an uninterrupted one.
pub fn command_line() -> Vec<String> {
    std::env::args().filter(|a| a != "--resume").collect()
}
