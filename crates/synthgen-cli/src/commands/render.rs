//! `synthgen render`: sample scenes, render them, write a BOP (or Linemod) dataset.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use rayon::prelude::*;
use synthgen_assets::Units;
use synthgen_core::sample::SceneObject;
use synthgen_core::scene::{BackgroundKind, Orientation, PlacementMode, UpAxis};
use synthgen_core::{Model, Progress, SceneSampler, SceneSpec, Symmetries, Texture};
use synthgen_dataset::manifest::{write_manifest, Manifest};
use synthgen_dataset::output::OutputLock;
use synthgen_render::{CpuRenderer, Renderer, SensorModel, ViewChecker};

use crate::cli::{Backend, BackgroundArg, FormatArg, OrientationArg, RenderArgs, UnitsArg};
use crate::commands::render_sink::{self, Sink};
use crate::commands::user_error;
use crate::commands::{render_extras, render_resume, replay};
use crate::{ExitStatus, Printer};

/// One mesh to load, with where it came from.
struct ObjectSource {
    path: PathBuf,
    units: Units,
    obj_id: Option<u32>,
    count: u32,
    /// Rest pose for upright placement (`--objects` keep +z).
    up: UpAxis,
    tilt_deg: f64,
}

pub fn run(args: RenderArgs, printer: &Printer) -> Result<ExitStatus> {
    if args.replay.is_some() {
        return replay::run(args, printer);
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
    let spec = build_spec(&args)?;
    let sources = collect_sources(&args, &spec)?;
    if !args.resume {
        check_out_dir(&args.out, args.force)?;
    }
    // One writer per output folder; a crashed run's lock goes with its process.
    let _lock = OutputLock::acquire(&args.out)?;

    // Models, in the order given; ids from flags, the spec, file names, or 1, 2, ...
    let mut models = Vec::new();
    for s in &sources {
        let loaded = synthgen_assets::load_model(&s.path, s.units, printer)
            .with_context(|| format!("cannot load object {}", s.path.display()))?;
        if let Some(note) = &loaded.auto_note {
            printer.info(note);
        }
        models.push(loaded.model);
    }
    name_by_folder_where_stems_repeat(&mut models, &sources);
    let ids = assign_obj_ids(&sources, &args.obj_ids)?;
    let scene_objects = scene_objects(&models, &ids, &sources);
    let n_targets = models.len();
    // Distractor models go after the targets' in the renderer's list.
    let distractors = render_extras::distractor_pool(&spec, &mut models, printer)?;
    // The bin's two wall models go last.
    let bin_models = spec.bin.enabled.then(|| {
        let first = models.len();
        models.extend(spec.bin.models());
        first
    });

    let backgrounds = load_backgrounds(&spec, printer)?;
    let (ground_textures, wall_textures) = render_extras::surface_textures(&spec, printer)?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.unwrap_or(0))
        .build()
        .context("cannot start worker threads")?;

    let intrinsics = spec.camera.intrinsics()?;
    let writer = Sink::create(
        &args,
        intrinsics,
        frame_range.clone(),
        &ycbv_classes(&sources, &ids),
    )?;
    let mut manifest = base_manifest(&args, &spec, &sources, &ids, &frame_range)?;
    let done = render_resume::begin(&args, &manifest, &writer, frame_range.clone())?;
    let symmetries: Vec<Option<Symmetries>> = sources
        .iter()
        .map(|s| source_symmetries(&s.path, printer))
        .collect::<Result<_>>()?;
    writer.write_models(&models[..n_targets], &ids, &symmetries)?;

    let mut sampler =
        SceneSampler::new(spec.clone(), scene_objects, args.seed)?.with_distractors(distractors);
    if let Some(first) = bin_models {
        sampler = sampler.with_bin_models(first);
    }
    if spec.placement.mode == PlacementMode::Physics {
        let p = sampler.distractor_pool();
        let all: Vec<SceneObject> = sampler
            .objects
            .iter()
            .chain(&p.primitives)
            .chain(&p.meshes)
            .cloned()
            .collect();
        let settler = synthgen_physics::PhysicsSettler::new(&all, spec.placement.physics.clone())?
            .with_bin(&if spec.bin.enabled {
                spec.bin.walls()
            } else {
                Vec::new()
            });
        sampler = sampler.with_settle(Arc::new(settler));
    }
    // The summary needs only the names: the meshes move into the renderer, not a copy.
    let names: Vec<String> = models[..n_targets].iter().map(|m| m.name.clone()).collect();
    let renderer: Box<dyn Renderer + Sync> = match args.backend {
        Backend::Cpu => {
            let cpu = CpuRenderer::new(models, backgrounds)?
                .with_surface_textures(&ground_textures, &wall_textures)?;
            if spec.camera.min_visib_fract > 0.0 {
                // A clone shares the prepared models.
                let check = ViewChecker::new(cpu.clone(), args.visib_delta_m as f32);
                sampler = sampler.with_view_check(Arc::new(check));
            }
            Box::new(cpu)
        }
        Backend::Blender => {
            if spec.camera.min_visib_fract > 0.0 {
                // The raster's depth-only pass: the Blender backend's alone depths come from
                // the same raster.
                let cpu = CpuRenderer::new(models.clone(), Vec::new())?
                    .with_surface_textures(&ground_textures, &wall_textures)?;
                let check = ViewChecker::new(cpu, args.visib_delta_m as f32);
                sampler = sampler.with_view_check(Arc::new(check));
            }
            let surfaces = [ground_textures, wall_textures];
            blender_renderer(&args, models, backgrounds, surfaces, printer)?
        }
    };
    // Applied after the annotations, so masks and GT come from the clean render.
    let sensor = SensorModel::new(spec.sensor.clone(), args.seed)?;
    let delta_m = args.visib_delta_m as f32;

    let range_len = frame_range.end - frame_range.start;
    if done.count() > 0 {
        printer.info(format!(
            "resuming: {} of {range_len} frames already written",
            done.count()
        ));
    }
    printer.start("rendering", range_len - done.count());
    let mut todo = frame_range.clone().filter(|&i| !done.is_done(i));
    let mut failures: Vec<(u64, String)> = Vec::new();
    let mut rendered: u64 = 0;
    let mut nothing_visible: Vec<u64> = Vec::new();
    // Batches bound memory (a frame's buffers are dropped once it is written) while giving
    // every thread several frames to work on.
    let batch = (pool.current_num_threads() * 8).max(8);
    'outer: loop {
        let batch_frames: Vec<u64> = todo.by_ref().take(batch).collect();
        if batch_frames.is_empty() {
            break;
        }
        let results: Vec<(u64, Result<_>)> = pool.install(|| {
            batch_frames
                .par_iter()
                .map(|&i| {
                    let r = (|| {
                        let scene = sampler.sample(i)?;
                        let (frame, ann) =
                            render_annotated(renderer.as_ref(), &scene, &sensor, delta_m)?;
                        let rec = writer.write_frame(i, &scene, &frame, &ann)?;
                        printer.advance(1);
                        // What was written is checked: a frame in which no target is
                        // visible is counted (wrong units or distances make all of them so).
                        let visible = ann.iter().any(|a| a.info.px_count_visib > 0);
                        anyhow::Ok((rec, visible))
                    })();
                    (i, r)
                })
                .collect()
        });
        for (i, r) in results {
            match r {
                // Records arrive in frame order; a scene folder's JSON is written as soon as
                // its last frame of this run is in.
                Ok((rec, visible)) => {
                    writer.add_record(rec)?;
                    rendered += 1;
                    if !visible {
                        nothing_visible.push(i);
                    }
                }
                Err(e) => {
                    printer.warning(format!("frame {i} failed: {e:#}"));
                    failures.push((i, format!("{e:#}")));
                    if args.fail_fast {
                        break 'outer;
                    }
                }
            }
        }
    }
    let summary = writer.finish(&args.out)?;
    printer.finish();
    let fallbacks = sampler.physics_fallbacks();
    if let Some((first, why)) = fallbacks.first() {
        printer.warning(format!(
            "{} frame{} did not settle and kept the non-physics placement (first: frame {first}: {why})",
            fallbacks.len(),
            if fallbacks.len() == 1 { "" } else { "s" },
        ));
        printer.hint("raise placement.physics.max_steps in the scene spec");
    }
    if summary.depth_out_of_range_px > 0 {
        printer.warning(format!(
            "{} depth pixels were beyond what a 16-bit PNG holds at depth_scale {} and were written as 0 (invalid)",
            summary.depth_out_of_range_px,
            render_sink::depth_scale(&args)
        ));
        printer.hint("pass --depth-scale 1.0 for 1 mm steps up to 65 m");
    }
    // Frames in the dataset: those an earlier, interrupted run wrote and this run's.
    let written = if matches!(args.format, FormatArg::Bop) {
        done.count() + rendered
    } else {
        summary.frames
    };

    let elapsed = started.elapsed().as_secs_f64();
    manifest.frames = written;
    if let Some(extra) = manifest.extra.as_object_mut() {
        extra.insert(
            "failed_frames".into(),
            failures.iter().map(|f| f.0).collect::<Vec<_>>().into(),
        );
        extra.insert(
            "physics_fallback_frames".into(),
            fallbacks.iter().map(|f| f.0).collect::<Vec<_>>().into(),
        );
    }
    write_manifest(&args.out, &manifest)?;
    render_resume::end(&args.out)?;

    let per_frame = spec.placement.objects_per_frame.map(|[lo, hi]| {
        let n = sampler.objects.len();
        [(lo as usize).min(n), (hi as usize).min(n)]
    });
    summarize(
        printer,
        &args,
        &names,
        per_frame,
        written,
        &failures,
        elapsed,
        &summary.description,
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
    Ok(if failures.is_empty() {
        ExitStatus::Success
    } else {
        ExitStatus::Failure
    })
}

