//! Where `synthgen render` writes: the BOP writer or the Linemod writer, behind one small
//! interface so `render.rs` stays format-agnostic.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

use anyhow::{Context, Result};
use synthgen_core::{FrameScene, Intrinsics, Model, ObjectAnnotation, RenderedFrame, Symmetries};
use synthgen_dataset::bop::{
    BopWriter, BopWriterOptions, DoneFrames, FrameRecord, ModelInfo, RgbFormat,
};
use synthgen_dataset::linemod::writer::LinemodRecord;
use synthgen_dataset::linemod::{LinemodWriter, LinemodWriterOptions, ListFile};

use crate::cli::{FormatArg, RenderArgs, RgbFormat as RgbArg};

pub enum Sink {
    Bop(BopWriter),
    Linemod(LinemodWriter),
}

pub enum Record {
    Bop(FrameRecord),
    Linemod(LinemodRecord),
}

/// What was written.
pub struct SinkSummary {
    pub frames: u64,
    pub depth_out_of_range_px: u64,
    /// "a BOP dataset to OUT (split train_pbr, 1 scene folder)" and the like.
    pub description: String,
}

/// The depth scale of `--depth-scale`, or the format's default.
pub fn depth_scale(args: &RenderArgs) -> f64 {
    args.depth_scale.unwrap_or(match args.format {
        FormatArg::Bop => 0.1,
        FormatArg::Linemod => 1.0,
    })
}

/// The writer options that shape the files, recorded in the manifest (so `--resume` and
/// `synthgen merge` can check that runs match).
pub fn dataset_options(args: &RenderArgs) -> serde_json::Value {
    serde_json::json!({
        "format": match args.format { FormatArg::Bop => "bop", FormatArg::Linemod => "linemod" },
        "split": args.split,
        "chunk_size": args.chunk_size,
        "rgb_format": match args.rgb_format { RgbArg::Png => "png", RgbArg::Jpg => "jpg" },
        "jpg_quality": args.jpg_quality,
        "depth_scale": depth_scale(args),
        "min_visib_fract": args.min_visib_fract,
    })
}

impl Sink {
    pub fn create(args: &RenderArgs, intrinsics: Intrinsics, frames: Range<u64>) -> Result<Sink> {
        Ok(match args.format {
            FormatArg::Bop => {
                let w = BopWriter::create(
                    &args.out,
                    BopWriterOptions {
                        split: args.split.clone(),
                        chunk_size: args.chunk_size,
                        rgb_format: match args.rgb_format {
                            RgbArg::Png => RgbFormat::Png,
                            RgbArg::Jpg => RgbFormat::Jpg {
                                quality: args.jpg_quality,
                            },
                        },
                        depth_scale: depth_scale(args),
                        frame_range: Some(frames),
                        merge_existing: args.resume,
                        // Every run keeps journals, so any run can be resumed after a crash.
                        journal: true,
                        ..BopWriterOptions::new(intrinsics)
                    },
                )?;
                w.write_camera_json()?;
                Sink::Bop(w)
            }
            FormatArg::Linemod => Sink::Linemod(LinemodWriter::create(
                &args.out,
                LinemodWriterOptions {
                    depth_scale: depth_scale(args),
                    min_visib_fract: args.min_visib_fract,
                    ..LinemodWriterOptions::default()
                },
            )?),
        })
    }

    /// Model PLYs in millimetres and the models_info file, once per object id.
    /// Writes `models/` and its info file; `symmetries[i]` (from the source's own
    /// models_info.json, when it had one) is carried over so symmetric objects stay symmetric.
    pub fn write_models(
        &self,
        models: &[Model],
        ids: &[u32],
        symmetries: &[Option<Symmetries>],
    ) -> Result<()> {
        let mut infos: BTreeMap<u32, ModelInfo> = BTreeMap::new();
        for (k, (m, &id)) in models.iter().zip(ids).enumerate() {
            if infos.contains_key(&id) {
                continue;
            }
            let path = match self {
                Sink::Bop(w) => w.model_ply_path(id)?,
                Sink::Linemod(w) => w.model_ply_path(id),
            };
            synthgen_assets::write_ply(&path, m, 1000.0)
                .with_context(|| format!("cannot write model {}", path.display()))?;
            let mut info = ModelInfo::from_model(m);
            if let Some(Some(sym)) = symmetries.get(k) {
                info.symmetries = sym.clone();
            }
            infos.insert(id, info);
        }
        match self {
            Sink::Bop(w) => {
                let entries: Vec<(u32, ModelInfo)> = infos.into_iter().collect();
                w.write_models_info(&entries)?;
            }
            Sink::Linemod(w) => {
                w.write_models_info(&infos)?;
            }
        }
        Ok(())
    }

    pub fn write_frame(
        &self,
        i: u64,
        scene: &FrameScene,
        frame: &RenderedFrame,
        ann: &[ObjectAnnotation],
    ) -> Result<Record> {
        Ok(match self {
            Sink::Bop(w) => Record::Bop(w.write_frame(i, scene, frame, ann)?),
            Sink::Linemod(w) => {
                let f = w.frame_from_render(scene, frame, ann)?;
                Record::Linemod(w.write_frame(&f, ListFile::Train)?)
            }
        })
    }

    /// The frames an interrupted run already wrote (BOP only; see `render_resume`).
    pub fn resume(&self) -> Result<DoneFrames> {
        match self {
            Sink::Bop(w) => Ok(w.resume()?),
            Sink::Linemod(_) => anyhow::bail!("internal error: resuming a Linemod dataset"),
        }
    }

    pub fn add_record(&self, record: Record) -> Result<()> {
        match (self, record) {
            (Sink::Bop(w), Record::Bop(r)) => {
                w.add_record(r)?;
            }
            (Sink::Linemod(w), Record::Linemod(r)) => w.add_record(r),
            _ => anyhow::bail!("internal error: a record of the other format"),
        }
        Ok(())
    }

    pub fn finish(self, out: &Path) -> Result<SinkSummary> {
        let plural = |n: usize, w: &str| format!("{n} {w}{}", if n == 1 { "" } else { "s" });
        Ok(match self {
            Sink::Bop(w) => {
                let split = w.options().split.clone();
                let s = w.finish()?;
                SinkSummary {
                    frames: s.frames,
                    depth_out_of_range_px: s.depth_out_of_range_px,
                    description: format!(
                        "a BOP dataset to {} (split {split}, {})",
                        out.display(),
                        plural(s.scenes.len(), "scene folder")
                    ),
                }
            }
            Sink::Linemod(w) => {
                let s = w.finish()?;
                SinkSummary {
                    frames: s.frames,
                    depth_out_of_range_px: s.depth_out_of_range_px,
                    description: format!(
                        "a Linemod dataset to {} ({} under data/)",
                        out.display(),
                        plural(s.folders.len(), "object folder")
                    ),
                }
            }
        })
    }
}
