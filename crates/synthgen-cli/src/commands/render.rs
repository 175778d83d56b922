//! `synthgen render`: sample scenes, render them, write a BOP, Linemod or YCB-Video dataset.
//! A skin over `synthgen_pipeline`: flags → scene spec and objects → `RenderJob` → `write`,
//! then the summary, warnings and hints.

use std::path::Path;
use std::time::Instant;

use anyhow::{Context, Result};
use synthgen_assets::Units;
use synthgen_core::scene::{BackgroundKind, Orientation};
use synthgen_core::SceneSpec;
use synthgen_formats::output::OutputLock;
use synthgen_pipeline::{error_chain, Backend as JobBackend, BlenderSettings};
use synthgen_pipeline::{ObjectSource, RenderJob, WriteOptions, WriteReport};

use crate::cli::{Backend, BackgroundArg, FormatArg, OrientationArg, RenderArgs, UnitsArg};
use crate::commands::render_sink::sink_options;
use crate::commands::user_error;
use crate::commands::{render_extras, render_resume, replay};
use crate::{ExitStatus, Printer};

pub fn run(args: RenderArgs, printer: &Printer) -> Result<ExitStatus> {
    if args.replay.is_some() {
        return replay::run(args, printer);
    }
    if args.replay_models.is_some() || args.replay_lit {
        // clap's `requires` lets them through beside a flag that conflicts with --replay.
        return Err(user_error(
            "--replay-models and --replay-lit apply only to --replay (a replay of real frames)",
            "add --replay REAL_DIR, or drop them",
        ));
    }
    if !args.scenes.is_empty() {
        // clap's `requires` lets it through beside a flag that conflicts with --replay.
        return Err(user_error(
            "--scenes applies only to --replay (the scene ids of the real frames to re-render)",
            "add --replay REAL_DIR, or drop --scenes",
        ));
    }
    let started = Instant::now();
    check_backend(&args)?;
    render_resume::check_supported(&args)?;
    let frame_range = render_resume::frame_range(&args)?;
    let asked = frame_range.end - frame_range.start;
    let spec = build_spec(&args)?;
    for w in spec.sensor.unused_sections() {
        printer.warning(w);
    }
    if spec.ground.visible && spec.camera_pose.elevation_deg[0] < 0.0 {
        printer.warning(format!(
            "camera_pose.elevation_deg starts at {}°, below the table: some cameras look at the objects from under the ground plane (a scene fitted to depth at the wrong scale looks like this)",
            spec.camera_pose.elevation_deg[0]
        ));
    }
    let sources = collect_sources(&args, &spec)?;
    if !args.resume {
        check_out_dir(&args.out, args.force)?;
    }
    // The folders this run creates: removed again (when empty) if the job cannot start.
    let created = first_missing_ancestor(&args.out);
    // One writer per output folder; a crashed run's lock goes with its process.
    let lock = OutputLock::acquire(&args.out)?;
    if args.force && !args.resume {
        synthgen_formats::output::replace_output(&args.out, printer)?;
    }

    let built = RenderJob::new(spec)
        .objects(&sources)
        .units(units_of(args.units))
        .frames(frame_range)
        .seed(args.seed)
        .threads(args.jobs.unwrap_or(0))
        .backend(job_backend(&args))
        .visib_delta_m(args.visib_delta_m)
        .build(printer);
    let job = match built {
        Ok(job) => job,
        Err(e) => {
            // A broken mesh must not leave an empty output folder behind: a folder this run
            // created and that holds only its lock file goes (the lock file while still held).
            if let Some(top) = created {
                let only_lock = std::fs::read_dir(&args.out).is_ok_and(|entries| {
                    entries.flatten().all(|e| {
                        e.file_name() == std::ffi::OsStr::new(synthgen_formats::output::LOCK_FILE)
                    })
                });
                if only_lock {
                    let _ =
                        std::fs::remove_file(args.out.join(synthgen_formats::output::LOCK_FILE));
                }
                drop(lock);
                remove_empty_dirs(&args.out, &top);
            }
            return Err(e.into());
        }
    };
    let _lock = lock;
    let options = WriteOptions {
        out: args.out.clone(),
        sink: sink_options(&args),
        resume: args.resume,
        fail_fast: args.fail_fast,
        command_line: render_resume::command_line(),
        first_frame: Some(args.first_frame),
        shard: args.shard.map(|s| [s.index, s.count]),
    };
    let report = job.write(&options, printer)?;
    let WriteReport {
        written,
        rendered,
        failures,
        nothing_visible,
        physics_fallbacks: fallbacks,
        resampled,
        depth_out_of_range_px,
        description,
        ..
    } = report;
    if let Some((first, why)) = fallbacks.first() {
        printer.warning(format!(
            "{} frame{} did not settle and kept the non-physics placement (first: frame {first}: {why})",
            fallbacks.len(),
            if fallbacks.len() == 1 { "" } else { "s" },
        ));
        printer.hint("raise placement.physics.max_steps in the scene spec");
    }
    if let Some(first) = resampled.first() {
        let fewer = resampled.iter().filter(|r| !r.dropped.is_empty()).count();
        printer.warning(format!(
            "{} frame{} did not fit on the first draw and {} drawn again ({fewer} with fewer objects; first: frame {}{}); synthgen.json lists them",
            resampled.len(),
            if resampled.len() == 1 { "" } else { "s" },
            if resampled.len() == 1 { "was" } else { "were" },
            first.frame,
            if first.dropped.is_empty() {
                String::new()
            } else {
                format!(
                    ", without {}",
                    synthgen_core::sample::name_summary(first.dropped.iter().map(String::as_str))
                )
            }
        ));
        printer.hint("widen [placement] area_m or lower objects_per_frame in the scene spec");
    }
    if depth_out_of_range_px > 0 {
        printer.warning(format!(
            "{} depth pixels were beyond what a 16-bit PNG holds at depth_scale {} and were written as 0 (invalid)",
            depth_out_of_range_px,
            options.sink.depth_scale()
        ));
        printer.hint("pass --depth-scale 1.0 for 1 mm steps up to 65 m");
    }

    let elapsed = started.elapsed().as_secs_f64();
    let failures: Vec<(u64, String)> = failures.iter().map(|(i, e)| (*i, error_chain(e))).collect();
    summarize(
        printer,
        &args,
        &job.object_names(),
        job.objects_per_frame(),
        written,
        &failures,
        elapsed,
        &description,
    );
    if !nothing_visible.is_empty() {
        let n = nothing_visible.len();
        printer.warning(format!(
            "{n} of the {rendered} frames rendered show no target at all (every visib_fract 0; first: frame {})",
            nothing_visible[0]
        ));
        if 2 * n > rendered as usize {
            return Err(user_error(
                format!(
                    "most frames show no object ({n} of {rendered}): the dataset in {} is not usable",
                    args.out.display()
                ),
                "check the units (--units mm|m: a model 1000x too large or too small), the camera \
                 distance (--distance-m) against the objects' size, and that the meshes have faces",
            ));
        }
    }
    Ok(failed_status(
        &failures,
        asked,
        args.max_failed_fraction,
        printer,
    ))
}

