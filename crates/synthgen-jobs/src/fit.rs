//! The fits that write files, as `synthgen scene fit` and `synthgen sensor fit` run them and
//! `experiment sim2real` chains them: a dataset's frames measured against its own models
//! rendered at the GT poses, the fit, and the TOML file a render reads.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use synthgen_core::scene::{DepthModel, SensorSpec, StructuredLightSpec};
use synthgen_core::{PoseRenderer, Progress};
use synthgen_fit::scene_fit::{self, spec_text, SceneFit, SceneFitOptions};
use synthgen_fit::sensor::{self, fit, measure::DepthStats, FitOptions, FitReport, MeasureOptions};
use synthgen_formats::layout::open_source;
use synthgen_formats::source::FrameSource;
use synthgen_render::ObjectRenderer;

use crate::models::{frame_obj_ids, load_models, object_renderer};
use crate::Log;

/// Fits a scene to the frames of `data` (in `scenes`, all when empty) and writes it to `out`
/// (overwriting it; its folder is created), with `[sensor] file` pointing at `sensor` when
/// given; warnings (skipped frames, several cameras) go to `printer`. Returns the fit.
pub fn fit_scene_to_file(
    data: &Path,
    scenes: &[u32],
    sensor: Option<impl AsRef<Path>>,
    out: &Path,
    progress: &dyn Progress,
) -> Result<SceneFit> {
    let printer = &Log::new(progress);
    let sensor = sensor.as_ref().map(AsRef::as_ref);
    if let Some(s) = sensor {
        SensorSpec::from_toml_file(s)
            .with_context(|| format!("cannot read the sensor file {}", s.display()))?;
    }
    let source =
        open_source(data).with_context(|| format!("cannot open dataset {}", data.display()))?;
    let frames = scene_fit::select_frames(source.as_ref(), scenes)?;
    let models: BTreeMap<_, _> = load_models(source.as_ref(), &frame_obj_ids(&frames), printer)?
        .into_iter()
        .collect();
    // The objects rendered at their GT poses: the check of the depth against them, and the
    // silhouettes of frames without `scene_gt_info` (their visib_fract).
    let renderer = ObjectRenderer::new(models.iter().map(|(&id, m)| (id, m.clone())).collect())?;
    let options = SceneFitOptions {
        scenes: scenes.to_vec(),
        ..SceneFitOptions::default()
    };
    printer.start("fitting", frames.len() as u64);
    let fit = scene_fit::fit_scene(
        source.as_ref(),
        &frames,
        &models,
        Some(&renderer as &dyn PoseRenderer),
        &options,
        printer,
    );
    printer.finish();
    let fit = fit?;
    for s in &fit.frames_skipped {
        printer.warning(format!(
            "skipped {}/{:06} image {}: {}",
            s.location.split, s.location.scene_id, s.location.im_id, s.reason
        ));
    }
    if !fit.camera.others.is_empty() {
        printer.warning(format!(
            "the frames have {} different intrinsics; the scene uses those of {} of the {} frames",
            fit.camera.others.len() + 1,
            fit.camera.frames,
            fit.frames_used
        ));
    }
    if fit.frames_plane_from_poses > 0 {
        printer.info(format!(
            "{} of the {} frames have no depth: their table planes come from the objects' lowest \
             points at the GT poses (docs/scenes.md)",
            fit.frames_plane_from_poses, fit.frames_used
        ));
    }
    if fit.frames_without_masks > 0 {
        printer.warning(format!(
            "{} frames have no visible masks for every object: their table planes were fitted to \
             the objects' depth too",
            fit.frames_without_masks
        ));
    }
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    let text = spec_text::spec_toml(&fit, out, sensor)?;
    synthgen_formats::io::atomic_write(out, text.as_bytes())?;
    if let Err(e) = spec_text::check_written(&fit, out) {
        let _ = std::fs::remove_file(out);
        return Err(e.into());
    }
    Ok(fit)
}

