//! `synthgen stats`: counts and distributions as a table, JSON or PNG charts; with several
//! datasets, side by side on shared bins.

use anyhow::{Context, Result};
use synthgen_curate::stats::{
    compare_stats, compute_stats, format_comparison, format_stats, write_comparison_plots,
    write_plots,
};
use synthgen_formats::layout::open_source;
use synthgen_formats::source::FrameSource;

use crate::cli::StatsArgs;
use crate::{ExitStatus, Printer};

pub fn run(args: StatsArgs, printer: &Printer) -> Result<ExitStatus> {
    let sources = args
        .dirs
        .iter()
        .map(|d| open_source(d).with_context(|| format!("cannot open dataset {}", d.display())))
        .collect::<Result<Vec<_>>>()?;
    if let [source] = sources.as_slice() {
        let stats = compute_stats(source.as_ref())?;
        if args.json {
            printer.data_line(serde_json::to_string_pretty(&stats)?)?;
        } else {
            printer.data(format_stats(&stats))?;
        }
        if let Some(dir) = &args.plot {
            for p in write_plots(&stats, dir)? {
                printer.info(format!("wrote {}", p.display()));
            }
        }
        return Ok(ExitStatus::Success);
    }
    let refs: Vec<&dyn FrameSource> = sources.iter().map(|s| s.as_ref()).collect();
    let stats = compare_stats(&refs)?;
    if args.json {
        printer.data_line(serde_json::to_string_pretty(&stats)?)?;
    } else {
        printer.data(format_comparison(&stats))?;
    }
    if let Some(dir) = &args.plot {
        for p in write_comparison_plots(&stats, dir)? {
            printer.info(format!("wrote {}", p.display()));
        }
        printer.info("bars: blue = [1], orange = [2], green = [3], purple = [4]");
    }
    Ok(ExitStatus::Success)
}