/// Exit 1 when more than `max_fraction` of the `asked` frames failed; a handful below it is
/// reported (and listed in synthgen.json) but does not fail the run.
fn failed_status(
    failures: &[(u64, String)],
    asked: u64,
    max_fraction: f64,
    printer: &Printer,
) -> ExitStatus {
    if failures.is_empty() {
        return ExitStatus::Success;
    }
    let share = failures.len() as f64 / asked.max(1) as f64;
    if share > max_fraction {
        ExitStatus::Failure
    } else {
        printer.warning(format!(
            "{} of {} frames failed ({:.2} %, within --max-failed-fraction {}); the others are written",
            failures.len(),
            asked,
            share * 100.0,
            max_fraction
        ));
        ExitStatus::Success
    }
}

pub(crate) fn job_backend(args: &RenderArgs) -> JobBackend {
    match args.backend {
        Backend::Cpu => JobBackend::Cpu,
        Backend::Blender => JobBackend::Blender(BlenderSettings {
            venv: args.blender_venv.clone(),
            samples: args.samples,
            denoise: args.denoise,
            threads: args.blender_threads.unwrap_or(0),
        }),
    }
}

pub(crate) fn check_backend(args: &RenderArgs) -> Result<()> {
    match args.backend {
        Backend::Cpu => {
            let blender_only = args.samples != 16
                || args.denoise
                || args.blender_threads.is_some()
                || args.blender_venv.is_some();
            if blender_only {
                return Err(user_error(
                    "--samples, --denoise, --blender-threads and --blender-venv apply only to --backend blender",
                    "add --backend blender, or drop those flags",
                ));
            }
            Ok(())
        }
        Backend::Blender if cfg!(feature = "blender") => Ok(()),
        Backend::Blender => Err(user_error(
            "synthgen was not compiled with the `blender` feature",
            "use --backend cpu (the default), or rebuild with `cargo build -p synthgen-cli --features blender` (docs/blender.md)",
        )),
    }
}

