//! Writing BOP datasets the way BlenderProc's BOP writer lays them out: frames are split
//! into scene folders of `chunk_size` images, every file is written atomically, and frames
//! may be written from several threads at once.

use std::collections::{BTreeMap, BTreeSet, HashSet};
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Mutex, MutexGuard};

use synthgen_core::{FrameScene, Intrinsics, ObjectAnnotation, RenderedFrame};

use super::chunk::{bop_json_text, ChunkAnnotations, FrameRecord};
use super::image::{
    depth_to_png_values, encode_gray16_png, encode_gray8_png, encode_rgb_jpeg, encode_rgb_png,
    PngCompression, RgbFormat,
};
use super::journal;
use super::json::save_json_object;
use super::types::{no_negative_zero, CameraInfo, GtEntry, ModelInfo, SceneCamera};
use crate::error::{Error, Result};
use crate::io::{atomic_write, create_dir_all, remove_stale_temp_files};

/// Options of a [`BopWriter`].
#[derive(Debug, Clone, PartialEq)]
pub struct BopWriterOptions {
    /// Split folder name (`train_pbr`, as BlenderProc names rendered training data).
    pub split: String,
    /// Images per scene folder: frame `i` goes to scene `i / chunk_size`, image
    /// `i % chunk_size`. Frame indices are global, so shards of one run never collide.
    pub chunk_size: u32,
    pub rgb_format: RgbFormat,
    /// Depth PNG value × `depth_scale` = millimetres. 0.1 (BlenderProc's PBR datasets) gives
    /// 0.1 mm steps up to 6.5535 m; 1.0 gives 1 mm steps up to 65.535 m.
    pub depth_scale: f64,
    pub png_compression: PngCompression,
    /// The camera written to `camera.json`; frames carry their own K in `scene_camera.json`.
    pub intrinsics: Intrinsics,
    /// The frame indices this run will write, when known. A scene folder's JSON is then
    /// written as soon as its last frame of this range arrives; otherwise when the folder
    /// holds `chunk_size` images, or at [`BopWriter::finish`].
    pub frame_range: Option<Range<u64>>,
    /// Keep the images of scene folders already on disk (resume): a folder's existing JSON
    /// entries are read when its first new frame arrives and rewritten with the new ones.
    pub merge_existing: bool,
    /// fsync the scene JSON files before renaming them into place.
    pub fsync_json: bool,
    /// Record every added frame in its scene folder's journal (see [`super::journal`]) so an
    /// interrupted run can be resumed with [`BopWriter::resume`].
    pub journal: bool,
}

impl BopWriterOptions {
    pub fn new(intrinsics: Intrinsics) -> BopWriterOptions {
        BopWriterOptions {
            split: "train_pbr".into(),
            chunk_size: 1000,
            rgb_format: RgbFormat::Png,
            depth_scale: 0.1,
            png_compression: PngCompression::default(),
            intrinsics,
            frame_range: None,
            merge_existing: false,
            fsync_json: false,
            journal: false,
        }
    }

    fn validate(&self) -> Result<()> {
        let bad = |m: String| Err(Error::InvalidOptions(m));
        if self.split.is_empty()
            || self.split.starts_with('.')
            || self.split.contains(['/', '\\'])
            || self.split.starts_with("models")
        {
            return bad(format!(
                "split name {:?} is not a plain folder name",
                self.split
            ));
        }
        if self.chunk_size == 0 {
            return bad("chunk_size must be at least 1".into());
        }
        if !(self.depth_scale.is_finite() && self.depth_scale > 0.0) {
            return bad(format!(
                "depth_scale must be positive, got {}",
                self.depth_scale
            ));
        }
        if let RgbFormat::Jpg { quality } = self.rgb_format {
            if !(1..=100).contains(&quality) {
                return bad(format!("JPEG quality must be 1..=100, got {quality}"));
            }
        }
        self.intrinsics
            .validate()
            .map_err(|e| Error::InvalidOptions(e.to_string()))
    }
}

