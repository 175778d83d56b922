//! `synthgen merge`: a skin over `synthgen_jobs::merge` (the shard folders of one `synthgen
//! render --shard I/N` run → one BOP dataset).

use anyhow::Result;
use synthgen_jobs::merge::{merge_shards, MergeRequest};

use crate::cli::MergeArgs;
use crate::{ExitStatus, Printer};

pub fn run(args: MergeArgs, printer: &Printer) -> Result<ExitStatus> {
    let request = MergeRequest {
        dirs: args.dirs,
        out: args.out,
        copy: args.copy,
        force: args.force,
        command_line: std::env::args().collect(),
    };
    merge_shards(&request, printer)?;
    Ok(ExitStatus::Success)
}
