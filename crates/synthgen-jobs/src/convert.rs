//! Conversion between the BOP, Linemod and YCB-Video layouts, as `synthgen convert` runs it
//! and `experiment mix` chains it (a Linemod or YCB-Video real set to BOP): the output
//! folder's guards, the conversion (through a renderer of the dataset's models where masks or
//! `scene_gt_info` must be computed), and the manifest.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use synthgen_core::Progress;
use synthgen_formats::convert::ycbv::{source_to_ycbv, ycbv_to_bop, YcbvConvertOptions};
use synthgen_formats::convert::{bop_to_linemod, linemod_to_bop, ConvertOptions, ConvertSummary};
use synthgen_formats::layout::open_source;
use synthgen_formats::layout::{detect_layout, Layout};
use synthgen_formats::manifest::{write_manifest, Manifest};
use synthgen_formats::output::{check_apart, is_empty, OutputLock};
use synthgen_formats::source::FrameSource;
use synthgen_formats::ycbv::{YcbvSource, YcbvWriterOptions};
use synthgen_render::ObjectRenderer;

use crate::models::{frame_obj_ids, object_renderer};
use crate::{user_error, Log};

/// What to convert: `synthgen convert`'s arguments.
#[derive(Debug, Clone, PartialEq)]
pub struct ConvertRequest {
    pub input: PathBuf,
    pub output: PathBuf,
    /// The layout of `input` (None: detected from its files).
    pub from: Option<Layout>,
    pub to: Layout,
    /// Depth units of the written depth PNGs, mm per step (None: the layout's default).
    pub depth_scale: Option<f64>,
    /// Instances below this visible fraction get no Linemod folder entry.
    pub min_visib_fract: f64,
    /// The YCB-Video class list to write (`classes.txt`).
    pub classes: Option<PathBuf>,
    /// Replace an output synthgen wrote.
    pub force: bool,
    /// The command recorded in the output's manifest.
    pub command_line: Vec<String>,
}

impl ConvertRequest {
    /// `synthgen convert --to TO INPUT OUTPUT` with the defaults.
    pub fn new(input: &Path, output: &Path, to: Layout) -> ConvertRequest {
        ConvertRequest {
            input: input.to_path_buf(),
            output: output.to_path_buf(),
            from: None,
            to,
            depth_scale: None,
            min_visib_fract: 0.1,
            classes: None,
            force: false,
            command_line: vec![
                "synthgen".into(),
                "convert".into(),
                "--to".into(),
                to.name().into(),
                input.display().to_string(),
                output.display().to_string(),
            ],
        }
    }
}

/// The layout of `dir`: `given` (a `--format`/`--from` flag) when given, else detected.
pub fn layout_of(dir: &Path, given: Option<Layout>, flag: &str) -> Result<Layout> {
    if let Some(l) = given {
        return Ok(l);
    }
    if !dir.is_dir() {
        return Err(user_error(
            format!("no such dataset folder: {}", dir.display()),
            "check the path",
        ));
    }
    detect_layout(dir).ok_or_else(|| {
        user_error(
            format!(
                "cannot tell the layout of {}: no camera.json (BOP), no classes.txt beside data/ (YCB-Video) and no data/NN/gt.yml (Linemod)",
                dir.display()
            ),
            format!("pass {flag} bop, {flag} linemod or {flag} ycbv"),
        )
    })
}

