//! `synthgen stats`: counts and distributions as a table, JSON or PNG charts.

use anyhow::{Context, Result};
use synthgen_dataset::source::open_source;
use synthgen_dataset::stats::{compute_stats, format_stats, write_plots};

use crate::cli::StatsArgs;
use crate::{ExitStatus, Printer};

pub fn run(args: StatsArgs, printer: &Printer) -> Result<ExitStatus> {
    let source = open_source(&args.dir)
        .with_context(|| format!("cannot open dataset {}", args.dir.display()))?;
    let stats = compute_stats(source.as_ref())?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&stats)?);
    } else {
        print!("{}", format_stats(&stats));
    }
    if let Some(dir) = &args.plot {
        for p in write_plots(&stats, dir)? {
            printer.info(format!("wrote {}", p.display()));
        }
    }
    Ok(ExitStatus::Success)
}