/// The scene spec: defaults, then `--scene FILE`, then flags.
fn build_spec(args: &RenderArgs) -> Result<SceneSpec> {
    let mut spec = match &args.scene {
        Some(path) => SceneSpec::from_toml_file(path)
            .with_context(|| format!("invalid scene spec {}", path.display()))?,
        None => SceneSpec::default(),
    };
    if let Some(name) = &args.camera {
        spec.camera.preset = name.clone();
    }
    // The size first: it scales the camera (a scene file's K too); --camera-k is K as given.
    if let Some(s) = &args.image_size {
        if s.len() != 2 {
            return Err(user_error(
                format!("--image-size needs 2 numbers, got {}", s.len()),
                "write it as --image-size 640,480",
            ));
        }
        if args.camera_k.is_some() {
            spec.camera.width = Some(s[0]);
            spec.camera.height = Some(s[1]);
        } else {
            spec.camera.set_image_size(s[0], s[1])?;
        }
    }
    if let Some(k) = &args.camera_k {
        if k.len() != 4 {
            return Err(user_error(
                format!("--camera-k needs 4 numbers, got {}", k.len()),
                "write it as --camera-k 572.41,573.57,325.26,242.05 (fx,fy,cx,cy in pixels)",
            ));
        }
        spec.camera.fx = Some(k[0]);
        spec.camera.fy = Some(k[1]);
        spec.camera.cx = Some(k[2]);
        spec.camera.cy = Some(k[3]);
    }
    if let Some(r) = args.distance_m {
        spec.camera_pose.distance_m = r;
    }
    if let Some(r) = args.elevation_deg {
        spec.camera_pose.elevation_deg = r;
    }
    if let Some(o) = args.orientation {
        spec.placement.orientation = match o {
            OrientationArg::Upright => Orientation::Upright,
            OrientationArg::Random => Orientation::Random,
        };
    }
    if let Some(b) = args.background {
        spec.background.kind = match b {
            BackgroundArg::Color => BackgroundKind::Color,
            BackgroundArg::Noise => BackgroundKind::Noise,
            BackgroundArg::Images => BackgroundKind::Images,
        };
    }
    if let Some(dir) = &args.background_dir {
        spec.background.images_dir = Some(dir.clone());
        if args.background.is_none() {
            spec.background.kind = BackgroundKind::Images;
        }
    }
    if let Some(arg) = &args.sensor {
        spec.sensor = render_extras::sensor_flag(arg, &spec.sensor)?;
    }
    spec.validate()?;
    Ok(spec)
}

fn units_of(arg: UnitsArg) -> Units {
    match arg {
        UnitsArg::Auto => Units::Auto,
        UnitsArg::Mm => Units::Mm,
        UnitsArg::M => Units::M,
    }
}

