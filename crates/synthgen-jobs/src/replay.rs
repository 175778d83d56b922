//! A replay, as `synthgen render --replay REAL_DIR` runs it: the synthetic twin of an
//! annotated dataset. Every
//! frame with GT poses is rendered with its own intrinsics and camera pose, only its annotated
//! objects (the dataset's own models, their own colours) on black, then annotated, passed
//! through the sensor model and written like any render, under the source's scene and image
//! ids.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use rayon::prelude::*;
use synthgen_core::sample::ObjectInstance;
use synthgen_core::scene::{DepthModel, SensorSpec};
use synthgen_core::{FrameScene, Progress, Symmetries};
use synthgen_formats::layout::open_source;
use synthgen_formats::layout::{detect_layout, Layout as SourceLayout};
use synthgen_formats::manifest::{write_manifest, Manifest};
use synthgen_formats::output::{check_apart, is_empty, OutputLock};
use synthgen_formats::source::{FrameSource, SourceFrame};
use synthgen_pipeline::{render_annotated, ycbv_class_index, Layout, Sink};
use synthgen_render::SensorModel;

use synthgen_pipeline::{Backend, Format, SinkOptions};

use crate::models::{frame_obj_ids, load_models, replacement_meshes};
use crate::render::sensor_flag;
use crate::{user_error, Log};

/// Images per scene folder in the output: frame index = scene_id × this + im_id, so the BOP
/// and YCB-Video writers put every frame back under its own scene and image id (BOP image
/// ids have at most 6 digits).
pub const CHUNK: u64 = 1_000_000;

/// One source frame to render and where it goes.
struct Job {
    frame: SourceFrame,
    /// scene_id × CHUNK + im_id.
    index: u64,
    /// Output split, and the index of its sink.
    split: String,
    sink: usize,
}

/// What to replay: `synthgen render --replay`'s arguments as data.
#[derive(Debug, Clone)]
pub struct ReplayRequest {
    /// The annotated dataset (BOP, Linemod or YCB-Video) whose frames are rendered again.
    pub real: PathBuf,
    /// Only these scene ids (empty: all).
    pub scenes: Vec<u32>,
    /// A sensor name or file (None: no sensor model).
    pub sensor: Option<String>,
    /// Replacement meshes, one folder per object (`--replay-models`).
    pub models: Option<PathBuf>,
    /// Lit like the realistic raster instead of flat (`--replay-lit`).
    pub lit: bool,
    pub seed: u64,
    /// bop_toolkit's visibility delta, metres.
    pub visib_delta_m: f64,
    pub out: PathBuf,
    pub force: bool,
    pub resume: bool,
    pub fail_fast: bool,
    /// Worker threads (None: all cores).
    pub jobs: Option<usize>,
    pub backend: Backend,
    /// The output split (None: each source frame's own).
    pub split: Option<String>,
    pub sink: SinkOptions,
    /// The command recorded in the manifest.
    pub command_line: Vec<String>,
}

/// What a replay did.
#[derive(Debug)]
pub struct ReplayOutcome {
    /// Frames rendered and written.
    pub rendered: u64,
    /// The frames that failed (`split/scene/image`) with their messages.
    pub failures: Vec<(String, String)>,
}

