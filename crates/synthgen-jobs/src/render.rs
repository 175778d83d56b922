//! A render as `synthgen render` runs it: the scene spec from a file and overrides, the
//! objects, the output folder's guards (empty or `force`, the lock, the folders a run that
//! cannot start created removed again), `RenderJob` → `write`, then the warnings, the summary
//! and whether too many frames failed. `experiment mix` renders its sets through it too.

use std::ops::Range;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use synthgen_assets::Units;
use synthgen_core::scene::{BackgroundKind, Orientation, RgbNoiseSpec, SensorSpec};
use synthgen_core::{Progress, SceneSpec};
use synthgen_formats::output::OutputLock;
use synthgen_pipeline::{error_chain, Backend, Format, ObjectSource, RenderJob, SinkOptions};
use synthgen_pipeline::{WriteOptions, WriteReport};

use crate::{user_error, Log};

/// What the scene's flags change in the scene spec (`--camera`, `--image-size`, ...).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SpecOverrides {
    /// A camera preset name.
    pub camera: Option<String>,
    /// Width, height: scales the camera (a scene file's K too) unless `camera_k` is given.
    pub image_size: Option<[u32; 2]>,
    /// fx, fy, cx, cy in pixels, as given.
    pub camera_k: Option<[f64; 4]>,
    pub distance_m: Option<[f64; 2]>,
    pub elevation_deg: Option<[f64; 2]>,
    pub orientation: Option<Orientation>,
    pub background: Option<BackgroundKind>,
    /// Background images (makes the background `images` unless `background` says otherwise).
    pub background_dir: Option<PathBuf>,
    /// A sensor name or file, which replaces the scene's `[sensor]`.
    pub sensor: Option<String>,
}

/// A render: `synthgen render`'s arguments as data.
#[derive(Debug, Clone)]
pub struct RenderRequest {
    /// The scene spec file (else the default scene).
    pub scene: Option<PathBuf>,
    pub overrides: SpecOverrides,
    /// Meshes, one instance of each per frame (beside the scene file's `[[objects]]`).
    pub objects: Vec<PathBuf>,
    /// BOP object ids of `objects`, in order (empty: from the file names, else 1, 2, ...).
    pub obj_ids: Vec<u32>,
    pub units: Units,
    /// The first frame of the whole run and its frame count (`--first-frame`, `--frames`).
    pub first_frame: u64,
    pub frames: u64,
    /// `[index, count]`: this process renders its share of the frames.
    pub shard: Option<[u64; 2]>,
    pub seed: u64,
    /// Worker threads (None: all cores).
    pub jobs: Option<usize>,
    pub backend: Backend,
    /// bop_toolkit's visibility delta, metres.
    pub visib_delta_m: f64,
    pub out: PathBuf,
    /// Replace an output synthgen wrote.
    pub force: bool,
    /// Continue an interrupted render in `out`.
    pub resume: bool,
    /// Stop at the first failed frame.
    pub fail_fast: bool,
    pub sink: SinkOptions,
    /// The share of frames that may fail before the render counts as failed.
    pub max_failed_fraction: f64,
    /// The command recorded in the manifest (without `--resume`).
    pub command_line: Vec<String>,
}

impl RenderRequest {
    /// `synthgen render --objects ... --frames N --seed S --out OUT` with every other flag at
    /// its default.
    pub fn new(objects: Vec<PathBuf>, frames: u64, seed: u64, out: &Path) -> RenderRequest {
        RenderRequest {
            scene: None,
            overrides: SpecOverrides::default(),
            objects,
            obj_ids: Vec::new(),
            units: Units::Auto,
            first_frame: 0,
            frames,
            shard: None,
            seed,
            jobs: None,
            backend: Backend::Cpu,
            visib_delta_m: DEFAULT_VISIB_DELTA_M,
            out: out.to_path_buf(),
            force: false,
            resume: false,
            fail_fast: false,
            sink: SinkOptions::new(Format::Bop),
            max_failed_fraction: DEFAULT_MAX_FAILED_FRACTION,
            command_line: Vec::new(),
        }
    }

