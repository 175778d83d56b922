//! Depth sensors against real frames: [`fit`] fits the structured-light model
//! (`synthgen_core::scene::StructuredLightSpec`) to a dataset's depth readings, [`compare`]
//! tells how close two datasets' readings are (real frames and their replay through a sensor
//! model, usually). Both work on what [`measure`] collects: every frame's objects rendered at
//! their GT poses by a [`PoseRenderer`] (the clean depth), and the dataset's own readings on
//! those object pixels. Method and numbers: docs/sensors.md.

pub mod compare;
pub mod fit;
pub mod measure;
mod optimize;
pub mod plot;

use rayon::prelude::*;
use synthgen_core::{PoseRenderer, Progress};

pub use compare::{compare, Aspect, Comparison};
pub use fit::{fit, FitOptions, FitReport};
pub use measure::DepthStats;

use synthgen_formats::source::{FrameSource, SourceFrame};
use synthgen_formats::{Error, Result};

/// Which frames to measure and how to treat frames with obviously wrong GT.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasureOptions {
    /// Only these scene ids (all when empty).
    pub scenes: Vec<u32>,
    /// A frame whose median |reading − clean depth| over its object pixels exceeds this is
    /// left out (and listed); `f64::INFINITY` keeps every frame.
    pub max_frame_residual_m: f64,
}

impl Default for MeasureOptions {
    fn default() -> Self {
        MeasureOptions {
            scenes: Vec::new(),
            max_frame_residual_m: f64::INFINITY,
        }
    }
}

/// The frames of `source` to measure: those with GT in the chosen scenes. Errors when the
/// dataset has no annotated frame there, or a chosen scene does not exist.
pub fn select_frames(source: &dyn FrameSource, scenes: &[u32]) -> Result<Vec<SourceFrame>> {
    select_frames_for(
        source,
        scenes,
        "fitting and comparing sensors needs objects at known poses",
        Some("fitting and comparing sensors needs the depth readings"),
    )
}

/// [`select_frames`] with the errors' reasons (`why_gt`, `why_depth`: what needs the GT
/// poses and the depth images) given by the caller; `why_depth` None: depth is optional.
pub(crate) fn select_frames_for(
    source: &dyn FrameSource,
    scenes: &[u32],
    why_gt: &str,
    why_depth: Option<&str>,
) -> Result<Vec<SourceFrame>> {
    let all = source.frames(&[])?;
    if all.is_empty() {
        return Err(Error::InvalidRequest(format!(
            "{} has no frames",
            source.root().display()
        )));
    }
    let mut known: Vec<u32> = all.iter().map(|f| f.location.scene_id).collect();
    known.sort_unstable();
    known.dedup();
    for s in scenes {
        if !known.contains(s) {
            return Err(Error::InvalidRequest(format!(
                "scene {s} is not in {} (scenes: {})",
                source.root().display(),
                known
                    .iter()
                    .map(u32::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
    }
    let frames: Vec<SourceFrame> = all
        .into_iter()
        .filter(|f| scenes.is_empty() || scenes.contains(&f.location.scene_id))
        .filter(|f| !f.gt.is_empty())
        .collect();
    if frames.is_empty() {
        return Err(Error::InvalidRequest(format!(
            "{} has no frame with GT poses{}: {why_gt}",
            source.root().display(),
            if scenes.is_empty() {
                String::new()
            } else {
                " in the chosen scenes".into()
            }
        )));
    }
    if let (Some(why_depth), Some(f)) = (why_depth, frames.iter().find(|f| f.depth.is_none())) {
        return Err(Error::InvalidRequest(format!(
            "{} has no depth images ({}/{:06} image {} has none): {why_depth}",
            source.root().display(),
            f.location.split,
            f.location.scene_id,
            f.location.im_id
        )));
    }
    Ok(frames)
}

/// Measures `frames` of `source` (see [`measure`]) in parallel, one `progress` step per frame.
pub fn measure_frames(
    source: &dyn FrameSource,
    frames: &[SourceFrame],
    renderer: &dyn PoseRenderer,
    options: &MeasureOptions,
    progress: &dyn Progress,
) -> Result<DepthStats> {
    let cam = source.camera();
    let parts: Vec<DepthStats> = frames
        .par_iter()
        .map(|f| {
            let view = measure::frame_view(renderer, f, cam.width, cam.height)?;
            let (st, _) = measure::measure_frame(&view, &f.location, options.max_frame_residual_m);
            progress.advance(1);
            Ok(st)
        })
        .collect::<Result<_>>()?;
    let mut total = DepthStats::default();
    for p in &parts {
        total.merge(p);
    }
    total
        .frame_residuals
        .sort_by(|a, b| a.location.cmp(&b.location));
    Ok(total)
}