/// Replays `req`; messages (warnings, the summary, hints) go to `progress`.
pub fn replay(req: &ReplayRequest, progress: &dyn Progress) -> Result<ReplayOutcome> {
    let printer = &Log::new(progress);
    let args = req;
    let started = Instant::now();
    let real = args.real.clone();
    let sensor_spec = match &args.sensor {
        Some(arg) => sensor_flag(arg, &SensorSpec::default())?,
        None => SensorSpec::default(),
    };
    for w in sensor_spec.unused_sections() {
        printer.warning(w);
    }
    // Before anything is created: an output inside the real dataset would be written there.
    check_apart(&args.out, &[("real dataset", &real)])?;

    let source = open_real(&real)?;
    let cam = source.camera();
    let (frames, skipped) = select_frames(source.as_ref(), &real, &args.scenes)?;
    if let Some(first) = skipped.first() {
        printer.warning(format!(
            "{} frame{} of {} without GT poses {} skipped (first: {first})",
            skipped.len(),
            if skipped.len() == 1 { "" } else { "s" },
            real.display(),
            if skipped.len() == 1 { "is" } else { "are" },
        ));
    }
    let obj_ids = frame_obj_ids(&frames);
    let mut loaded = load_models(source.as_ref(), &obj_ids, printer)?;
    if let Some(dir) = &args.models {
        replace_models(source.as_ref(), dir, &mut loaded, printer)?;
    }
    let index: BTreeMap<u32, usize> = obj_ids.iter().enumerate().map(|(i, &id)| (id, i)).collect();
    let models: Vec<_> = loaded.into_iter().map(|(_, m)| m).collect();
    let symmetries: Vec<Option<Symmetries>> = obj_ids
        .iter()
        .map(|id| {
            source
                .models_info()
                .and_then(|m| m.get(id))
                .map(|i| i.symmetries.clone())
        })
        .collect();

    if args.resume && args.sink.format != Format::Bop {
        return Err(user_error(
            "--resume works with --format bop only",
            "replay into BOP and convert the dataset with `synthgen convert --to linemod` or `--to ycbv`",
        ));
    }
    if !is_empty(&args.out) && !args.force && !args.resume {
        return Err(user_error(
            format!("output folder is not empty: {}", args.out.display()),
            "continue an interrupted replay with --resume, replace it with --force, or choose another --out",
        ));
    }
    if args.force {
        synthgen_formats::output::check_force(&args.out)?;
    }
    if args.out.exists() && !args.out.is_dir() {
        return Err(user_error(
            format!(
                "output path exists and is not a folder: {}",
                args.out.display()
            ),
            "choose another --out",
        ));
    }
    let _lock = OutputLock::acquire(&args.out)?;
    if args.force {
        synthgen_formats::output::replace_output(&args.out, printer)?;
    }
    let splits: BTreeSet<String> = frames
        .iter()
        .map(|f| {
            args.split
                .clone()
                .unwrap_or_else(|| f.location.split.clone())
        })
        .collect();
    let mut dataset = args.sink.manifest_json();
    if let Some(o) = dataset.as_object_mut() {
        o.insert(
            "split".into(),
            splits.into_iter().collect::<Vec<_>>().into(),
        );
        o.insert("chunk_size".into(), CHUNK.into());
    }
    // What makes this replay: the run plan says so from the start, so that an interrupted
    // run is recognised by --force (replaced) and --resume (continued, only as the same run).
    let mut manifest = Manifest::new(args.command_line.clone(), args.seed);
    manifest.backend = args.backend.name().into();
    manifest.scene_spec = serde_json::json!({
        "sensor": serde_json::to_value(&sensor_spec).context("cannot serialize the sensor")?,
    });
    manifest.extra = serde_json::json!({
        "replay": {
            "source": synthgen_core::paths::resolve(&real),
            "scenes": args.scenes,
            "models": args.models.as_deref().map(synthgen_core::paths::resolve),
            "lit": args.lit,
        },
        "objects": obj_ids,
        "visib_delta_m": args.visib_delta_m,
        "dataset": dataset,
    });
    begin_run(&args.out, args.resume, &manifest)?;

    let (mut jobs, mut sinks) = plan(
        args,
        frames,
        cam.intrinsics(),
        &ycbv_classes(source.as_ref(), &obj_ids),
    )?;
    // One models/ folder, whatever the number of splits.
    if let Some(first) = sinks.first() {
        first.write_models(&models, &obj_ids, &symmetries)?;
    }
    if args.resume {
        let mut done = Vec::with_capacity(sinks.len());
        for sink in &sinks {
            done.push(sink.resume()?);
        }
        let before = jobs.len();
        jobs.retain(|j| !done[j.sink].is_done(j.index));
        printer.info(format!(
            "--resume: {} of {before} frames were written before; replaying the other {}",
            before - jobs.len(),
            jobs.len()
        ));
    }
    let backend = args.backend.clone();
    let renderer = synthgen_pipeline::renderer_for(&backend, models, Vec::new(), printer)?;
    let sensor =
        SensorModel::new(sensor_spec.clone(), args.seed).context("invalid sensor model")?;
    printer.info(sensor_line(args.sensor.as_deref(), &sensor_spec, args.seed));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.jobs.unwrap_or(0))
        .build()
        .context("cannot start worker threads")?;
    let delta_m = args.visib_delta_m as f32;

    printer.start("replaying", jobs.len() as u64);
    let mut failures: Vec<(String, String)> = Vec::new();
    let mut nothing_visible: Vec<String> = Vec::new();
    let mut rendered: u64 = 0;
    let batch = (pool.current_num_threads() * 8).max(8);
    'outer: for chunk in jobs.chunks(batch) {
        let results: Vec<Result<_>> = pool.install(|| {
            chunk
                .par_iter()
                .map(|job| {
                    let mut scene = frame_scene(job, &index, cam.width, cam.height);
                    if args.lit {
                        light(&mut scene);
                    }
                    let (frame, ann) = render_annotated(&*renderer, &scene, &sensor, delta_m)?;
                    let rec = sinks[job.sink].write_frame_in(
                        Some(&job.split),
                        job.index,
                        &scene,
                        &frame,
                        &ann,
                    )?;
                    printer.advance(1);
                    let visible = ann.iter().any(|a| a.info.px_count_visib > 0);
                    anyhow::Ok((rec, visible))
                })
                .collect()
        });
        for (job, r) in chunk.iter().zip(results) {
            match r {
                Ok((rec, visible)) => {
                    sinks[job.sink].add_record(rec)?;
                    rendered += 1;
                    if !visible {
                        nothing_visible.push(location(&job.frame));
                    }
                }
                Err(e) => {
                    let at = location(&job.frame);
                    printer.warning(format!("frame {at} failed: {e:#}"));
                    failures.push((at, format!("{e:#}")));
                    if args.fail_fast {
                        break 'outer;
                    }
                }
            }
        }
    }
    let mut written = 0;
    let mut overflow = 0;
    let mut wrote = Vec::new();
    for sink in sinks.drain(..) {
        let s = sink.finish(&args.out)?;
        written += s.frames;
        overflow += s.depth_out_of_range_px;
        wrote.push(s.description);
    }
    printer.finish();
    if overflow > 0 {
        printer.warning(format!(
            "{overflow} depth pixels were beyond what a 16-bit PNG holds at depth_scale {} and were written as 0 (invalid)",
            args.sink.depth_scale()
        ));
    }
    if let Some(first) = nothing_visible.first() {
        printer.warning(format!(
            "{} of the {rendered} frames show no object at all (every visib_fract 0; first: {first})",
            nothing_visible.len()
        ));
    }

    manifest.frames = written;
    if let Some(extra) = manifest.extra.as_object_mut() {
        if let Some(r) = extra.get_mut("replay").and_then(|r| r.as_object_mut()) {
            r.insert("frames".into(), written.into());
            r.insert("skipped_without_gt".into(), skipped.len().into());
        }
        extra.insert(
            "failed_frames".into(),
            failures
                .iter()
                .map(|f| f.0.clone())
                .collect::<Vec<_>>()
                .into(),
        );
    }
    write_manifest(&args.out, &manifest)?;
    std::fs::remove_file(args.out.join(synthgen_formats::output::RUN_PLAN_FILE))
        .or_else(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                Ok(())
            } else {
                Err(e)
            }
        })
        .context("cannot remove the run plan")?;

    let elapsed = started.elapsed().as_secs_f64();
    printer.info(format!(
        "Replayed {rendered} frames of {} ({} object{}: {}) in {elapsed:.1} s with {}; wrote {}.{}{}",
        real.display(),
        obj_ids.len(),
        if obj_ids.len() == 1 { "" } else { "s" },
        obj_ids.iter().map(u32::to_string).collect::<Vec<_>>().join(", "),
        match args.backend {
            Backend::Cpu => "the embedded CPU renderer",
            Backend::Blender(_) => "Blender Cycles",
        },
        wrote.join(" and "),
        if skipped.is_empty() {
            String::new()
        } else {
            format!(
                " {} frame{} without GT poses skipped.",
                skipped.len(),
                if skipped.len() == 1 { "" } else { "s" }
            )
        },
        match failures.first() {
            None => String::new(),
            Some((at, why)) => format!(
                " {} frame{} failed (first: {at}: {why}).",
                failures.len(),
                if failures.len() == 1 { "" } else { "s" }
            ),
        },
    ));
    if rendered > 0 {
        printer.hint(format!(
            "check it with `synthgen validate {}`",
            args.out.display()
        ));
    }
    Ok(ReplayOutcome { rendered, failures })
}

