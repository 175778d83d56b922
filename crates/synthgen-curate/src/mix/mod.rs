//! `synthgen mix`: a reproducible, stratified draw of real and synthetic frames into one BOP
//! dataset, with a held-out real test split and per-frame provenance.
//!
//! The draw is three independent seeded draws, each stratified by a frame's object set:
//! 1. the test split, from all real frames, with an RNG that depends only on the seed (never
//!    on the counts or ratio), so every row of a mixing table is tested on the same frames;
//!    or, with [`MixOptions::test_scenes`], every frame of those scenes (no draw; see
//!    [`scenes`]);
//! 2. the real training frames, from the real frames not in the test split;
//! 3. the synthetic training frames.
//!
//! Inside a stratum the frames are shuffled once per seed and the first k are taken, so a
//! larger count extends a smaller one's draw.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use synthgen_core::rng::splitmix64;
use synthgen_core::{GtInfo, PoseRenderer, Progress};

pub use scenes::{available_scenes, scene_list, scene_test_frames, SceneRef};
use synthgen_formats::annotate::write_completed_masks;
use synthgen_formats::bop::image::encode_gray8_png;
use synthgen_formats::bop::write_map;
use synthgen_formats::bop::writer::write_camera_info;
use synthgen_formats::bop::{GtEntry, ModelInfo, PngCompression, SceneCamera};
use synthgen_formats::io::{atomic_write, create_dir_all};
use synthgen_formats::manifest::{write_manifest, Manifest};
use synthgen_formats::source::{write_bop_model, FrameLocation, FrameSource, MaskRef, SourceFrame};
use synthgen_formats::{Error, Result};

/// Output split of the training frames.
pub const TRAIN_SPLIT: &str = "train";
/// Output split of the held-out real frames.
pub const TEST_SPLIT: &str = "test";
/// Images per output scene folder.
pub const SCENE_SIZE: usize = 1000;
/// Per-frame provenance, at the output's root.
pub const PROVENANCE_FILE: &str = "provenance.json";

const STREAM_TEST: u64 = 0x7465_7374; // "test"
const STREAM_REAL: u64 = 0x7265_616c; // "real"
const STREAM_SYNTH: u64 = 0x7379_6e74; // "synt"
const STREAM_ORDER: u64 = 0x6f72_6465; // "orde"

fn rng(seed: u64, stream: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(splitmix64(splitmix64(seed) ^ stream))
}

/// Which source a frame comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Origin {
    Real,
    Synth,
}

/// How many frames to draw.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MixCounts {
    pub real: usize,
    pub synth: usize,
    /// Real frames held out for testing; `None`: 10% of the real frames (rounded down).
    pub test: Option<usize>,
}

impl MixCounts {
    /// Counts from a synthetic fraction of a total: synth = round(ratio × total).
    pub fn from_ratio(ratio: f64, total: usize, test: Option<usize>) -> Result<MixCounts> {
        if !(0.0..=1.0).contains(&ratio) {
            return Err(Error::InvalidRequest(format!(
                "ratio must be between 0 and 1 (the synthetic fraction), got {ratio}"
            )));
        }
        let synth = (ratio * total as f64).round() as usize;
        Ok(MixCounts {
            real: total - synth.min(total),
            synth: synth.min(total),
            test,
        })
    }
}

/// Default size of the test split: 10% of the real frames.
pub fn default_test_count(real_frames: usize) -> usize {
    real_frames / 10
}

/// Which frames go where: indices into the real and synthetic frame lists.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MixPlan {
    /// Real frames held out, sorted.
    pub test: Vec<usize>,
    /// Training frames in output order.
    pub train: Vec<(Origin, usize)>,
}

/// Splits `n` over strata of the given sizes in proportion (largest remainder; ties go to
/// the earlier stratum). Requires `n <= sum(sizes)`; each share is at most its size.
pub fn allocate(n: usize, sizes: &[usize]) -> Vec<usize> {
    let total: usize = sizes.iter().sum();
    if total == 0 {
        return vec![0; sizes.len()];
    }
    let n = n.min(total);
    let mut shares: Vec<usize> = sizes.iter().map(|&s| n * s / total).collect();
    let given: usize = shares.iter().sum();
    let mut order: Vec<usize> = (0..sizes.len()).collect();
    // Largest remainder first; stable sort keeps ties in stratum order.
    order.sort_by_key(|&i| std::cmp::Reverse(n * sizes[i] % total));
    for &i in order.iter().take(n - given) {
        shares[i] += 1;
    }
    shares
}