/// What [`BopWriter::finish`] reports.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WriteSummary {
    /// Records added (frames whose annotations were written).
    pub frames: u64,
    /// Scene folders whose JSON was written, sorted.
    pub scenes: Vec<u32>,
    /// Depth pixels beyond 16 bits at the chosen `depth_scale`, written as 0.
    pub depth_out_of_range_px: u64,
}

#[derive(Default)]
struct Chunks {
    open: BTreeMap<u32, ChunkAnnotations>,
    written: BTreeSet<u32>,
}

/// Writes a BOP dataset. `write_frame` and `add_record` take `&self` and may be called from
/// many threads at once.
///
/// Files are written atomically, so a crash never leaves a truncated file under its final
/// name; a scene folder's JSON lists only frames whose record was added before it was written.
pub struct BopWriter {
    root: PathBuf,
    split_dir: PathBuf,
    opts: BopWriterOptions,
    scene_dirs: Mutex<HashSet<u32>>,
    chunks: Mutex<Chunks>,
    frames: AtomicU64,
    depth_out_of_range_px: AtomicU64,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic in another thread while holding the lock leaves plain data in a usable state.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

const IMAGE_DIRS: [&str; 4] = ["rgb", "depth", "mask", "mask_visib"];

impl BopWriter {
    /// Creates `root/{split}`.
    pub fn create(root: &Path, opts: BopWriterOptions) -> Result<BopWriter> {
        opts.validate()?;
        let split_dir = root.join(&opts.split);
        create_dir_all(&split_dir)?;
        Ok(BopWriter {
            root: root.to_path_buf(),
            split_dir,
            opts,
            scene_dirs: Mutex::default(),
            chunks: Mutex::default(),
            frames: AtomicU64::new(0),
            depth_out_of_range_px: AtomicU64::new(0),
        })
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    pub fn options(&self) -> &BopWriterOptions {
        &self.opts
    }

    /// `(scene_id, im_id)` of a global frame index.
    pub fn frame_location(&self, frame_index: u64) -> Result<(u32, u32)> {
        let cs = self.opts.chunk_size as u64;
        let scene = u32::try_from(frame_index / cs).map_err(|_| Error::InvalidFrame {
            frame_index,
            message: format!("scene id over u32 with chunk_size {cs}"),
        })?;
        Ok((scene, (frame_index % cs) as u32))
    }

    /// `root/{split}/{scene_id:06d}`.
    pub fn scene_dir(&self, scene_id: u32) -> PathBuf {
        self.split_dir.join(format!("{scene_id:06}"))
    }

    /// Writes `camera.json` at the root from the options' intrinsics and depth scale.
    pub fn write_camera_json(&self) -> Result<PathBuf> {
        let path = self.root.join("camera.json");
        let cam = CameraInfo::new(&self.opts.intrinsics, self.opts.depth_scale);
        write_camera_info(&path, &cam)?;
        Ok(path)
    }

    /// Writes `models/models_info.json`.
    pub fn write_models_info(&self, entries: &[(u32, ModelInfo)]) -> Result<PathBuf> {
        let dir = self.root.join("models");
        create_dir_all(&dir)?;
        let path = dir.join("models_info.json");
        let mut map = BTreeMap::new();
        for (id, info) in entries {
            if map.insert(*id, info).is_some() {
                return Err(Error::InvalidOptions(format!(
                    "object id {id} given twice for {}",
                    path.display()
                )));
            }
        }
        let text = bop_json_text(&path, &map)?;
        atomic_write(&path, text.as_bytes())?;
        Ok(path)
    }

    /// `models/obj_{id:06d}.ply`, creating `models/`. The PLY itself comes from
    /// `synthgen_assets::write_ply` (millimetres).
    pub fn model_ply_path(&self, obj_id: u32) -> Result<PathBuf> {
        let dir = self.root.join("models");
        create_dir_all(&dir)?;
        Ok(dir.join(format!("obj_{obj_id:06}.ply")))
    }

    fn ensure_scene_dirs(&self, scene_id: u32) -> Result<PathBuf> {
        let dir = self.scene_dir(scene_id);
        if lock(&self.scene_dirs).contains(&scene_id) {
            return Ok(dir);
        }
        for sub in IMAGE_DIRS {
            create_dir_all(&dir.join(sub))?;
        }
        lock(&self.scene_dirs).insert(scene_id);
        Ok(dir)
    }

    /// Encodes and writes the images of one frame (rgb, depth, and per object `mask` and
    /// `mask_visib`) and returns its annotations. Hand the record to
    /// [`add_record`](Self::add_record) once the frame counts as done.
    pub fn write_frame(
        &self,
        frame_index: u64,
        scene: &FrameScene,
        frame: &RenderedFrame,
        ann: &[ObjectAnnotation],
    ) -> Result<FrameRecord> {
        let invalid = |message: String| Error::InvalidFrame {
            frame_index,
            message,
        };
        let (w, h) = (frame.width, frame.height);
        let n = w as usize * h as usize;
        let k = &scene.intrinsics;
        if (k.width, k.height) != (w, h) {
            return Err(invalid(format!(
                "image is {w}x{h} but the camera is {}x{}",
                k.width, k.height
            )));
        }
        if frame.rgb.len() != n * 3 || frame.depth_m.len() != n {
            return Err(invalid(
                "rgb or depth buffer does not match the image size".into(),
            ));
        }
        if ann.len() != scene.objects.len() {
            return Err(invalid(format!(
                "{} annotations for {} objects",
                ann.len(),
                scene.objects.len()
            )));
        }
        if ann
            .iter()
            .any(|a| a.mask.len() != n || a.mask_visib.len() != n)
        {
            return Err(invalid("a mask does not match the image size".into()));
        }
        let mut gt = Vec::with_capacity(ann.len());
        for (i, o) in scene.objects.iter().enumerate() {
            o.cam_from_obj
                .validate(synthgen_core::pose::rotation_tolerance())
                .map_err(|e| invalid(format!("object {i}: {e}")))?;
            gt.push(GtEntry::new(o.obj_id, &o.cam_from_obj));
        }
        let cam_from_world = scene.world_from_cam.inverse();
        cam_from_world
            .validate(synthgen_core::pose::rotation_tolerance())
            .map_err(|e| invalid(format!("camera: {e}")))?;
        let k_row = k.k_row_major();
        if k_row.iter().any(|v| !v.is_finite()) {
            return Err(invalid("non-finite intrinsics".into()));
        }

        let (scene_id, im_id) = self.frame_location(frame_index)?;
        let dir = self.ensure_scene_dirs(scene_id)?;
        let c = self.opts.png_compression;

        let rgb_path = dir
            .join("rgb")
            .join(format!("{im_id:06}.{}", self.opts.rgb_format.extension()));
        let rgb_bytes = match self.opts.rgb_format {
            RgbFormat::Png => encode_rgb_png(&frame.rgb, w, h, c, &rgb_path)?,
            RgbFormat::Jpg { quality } => encode_rgb_jpeg(&frame.rgb, w, h, quality, &rgb_path)?,
        };
        atomic_write(&rgb_path, &rgb_bytes)?;

        let depth_path = dir.join("depth").join(format!("{im_id:06}.png"));
        let (depth, overflow) = depth_to_png_values(&frame.depth_m, self.opts.depth_scale);
        atomic_write(
            &depth_path,
            &encode_gray16_png(&depth, w, h, c, &depth_path)?,
        )?;
        self.depth_out_of_range_px
            .fetch_add(overflow, Ordering::Relaxed);

        for (gt_id, a) in ann.iter().enumerate() {
            let name = format!("{im_id:06}_{gt_id:06}.png");
            for (sub, mask) in [("mask", &a.mask), ("mask_visib", &a.mask_visib)] {
                let p = dir.join(sub).join(&name);
                atomic_write(&p, &encode_gray8_png(mask, w, h, c, &p)?)?;
            }
        }

        Ok(FrameRecord {
            frame_index,
            scene_id,
            im_id,
            camera: SceneCamera {
                cam_k: k_row,
                cam_r_w2c: Some(cam_from_world.rotation_row_major().map(no_negative_zero)),
                cam_t_w2c: Some(cam_from_world.translation_mm().map(no_negative_zero)),
                depth_scale: self.opts.depth_scale,
            },
            gt,
            gt_info: ann.iter().map(|a| a.info).collect(),
            depth_out_of_range_px: overflow,
        })
    }

    /// The image ids of `scene_id` this run is expected to deliver.
    fn expected_ims(&self, scene_id: u32) -> Range<u32> {
        let cs = self.opts.chunk_size as u64;
        let lo = scene_id as u64 * cs;
        let (mut a, mut b) = (lo, lo + cs);
        if let Some(r) = &self.opts.frame_range {
            a = a.max(r.start);
            b = b.min(r.end).max(a);
        }
        (a - lo) as u32..(b - lo) as u32
    }

    /// Adds a frame's annotations to its scene folder's JSON. Returns the scene id when this
    /// completed the folder and its JSON was written.
    pub fn add_record(&self, record: FrameRecord) -> Result<Option<u32>> {
        self.add_record_inner(record, self.opts.journal)
    }

    fn add_record_inner(&self, record: FrameRecord, to_journal: bool) -> Result<Option<u32>> {
        let scene_id = record.scene_id;
        let mut chunks = lock(&self.chunks);
        if to_journal {
            // After the images, before the JSON: the line is what makes the frame count as done.
            journal::append(&self.scene_dir(scene_id), &record, self.opts.fsync_json)?;
        }
        if !chunks.open.contains_key(&scene_id) {
            let mut chunk = ChunkAnnotations::new(scene_id, self.expected_ims(scene_id));
            // A folder written earlier (by this run or, when resuming, by another) keeps its
            // images.
            if self.opts.merge_existing || chunks.written.contains(&scene_id) {
                chunk.load_existing(&self.scene_dir(scene_id))?;
            }
            chunks.open.insert(scene_id, chunk);
        }
        let complete = match chunks.open.get_mut(&scene_id) {
            Some(chunk) => {
                chunk.add(record);
                chunk.is_complete()
            }
            None => false,
        };
        self.frames.fetch_add(1, Ordering::Relaxed);
        if !complete {
            return Ok(None);
        }
        if let Some(chunk) = chunks.open.remove(&scene_id) {
            // Written under the lock so a late record for this folder cannot read it half-done.
            if let Err(e) = chunk.write(&self.scene_dir(scene_id), self.opts.fsync_json) {
                chunks.open.insert(scene_id, chunk);
                return Err(e);
            }
            chunks.written.insert(scene_id);
            if self.opts.journal {
                journal::remove(&self.scene_dir(scene_id))?;
            }
        }
        Ok(Some(scene_id))
    }

    /// Writes the JSON of every open scene folder (e.g. before stopping early). Later records
    /// for those folders are merged with what was written.
    pub fn flush(&self) -> Result<()> {
        let mut chunks = lock(&self.chunks);
        while let Some((scene_id, chunk)) = chunks.open.pop_first() {
            // The scene folder exists unless the chunk came from records of another writer.
            create_dir_all(&self.scene_dir(scene_id))?;
            if let Err(e) = chunk.write(&self.scene_dir(scene_id), self.opts.fsync_json) {
                chunks.open.insert(scene_id, chunk);
                return Err(e);
            }
            chunks.written.insert(scene_id);
            if self.opts.journal {
                journal::remove(&self.scene_dir(scene_id))?;
            }
        }
        Ok(())
    }

    /// Picks up an interrupted run over the options' `frame_range`: removes the temporary
    /// files a killed process left, re-adds the frames recorded in the scene folders'
    /// journals (a folder they complete gets its JSON written) and returns which frames are
    /// done: those in a `scene_camera.json` or a journal. Needs `merge_existing`.
    pub fn resume(&self) -> Result<DoneFrames> {
        let Some(range) = self.opts.frame_range.clone() else {
            return Err(Error::InvalidOptions(
                "resuming needs the run's frame range".into(),
            ));
        };
        if !self.opts.merge_existing {
            return Err(Error::InvalidOptions(
                "resuming needs merge_existing".into(),
            ));
        }
        let mut done = DoneFrames::new(range.clone());
        for dir in [
            self.root.clone(),
            self.root.join("models"),
            self.split_dir.clone(),
        ] {
            remove_stale_temp_files(&dir)?;
        }
        if range.is_empty() {
            return Ok(done);
        }
        let (first, _) = self.frame_location(range.start)?;
        let (last, _) = self.frame_location(range.end - 1)?;
        let cs = u64::from(self.opts.chunk_size);
        for scene_id in first..=last {
            let dir = self.scene_dir(scene_id);
            if !dir.is_dir() {
                continue;
            }
            remove_stale_temp_files(&dir)?;
            for sub in IMAGE_DIRS {
                remove_stale_temp_files(&dir.join(sub))?;
            }
            let base = u64::from(scene_id) * cs;
            let camera_path = dir.join(super::SCENE_CAMERA);
            if camera_path.exists() {
                for im in super::reader::read_scene_camera(&camera_path)?.keys() {
                    done.mark(base + u64::from(*im));
                }
            }
            let (all, whole) = journal::read_checked(&dir)?;
            let n_all = all.len();
            let records: Vec<FrameRecord> = all
                .into_iter()
                .filter(|r| {
                    r.scene_id == scene_id
                        && r.frame_index == base + u64::from(r.im_id)
                        && range.contains(&r.frame_index)
                })
                .collect();
            if records.len() != n_all || !whole {
                // Drop a torn last line before new lines are appended after it.
                journal::rewrite(&dir, &records)?;
            }
            for r in records {
                done.mark(r.frame_index);
                self.add_record_inner(r, false)?;
            }
        }
        Ok(done)
    }

    /// Flushes the open scene folders and reports what was written.
    pub fn finish(self) -> Result<WriteSummary> {
        self.flush()?;
        let chunks = lock(&self.chunks);
        Ok(WriteSummary {
            frames: self.frames.load(Ordering::Relaxed),
            scenes: chunks.written.iter().copied().collect(),
            depth_out_of_range_px: self.depth_out_of_range_px.load(Ordering::Relaxed),
        })
    }
}

/// Which frames of a range are done, one bit per frame (a million frames take 125 kB).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DoneFrames {
    range: Range<u64>,
    bits: Vec<u64>,
    count: u64,
}

impl DoneFrames {
    pub fn new(range: Range<u64>) -> DoneFrames {
        let n = range.end.saturating_sub(range.start);
        DoneFrames {
            bits: vec![0; n.div_ceil(64) as usize],
            range,
            count: 0,
        }
    }

    pub fn mark(&mut self, frame_index: u64) {
        if !self.range.contains(&frame_index) {
            return;
        }
        let k = frame_index - self.range.start;
        let (w, b) = ((k / 64) as usize, k % 64);
        if self.bits[w] & (1 << b) == 0 {
            self.bits[w] |= 1 << b;
            self.count += 1;
        }
    }

    pub fn is_done(&self, frame_index: u64) -> bool {
        if !self.range.contains(&frame_index) {
            return false;
        }
        let k = frame_index - self.range.start;
        self.bits[(k / 64) as usize] & (1 << (k % 64)) != 0
    }

    /// Frames marked done.
    pub fn count(&self) -> u64 {
        self.count
    }
}

/// Writes a dataset's `camera.json` in bop_toolkit's layout.
pub fn write_camera_info(path: &Path, cam: &CameraInfo) -> Result<()> {
    let text = serde_json::to_value(cam)
        .ok()
        .and_then(|v| save_json_object(&v).ok())
        .ok_or_else(|| Error::NonFinite {
            what: "camera intrinsics".into(),
            path: path.to_path_buf(),
        })?;
    atomic_write(path, text.as_bytes())
}