/// `--replay-models DIR`: each object with a folder `DIR/<its name>/` holding one mesh gets
/// that mesh (units decided per file) instead of the dataset's model.
fn replace_models(
    source: &dyn FrameSource,
    dir: &Path,
    loaded: &mut [(u32, synthgen_core::Model)],
    printer: &Log,
) -> Result<()> {
    let ids: Vec<u32> = loaded.iter().map(|(id, _)| *id).collect();
    let (meshes, kept) = replacement_meshes(source, dir, ids, "--replay-models")?;
    for ((id, model), mesh) in loaded.iter_mut().zip(meshes) {
        let Some(mesh) = mesh else { continue };
        let l = synthgen_assets::load_model(&mesh, synthgen_assets::Units::Auto, printer)
            .with_context(|| format!("cannot load the replacement model of object {id}"))?;
        crate::models::check_replacement(source, *id, &mesh, &l.model, "--replay-models")?;
        *model = l.model;
    }
    if !kept.is_empty() {
        printer.warning(format!(
            "--replay-models: no folder for {} in {}; their dataset models are rendered",
            kept.join(", "),
            dir.display()
        ));
    }
    Ok(())
}

/// The parts of a replay's manifest two runs must share to write the same dataset.
fn run_identity(m: &Manifest) -> serde_json::Value {
    // Not the counts a finished run adds (frames, skipped_without_gt).
    let replay = ["source", "scenes", "models", "lit"]
        .map(|k| m.extra.get("replay").and_then(|r| r.get(k)).cloned());
    serde_json::json!({
        "synthgen_version": m.synthgen_version,
        "seed": m.seed,
        "backend": m.backend,
        "scene_spec": m.scene_spec,
        "replay": replay,
        "objects": m.extra.get("objects"),
        "visib_delta_m": m.extra.get("visib_delta_m"),
        "dataset": m.extra.get("dataset"),
    })
}

