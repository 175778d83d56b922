//! [`PreparedJob::write`]: the job's frames into a BOP, Linemod or YCB-Video folder, with
//! the models, the manifest, resume journals and per-frame failures recorded, not fatal.

use std::path::PathBuf;

use rayon::prelude::*;
use synthgen_core::Progress;
use synthgen_formats::manifest::{write_manifest, Manifest};

use crate::error::{Error, Result};
use crate::job::PreparedJob;
use crate::objects;
use crate::resume;
use crate::sink::{Format, Sink, SinkOptions};

/// Where and how [`PreparedJob::write`] writes.
#[derive(Debug, Clone, PartialEq)]
pub struct WriteOptions {
    /// The dataset folder. The caller checks it is empty (or meant to be written into) and
    /// holds its `OutputLock`.
    pub out: PathBuf,
    pub sink: SinkOptions,
    /// Continue an interrupted BOP write from its journals (the run plan must match).
    pub resume: bool,
    /// Stop at the first failed frame instead of recording it and going on.
    pub fail_fast: bool,
    /// Recorded in the manifest: the command that made the dataset, program name first.
    pub command_line: Vec<String>,
    /// Recorded in the manifest: the first frame of the whole run, of which this job's
    /// frames may be a shard; `None`: the job's first frame.
    pub first_frame: Option<u64>,
    /// Recorded in the manifest: this job as shard `index` (0-based) of `count`.
    pub shard: Option<[u64; 2]>,
}

impl WriteOptions {
    pub fn new(out: impl Into<PathBuf>, sink: SinkOptions) -> WriteOptions {
        WriteOptions {
            out: out.into(),
            sink,
            resume: false,
            fail_fast: false,
            command_line: Vec::new(),
            first_frame: None,
            shard: None,
        }
    }
}

/// What [`PreparedJob::write`] did.
#[derive(Debug)]
pub struct WriteReport {
    /// Frames in the dataset: this run's, and with `resume` those an earlier run wrote.
    pub written: u64,
    /// Frames this run rendered and wrote.
    pub rendered: u64,
    /// Frames that failed, in frame order, with why (the run went on unless `fail_fast`).
    pub failures: Vec<(u64, Error)>,
    /// Written frames in which no target is visible at all (every `visib_fract` 0).
    pub nothing_visible: Vec<u64>,
    /// Frames whose physics did not settle and kept the non-physics placement, with why.
    pub physics_fallbacks: Vec<(u64, String)>,
    /// Frames whose targets did not fit on the first draw: placed on another draw, or with
    /// fewer targets (`synthgen_core::sample::Resample`).
    pub resampled: Vec<synthgen_core::sample::Resample>,
    /// Depth pixels beyond what the format's 16-bit depth holds, written as 0.
    pub depth_out_of_range_px: u64,
    /// "a BOP dataset to OUT (split train_pbr, 1 scene folder)" and the like.
    pub description: String,
    /// Frames an interrupted run had written before this one resumed it.
    pub resumed: u64,
}

/// `e` and its causes, joined by ": " (as `anyhow` prints `{:#}`).
pub fn error_chain(e: &(dyn std::error::Error + 'static)) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        text.push_str(": ");
        text.push_str(&c.to_string());
        cause = c.source();
    }
    text
}