/// The meshes of `--objects`, with their `--obj-ids`. The scene spec's own `[[objects]]` are
/// the job's to add; they are read here only to refuse bad ones before anything is written.
fn collect_sources(args: &RenderArgs, spec: &SceneSpec) -> Result<Vec<ObjectSource>> {
    let in_spec = ObjectSource::from_spec(spec, units_of(args.units))?;
    if args.objects.is_empty() && in_spec.is_empty() {
        return Err(user_error(
            "no objects to render",
            "pass meshes with --objects, e.g. `synthgen render --objects drill.obj`, or list them as [[objects]] in a --scene file",
        ));
    }
    if !args.obj_ids.is_empty() && args.obj_ids.len() != args.objects.len() {
        return Err(user_error(
            format!(
                "--obj-ids has {} ids but --objects has {} meshes",
                args.obj_ids.len(),
                args.objects.len()
            ),
            "give one id per mesh, in the same order",
        ));
    }
    Ok(args
        .objects
        .iter()
        .enumerate()
        .map(|(i, p)| ObjectSource {
            obj_id: args.obj_ids.get(i).copied(),
            ..ObjectSource::new(p.clone(), units_of(args.units))
        })
        .collect())
}

fn check_out_dir(out: &Path, force: bool) -> Result<()> {
    if out.is_dir() {
        if !synthgen_formats::output::is_empty(out) && !force {
            return Err(user_error(
                format!("output folder is not empty: {}", out.display()),
                "if a render there was interrupted (Ctrl-C, a crash), continue it with the same \
                 command and --resume; else choose another --out, or pass --force to replace it",
            ));
        }
        if force {
            synthgen_formats::output::check_force(out)?;
        }
    } else if out.exists() {
        return Err(user_error(
            format!("output path exists and is not a folder: {}", out.display()),
            "choose another --out",
        ));
    }
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn summarize(
    printer: &Printer,
    args: &RenderArgs,
    names: &[String],
    per_frame: Option<[usize; 2]>,
    written: u64,
    failures: &[(u64, String)],
    elapsed_s: f64,
    wrote: &str,
) {
    let fps = if elapsed_s > 0.0 {
        written as f64 / elapsed_s
    } else {
        0.0
    };
    printer.info(format!(
        "Rendered {written} frames of {} object{} ({}){} in {elapsed_s:.1} s ({fps:.1} frames/s) \
         with the {} renderer, seed {}; wrote {wrote}.{}",
        names.len(),
        if names.len() == 1 { "" } else { "s" },
        synthgen_core::sample::name_summary(names.iter().map(String::as_str)),
        match per_frame {
            Some([lo, hi]) if lo == hi => format!(", {lo} per frame"),
            Some([lo, hi]) => format!(", {lo}–{hi} per frame"),
            None => String::new(),
        },
        match args.backend {
            Backend::Cpu => "embedded CPU",
            Backend::Blender => "Blender Cycles",
        },
        args.seed,
        if failures.is_empty() {
            String::new()
        } else {
            format!(
                " {} frame{} failed (first: frame {}: {}).",
                failures.len(),
                if failures.len() == 1 { "" } else { "s" },
                failures[0].0,
                failures[0].1
            )
        }
    ));
    if written > 0 && args.format == FormatArg::Linemod {
        printer.hint(format!("look at {}", args.out.join("data").display()));
    } else if written > 0 {
        printer.hint(format!(
            "look at {}",
            args.out
                .join(args.split_name())
                .join(format!(
                    "{:06}",
                    args.first_frame / u64::from(args.chunk_size.max(1))
                ))
                .join("rgb")
                .display()
        ));
    }
}

/// The outermost ancestor of `path` (or `path` itself) that does not exist yet: what creating
/// `path` creates.
fn first_missing_ancestor(path: &std::path::Path) -> Option<std::path::PathBuf> {
    let mut missing = None;
    for a in path.ancestors() {
        if a.as_os_str().is_empty() || a.exists() {
            break;
        }
        missing = Some(a.to_path_buf());
    }
    missing
}

/// Removes `path` and its ancestors up to `top`, each only while it is empty.
fn remove_empty_dirs(path: &std::path::Path, top: &std::path::Path) {
    for a in path.ancestors() {
        if std::fs::remove_dir(a).is_err() || a == top {
            break;
        }
    }
}