    /// The frames this process renders: all of `first_frame .. + frames`, or its shard.
    pub fn frame_range(&self) -> Result<Range<u64>> {
        // BOP names scene folders with 6 digits: frame index / chunk size must stay below 10^6.
        let last = u64::from(self.sink.chunk_size.max(1)) * 1_000_000;
        if self
            .first_frame
            .checked_add(self.frames)
            .is_none_or(|end| end > last)
        {
            return Err(user_error(
                format!(
                    "--first-frame {} + --frames {} is beyond the last frame a dataset numbers ({last}: 10^6 scene folders of --chunk-size {} images)",
                    self.first_frame, self.frames, self.sink.chunk_size
                ),
                "render fewer frames, or raise --chunk-size",
            ));
        }
        Ok(match self.shard {
            Some([index, count]) => shard_range(self.first_frame, self.frames, index, count),
            None => self.first_frame..self.first_frame + self.frames,
        })
    }

    /// The scene spec: defaults, then the scene file, then the overrides.
    pub fn spec(&self) -> Result<SceneSpec> {
        let mut spec = match &self.scene {
            Some(path) => SceneSpec::from_toml_file(path)
                .with_context(|| format!("invalid scene spec {}", path.display()))?,
            None => SceneSpec::default(),
        };
        let o = &self.overrides;
        if let Some(name) = &o.camera {
            spec.camera.preset = name.clone();
        }
        // The size first: it scales the camera (a scene file's K too); the K is as given.
        if let Some([w, h]) = o.image_size {
            if o.camera_k.is_some() {
                spec.camera.width = Some(w);
                spec.camera.height = Some(h);
            } else {
                spec.camera.set_image_size(w, h)?;
            }
        }
        if let Some([fx, fy, cx, cy]) = o.camera_k {
            spec.camera.fx = Some(fx);
            spec.camera.fy = Some(fy);
            spec.camera.cx = Some(cx);
            spec.camera.cy = Some(cy);
        }
        if let Some(r) = o.distance_m {
            spec.camera_pose.distance_m = r;
        }
        if let Some(r) = o.elevation_deg {
            spec.camera_pose.elevation_deg = r;
        }
        if let Some(orientation) = o.orientation {
            spec.placement.orientation = orientation;
        }
        if let Some(kind) = o.background {
            spec.background.kind = kind;
        }
        if let Some(dir) = &o.background_dir {
            spec.background.images_dir = Some(dir.clone());
            if o.background.is_none() {
                spec.background.kind = BackgroundKind::Images;
            }
        }
        if let Some(arg) = &o.sensor {
            spec.sensor = sensor_flag(arg, &spec.sensor)?;
        }
        spec.validate()?;
        Ok(spec)
    }

    /// The meshes of `objects`, with their ids. The scene spec's own `[[objects]]` are the
    /// job's to add; they are read here only to refuse bad ones before anything is written.
    fn sources(&self, spec: &SceneSpec) -> Result<Vec<ObjectSource>> {
        let in_spec = ObjectSource::from_spec(spec, self.units)?;
        if self.objects.is_empty() && in_spec.is_empty() {
            return Err(user_error(
                "no objects to render",
                "pass meshes with --objects, e.g. `synthgen render --objects drill.obj`, or list them as [[objects]] in a --scene file",
            ));
        }
        if !self.obj_ids.is_empty() && self.obj_ids.len() != self.objects.len() {
            return Err(user_error(
                format!(
                    "--obj-ids has {} ids but --objects has {} meshes",
                    self.obj_ids.len(),
                    self.objects.len()
                ),
                "give one id per mesh, in the same order",
            ));
        }
        Ok(self
            .objects
            .iter()
            .enumerate()
            .map(|(i, p)| ObjectSource {
                obj_id: self.obj_ids.get(i).copied(),
                ..ObjectSource::new(p.clone(), self.units)
            })
            .collect())
    }
}

/// The frames of shard `index` of `count` out of `frames` frames starting at `first`: shard i
/// gets `[first + i*frames/count, first + (i+1)*frames/count)`, so shards differ by at most one
/// frame and together cover every frame exactly once.
pub fn shard_range(first: u64, frames: u64, index: u64, count: u64) -> Range<u64> {
    let at = |k: u64| first + (u128::from(frames) * u128::from(k) / u128::from(count)) as u64;
    at(index)..at(index + 1)
}

/// `--visib-delta-m`'s default (bop_toolkit's 15 mm).
pub const DEFAULT_VISIB_DELTA_M: f64 = 0.015;
/// `--max-failed-fraction`'s default.
pub const DEFAULT_MAX_FAILED_FRACTION: f64 = 0.01;