/// Draws `n` of `pool` (indices into `keys`), stratified by key; result sorted.
fn stratified_draw<K: Ord>(
    keys: &[K],
    pool: &[usize],
    n: usize,
    rng: &mut ChaCha8Rng,
) -> Vec<usize> {
    let mut strata: BTreeMap<&K, Vec<usize>> = BTreeMap::new();
    for &i in pool {
        strata.entry(&keys[i]).or_default().push(i);
    }
    let sizes: Vec<usize> = strata.values().map(Vec::len).collect();
    let shares = allocate(n, &sizes);
    let mut out = Vec::with_capacity(n);
    for (members, k) in strata.into_values().zip(shares) {
        let mut members = members;
        // Shuffle every stratum, even when k = 0, so draws do not depend on the counts.
        members.shuffle(rng);
        out.extend_from_slice(&members[..k]);
    }
    out.sort_unstable();
    out
}

/// Chooses the frames of a mix. `real_keys` / `synth_keys` are the frames' strata (their
/// object sets); `real_path` / `synth_path` only name the datasets in errors.
pub fn plan_mix<K: Ord>(
    real_keys: &[K],
    synth_keys: &[K],
    counts: MixCounts,
    seed: u64,
    real_path: &Path,
    synth_path: &Path,
) -> Result<MixPlan> {
    let test_count = counts
        .test
        .unwrap_or_else(|| default_test_count(real_keys.len()));
    if test_count > real_keys.len() {
        return Err(Error::NotEnoughFrames {
            what: "real test".into(),
            asked: test_count,
            available: real_keys.len(),
            note: String::new(),
            path: real_path.to_path_buf(),
        });
    }
    let all_real: Vec<usize> = (0..real_keys.len()).collect();
    let test = stratified_draw(
        real_keys,
        &all_real,
        test_count,
        &mut rng(seed, STREAM_TEST),
    );
    let note = format!(
        " ({} real frames, {} held out for the test split)",
        real_keys.len(),
        test.len()
    );
    plan_mix_with_test(
        real_keys, synth_keys, counts, test, &note, seed, real_path, synth_path,
    )
}

/// As [`plan_mix`] with the test split given (sorted indices into the real frames, e.g.
/// whole scenes); `counts.test` is ignored. The training draws are those of `plan_mix`, from
/// the real frames outside `test`. `held_out` ends the "not enough real frames" message.
#[allow(clippy::too_many_arguments)]
pub fn plan_mix_with_test<K: Ord>(
    real_keys: &[K],
    synth_keys: &[K],
    counts: MixCounts,
    test: Vec<usize>,
    held_out: &str,
    seed: u64,
    real_path: &Path,
    synth_path: &Path,
) -> Result<MixPlan> {
    let pool: Vec<usize> = (0..real_keys.len())
        .filter(|i| test.binary_search(i).is_err())
        .collect();
    if counts.real > pool.len() {
        return Err(Error::NotEnoughFrames {
            what: "real training".into(),
            asked: counts.real,
            available: pool.len(),
            note: held_out.to_string(),
            path: real_path.to_path_buf(),
        });
    }
    if counts.synth > synth_keys.len() {
        return Err(Error::NotEnoughFrames {
            what: "synthetic".into(),
            asked: counts.synth,
            available: synth_keys.len(),
            note: String::new(),
            path: synth_path.to_path_buf(),
        });
    }
    let real = stratified_draw(real_keys, &pool, counts.real, &mut rng(seed, STREAM_REAL));
    let all_synth: Vec<usize> = (0..synth_keys.len()).collect();
    let synth = stratified_draw(
        synth_keys,
        &all_synth,
        counts.synth,
        &mut rng(seed, STREAM_SYNTH),
    );
    let mut train: Vec<(Origin, usize)> = real
        .into_iter()
        .map(|i| (Origin::Real, i))
        .chain(synth.into_iter().map(|i| (Origin::Synth, i)))
        .collect();
    train.shuffle(&mut rng(seed, STREAM_ORDER));
    Ok(MixPlan { test, train })
}