/// Renders `scene`, annotates the clean render, then applies the sensor model to the frame's
/// RGB and depth (masks and GT stay those of the clean render): the step every rendered
/// frame goes through, sampled or replayed.
pub(crate) fn render_annotated(
    renderer: &(dyn Renderer + Sync),
    scene: &synthgen_core::FrameScene,
    sensor: &SensorModel,
    delta_m: f32,
) -> Result<(
    synthgen_core::RenderedFrame,
    Vec<synthgen_core::ObjectAnnotation>,
)> {
    let mut frame = renderer.render(scene)?;
    let ann = synthgen_core::annotate(&scene.intrinsics, &frame.depth_m, &frame.alone, delta_m);
    if !sensor.is_identity() {
        sensor.apply(scene, &mut frame);
    }
    Ok((frame, ann))
}

/// The manifest of this run before any frame is rendered (frames 0, no failures).
fn base_manifest(
    args: &RenderArgs,
    spec: &SceneSpec,
    sources: &[ObjectSource],
    ids: &[u32],
    frame_range: &std::ops::Range<u64>,
) -> Result<Manifest> {
    let mut manifest = Manifest::new(render_resume::command_line(), args.seed);
    manifest.backend = match args.backend {
        Backend::Cpu => "cpu",
        Backend::Blender => "blender",
    }
    .into();
    manifest.scene_spec = serde_json::to_value(spec).context("cannot serialize the scene spec")?;
    let mut extra = serde_json::json!({
        "first_frame": args.first_frame,
        "frame_range": [frame_range.start, frame_range.end],
        "objects": sources.iter().zip(ids).map(|(s, id)| serde_json::json!({
            "path": s.path, "obj_id": id, "count": s.count,
        })).collect::<Vec<_>>(),
        "visib_delta_m": args.visib_delta_m,
        "dataset": render_sink::dataset_options(args),
        "failed_frames": [],
        "physics_fallback_frames": [],
    });
    if let (Some(shard), Some(o)) = (args.shard, extra.as_object_mut()) {
        o.insert(
            "shard".into(),
            serde_json::json!({"index": shard.index, "count": shard.count}),
        );
    }
    manifest.extra = extra;
    Ok(manifest)
}

