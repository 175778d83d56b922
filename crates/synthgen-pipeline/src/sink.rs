//! Where a job writes: the BOP, Linemod or YCB-Video writer, behind one small interface so
//! the write loop (and `render --replay`) stays format-agnostic.

use std::collections::BTreeMap;
use std::ops::Range;
use std::path::Path;

use synthgen_core::{FrameScene, Intrinsics, Model, ObjectAnnotation, RenderedFrame, Symmetries};
use synthgen_formats::bop::{
    BopWriter, BopWriterOptions, DoneFrames, FrameRecord, ModelInfo, RgbFormat,
};
use synthgen_formats::linemod::writer::LinemodRecord;
use synthgen_formats::linemod::{LinemodWriter, LinemodWriterOptions, ListFile};
use synthgen_formats::ycbv::{YcbvFrame, YcbvObject, YcbvPose, YcbvWriter, YcbvWriterOptions};

use crate::error::{Error, Result};

/// Dataset layouts.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// bop_toolkit / BlenderProc.
    Bop,
    /// DenseFusion's Linemod_preprocessed.
    Linemod,
    /// YCB-Video (PoseCNN, DenseFusion).
    Ycbv,
}

/// How RGB images are encoded.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    Png,
    Jpg,
}

/// The options that shape a dataset's files.
#[derive(Debug, Clone, PartialEq)]
pub struct SinkOptions {
    pub format: Format,
    /// BOP's split folder (`train_pbr`), YCB-Video's image set.
    pub split: String,
    /// Frames per scene folder: frame `i` is image `i % chunk_size` of scene `i / chunk_size`.
    pub chunk_size: u32,
    pub rgb_format: ImageFormat,
    /// 1..=100, for `ImageFormat::Jpg`.
    pub jpg_quality: u8,
    /// Depth PNG value × this = millimetres; `None`: the format's default
    /// ([`depth_scale`](Self::depth_scale)).
    pub depth_scale: Option<f64>,
    /// Linemod lists only instances at least this visible.
    pub min_visib_fract: f64,
}

impl SinkOptions {
    /// The format's defaults: split `train_pbr`, 1000 frames per scene folder, PNG.
    pub fn new(format: Format) -> SinkOptions {
        SinkOptions {
            format,
            split: "train_pbr".into(),
            chunk_size: 1000,
            rgb_format: ImageFormat::Png,
            jpg_quality: 95,
            depth_scale: None,
            min_visib_fract: 0.1,
        }
    }

    /// The depth scale given, or the format's default (0.1 mm for BOP and YCB-Video, 1 mm
    /// for Linemod).
    pub fn depth_scale(&self) -> f64 {
        self.depth_scale.unwrap_or(match self.format {
            Format::Bop | Format::Ycbv => 0.1,
            Format::Linemod => 1.0,
        })
    }

    /// The options as recorded in the manifest (so `--resume` and `synthgen merge` can check
    /// that runs match).
    pub fn manifest_json(&self) -> serde_json::Value {
        serde_json::json!({
            "format": match self.format {
                Format::Bop => "bop",
                Format::Linemod => "linemod",
                Format::Ycbv => "ycbv",
            },
            "split": self.split,
            "chunk_size": self.chunk_size,
            "rgb_format": match self.rgb_format { ImageFormat::Png => "png", ImageFormat::Jpg => "jpg" },
            "jpg_quality": self.jpg_quality,
            "depth_scale": self.depth_scale(),
            "min_visib_fract": self.min_visib_fract,
        })
    }
}

pub enum Sink {
    Bop(BopWriter),
    Linemod(LinemodWriter),
    Ycbv(YcbvSink),
}

/// What a sink returns for a written frame, for [`Sink::add_record`] in frame order.
pub enum Record {
    Bop(FrameRecord),
    Linemod(LinemodRecord),
    Ycbv,
}

/// The YCB-Video writer and how frame indices become (scene, image) ids.
pub struct YcbvSink {
    writer: YcbvWriter,
    split: String,
    chunk_size: u32,
}

/// What was written.
#[derive(Debug, Clone, PartialEq)]
pub struct SinkSummary {
    pub frames: u64,
    pub depth_out_of_range_px: u64,
    /// "a BOP dataset to OUT (split train_pbr, 1 scene folder)" and the like.
    pub description: String,
}