/// Where one output frame came from (one entry of `provenance.json`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Provenance {
    pub split: String,
    pub scene_id: u32,
    pub im_id: u32,
    pub origin: Origin,
    /// Root of the source dataset.
    pub source: PathBuf,
    pub source_split: String,
    pub source_scene_id: u32,
    pub source_im_id: u32,
}

/// What to mix and where.
#[derive(Debug, Clone)]
pub struct MixOptions {
    pub counts: MixCounts,
    pub seed: u64,
    /// Recorded in the manifest.
    pub command_line: Vec<String>,
    /// Replace an existing mix in `out` (its train/, test/, models/ and JSON files).
    pub force: bool,
    /// Leave out training frames that are the same image as a held-out test frame (same
    /// file, hard link or bytes) instead of refusing the mix.
    pub exclude_shared: bool,
    /// Hold out every real frame of these scenes as the test split, and draw the real
    /// training frames from the other scenes only; empty: a seeded draw of `counts.test`
    /// frames. Not together with `counts.test`.
    pub test_scenes: Vec<SceneRef>,
}

/// Renderers that fill in what a source's frames lack, one per source: BOP's `mask/` and
/// `scene_gt_info.json` (YCB-Video and Linemod frames have only visible masks), computed
/// from the poses and models ([`synthgen_formats::annotate::complete_annotations`]). `None` leaves such
/// frames as they are, with a warning.
#[derive(Default, Clone, Copy)]
pub struct Completion<'a> {
    pub real: Option<&'a dyn PoseRenderer>,
    pub synth: Option<&'a dyn PoseRenderer>,
}

/// What a mix wrote.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MixReport {
    pub train_real: usize,
    pub train_synth: usize,
    pub test: usize,
    /// Files hard-linked and copied (copies when linking fails, e.g. across filesystems).
    pub linked: usize,
    pub copied: usize,
    /// Non-fatal findings (differing cameras or models).
    pub warnings: Vec<String>,
    /// Frames whose mask/ and scene_gt_info entries were computed (see [`Completion`]).
    pub completed: usize,
    /// Training frames left out because they are test frames (`exclude_shared`).
    pub excluded_shared: usize,
    /// Training frames that are the same image as an earlier training frame.
    pub duplicate_train: usize,
}