/// What a render did.
#[derive(Debug)]
pub struct RenderOutcome {
    pub report: WriteReport,
    /// The failed frames with their messages.
    pub failures: Vec<(u64, String)>,
    /// More than `max_failed_fraction` of the frames failed (the CLI exits with 1).
    pub too_many_failed: bool,
}

/// The sensor of `--sensor NAME|FILE`, which replaces the scene's `sensor` section; the
/// scene's RGB noise stays when the flag's sensor leaves `rgb` at its defaults (a built-in
/// name, or a file without `[rgb]`).
pub fn sensor_flag(arg: &str, scene: &SensorSpec) -> Result<SensorSpec> {
    let mut sensor =
        SensorSpec::from_name_or_file(arg).with_context(|| format!("invalid --sensor {arg}"))?;
    if sensor.rgb == RgbNoiseSpec::default() {
        sensor.rgb = scene.rgb.clone();
    }
    Ok(sensor)
}

/// Renders `req` into `req.out`; messages (warnings, the summary, hints) go to `progress`.
pub fn render(req: &RenderRequest, progress: &dyn Progress) -> Result<RenderOutcome> {
    let printer = &Log::new(progress);
    let started = Instant::now();
    if req.sink.format != Format::Bop && (req.shard.is_some() || req.resume) {
        return Err(user_error(
            "--shard and --resume work with --format bop only",
            "render BOP and convert the merged dataset with `synthgen convert --to linemod`",
        ));
    }
    let frame_range = req.frame_range()?;
    let asked = frame_range.end - frame_range.start;
    let spec = req.spec()?;
    for w in spec.unused_settings() {
        printer.warning(w);
    }
    if spec.ground.visible && spec.camera_pose.elevation_deg[0] < 0.0 {
        printer.warning(format!(
            "camera_pose.elevation_deg starts at {}°, below the table: some cameras look at the objects from under the ground plane (a scene fitted to depth at the wrong scale looks like this)",
            spec.camera_pose.elevation_deg[0]
        ));
    }
    let sources = req.sources(&spec)?;
    // What the scene file names is an input too (the command line's are checked by the CLI).
    let inputs = spec.input_paths();
    let named: Vec<(&str, &Path)> = inputs
        .iter()
        .map(|(r, p)| (*r, p.as_path()))
        .chain(sources.iter().map(|s| ("object mesh", s.path.as_path())))
        .collect();
    synthgen_formats::output::check_apart(&req.out, &named)?;
    if !req.resume {
        check_out_dir(&req.out, req.force)?;
    }
    // The folders this run creates: removed again (when empty) if the job cannot start.
    let created = first_missing_ancestor(&req.out);
    // One writer per output folder; a crashed run's lock goes with its process.
    let lock = OutputLock::acquire(&req.out)?;
    if req.force && !req.resume {
        synthgen_formats::output::replace_output(&req.out, printer)?;
    }

    let built = RenderJob::new(spec)
        .objects(&sources)
        .units(req.units)
        .frames(frame_range)
        .seed(req.seed)
        .threads(req.jobs.unwrap_or(0))
        .backend(req.backend.clone())
        .visib_delta_m(req.visib_delta_m)
        .build(printer);
    let job = match built {
        Ok(job) => job,
        Err(e) => {
            // A broken mesh must not leave an empty output folder behind: a folder this run
            // created and that holds only its lock file goes (the lock file while still held).
            if let Some(top) = created {
                let only_lock = std::fs::read_dir(&req.out).is_ok_and(|entries| {
                    entries.flatten().all(|e| {
                        e.file_name() == std::ffi::OsStr::new(synthgen_formats::output::LOCK_FILE)
                    })
                });
                if only_lock {
                    let _ = std::fs::remove_file(req.out.join(synthgen_formats::output::LOCK_FILE));
                }
                drop(lock);
                remove_empty_dirs(&req.out, &top);
            }
            return Err(e.into());
        }
    };
    let _lock = lock;
    let options = WriteOptions {
        out: req.out.clone(),
        sink: req.sink.clone(),
        resume: req.resume,
        fail_fast: req.fail_fast,
        command_line: req
            .command_line
            .iter()
            .filter(|a| *a != "--resume")
            .cloned()
            .collect(),
        first_frame: Some(req.first_frame),
        shard: req.shard,
    };
    let report = job.write(&options, printer)?;
    if let Some((first, why)) = report.physics_fallbacks.first() {
        let n = report.physics_fallbacks.len();
        printer.warning(format!(
            "{n} frame{} did not settle and kept the non-physics placement (first: frame {first}: {why})",
            if n == 1 { "" } else { "s" },
        ));
        printer.hint("raise placement.physics.max_steps in the scene spec");
    }
    let resampled = &report.resampled;
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
    if report.depth_out_of_range_px > 0 {
        printer.warning(format!(
            "{} depth pixels were beyond what a 16-bit PNG holds at depth_scale {} and were written as 0 (invalid)",
            report.depth_out_of_range_px,
            options.sink.depth_scale()
        ));
        printer.hint("pass --depth-scale 1.0 for 1 mm steps up to 65 m");
    }

    let elapsed = started.elapsed().as_secs_f64();
    let failures: Vec<(u64, String)> = report
        .failures
        .iter()
        .map(|(i, e)| (*i, error_chain(e)))
        .collect();
    summarize(
        printer,
        req,
        &job.object_names(),
        job.objects_per_frame(),
        &report,
        &failures,
        elapsed,
    );
    if !report.nothing_visible.is_empty() {
        let n = report.nothing_visible.len();
        let rendered = report.rendered;
        printer.warning(format!(
            "{n} of the {rendered} frames rendered show no target at all (every visib_fract 0; first: frame {})",
            report.nothing_visible[0]
        ));
        if 2 * n > rendered as usize {
            return Err(user_error(
                format!(
                    "most frames show no object ({n} of {rendered}): the dataset in {} is not usable",
                    req.out.display()
                ),
                "check the units (--units mm|m: a model 1000x too large or too small), the camera \
                 distance (--distance-m) against the objects' size, and that the meshes have faces",
            ));
        }
    }
    let too_many_failed = failed_too_many(&failures, asked, req.max_failed_fraction, printer);
    Ok(RenderOutcome {
        report,
        failures,
        too_many_failed,
    })
}