/// Where a sink puts frames: frame `i` goes to scene `i / chunk_size`, image
/// `i % chunk_size` of `split`.
pub struct Layout {
    pub split: String,
    pub chunk_size: u32,
    /// The frames this run writes, when known (a BOP scene folder's JSON is then written as
    /// soon as its last one is in); `None`: at finish. A known range also keeps journals, so
    /// the run can be resumed.
    pub frames: Option<Range<u64>>,
}

impl Sink {
    /// A sink for `out` with the layout of `options` and `frames`. `classes`: the YCB-Video
    /// class list (line i = obj_id i), for `Format::Ycbv`. `resume`: a BOP writer merges
    /// with what an interrupted run wrote.
    pub fn create(
        out: &Path,
        options: &SinkOptions,
        resume: bool,
        intrinsics: Intrinsics,
        frames: Range<u64>,
        classes: &[String],
    ) -> Result<Sink> {
        let layout = Layout {
            split: options.split.clone(),
            chunk_size: options.chunk_size,
            frames: Some(frames),
        };
        Sink::create_with(out, options, resume, intrinsics, layout, classes)
    }

    /// [`create`](Self::create) with the split and numbering given.
    pub fn create_with(
        out: &Path,
        options: &SinkOptions,
        resume: bool,
        intrinsics: Intrinsics,
        layout: Layout,
        classes: &[String],
    ) -> Result<Sink> {
        Ok(match options.format {
            Format::Bop => {
                let journal = layout.frames.is_some();
                let w = BopWriter::create(
                    out,
                    BopWriterOptions {
                        split: layout.split,
                        chunk_size: layout.chunk_size,
                        rgb_format: match options.rgb_format {
                            ImageFormat::Png => RgbFormat::Png,
                            ImageFormat::Jpg => RgbFormat::Jpg {
                                quality: options.jpg_quality,
                            },
                        },
                        depth_scale: options.depth_scale(),
                        frame_range: layout.frames,
                        merge_existing: resume,
                        // Every run over a known range keeps journals, so it can be resumed
                        // after a crash.
                        journal,
                        ..BopWriterOptions::new(intrinsics)
                    },
                )?;
                w.write_camera_json()?;
                Sink::Bop(w)
            }
            Format::Linemod => Sink::Linemod(LinemodWriter::create(
                out,
                LinemodWriterOptions {
                    depth_scale: options.depth_scale(),
                    min_visib_fract: options.min_visib_fract,
                    ..LinemodWriterOptions::default()
                },
            )?),
            Format::Ycbv => {
                if layout.chunk_size == 0 {
                    // Kept an internal error (exit code 2), as the CLI has always answered it.
                    return Err(Error::Internal("--chunk-size must be at least 1".into()));
                }
                Sink::Ycbv(YcbvSink {
                    writer: YcbvWriter::create(
                        out,
                        classes.to_vec(),
                        YcbvWriterOptions {
                            factor_depth: 1000.0 / options.depth_scale(),
                            ..YcbvWriterOptions::default()
                        },
                    )?,
                    split: layout.split,
                    chunk_size: layout.chunk_size,
                })
            }
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
                Sink::Ycbv(y) => {
                    y.writer.write_model(id, m)?;
                    infos.insert(id, ModelInfo::from_model(m));
                    continue;
                }
            };
            synthgen_assets::write_ply(&path, m, 1000.0).map_err(|e| Error::WriteModel {
                path,
                source: Box::new(e),
            })?;
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
            // YCB-Video has no models_info; its evaluation uses points.xyz.
            Sink::Ycbv(_) => {}
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
        self.write_frame_in(None, i, scene, frame, ann)
    }

    /// [`write_frame`](Self::write_frame) into `split` instead of the layout's: YCB-Video
    /// lists it in `image_sets/<split>.txt`; a BOP writer has one split (asking for another
    /// is a bug) and Linemod none.
    pub fn write_frame_in(
        &self,
        split: Option<&str>,
        i: u64,
        scene: &FrameScene,
        frame: &RenderedFrame,
        ann: &[ObjectAnnotation],
    ) -> Result<Record> {
        Ok(match self {
            Sink::Bop(w) => {
                if split.is_some_and(|s| s != w.options().split) {
                    return Err(Error::Internal(
                        "internal error: a frame for another split's BOP writer".into(),
                    ));
                }
                Record::Bop(w.write_frame(i, scene, frame, ann)?)
            }
            Sink::Linemod(w) => {
                let f = w.frame_from_render(scene, frame, ann)?;
                Record::Linemod(w.write_frame(&f, ListFile::Train)?)
            }
            Sink::Ycbv(y) => {
                let mut f = y.frame_from_render(i, scene, frame)?;
                if let Some(s) = split {
                    f.split = s.to_string();
                }
                y.writer.write_frame(&f)?;
                Record::Ycbv
            }
        })
    }

    /// The frames an interrupted run already wrote (BOP only; see `render_resume`).
    pub fn resume(&self) -> Result<DoneFrames> {
        match self {
            Sink::Bop(w) => Ok(w.resume()?),
            Sink::Linemod(_) | Sink::Ycbv(_) => Err(Error::Internal(
                "internal error: resuming a Linemod or YCB-Video dataset".into(),
            )),
        }
    }

    pub fn add_record(&self, record: Record) -> Result<()> {
        match (self, record) {
            (Sink::Bop(w), Record::Bop(r)) => {
                w.add_record(r)?;
            }
            (Sink::Linemod(w), Record::Linemod(r)) => w.add_record(r),
            (Sink::Ycbv(_), Record::Ycbv) => {}
            _ => {
                return Err(Error::Internal(
                    "internal error: a record of the other format".into(),
                ))
            }
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
            Sink::Ycbv(y) => {
                let overflow = y.depth_out_of_range_px();
                let s = y.writer.finish()?;
                SinkSummary {
                    frames: s.frames,
                    depth_out_of_range_px: overflow,
                    description: format!(
                        "a YCB-Video dataset to {} ({} under data/)",
                        out.display(),
                        plural(s.scenes, "scene folder")
                    ),
                }
            }
        })
    }
}