/// Draws the mix and writes it as a BOP dataset at `out`: `train/` and `test/` scene
/// folders, camera.json and models from the real set (synthetic-only objects' models from
/// the synthetic set), `provenance.json` and `synthgen.json`. All or nothing: a missing
/// source file stops the run, since a partial mix would break the counts.
pub fn write_mix(
    real: &dyn FrameSource,
    synth: &dyn FrameSource,
    out: &Path,
    opts: &MixOptions,
    completion: Completion,
    progress: &dyn Progress,
) -> Result<MixReport> {
    let real_frames = real.frames(&[])?;
    let synth_frames = synth.frames(&[])?;
    let real_keys: Vec<Vec<u32>> = real_frames.iter().map(SourceFrame::object_set).collect();
    let synth_keys: Vec<Vec<u32>> = synth_frames.iter().map(SourceFrame::object_set).collect();
    let mut plan = if opts.test_scenes.is_empty() {
        plan_mix(
            &real_keys,
            &synth_keys,
            opts.counts,
            opts.seed,
            real.root(),
            synth.root(),
        )?
    } else {
        if let Some(n) = opts.counts.test {
            return Err(Error::InvalidRequest(format!(
                "a test count ({n}) and test scenes ({}) do not go together: the test split is every frame of the test scenes",
                scene_list(&opts.test_scenes)
            )));
        }
        let locations: Vec<&FrameLocation> = real_frames.iter().map(|f| &f.location).collect();
        let test = scene_test_frames(&locations, &opts.test_scenes, real.root())?;
        let note = format!(
            " ({} real frames, {} of them in the test scenes {})",
            real_frames.len(),
            test.len(),
            scene_list(&opts.test_scenes)
        );
        plan_mix_with_test(
            &real_keys,
            &synth_keys,
            opts.counts,
            test,
            &note,
            opts.seed,
            real.root(),
            synth.root(),
        )?
    };
    let frame_of = |&(origin, i): &(Origin, usize)| match origin {
        Origin::Real => &real_frames[i],
        Origin::Synth => &synth_frames[i],
    };
    // The test split must be frames the model never saw: the two sources may be one folder,
    // or share frames by hard link or copy.
    let test_frames: Vec<&SourceFrame> = plan.test.iter().map(|&i| &real_frames[i]).collect();
    let train_frames: Vec<&SourceFrame> = plan.train.iter().map(frame_of).collect();
    let leaks = synthgen_formats::shared_frames::same_images(&test_frames, &train_frames)?;
    let mut excluded_shared = 0;
    if let Some(&(j, i)) = leaks.first() {
        if !opts.exclude_shared {
            return Err(Error::InvalidRequest(format!(
                "{} of the {} training frames are the same images as held-out test frames (the same file, a hard link or the same bytes), e.g. {} is the test frame {}: the test error would measure memorized frames. Mix datasets that share no frames, or pass --exclude-shared to leave those frames out of training",
                leaks.len(),
                train_frames.len(),
                train_frames[j].rgb.display(),
                test_frames[i].rgb.display()
            )));
        }
        let drop: std::collections::BTreeSet<usize> = leaks.iter().map(|&(j, _)| j).collect();
        plan.train = plan
            .train
            .iter()
            .enumerate()
            .filter(|(k, _)| !drop.contains(k))
            .map(|(_, t)| *t)
            .collect();
        excluded_shared = drop.len();
    }
    let train_frames: Vec<&SourceFrame> = plan.train.iter().map(frame_of).collect();
    let duplicate_train =
        synthgen_formats::shared_frames::same_images(&train_frames, &train_frames)?
            .iter()
            .filter(|(j, i)| i != j)
            .count();
    synthgen_formats::output::check_apart(
        out,
        &[
            ("real dataset", real.root()),
            ("synthetic dataset", synth.root()),
        ],
    )?;
    prepare_out(out, opts.force)?;

    let mut report = MixReport {
        test: plan.test.len(),
        excluded_shared,
        duplicate_train,
        ..MixReport::default()
    };
    if excluded_shared > 0 {
        report.warnings.push(format!(
            "left {excluded_shared} training frames out: they are the same images as held-out test frames (--exclude-shared); the mix has {} training frames, not {}",
            plan.train.len(),
            plan.train.len() + excluded_shared
        ));
    }
    if duplicate_train > 0 {
        report.warnings.push(format!(
            "{duplicate_train} training frames are the same image as another training frame (the two datasets share frames)"
        ));
    }
    let (rc, sc) = (real.camera(), synth.camera());
    if (rc.width, rc.height) != (sc.width, sc.height) {
        report.warnings.push(format!(
            "image sizes differ: real {}x{}, synthetic {}x{}; camera.json takes the real one (per-image cam_K is kept)",
            rc.width, rc.height, sc.width, sc.height
        ));
    }
    write_camera_info(&out.join("camera.json"), &rc)?;
    write_models(real, synth, out, &mut report)?;

    let total = plan.test.len() + plan.train.len();
    progress.start("mixing", total as u64);
    let mut provenance = Vec::with_capacity(total);
    let test: Vec<(Origin, usize)> = plan.test.iter().map(|&i| (Origin::Real, i)).collect();
    for (split, list) in [(TRAIN_SPLIT, &plan.train), (TEST_SPLIT, &test)] {
        let mut scenes: BTreeMap<u32, SceneJson> = BTreeMap::new();
        for (n, &(origin, i)) in list.iter().enumerate() {
            let (source, frame, renderer) = match origin {
                Origin::Real => (real, &real_frames[i], completion.real),
                Origin::Synth => (synth, &synth_frames[i], completion.synth),
            };
            let scene_id = (n / SCENE_SIZE) as u32;
            let im_id = (n % SCENE_SIZE) as u32;
            let dir = out.join(split).join(format!("{scene_id:06}"));
            copy_frame_files(frame, &dir, im_id, &mut report)?;
            let scene = scenes.entry(scene_id).or_default();
            scene.camera.insert(im_id, frame.camera);
            scene.gt.insert(im_id, frame.gt.clone());
            match (&frame.gt_info, renderer) {
                (Some(info), _) => {
                    scene.gt_info.insert(im_id, info.clone());
                }
                (None, Some(r)) => {
                    let cam = source.camera();
                    let info = complete_frame(r, frame, &dir, im_id, (cam.width, cam.height))?;
                    scene.gt_info.insert(im_id, info);
                    report.completed += 1;
                }
                (None, None) => {}
            }
            match (split, origin) {
                (TEST_SPLIT, _) => {}
                (_, Origin::Real) => report.train_real += 1,
                (_, Origin::Synth) => report.train_synth += 1,
            }
            provenance.push(Provenance {
                split: split.to_string(),
                scene_id,
                im_id,
                origin,
                source: source.root().to_path_buf(),
                source_split: frame.location.split.clone(),
                source_scene_id: frame.location.scene_id,
                source_im_id: frame.location.im_id,
            });
            progress.advance(1);
        }
        for (scene_id, scene) in scenes {
            scene.write(&out.join(split).join(format!("{scene_id:06}")))?;
        }
    }
    progress.finish();
    if provenance.iter().any(|p| p.origin == Origin::Real)
        && completion.real.is_none()
        && real_frames.iter().any(|f| f.gt_info.is_none())
    {
        report.warnings.push(
            "some real frames have no scene_gt_info.json entries; their scene folders have none"
                .into(),
        );
    }

    let prov_path = out.join(PROVENANCE_FILE);
    let mut text =
        serde_json::to_string_pretty(&provenance).map_err(|e| Error::json(&prov_path, e))?;
    text.push('\n');
    atomic_write(&prov_path, text.as_bytes())?;

    let mut manifest = Manifest::new(opts.command_line.clone(), opts.seed);
    manifest.frames = total as u64;
    manifest.extra = serde_json::json!({
        "mix": {
            "real": real.root(),
            "synth": synth.root(),
            "train_real": report.train_real,
            "train_synth": report.train_synth,
            "test": report.test,
            "excluded_shared": report.excluded_shared,
            "train_split": TRAIN_SPLIT,
            "test_split": TEST_SPLIT,
            "stratified_by": "object set",
            "provenance": PROVENANCE_FILE,
        }
    });
    if !opts.test_scenes.is_empty() {
        // The test split is these scenes' frames, not a seeded draw.
        manifest.extra["mix"]["test_scenes"] = serde_json::json!(opts
            .test_scenes
            .iter()
            .map(SceneRef::to_string)
            .collect::<Vec<_>>());
    }
    write_manifest(out, &manifest)?;
    Ok(report)
}