/// Writes the run plan (`manifest` before any frame); with `resume`, first checks that `out`
/// holds an earlier run of the same replay (its run plan, or its manifest once finished).
fn begin_run(out: &Path, resume: bool, manifest: &Manifest) -> Result<()> {
    let plan_path = out.join(synthgen_formats::output::RUN_PLAN_FILE);
    if resume {
        let earlier = [
            plan_path.clone(),
            out.join(synthgen_formats::manifest::MANIFEST_FILE),
        ]
        .into_iter()
        .find(|p| p.is_file());
        if let Some(p) = earlier {
            let text = std::fs::read_to_string(&p)
                .with_context(|| format!("cannot read {}", p.display()))?;
            let m: Manifest = serde_json::from_str(&text)
                .with_context(|| format!("cannot read {}", p.display()))?;
            let (a, b) = (run_identity(&m), run_identity(manifest));
            if a != b {
                return Err(user_error(
                    format!(
                        "--resume: {} holds another run (its {} differs from this command's)",
                        out.display(),
                        p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
                    ),
                    "pass exactly the options of the interrupted replay (its command line is in that file), or use --force or another --out",
                ));
            }
        } else if !is_empty(out) {
            return Err(user_error(
                format!("--resume: {} holds no interrupted replay", out.display()),
                "choose the folder an interrupted `render --replay` wrote, or another --out",
            ));
        }
    }
    let text = serde_json::to_string_pretty(manifest)? + "\n";
    synthgen_formats::io::atomic_write(&plan_path, text.as_bytes())?;
    Ok(())
}

fn open_real(real: &Path) -> Result<Box<dyn FrameSource>> {
    if !real.is_dir() {
        return Err(user_error(
            format!("no such dataset folder: {}", real.display()),
            "--replay takes a BOP, Linemod or YCB-Video dataset with GT poses and models",
        ));
    }
    if detect_layout(real).is_none() {
        return Err(user_error(
            format!(
                "not a dataset synthgen reads: {} has no camera.json (BOP), no classes.txt beside data/ (YCB-Video) and no data/NN/gt.yml (Linemod)",
                real.display()
            ),
            "--replay takes a BOP, Linemod or YCB-Video dataset with GT poses and models",
        ));
    }
    open_source(real).with_context(|| format!("cannot read the dataset {}", real.display()))
}

