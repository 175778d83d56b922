//! `synthgen export coco`: COCO instance annotations from a BOP split.

use anyhow::{Context, Result};
use synthgen_formats::bop::BopDataset;
use synthgen_formats::coco::{export_coco, CocoOptions, RleFormat};
use synthgen_formats::output::OutputLock;

use crate::cli::{CocoArgs, RleArg};
use crate::{ExitStatus, Printer};

pub fn run_coco(args: CocoArgs, printer: &Printer) -> Result<ExitStatus> {
    let ds = BopDataset::open(&args.dir)
        .with_context(|| format!("cannot open dataset {}", args.dir.display()))?;
    let opts = CocoOptions {
        split: args.split.clone(),
        ignore_below_visib_fract: args.ignore_below,
        rle: match args.rle {
            RleArg::Uncompressed => RleFormat::Uncompressed,
            RleArg::Compressed => RleFormat::Compressed,
        },
    };
    // Without --out the files go into the dataset's scene folders.
    let _lock = match args.out {
        None => Some(OutputLock::acquire(&args.dir)?),
        Some(_) => None,
    };
    let s = export_coco(&ds, &opts, args.out.as_deref(), printer)?;
    for f in &s.files {
        printer.info(format!("wrote {}", f.display()));
    }
    printer.info(format!(
        "{} images, {} annotations ({} marked ignore) in {} file(s)",
        s.images,
        s.annotations,
        s.ignored,
        s.files.len()
    ));
    Ok(ExitStatus::Success)
}