impl YcbvSink {
    fn depth_out_of_range_px(&self) -> u64 {
        self.writer.depth_out_of_range_px()
    }

    /// A rendered frame in YCB-Video's terms: the label from the instance ids (distractors are
    /// 0 there), the vertmap from each object's own clean depth (the sensor model only touched
    /// the frame's `depth_m`), scene `i / chunk_size`, image `i % chunk_size`.
    fn frame_from_render(
        &self,
        i: u64,
        scene: &FrameScene,
        frame: &RenderedFrame,
    ) -> Result<YcbvFrame> {
        let k = &scene.intrinsics;
        let (w, h) = (frame.width, frame.height);
        let cs = u64::from(self.chunk_size);
        let scene_id = u32::try_from(i / cs)
            .map_err(|e| Error::Internal(format!("scene id over u32: {e}")))?;
        let ids: Vec<u8> = scene
            .objects
            .iter()
            .map(|o| u8::try_from(o.obj_id))
            .collect::<Result<_, _>>()
            .map_err(|_| {
                Error::Internal(
                    "object ids over 255 do not fit YCB-Video's 8-bit label image".into(),
                )
            })?;
        let label: Vec<u8> = frame
            .instance
            .iter()
            .map(|&v| {
                if v == 0 {
                    0
                } else {
                    ids.get(usize::from(v) - 1).copied().unwrap_or(0)
                }
            })
            .collect();
        let obj_from_cam: Vec<_> = scene
            .objects
            .iter()
            .map(|o| o.cam_from_obj.inverse())
            .collect();
        let mut vertmap = vec![0f32; label.len() * 3];
        for (p, &v) in frame.instance.iter().enumerate() {
            if v == 0 {
                continue;
            }
            let o = usize::from(v) - 1;
            let (x, y) = ((p % w as usize) as i32, (p / w as usize) as i32);
            let z = frame.alone.get(o).map_or(0.0, |a| a.at(x, y));
            if z > 0.0 {
                let q = obj_from_cam[o].transform_point(k.back_project(
                    f64::from(x),
                    f64::from(y),
                    f64::from(z),
                ));
                vertmap[3 * p..3 * p + 3].copy_from_slice(&q.as_vec3().to_array());
            }
        }
        let depth = self.writer.depth_values(&frame.depth_m);
        Ok(YcbvFrame {
            split: self.split.clone(),
            scene_id,
            im_id: (i % cs) as u32,
            width: w,
            height: h,
            rgb: frame.rgb.clone(),
            depth,
            label,
            vertmap,
            cam_k: k.k_row_major(),
            cam_from_world: Some(YcbvPose::from_pose(&scene.world_from_cam.inverse())),
            objects: scene
                .objects
                .iter()
                .map(|o| YcbvObject {
                    obj_id: o.obj_id,
                    pose: YcbvPose::from_pose(&o.cam_from_obj),
                })
                .collect(),
        })
    }
}