/// The frames to replay (of `--scenes`, when given) and the locations of those skipped for
/// having no GT pose.
fn select_frames(
    source: &dyn FrameSource,
    real: &Path,
    scenes: &[u32],
) -> Result<(Vec<SourceFrame>, Vec<String>)> {
    let mut frames = source
        .frames(&[])
        .with_context(|| format!("cannot read the frames of {}", real.display()))?;
    if frames.is_empty() {
        return Err(user_error(
            format!("no frames in {}", real.display()),
            "--replay takes a dataset with annotated frames (images and GT poses)",
        ));
    }
    if !scenes.is_empty() {
        let available: BTreeSet<u32> = frames.iter().map(|f| f.location.scene_id).collect();
        let unknown: Vec<String> = scenes
            .iter()
            .filter(|s| !available.contains(s))
            .map(u32::to_string)
            .collect();
        if !unknown.is_empty() {
            return Err(user_error(
                format!(
                    "--scenes: no scene {} in {}",
                    unknown.join(", "),
                    real.display()
                ),
                format!(
                    "its scenes are {}",
                    available
                        .iter()
                        .map(u32::to_string)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        frames.retain(|f| scenes.contains(&f.location.scene_id));
    }
    let (frames, empty): (Vec<_>, Vec<_>) = frames.into_iter().partition(|f| !f.gt.is_empty());
    if frames.is_empty() {
        return Err(user_error(
            format!(
                "no frame of {} has annotated objects (GT poses)",
                real.display()
            ),
            "--replay renders the annotated objects of each frame; this dataset has none",
        ));
    }
    if let Some(f) = frames.iter().find(|f| u64::from(f.location.im_id) >= CHUNK) {
        return Err(user_error(
            format!(
                "image id {} of {} is over 999999, more than --replay's numbering keeps",
                f.location.im_id,
                location(f)
            ),
            "BOP image ids have at most 6 digits; renumber the dataset's images",
        ));
    }
    Ok((frames, empty.iter().map(location).collect()))
}

/// The jobs and their sinks: one BOP writer per output split (one data/ folder for
/// YCB-Video, one Linemod writer), refusing two frames that would land on one file.
fn plan(
    args: &ReplayRequest,
    frames: Vec<SourceFrame>,
    intrinsics: synthgen_core::Intrinsics,
    classes: &[String],
) -> Result<(Vec<Job>, Vec<Sink>)> {
    let mut sinks: Vec<Sink> = Vec::new();
    let mut sink_of: BTreeMap<String, usize> = BTreeMap::new();
    let mut taken: BTreeMap<(String, u32, u32), String> = BTreeMap::new();
    let mut jobs = Vec::with_capacity(frames.len());
    let split_of = |f: &SourceFrame| {
        args.split
            .clone()
            .unwrap_or_else(|| f.location.split.clone())
    };
    // Each BOP split's frame indices, so that its writer keeps journals and can resume.
    let mut ranges: BTreeMap<String, std::ops::Range<u64>> = BTreeMap::new();
    for f in &frames {
        let i = u64::from(f.location.scene_id) * CHUNK + u64::from(f.location.im_id);
        let r = ranges.entry(split_of(f)).or_insert(i..i + 1);
        *r = r.start.min(i)..r.end.max(i + 1);
    }
    for frame in frames {
        let split = split_of(&frame);
        let sink = match (sink_of.get(&split), args.sink.format) {
            (Some(&s), _) => s,
            (None, Format::Linemod | Format::Ycbv) if !sinks.is_empty() => {
                sink_of.insert(split.clone(), 0);
                0
            }
            (None, _) => {
                let layout = Layout {
                    split: split.clone(),
                    chunk_size: CHUNK as u32,
                    frames: ranges.get(&split).cloned(),
                };
                sinks.push(Sink::create_with(
                    &args.out,
                    &args.sink,
                    args.resume,
                    intrinsics,
                    layout,
                    classes,
                )?);
                sink_of.insert(split.clone(), sinks.len() - 1);
                sinks.len() - 1
            }
        };
        let (scene_id, im_id) = (frame.location.scene_id, frame.location.im_id);
        // YCB-Video has one data/ folder for all splits; Linemod numbers frames anew.
        let key_split = match args.sink.format {
            Format::Bop => Some(split.clone()),
            Format::Ycbv => Some(String::new()),
            Format::Linemod => None,
        };
        let clash = key_split.and_then(|k| taken.insert((k, scene_id, im_id), location(&frame)));
        if let Some(other) = clash {
            return Err(user_error(
                format!(
                    "{} and {} would both be written as scene {scene_id} image {im_id}{}",
                    other,
                    location(&frame),
                    match args.sink.format {
                        Format::Bop => format!(" of split {split}"),
                        _ => String::new(),
                    }
                ),
                "replay into BOP without --split, which keeps each source split apart",
            ));
        }
        jobs.push(Job {
            index: u64::from(scene_id) * CHUNK + u64::from(im_id),
            frame,
            split,
            sink,
        });
    }
    Ok((jobs, sinks))
}

/// The frame's objects at their GT poses (nearest proper rotations), seen with its camera,
/// lit flat so the models keep their own colours.
fn frame_scene(job: &Job, index: &BTreeMap<u32, usize>, width: u32, height: u32) -> FrameScene {
    let f = &job.frame;
    let objects =
        f.gt.iter()
            .map(|g| ObjectInstance {
                // Every id of the frames has a model: they were all loaded up front.
                model_index: index.get(&g.obj_id).copied().unwrap_or(0),
                obj_id: g.obj_id,
                cam_from_obj: g.cam_from_obj(),
                brightness: 1.0,
                specular: 0.0,
                shininess: 1.0,
                tint: [1.0; 3],
                hue_deg: 0.0,
                metallic: 0.0,
            })
            .collect();
    let mut scene = FrameScene::bare(job.index, f.camera.intrinsics(width, height), objects);
    if let Some(cam_from_world) = f.camera.cam_from_world() {
        scene.world_from_cam = cam_from_world.inverse();
    }
    scene
}

/// `--replay-lit`: the realistic raster's options on a replayed frame. The light sits 0.5 m
/// above the camera (world up where the frame knows its table, else the image's up), as a
/// room's ceiling light does for a handheld camera; the materials are a plain dielectric
/// (specular 0.5: F0 4 %, roughness 0.5).
fn light(scene: &mut FrameScene) {
    use synthgen_core::glam::DVec3;
    let up = if scene.world_from_cam == synthgen_core::Pose::IDENTITY {
        DVec3::new(0.0, -1.0, 0.0)
    } else {
        scene.world_from_cam.rotation.transpose() * DVec3::Z
    };
    scene.lights = vec![synthgen_core::sample::PointLight {
        position_cam_m: up * 0.5,
        color: [1.0; 3],
        intensity: 0.8,
    }];
    scene.ambient = 0.35;
    scene.shadows = true;
    scene.ambient_occlusion = 0.6;
    scene.shading = synthgen_core::scene::Shading::Ggx;
    scene.environment = Some([[1.15, 1.15, 1.2], [0.7, 0.7, 0.7]]);
    for o in &mut scene.objects {
        o.specular = 0.5;
        // Roughness 0.5: n = 2 / r⁴ − 2.
        o.shininess = 30.0;
    }
}

/// `split/scene/image` of a source frame, for messages.
fn location(f: &SourceFrame) -> String {
    format!(
        "{}/{:06}/{:06}",
        f.location.split, f.location.scene_id, f.location.im_id
    )
}

/// `classes.txt` of a YCB-Video output, up to the largest id: a YCB-Video source's own class
/// names (its model folders); else YCB-Video's name for a model kept in that class's folder
/// under that class's index, `obj_NNNNNN` for the others.
fn ycbv_classes(source: &dyn FrameSource, obj_ids: &[u32]) -> Vec<String> {
    let mut names = synthgen_formats::ycbv::class_list(obj_ids, false);
    let from_ycbv = detect_layout(source.root()) == Some(SourceLayout::Ycbv);
    for (i, name) in names.iter_mut().enumerate() {
        let id = i as u32 + 1;
        let model = source.model_file(id);
        if from_ycbv {
            // models/<class>/textured_simple.obj
            if let Some(class) = model.parent().and_then(|p| p.file_name()) {
                *name = class.to_string_lossy().into_owned();
            }
        } else if ycbv_class_index(&model) == Some(id) {
            *name = synthgen_formats::ycbv::YCBV_CLASSES[i].into();
        }
    }
    names
}

/// The info line saying which sensor model the replay applies.
fn sensor_line(arg: Option<&str>, spec: &SensorSpec, seed: u64) -> String {
    let depth = match spec.depth {
        DepthModel::None => "none (the clean rendered depth)",
        DepthModel::D455 => "d455 (active stereo)",
        DepthModel::Tof => "tof (time of flight)",
        DepthModel::StructuredLight => "structured_light",
    };
    let from = match arg {
        Some(a) if SensorSpec::builtin(a).is_none() => format!(" from {a}"),
        _ => String::new(),
    };
    let rgb = if spec.rgb.enabled {
        ", RGB noise on"
    } else {
        ""
    };
    let noise = if spec.is_identity() {
        String::new()
    } else {
        format!(", noise seed {seed}")
    };
    format!("sensor: depth {depth}{from}{rgb}{noise}")
}