#[derive(Default)]
struct SceneJson {
    camera: BTreeMap<u32, SceneCamera>,
    gt: BTreeMap<u32, Vec<GtEntry>>,
    gt_info: BTreeMap<u32, Vec<GtInfo>>,
}

impl SceneJson {
    fn write(&self, dir: &Path) -> Result<()> {
        // scene_gt_info.json only when every image has its entries (readers require that).
        if self.gt_info.len() == self.camera.len() {
            write_map(
                &dir.join(synthgen_formats::bop::SCENE_GT_INFO),
                &self.gt_info,
                false,
            )?;
        }
        write_map(&dir.join(synthgen_formats::bop::SCENE_GT), &self.gt, false)?;
        write_map(
            &dir.join(synthgen_formats::bop::SCENE_CAMERA),
            &self.camera,
            false,
        )
    }
}

/// Creates `out`; refuses a non-empty folder unless `force`, which removes what a mix writes.
/// An absent or empty `out`; with `force`, one synthgen wrote, emptied (but for its lock) so
/// that nothing of the old output is left among the new mix.
fn prepare_out(out: &Path, force: bool) -> Result<()> {
    if out.exists() && !synthgen_formats::output::is_empty(out) {
        if !force {
            return Err(Error::InvalidRequest(format!(
                "output folder is not empty (use --force to replace a mix there): {}",
                out.display()
            )));
        }
        synthgen_formats::output::check_force(out)?;
        synthgen_formats::output::clear_output(out)?;
    }
    create_dir_all(out)
}

/// Hard-links `src` to `dst`, copying when linking fails (other filesystem, no support).
fn link_or_copy(src: &Path, dst: &Path, report: &mut MixReport) -> Result<()> {
    if let Some(parent) = dst.parent() {
        create_dir_all(parent)?;
    }
    if std::fs::hard_link(src, dst).is_ok() {
        report.linked += 1;
        return Ok(());
    }
    if !src.is_file() {
        return Err(Error::MissingFile {
            path: src.to_path_buf(),
        });
    }
    std::fs::copy(src, dst).map_err(|e| Error::io("copy to", dst, e))?;
    report.copied += 1;
    Ok(())
}