/// More than `max_fraction` of the `asked` frames failed; a handful below it is reported
/// (and listed in synthgen.json) but does not fail the run.
fn failed_too_many(
    failures: &[(u64, String)],
    asked: u64,
    max_fraction: f64,
    printer: &Log,
) -> bool {
    if failures.is_empty() {
        return false;
    }
    let share = failures.len() as f64 / asked.max(1) as f64;
    if share > max_fraction {
        true
    } else {
        printer.warning(format!(
            "{} of {} frames failed ({:.2} %, within --max-failed-fraction {}); the others are written",
            failures.len(),
            asked,
            share * 100.0,
            max_fraction
        ));
        false
    }
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

fn summarize(
    printer: &Log,
    req: &RenderRequest,
    names: &[String],
    per_frame: Option<[usize; 2]>,
    report: &WriteReport,
    failures: &[(u64, String)],
    elapsed_s: f64,
) {
    let written = report.written;
    let fps = if elapsed_s > 0.0 {
        written as f64 / elapsed_s
    } else {
        0.0
    };
    printer.info(format!(
        "Rendered {written} frames of {} object{} ({}){} in {elapsed_s:.1} s ({fps:.1} frames/s) \
         with the {} renderer, seed {}; wrote {}.{}",
        names.len(),
        if names.len() == 1 { "" } else { "s" },
        synthgen_core::sample::name_summary(names.iter().map(String::as_str)),
        match per_frame {
            Some([lo, hi]) if lo == hi => format!(", {lo} per frame"),
            Some([lo, hi]) => format!(", {lo}–{hi} per frame"),
            None => String::new(),
        },
        match req.backend {
            Backend::Cpu => "embedded CPU",
            Backend::Blender(_) => "Blender Cycles",
        },
        req.seed,
        report.description,
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
    if written > 0 && req.sink.format == Format::Linemod {
        printer.hint(format!("look at {}", req.out.join("data").display()));
    } else if written > 0 {
        printer.hint(format!(
            "look at {}",
            req.out
                .join(&req.sink.split)
                .join(format!(
                    "{:06}",
                    req.first_frame / u64::from(req.sink.chunk_size.max(1))
                ))
                .join("rgb")
                .display()
        ));
    }
}

/// The outermost ancestor of `path` (or `path` itself) that does not exist yet: what creating
/// `path` creates.
fn first_missing_ancestor(path: &Path) -> Option<PathBuf> {
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
fn remove_empty_dirs(path: &Path, top: &Path) {
    for a in path.ancestors() {
        if std::fs::remove_dir(a).is_err() || a == top {
            break;
        }
    }
}
