//! `synthgen convert`: BOP ⇄ Linemod, YCB-Video → BOP and Linemod, BOP and Linemod → YCB-Video.
//! A skin over `synthgen_jobs::convert`.

use anyhow::Result;
use synthgen_formats::layout::Layout;
use synthgen_jobs::convert::{convert_dataset, ConvertRequest};

use crate::cli::{ConvertArgs, FormatArg};
use crate::{ExitStatus, Printer};

/// The layout a `--format`/`--from`/`--to` flag names.
pub fn layout(f: FormatArg) -> Layout {
    match f {
        FormatArg::Bop => Layout::Bop,
        FormatArg::Linemod => Layout::Linemod,
        FormatArg::Ycbv => Layout::Ycbv,
    }
}

pub fn run(args: ConvertArgs, printer: &Printer) -> Result<ExitStatus> {
    let request = ConvertRequest {
        input: args.input,
        output: args.output,
        from: args.from.map(layout),
        to: layout(args.to),
        depth_scale: args.depth_scale,
        min_visib_fract: args.min_visib_fract,
        classes: args.classes,
        force: args.force,
        command_line: std::env::args().collect(),
    };
    convert_dataset(&request, printer)?;
    Ok(ExitStatus::Success)
}
