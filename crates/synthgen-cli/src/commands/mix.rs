//! `synthgen mix`: resolve the two sources (flags, env, synthgen.toml) and the counts, then
//! `synthgen_jobs::mix` draws and writes the mix.

use std::path::PathBuf;

use anyhow::Result;
use synthgen_curate::mix::{MixCounts, MixOptions};
use synthgen_jobs::mix::mix_datasets;

use crate::cli::{MixArgs, PathOrCount};
use crate::commands::user_error;
use crate::config::{self, Config, CONFIG_FILE};
use crate::{ExitStatus, Printer};

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

    let opts = MixOptions {
        counts,
        seed: args.seed,
        command_line: std::env::args().collect(),
        force: args.force,
        exclude_shared: args.exclude_shared,
        test_scenes: args.test_scenes.clone(),
    };
    mix_datasets(&real, &synth, &out, &opts, printer)?;
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