fn copy_frame_files(
    frame: &SourceFrame,
    dir: &Path,
    im_id: u32,
    report: &mut MixReport,
) -> Result<()> {
    let ext = frame
        .rgb
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_else(|| "png".into());
    // itodd keeps grayscale images in gray/; everything else (BOP rgb/, Linemod rgb/,
    // YCB-Video's -color files) goes to rgb/.
    let rgb_dir = match frame.rgb.parent().and_then(Path::file_name) {
        Some(n) if n == "gray" => "gray",
        _ => "rgb",
    };
    link_or_copy(
        &frame.rgb,
        &dir.join(rgb_dir).join(format!("{im_id:06}.{ext}")),
        report,
    )?;
    if let Some(depth) = &frame.depth {
        link_or_copy(
            depth,
            &dir.join("depth").join(format!("{im_id:06}.png")),
            report,
        )?;
    }
    for (folder, masks) in [("mask", &frame.masks), ("mask_visib", &frame.masks_visib)] {
        for (gt_id, mask) in masks.iter().enumerate() {
            let dst = dir.join(folder).join(format!("{im_id:06}_{gt_id:06}.png"));
            match mask {
                Some(MaskRef::File(m)) => link_or_copy(m, &dst, report)?,
                // A label image's instance becomes a BOP 0/255 mask of its own.
                Some(label @ MaskRef::Label { .. }) => {
                    let m = label.read()?;
                    create_dir_all(&dir.join(folder))?;
                    let png =
                        encode_gray8_png(&m.data, m.width, m.height, PngCompression::Fast, &dst)?;
                    atomic_write(&dst, &png)?;
                    report.copied += 1;
                }
                None => {}
            }
        }
    }
    Ok(())
}

/// Writes the frame's `mask/` (the silhouettes rendered at its poses, see
/// [`synthgen_formats::annotate::complete_annotations`]) and returns its `scene_gt_info` entries, whose
/// visible counts are those of the frame's visible masks.
fn complete_frame(
    renderer: &dyn PoseRenderer,
    frame: &SourceFrame,
    dir: &Path,
    im_id: u32,
    (w, h): (u32, u32),
) -> Result<Vec<GtInfo>> {
    let mut visib = Vec::with_capacity(frame.gt.len());
    for gt_id in 0..frame.gt.len() {
        visib.push(
            match frame.masks_visib.get(gt_id).and_then(Option::as_ref) {
                Some(m) => m.read()?.data,
                None => vec![0; (w * h) as usize],
            },
        );
    }
    write_completed_masks(renderer, frame, &visib, dir, im_id, (w, h))
}

/// Models and models_info.json: the real set's, plus the synthetic set's objects the real
/// set lacks.
fn write_models(
    real: &dyn FrameSource,
    synth: &dyn FrameSource,
    out: &Path,
    report: &mut MixReport,
) -> Result<()> {
    let mut info: BTreeMap<u32, ModelInfo> = BTreeMap::new();
    let mut files: BTreeMap<u32, &dyn FrameSource> = BTreeMap::new();
    for (name, src) in [("real", real), ("synthetic", synth)] {
        for (&id, mi) in src.models_info().into_iter().flatten() {
            match info.get(&id) {
                Some(existing) => {
                    let rel = (existing.diameter - mi.diameter).abs() / existing.diameter;
                    if rel > 0.01 {
                        report.warnings.push(format!(
                            "object {id}: the {name} model's diameter ({:.1} mm) differs from the real one ({:.1} mm); keeping the real model",
                            mi.diameter, existing.diameter
                        ));
                    }
                }
                None => {
                    info.insert(id, mi.clone());
                    if src.model_path(id).is_some() {
                        files.insert(id, src);
                    }
                }
            }
        }
    }
    if info.is_empty() {
        return Ok(());
    }
    let models = out.join("models");
    create_dir_all(&models)?;
    for (&id, &src) in &files {
        let dst = models.join(format!("obj_{id:06}.ply"));
        if write_bop_model(src, id, &dst)? {
            report.copied += 1;
        } else {
            report.linked += 1;
        }
    }
    write_map(&models.join("models_info.json"), &info, false)
}

pub mod scenes;

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests;