/// Converts `req.input` into `req.output` and writes its manifest; a failed conversion leaves
/// nothing behind in a folder that was empty or absent. Messages (the summary, warnings, a
/// hint) go to `progress`.
pub fn convert_dataset(req: &ConvertRequest, progress: &dyn Progress) -> Result<ConvertSummary> {
    let printer = &Log::new(progress);
    let args = req;
    let started = Instant::now();
    let from = layout_of(&args.input, args.from, "--from")?;
    let to = args.to;
    if from == to {
        return Err(user_error(
            format!("{} is already a {from} dataset", args.input.display()),
            "pick the other layout with --to, or copy the folder",
        ));
    }
    if let Some(s) = args.depth_scale {
        if !(s.is_finite() && s > 0.0) {
            return Err(user_error(
                format!("--depth-scale must be positive, got {s}"),
                "1.0 stores millimetres, 0.1 tenths of a millimetre",
            ));
        }
    }
    if !(0.0..=1.0).contains(&args.min_visib_fract) {
        return Err(user_error(
            format!(
                "--min-visib-fract must be in 0..1, got {}",
                args.min_visib_fract
            ),
            "0.1 (the default) keeps objects at least 10% visible",
        ));
    }
    check_apart(&args.output, &[("input", &args.input)])?;
    // Empty or absent, or replaced (--force into what synthgen wrote): a failed conversion
    // then leaves nothing behind.
    if !is_empty(&args.output) {
        if !args.force {
            return Err(user_error(
                format!("output folder is not empty: {}", args.output.display()),
                "choose another OUT, or pass --force to replace it",
            ));
        }
        synthgen_formats::output::check_force(&args.output)?;
    }
    let existed = args.output.exists();
    let lock = OutputLock::acquire(&args.output)?;
    if args.force {
        synthgen_formats::output::replace_output(&args.output, printer)?;
    }
    let opts = ConvertOptions {
        depth_scale: args.depth_scale,
        min_visib_fract: args.min_visib_fract,
    };
    let result = convert(args, from, to, &opts, printer);
    printer.finish();
    let (summary, classes) = match result {
        Ok(r) => r,
        Err(e) => {
            discard_output(&args.output, existed);
            drop(lock);
            return Err(e.context(format!("cannot convert {} to {to}", args.input.display())));
        }
    };

    let mut manifest = Manifest::new(args.command_line.clone(), 0);
    manifest.frames = summary.frames;
    manifest.extra = serde_json::json!({
        "convert": {
            "from": from,
            "to": to,
            "source": args.input,
            "depth_scale": args.depth_scale,
            "min_visib_fract": args.min_visib_fract,
            "ycbv_classes": classes,
        }
    });
    write_manifest(&args.output, &manifest)?;

    if summary.depth_out_of_range_px > 0 {
        printer.warning(format!(
            "{} depth values did not fit 16 bits at the new depth scale and were written as 0",
            summary.depth_out_of_range_px
        ));
    }
    let note = match (to, summary.instances_without_mask) {
        (_, 0) => String::new(),
        (Layout::Linemod, n) => format!(
            " {n} object instance{} below --min-visib-fract got no folder entry (their poses are kept in the other folders' gt.yml).",
            if n == 1 { "" } else { "s" }
        ),
        (Layout::Bop, n) => format!(
            " {n} object instance{} had no {from} mask and got an empty mask_visib.",
            if n == 1 { "" } else { "s" }
        ),
        (Layout::Ycbv, n) => format!(
            " {n} object instance{} had no visible pixel in the label image.",
            if n == 1 { "" } else { "s" }
        ),
    };
    printer.info(format!(
        "Converted {} frames ({} object instances, {} models) from {from} to {to} in {:.1} s: {}.{note}",
        summary.frames,
        summary.instances,
        summary.models,
        started.elapsed().as_secs_f64(),
        args.output.display()
    ));
    printer.hint(format!(
        "check it with `synthgen validate {}`",
        args.output.display()
    ));
    Ok(summary)
}

