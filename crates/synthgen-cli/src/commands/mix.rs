//! `synthgen mix`: resolve the two sources (flags, env, synthgen.toml) and the counts, then
//! draw and write the mix.

use std::path::PathBuf;

use anyhow::{Context, Result};
use synthgen_core::PoseRenderer;
use synthgen_curate::mix::{write_mix, Completion, MixCounts, MixOptions, PROVENANCE_FILE};
use synthgen_formats::layout::open_source;
use synthgen_formats::output::{check_apart, OutputLock};
use synthgen_formats::source::FrameSource;
use synthgen_render::ObjectRenderer;

use crate::cli::{MixArgs, PathOrCount};
use crate::commands::user_error;
use crate::config::{self, Config, CONFIG_FILE};
use crate::{ExitStatus, Printer};
use synthgen_jobs::models::{frame_obj_ids, object_renderer};

pub const ENV_REAL: &str = "SYNTHGEN_REAL";
pub const ENV_SYNTH: &str = "SYNTHGEN_SYNTH";

pub fn run(args: MixArgs, printer: &Printer) -> Result<ExitStatus> {
    let needs_config = matches!(args.real, PathOrCount::Count(_))
        || matches!(args.synth, PathOrCount::Count(_))
        || args.out.is_none();
    let (config, config_path) = if needs_config {
        config::load()?
    } else {
        (Config::default(), None)
    };
    if let Some(p) = &config_path {
        printer.info(format!("using {}", p.display()));
    }
    let real = source_path("real", &args.real, ENV_REAL, config.mix.real.as_ref())?;
    let synth = source_path("synth", &args.synth, ENV_SYNTH, config.mix.synth.as_ref())?;
    let counts = counts(&args)?;
    let out = args
        .out
        .clone()
        .or(config.mix.out.clone())
        .unwrap_or_else(|| PathBuf::from("data/mix"));

    check_apart(
        &out,
        &[("real dataset", &real), ("synthetic dataset", &synth)],
    )?;
    let _lock = OutputLock::acquire(&out)?;
    let real_ds = open_source(&real).context("cannot open the real dataset")?;
    let synth_ds = open_source(&synth).context("cannot open the synthetic dataset")?;
    let opts = MixOptions {
        counts,
        seed: args.seed,
        command_line: std::env::args().collect(),
        force: args.force,
        exclude_shared: args.exclude_shared,
        test_scenes: args.test_scenes.clone(),
    };
    // Frames without mask/ and scene_gt_info (YCB-Video, Linemod) get them computed from
    // their poses and models, so the mix is a complete BOP dataset.
    let real_r = completion_renderer(real_ds.as_ref(), printer)?;
    let synth_r = completion_renderer(synth_ds.as_ref(), printer)?;
    let completion = Completion {
        real: real_r.as_ref().map(|r| r as &dyn PoseRenderer),
        synth: synth_r.as_ref().map(|r| r as &dyn PoseRenderer),
    };
    let report = write_mix(
        real_ds.as_ref(),
        synth_ds.as_ref(),
        &out,
        &opts,
        completion,
        printer,
    )
    .map_err(|e| match e {
        synthgen_formats::Error::InvalidRequest(m) if m.contains("--force") => user_error(
            m,
            "choose another --out, or add --force to replace the mix there",
        ),
        synthgen_formats::Error::NotEnoughFrames { .. } => {
            let msg = e.to_string();
            user_error(
                msg,
                "lower the counts (or --test-count, or hold out fewer --test-scenes), or render more frames",
            )
        }
        synthgen_formats::Error::UnknownScenes { .. } => {
            let msg = e.to_string();
            user_error(msg, "pass --test-scenes with ids from that list")
        }
        e => anyhow::Error::new(e),
    })?;
    for w in &report.warnings {
        printer.warning(w);
    }
    let held_out = if args.test_scenes.is_empty() {
        String::new()
    } else {
        format!(
            " (every frame of scene(s) {})",
            synthgen_curate::mix::scene_list(&args.test_scenes)
        )
    };
    printer.info(format!(
        "mixed {} real + {} synthetic training frames and {} real test frames{held_out} into {}",
        report.train_real,
        report.train_synth,
        report.test,
        out.display()
    ));
    printer.info(format!(
        "{} files hard-linked, {} copied; per-frame sources in {}",
        report.linked,
        report.copied,
        out.join(PROVENANCE_FILE).display()
    ));
    printer.hint(format!("look at it: synthgen preview {}", out.display()));
    Ok(ExitStatus::Success)
}

/// The dataset folder for `--real`/`--synth`: the flag's path, else the env var, else the
/// config; canonical, so provenance records absolute paths.
fn source_path(
    flag: &str,
    value: &PathOrCount,
    env: &str,
    from_config: Option<&PathBuf>,
) -> Result<PathBuf> {
    let path = match value {
        PathOrCount::Path(p) => p.clone(),
        PathOrCount::Count(_) => match std::env::var_os(env).filter(|v| !v.is_empty()) {
            Some(v) => PathBuf::from(v),
            None => from_config.cloned().ok_or_else(|| {
                user_error(
                    format!("--{flag} is a count, but no {flag} dataset folder is configured"),
                    format!(
                        "pass the folder (--{flag} DIR --{flag}-count N), set {env}=DIR, or add \
                         `[mix]` with `{flag} = \"DIR\"` to a {CONFIG_FILE} in this folder or a parent"
                    ),
                )
            })?,
        },
    };
    path.canonicalize().map_err(|_| {
        user_error(
            format!("{flag} dataset folder not found: {}", path.display()),
            "check the path (relative paths in synthgen.toml are relative to the file)",
        )
    })
}

fn counts(args: &MixArgs) -> Result<MixCounts> {
    if let (Some(ratio), Some(total)) = (args.ratio, args.total) {
        if matches!(args.real, PathOrCount::Count(_)) || matches!(args.synth, PathOrCount::Count(_))
        {
            return Err(user_error(
                "--ratio/--total and counts in --real/--synth do not go together",
                "give either counts or --ratio with --total",
            ));
        }
        return Ok(MixCounts::from_ratio(ratio, total, args.test_count)?);
    }
    let pick = |flag: &str, value: &PathOrCount, count: Option<usize>| match (value, count) {
        (PathOrCount::Count(n), None) => Ok(*n),
        (PathOrCount::Path(_), Some(n)) => Ok(n),
        (PathOrCount::Count(_), Some(_)) => Err(user_error(
            format!("--{flag} is already a count; --{flag}-count is for --{flag} DIR"),
            format!("drop --{flag}-count"),
        )),
        (PathOrCount::Path(_), None) => Err(user_error(
            format!("how many {flag} frames? --{flag}-count is missing"),
            format!("add --{flag}-count N, or use --ratio R --total N"),
        )),
    };
    Ok(MixCounts {
        real: pick("real", &args.real, args.real_count)?,
        synth: pick("synth", &args.synth, args.synth_count)?,
        test: args.test_count,
    })
}

/// A renderer of the dataset's objects when some of its frames lack scene_gt_info (a
/// YCB-Video or Linemod set), else `None`.
fn completion_renderer(
    source: &dyn FrameSource,
    printer: &Printer,
) -> Result<Option<ObjectRenderer>> {
    let frames = source.frames(&[])?;
    if frames.iter().all(|f| f.gt_info.is_some()) {
        return Ok(None);
    }
    printer.info(format!(
        "{}: computing mask/ and scene_gt_info from the poses and models (as `synthgen annotate`)",
        source.root().display()
    ));
    Ok(Some(object_renderer(
        source,
        &frame_obj_ids(&frames),
        printer,
    )?))
}