impl PreparedJob {
    /// Renders the job's frames into `options.out`: what `synthgen render` does. Progress:
    /// one `start("rendering", n)`, an `advance(1)` per frame, a `warn` per failed frame.
    pub fn write(&self, options: &WriteOptions, progress: &dyn Progress) -> Result<WriteReport> {
        let range = self.frames.clone();
        let out = &options.out;
        let writer = Sink::create(
            out,
            &options.sink,
            options.resume,
            self.intrinsics,
            range.clone(),
            &objects::ycbv_classes(&self.sources, &self.ids),
        )?;
        let mut manifest = self.base_manifest(options)?;
        let done = resume::begin(out, options.resume, &manifest, &writer, range.clone())?;
        writer.write_models(&self.target_models, &self.ids, &self.symmetries)?;

        let range_len = range.end - range.start;
        if done.count() > 0 {
            progress.info(&format!(
                "resuming: {} of {range_len} frames already written",
                done.count()
            ));
        }
        progress.start("rendering", range_len - done.count());
        let mut todo = range.clone().filter(|&i| !done.is_done(i));
        let mut failures: Vec<(u64, Error)> = Vec::new();
        let mut rendered: u64 = 0;
        let mut nothing_visible: Vec<u64> = Vec::new();
        // Batches bound memory (a frame's buffers are dropped once it is written) while
        // giving every thread several frames to work on.
        let batch = (self.pool.current_num_threads() * 8).max(8);
        'outer: loop {
            let batch_frames: Vec<u64> = todo.by_ref().take(batch).collect();
            if batch_frames.is_empty() {
                break;
            }
            let results: Vec<(u64, Result<_>)> = self.pool.install(|| {
                batch_frames
                    .par_iter()
                    .map(|&i| {
                        let r = (|| {
                            let (scene, frame, ann) = self.render(i)?;
                            let rec = writer.write_frame(i, &scene, &frame, &ann)?;
                            progress.advance(1);
                            // What was written is checked: a frame in which no target is
                            // visible is counted (wrong units or distances make all so).
                            let visible = ann.iter().any(|a| a.info.px_count_visib > 0);
                            Ok((rec, visible))
                        })();
                        (i, r)
                    })
                    .collect()
            });
            for (i, r) in results {
                match r {
                    // Records arrive in frame order; a scene folder's JSON is written as soon
                    // as its last frame of this run is in.
                    Ok((rec, visible)) => {
                        writer.add_record(rec)?;
                        rendered += 1;
                        if !visible {
                            nothing_visible.push(i);
                        }
                    }
                    Err(e) => {
                        progress.warn(&format!("frame {i} failed: {}", error_chain(&e)));
                        failures.push((i, e));
                        if options.fail_fast {
                            break 'outer;
                        }
                    }
                }
            }
        }
        let summary = writer.finish(out)?;
        progress.finish();
        let fallbacks = self.sampler.physics_fallbacks();
        let resampled = self.sampler.resamples();
        // Frames in the dataset: those an earlier, interrupted run wrote and this run's.
        let written = if options.sink.format == Format::Bop {
            done.count() + rendered
        } else {
            summary.frames
        };

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
            // Recorded only when it happened, so that other manifests stay as they were.
            if !resampled.is_empty() {
                extra.insert(
                    "resampled_frames".into(),
                    serde_json::to_value(&resampled).unwrap_or_default(),
                );
            }
        }
        write_manifest(out, &manifest)?;
        resume::end(out)?;
        Ok(WriteReport {
            written,
            rendered,
            failures,
            nothing_visible,
            physics_fallbacks: fallbacks,
            resampled,
            depth_out_of_range_px: summary.depth_out_of_range_px,
            description: summary.description,
            resumed: done.count(),
        })
    }

    /// The manifest of this run before any frame is rendered (frames 0, no failures).
    fn base_manifest(&self, options: &WriteOptions) -> Result<Manifest> {
        let range = &self.frames;
        let mut manifest = Manifest::new(options.command_line.clone(), self.seed);
        manifest.backend = self.backend.name().into();
        manifest.scene_spec = serde_json::to_value(&self.spec).map_err(|e| Error::Serialize {
            what: "the scene spec",
            source: e,
        })?;
        let mut extra = serde_json::json!({
            "first_frame": options.first_frame.unwrap_or(range.start),
            "frame_range": [range.start, range.end],
            "objects": self.sources.iter().zip(&self.ids).map(|(s, id)| serde_json::json!({
                "path": s.path, "obj_id": id, "count": s.count,
            })).collect::<Vec<_>>(),
            "visib_delta_m": self.visib_delta_m,
            "dataset": options.sink.manifest_json(),
            "failed_frames": [],
            "physics_fallback_frames": [],
        });
        if let (Some([index, count]), Some(o)) = (options.shard, extra.as_object_mut()) {
            o.insert(
                "shard".into(),
                serde_json::json!({"index": index, "count": count}),
            );
        }
        manifest.extra = extra;
        Ok(manifest)
    }
}

#[cfg(test)]
mod tests {
    use synthgen_core::NoProgress;
    use synthgen_formats::bop::image::depth_to_png_values;
    use synthgen_formats::bop::reader::{read_scene_gt, read_scene_gt_info};

    use super::*;
    use crate::test_support::job;

    fn png(path: &std::path::Path) -> image::DynamicImage {
        image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    }

    #[test]
    fn written_frames_are_the_frames_in_memory() {
        let j = job(0..3, 2);
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("bop");
        let options = WriteOptions::new(&out, SinkOptions::new(Format::Bop));
        let report = j.write(&options, &NoProgress).unwrap();
        assert_eq!((report.written, report.failures.len()), (3, 0));

        let scene = out.join("train_pbr/000000");
        let gt = read_scene_gt(&scene.join("scene_gt.json")).unwrap();
        let info = read_scene_gt_info(&scene.join("scene_gt_info.json")).unwrap();
        for f in j.frames().map(Result::unwrap) {
            let im = f.index as u32;
            let name = |sub: &str| scene.join(sub).join(format!("{im:06}.png"));
            assert_eq!(png(&name("rgb")).to_rgb8().into_raw(), f.rgb);
            let (depth, _) = depth_to_png_values(&f.depth_m, options.sink.depth_scale());
            assert_eq!(png(&name("depth")).to_luma16().into_raw(), depth);
            assert_eq!(gt[&im].len(), f.objects.len());
            for (k, o) in f.objects.iter().enumerate() {
                let mask = |sub: &str| {
                    png(&scene.join(sub).join(format!("{im:06}_{k:06}.png")))
                        .to_luma8()
                        .into_raw()
                };
                assert_eq!(mask("mask"), o.mask);
                assert_eq!(mask("mask_visib"), o.mask_visib);
                let i = info[&im][k];
                assert_eq!(
                    (i.bbox_obj, i.bbox_visib, i.px_count_all, i.px_count_valid),
                    (
                        o.info.bbox_obj,
                        o.info.bbox_visib,
                        o.info.px_count_all,
                        o.info.px_count_valid
                    )
                );
                assert_eq!(i.px_count_visib, o.info.px_count_visib);
                assert!((i.visib_fract - o.info.visib_fract).abs() < 1e-9);
                assert_eq!(gt[&im][k].obj_id, o.obj_id);
                let t_mm = gt[&im][k].cam_t_m2c;
                for (a, b) in t_mm.iter().zip(o.cam_from_obj.translation_m.to_array()) {
                    assert!((a - 1000.0 * b).abs() < 1e-6, "{a} vs {b} m");
                }
            }
        }
    }
}