fn check_backend(args: &RenderArgs) -> Result<()> {
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

/// The symmetries of a BOP model (`.../models/obj_000010.ply`) from the `models_info.json`
/// beside it, so a dataset rendered from BOP models keeps them (ADD-S, symmetric losses).
/// `None` for other meshes or when the file has no entry for the object.
fn source_symmetries(path: &Path, printer: &Printer) -> Result<Option<Symmetries>> {
    let Some(id) = path
        .file_stem()
        .and_then(|s| s.to_str())
        .and_then(|s| s.strip_prefix("obj_"))
        .and_then(|s| s.parse::<u32>().ok())
    else {
        return Ok(None);
    };
    let info_path = path.with_file_name("models_info.json");
    if !info_path.is_file() {
        return Ok(None);
    }
    let infos = synthgen_dataset::bop::reader::read_models_info(&info_path)
        .with_context(|| format!("cannot read the symmetries of {}", path.display()))?;
    let sym = infos.get(&id).map(|i| i.symmetries.clone());
    if let Some(s) = &sym {
        if !s.symmetries_discrete.is_empty() || !s.symmetries_continuous.is_empty() {
            printer.info(format!(
                "object {id}: symmetries from {}",
                info_path.display()
            ));
        }
    }
    Ok(sym)
}

#[cfg(feature = "blender")]
fn blender_renderer(
    args: &RenderArgs,
    models: Vec<Model>,
    backgrounds: Vec<Arc<Texture>>,
    surfaces: [Vec<Arc<Texture>>; 2],
    printer: &Printer,
) -> Result<Box<dyn Renderer + Sync>> {
    use synthgen_blender::{BlenderOptions, BlenderRenderer, Error};
    let options = BlenderOptions {
        venv: args.blender_venv.clone(),
        samples: args.samples,
        denoise: args.denoise,
        threads: args.blender_threads.unwrap_or(0),
        ..BlenderOptions::default()
    };
    printer.info(format!(
        "starting Blender (Cycles, {} samples{})",
        options.samples,
        if options.denoise { ", denoised" } else { "" }
    ));
    let [ground, walls] = surfaces;
    match BlenderRenderer::with_surfaces(models, backgrounds, ground, walls, options) {
        Ok(r) => Ok(Box::new(r)),
        Err(e @ Error::BpyNotFound { .. }) => {
            Err(user_error(e.to_string(), synthgen_blender::SETUP_HINT))
        }
        Err(e @ Error::InvalidOption { .. }) => {
            Err(user_error(e.to_string(), "see synthgen render --help"))
        }
        Err(e) => Err(anyhow::Error::new(e).context("cannot start the blender backend")),
    }
}

#[cfg(not(feature = "blender"))]
fn blender_renderer(
    _args: &RenderArgs,
    _models: Vec<Model>,
    _backgrounds: Vec<Arc<Texture>>,
    _surfaces: [Vec<Arc<Texture>>; 2],
    _printer: &Printer,
) -> Result<Box<dyn Renderer + Sync>> {
    // check_backend refuses --backend blender first in this build.
    Err(user_error(
        "synthgen was not compiled with the `blender` feature",
        "rebuild with `cargo build -p synthgen-cli --features blender`",
    ))
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
    if let Some(s) = &args.image_size {
        if s.len() != 2 {
            return Err(user_error(
                format!("--image-size needs 2 numbers, got {}", s.len()),
                "write it as --image-size 640,480",
            ));
        }
        spec.camera.width = Some(s[0]);
        spec.camera.height = Some(s[1]);
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

fn collect_sources(args: &RenderArgs, spec: &SceneSpec) -> Result<Vec<ObjectSource>> {
    let mut sources: Vec<ObjectSource> = args
        .objects
        .iter()
        .map(|p| ObjectSource {
            path: p.clone(),
            units: units_of(args.units),
            obj_id: None,
            count: 1,
            up: UpAxis::PlusZ,
            tilt_deg: 0.0,
        })
        .collect();
    for o in &spec.objects {
        let units = match o.units.as_deref() {
            None => units_of(args.units),
            Some(u) => u.parse::<Units>().map_err(|_| {
                user_error(
                    format!(
                        "unknown units {u:?} for {} in the scene spec",
                        o.path.display()
                    ),
                    "use units = \"mm\", \"m\" or \"auto\"",
                )
            })?,
        };
        sources.push(ObjectSource {
            path: o.path.clone(),
            units,
            obj_id: o.obj_id,
            count: o.count,
            up: o.up,
            tilt_deg: o.tilt_deg,
        });
    }
    if sources.is_empty() {
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
    Ok(sources)
}

/// Models of different files with the same stem (YCB-Video's `*/textured_simple.obj`) are
/// named after their folder in messages (`025_mug`), so that a summary tells them apart.
fn name_by_folder_where_stems_repeat(models: &mut [Model], sources: &[ObjectSource]) {
    let stem = |p: &Path| p.file_stem().map(|s| s.to_string_lossy().into_owned());
    for i in 0..models.len() {
        let shared = sources
            .iter()
            .any(|o| o.path != sources[i].path && stem(&o.path) == stem(&sources[i].path));
        let folder = sources[i]
            .path
            .parent()
            .and_then(Path::file_name)
            .map(|f| f.to_string_lossy().into_owned());
        if let (true, Some(folder)) = (shared, folder) {
            models[i].name = folder;
        }
    }
}

/// The number in BOP-style names such as `obj_000008.ply` or `obj_08.ply`.
/// The id a model's path implies: BOP's `obj_000008.ply` → 8; a YCB-Video model
/// (`models/025_mug/textured_simple.obj`) → its class index (14), BOP `ycbv`'s obj_id.
fn id_from_name(path: &Path) -> Option<u32> {
    let stem = path.file_stem()?.to_str()?;
    if let Some(digits) = stem.strip_prefix("obj_") {
        return digits.parse::<u32>().ok().filter(|&v| v > 0);
    }
    ycbv_class_index(path)
}

/// The YCB-Video class index of a model whose folder is named after the class.
pub(crate) fn ycbv_class_index(path: &Path) -> Option<u32> {
    let folder = path.parent()?.file_name()?.to_str()?;
    let i = synthgen_dataset::ycbv::YCBV_CLASSES
        .iter()
        .position(|c| *c == folder)?;
    u32::try_from(i + 1).ok()
}

/// `classes.txt` of a YCB-Video output: YCB-Video's name for an object whose model sits in
/// that class's folder under that class's id, else `obj_NNNNNN`; ids up to the largest.
fn ycbv_classes(sources: &[ObjectSource], ids: &[u32]) -> Vec<String> {
    let mut names = synthgen_dataset::ycbv::class_list(ids, false);
    for (s, &id) in sources.iter().zip(ids) {
        if ycbv_class_index(&s.path) == Some(id) {
            names[id as usize - 1] = synthgen_dataset::ycbv::YCBV_CLASSES[id as usize - 1].into();
        }
    }
    names
}

/// Object ids in source order: explicit ids first, then file-name ids, then the smallest free.
fn assign_obj_ids(sources: &[ObjectSource], flag_ids: &[u32]) -> Result<Vec<u32>> {
    let mut ids: Vec<Option<u32>> = sources
        .iter()
        .enumerate()
        .map(|(i, s)| {
            flag_ids
                .get(i)
                .copied()
                .or(s.obj_id)
                .or_else(|| id_from_name(&s.path))
        })
        .collect();
    let mut by_path: BTreeMap<u32, &Path> = BTreeMap::new();
    for (s, id) in sources.iter().zip(&ids) {
        if let Some(id) = id {
            if *id == 0 {
                return Err(user_error(
                    "object id 0 is not allowed",
                    "BOP ids start at 1",
                ));
            }
            match by_path.get(id) {
                Some(p) if *p != s.path.as_path() => {
                    return Err(user_error(
                        format!(
                            "object id {id} is given to both {} and {}",
                            p.display(),
                            s.path.display()
                        ),
                        "pass distinct ids with --obj-ids",
                    ))
                }
                _ => {
                    by_path.insert(*id, &s.path);
                }
            }
        }
    }
    let mut next = 1;
    for (s, id) in sources.iter().zip(ids.iter_mut()) {
        if id.is_none() {
            // The same file listed twice shares one id.
            if let Some((&k, _)) = by_path.iter().find(|(_, p)| **p == s.path.as_path()) {
                *id = Some(k);
                continue;
            }
            while by_path.contains_key(&next) {
                next += 1;
            }
            by_path.insert(next, &s.path);
            *id = Some(next);
        }
    }
    Ok(ids.into_iter().map(|i| i.unwrap_or(0)).collect())
}

fn scene_objects(models: &[Model], ids: &[u32], sources: &[ObjectSource]) -> Vec<SceneObject> {
    let mut out = Vec::new();
    for (i, ((m, &id), s)) in models.iter().zip(ids).zip(sources).enumerate() {
        let support = m.support_points(256);
        for _ in 0..s.count {
            out.push(SceneObject {
                model_index: i,
                obj_id: id,
                name: m.name.clone(),
                support_points_m: support.clone(),
                up: s.up,
                tilt_deg: s.tilt_deg,
            });
        }
    }
    out
}

fn check_out_dir(out: &Path, force: bool) -> Result<()> {
    if out.is_dir() {
        if !synthgen_dataset::output::is_empty(out) && !force {
            return Err(user_error(
                format!("output folder is not empty: {}", out.display()),
                "if a render there was interrupted (Ctrl-C, a crash), continue it with the same \
                 command and --resume; else choose another --out, or pass --force to write into it",
            ));
        }
    } else if out.exists() {
        return Err(user_error(
            format!("output path exists and is not a folder: {}", out.display()),
            "choose another --out",
        ));
    }
    Ok(())
}

fn load_backgrounds(spec: &SceneSpec, printer: &Printer) -> Result<Vec<Arc<Texture>>> {
    if spec.background.kind != BackgroundKind::Images {
        return Ok(Vec::new());
    }
    let Some(dir) = &spec.background.images_dir else {
        return Ok(Vec::new());
    };
    let images = synthgen_assets::load_images_in_dir(dir, printer)
        .with_context(|| format!("cannot load background images from {}", dir.display()))?;
    if images.is_empty() {
        return Err(user_error(
            format!("no PNG or JPEG images in {}", dir.display()),
            "point --background-dir at a folder of images, or use --background noise",
        ));
    }
    printer.info(format!(
        "{} background images from {}",
        images.len(),
        dir.display()
    ));
    Ok(images)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn src(p: &str) -> ObjectSource {
        ObjectSource {
            path: PathBuf::from(p),
            units: Units::Auto,
            obj_id: None,
            count: 1,
            up: UpAxis::PlusZ,
            tilt_deg: 0.0,
        }
    }

    #[test]
    fn ids_from_names_then_free_numbers() {
        let s = [
            src("a/obj_000008.ply"),
            src("drill.obj"),
            src("obj_01.ply"),
            src("banana.obj"),
        ];
        assert_eq!(assign_obj_ids(&s, &[]).unwrap(), vec![8, 2, 1, 3]);
    }

    #[test]
    fn flag_ids_win_and_duplicates_are_errors() {
        let s = [src("drill.obj"), src("banana.obj")];
        assert_eq!(assign_obj_ids(&s, &[5, 6]).unwrap(), vec![5, 6]);
        assert!(assign_obj_ids(&s, &[5, 5]).is_err());
        let same = [src("drill.obj"), src("drill.obj")];
        assert_eq!(assign_obj_ids(&same, &[]).unwrap(), vec![1, 1]);
    }
}