/// Runs the conversion; returns what it did and, when the source is YCB-Video, its class
/// list (kept in the manifest, so a conversion back restores the names).
fn convert(
    args: &ConvertRequest,
    from: Layout,
    to: Layout,
    opts: &ConvertOptions,
    printer: &Log,
) -> Result<(ConvertSummary, Option<Vec<String>>)> {
    let (src, dst) = (&args.input, &args.output);
    Ok(match (from, to) {
        (Layout::Bop, Layout::Linemod) => (bop_to_linemod(src, dst, opts, printer)?, None),
        (Layout::Linemod, Layout::Bop) => (linemod_to_bop(src, dst, opts, printer)?, None),
        (Layout::Ycbv, Layout::Bop) => {
            let (renderer, classes) = ycbv_renderer(src, printer)?;
            let s = ycbv_to_bop(src, dst, renderer.as_ref().map(|r| r as _), printer)?;
            (s, Some(classes))
        }
        (Layout::Ycbv, Layout::Linemod) => {
            // Through BOP, which carries the visible fractions Linemod's folders need.
            let tmp = PathBuf::from(format!("{}.synthgen-tmp-bop", dst.display()));
            if tmp.exists() {
                std::fs::remove_dir_all(&tmp)
                    .with_context(|| format!("cannot remove {}", tmp.display()))?;
            }
            let (renderer, classes) = ycbv_renderer(src, printer)?;
            let r = ycbv_to_bop(src, &tmp, renderer.as_ref().map(|r| r as _), printer)
                .map_err(anyhow::Error::from)
                .and_then(|_| Ok(bop_to_linemod(&tmp, dst, opts, printer)?));
            let _ = std::fs::remove_dir_all(&tmp);
            (r?, Some(classes))
        }
        (Layout::Bop | Layout::Linemod, Layout::Ycbv) => {
            // The class list first: a bad one is refused before any model is loaded.
            let classes = match &args.classes {
                Some(path) => Some(read_classes(path)?),
                None => manifest_classes(src),
            };
            let source = open_source(src)?;
            let frames = source.frames(&[])?;
            let renderer = object_renderer(source.as_ref(), &frame_obj_ids(&frames), printer)?;
            let factor_depth = 1000.0 / args.depth_scale.unwrap_or(0.1);
            let yopts = YcbvConvertOptions {
                classes,
                writer: YcbvWriterOptions {
                    factor_depth,
                    ..YcbvWriterOptions::default()
                },
            };
            let s = source_to_ycbv(source.as_ref(), dst, &yopts, &renderer, printer)?;
            (s, None)
        }
        (a, b) => anyhow::bail!("internal: no conversion from {a} to {b}"),
    })
}

/// The renderer of a YCB-Video dataset's used classes (for BOP's mask/ and scene_gt_info),
/// `None` with a warning when a model is missing; and the class list.
fn ycbv_renderer(src: &Path, printer: &Log) -> Result<(Option<ObjectRenderer>, Vec<String>)> {
    let source = YcbvSource::open(src)?;
    let frames = source.frames(&[])?;
    let ids = frame_obj_ids(&frames);
    let missing: Vec<PathBuf> = ids
        .iter()
        .map(|&id| source.model_file(id))
        .filter(|p| !p.is_file())
        .collect();
    let classes = source.dataset.classes.clone();
    if let Some(first) = missing.first() {
        printer.warning(format!(
            "{} model file(s) missing (first: {}): mask/ and scene_gt_info.json are not written",
            missing.len(),
            first.display()
        ));
        printer.hint("add the models, or compute them later with `synthgen annotate OUT`");
        return Ok((None, classes));
    }
    Ok((Some(object_renderer(&source, &ids, printer)?), classes))
}

/// `classes.txt`: one class name per line.
fn read_classes(path: &Path) -> Result<Vec<String>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read the class list {}", path.display()))?;
    let mut classes: Vec<String> = text.lines().map(|l| l.trim().to_string()).collect();
    while classes.last().is_some_and(String::is_empty) {
        classes.pop();
    }
    synthgen_formats::ycbv::check_class_names(&classes).map_err(|m| {
        user_error(
            format!("{m}: {}", path.display()),
            "give each object a class name of its own",
        )
    })?;
    Ok(classes)
}

/// The YCB-Video class list a conversion from YCB-Video recorded in the manifest.
fn manifest_classes(src: &Path) -> Option<Vec<String>> {
    let m = synthgen_formats::read_manifest(src).ok()?;
    let list = m.extra.get("convert")?.get("ycbv_classes")?.as_array()?;
    list.iter()
        .map(|v| v.as_str().map(str::to_string))
        .collect()
}

/// Removes what a failed conversion wrote into a folder that was empty or absent (leaving an
/// empty folder where there was one).
fn discard_output(out: &Path, existed: bool) {
    let _ = std::fs::remove_dir_all(out);
    if existed {
        let _ = std::fs::create_dir_all(out);
    }
}