/// Opens a dataset and measures its frames (see `synthgen_fit::sensor::measure`).
pub fn measure(
    dir: &Path,
    scenes: &[u32],
    max_frame_residual_m: f64,
    progress: &dyn Progress,
) -> Result<(Box<dyn FrameSource>, DepthStats)> {
    let printer = &Log::new(progress);
    let source =
        open_source(dir).with_context(|| format!("cannot open dataset {}", dir.display()))?;
    let frames = sensor::select_frames(source.as_ref(), scenes)?;
    let renderer = object_renderer(source.as_ref(), &frame_obj_ids(&frames), printer)?;
    printer.start("measuring", frames.len() as u64);
    let stats = sensor::measure_frames(
        source.as_ref(),
        &frames,
        &renderer,
        &MeasureOptions {
            scenes: scenes.to_vec(),
            max_frame_residual_m,
        },
        printer,
    )?;
    printer.finish();
    Ok((source, stats))
}

/// Measures `data` (the chosen scenes), fits the structured-light model and writes the sensor
/// file `out`; frames left out are warned about. What `sensor fit` and `experiment sim2real`
/// run.
pub fn fit_sensor_to_file(
    data: &Path,
    scenes: &[u32],
    max_frame_residual_m: f64,
    base: StructuredLightSpec,
    out: &Path,
    progress: &dyn Progress,
) -> Result<FitReport> {
    let printer = &Log::new(progress);
    let (_, stats) = measure(data, scenes, max_frame_residual_m, printer)?;
    let report = fit(&stats, &FitOptions { base })?;
    for f in &report.frames_excluded {
        printer.warning(format!(
            "left out {}/{:06} image {}: median |depth - GT render| {:.1} mm > {:.0} mm (GT obviously off)",
            f.location.split,
            f.location.scene_id,
            f.location.im_id,
            f.median_abs_m * 1000.0,
            max_frame_residual_m * 1000.0
        ));
    }
    for w in &report.warnings {
        printer.warning(w);
    }
    let text = sensor_file_text(&report, data, scenes)?;
    if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    synthgen_formats::io::atomic_write(out, text.as_bytes())?;
    Ok(report)
}

/// The sensor file: provenance comments, `depth = "structured_light"` and the fitted
/// `[structured_light]` table.
fn sensor_file_text(report: &FitReport, data: &Path, scenes: &[u32]) -> Result<String> {
    let spec = SensorSpec {
        depth: DepthModel::StructuredLight,
        structured_light: report.spec.clone(),
        ..SensorSpec::default()
    };
    spec.validate()
        .context("the fit produced an invalid sensor (please report this)")?;
    let mut table = toml::Table::new();
    table.insert(
        "depth".into(),
        toml::Value::String("structured_light".into()),
    );
    table.insert(
        "structured_light".into(),
        toml::Value::try_from(&report.spec).context("cannot serialize the fitted sensor")?,
    );
    let mut text = String::new();
    let _ = writeln!(
        text,
        "# Structured-light depth sensor fitted by `synthgen sensor fit` (synthgen {}) to",
        synthgen_core::VERSION
    );
    let _ = writeln!(
        text,
        "# {} ({} frames{}, {} instances, {} object pixels; {} frames left out).",
        data.display(),
        report.frames_used,
        if scenes.is_empty() {
            String::new()
        } else {
            format!(
                ", scenes {}",
                scenes
                    .iter()
                    .map(u32::to_string)
                    .collect::<Vec<_>>()
                    .join(",")
            )
        },
        report.instances,
        report.pixels,
        report.frames_excluded.len()
    );
    for w in &report.warnings {
        let _ = writeln!(text, "# warning: {w}");
    }
    let _ = writeln!(
        text,
        "# Use it with `synthgen render --sensor FILE` or `[sensor] file = \"FILE\"` in a scene.\n# Parameters: docs/sensors.md.\n"
    );
    text.push_str(&toml::to_string_pretty(&table).context("cannot write the sensor file")?);
    // The file must read back as what was fitted.
    let back = SensorSpec::from_toml_str(&text)
        .context("the written sensor file does not read back (please report this)")?;
    if back.structured_light != report.spec {
        anyhow::bail!("the written sensor file does not read back as fitted (please report this)");
    }
    Ok(text)
}
