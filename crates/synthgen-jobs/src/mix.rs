//! A mix as `synthgen mix` writes it: the output's guards (apart from both inputs, locked),
//! both datasets opened, the frames YCB-Video and Linemod sets lack (`mask/`,
//! `scene_gt_info`) computed from their poses and models, `synthgen_curate::mix::write_mix`,
//! and the summary.

use std::path::Path;

use anyhow::{Context, Result};
use synthgen_core::{PoseRenderer, Progress};
use synthgen_curate::mix::{write_mix, Completion, MixOptions, MixReport, PROVENANCE_FILE};
use synthgen_formats::layout::open_source;
use synthgen_formats::output::{check_apart, OutputLock};
use synthgen_formats::source::FrameSource;
use synthgen_render::ObjectRenderer;

use crate::models::{frame_obj_ids, object_renderer};
use crate::{user_error, Log};

/// Mixes `real` and `synth` into `out` with `opts`; warnings and the summary go to `progress`.
pub fn mix_datasets(
    real: &Path,
    synth: &Path,
    out: &Path,
    opts: &MixOptions,
    progress: &dyn Progress,
) -> Result<MixReport> {
    let printer = &Log::new(progress);
    check_apart(out, &[("real dataset", real), ("synthetic dataset", synth)])?;
    let _lock = OutputLock::acquire(out)?;
    let real_ds = open_source(real).context("cannot open the real dataset")?;
    let synth_ds = open_source(synth).context("cannot open the synthetic dataset")?;
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
        out,
        opts,
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
    let held_out = if opts.test_scenes.is_empty() {
        String::new()
    } else {
        format!(
            " (every frame of scene(s) {})",
            synthgen_curate::mix::scene_list(&opts.test_scenes)
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
    Ok(report)
}

/// A renderer of the dataset's objects when some of its frames lack scene_gt_info (a
/// YCB-Video or Linemod set), else `None`.
fn completion_renderer(source: &dyn FrameSource, printer: &Log) -> Result<Option<ObjectRenderer>> {
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
