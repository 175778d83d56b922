//! Writing the Linemod layout. A frame goes into the folder of every object visible enough in
//! it (`min_visib_fract`), under the same frame id everywhere, so frames can be written from
//! several threads and shards never collide. Each folder's `gt.yml` lists all objects of the
//! frame with the folder's object first (DenseFusion reads entry 0, or searches by `obj_id`
//! for object 2); `mask/` holds the folder object's visible mask (BOP's `mask_visib`).

use std::collections::{BTreeMap, BTreeSet, HashSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use synthgen_core::{FrameScene, ObjectAnnotation, RenderedFrame};

use super::yaml::{gt_yml_text, info_yml_text, models_info_yml_text};
use super::{folder_name, frame_file, LinemodGt, LinemodInfo, DEFAULT_MIN_VISIB_FRACT};
use crate::bop::image::{depth_to_png_values, encode_gray16_png, encode_gray8_png, encode_rgb_png};
use crate::bop::types::no_negative_zero;
use crate::bop::{ModelInfo, PngCompression};
use crate::error::{Error, Result};
use crate::io::{atomic_write, create_dir_all};

/// Options of a [`LinemodWriter`].
#[derive(Debug, Clone, PartialEq)]
pub struct LinemodWriterOptions {
    /// Depth PNG value × `depth_scale` = mm. Linemod uses 1.0 (DenseFusion assumes it).
    pub depth_scale: f64,
    /// See [`DEFAULT_MIN_VISIB_FRACT`].
    pub min_visib_fract: f64,
    pub png_compression: PngCompression,
}

impl Default for LinemodWriterOptions {
    fn default() -> Self {
        LinemodWriterOptions {
            depth_scale: 1.0,
            min_visib_fract: DEFAULT_MIN_VISIB_FRACT,
            png_compression: PngCompression::default(),
        }
    }
}

/// Which list file a frame goes to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ListFile {
    Train,
    Test,
}

/// One object instance of a frame, in the units of the files.
#[derive(Debug, Clone, PartialEq)]
pub struct LinemodObject {
    pub gt: LinemodGt,
    pub visib_fract: f64,
    /// The visible mask (0/255, image size); `None` when unknown (the object then gets no
    /// folder entry).
    pub mask_visib: Option<Vec<u8>>,
}

/// A frame ready to be written: images in file units and all its objects in scene order.
#[derive(Debug, Clone, PartialEq)]
pub struct LinemodFrame {
    pub frame_id: u64,
    pub width: u32,
    pub height: u32,
    pub cam_k: [f64; 9],
    /// RGB8, row-major.
    pub rgb: Vec<u8>,
    /// Depth PNG values at the writer's `depth_scale`.
    pub depth: Vec<u16>,
    pub objects: Vec<LinemodObject>,
}

/// What one frame adds to the folders' YAML files.
#[derive(Debug, Clone, PartialEq)]
pub struct LinemodRecord {
    pub frame_id: u64,
    pub list: ListFile,
    pub info: LinemodInfo,
    /// Per folder written (object id): the frame's `gt.yml` list.
    pub folders: Vec<(u32, Vec<LinemodGt>)>,
    pub depth_out_of_range_px: u64,
}

#[derive(Default)]
struct Folder {
    gt: BTreeMap<u64, Vec<LinemodGt>>,
    info: BTreeMap<u64, LinemodInfo>,
    train: BTreeSet<u64>,
    test: BTreeSet<u64>,
}

/// What [`LinemodWriter::finish`] reports.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinemodSummary {
    pub frames: u64,
    /// Object folders written, sorted.
    pub folders: Vec<u32>,
    pub depth_out_of_range_px: u64,
}

/// Writes a Linemod dataset. `write_*` and `add_record` take `&self` (many threads at once);
/// the YAML and list files are written by [`finish`](Self::finish).
pub struct LinemodWriter {
    root: PathBuf,
    opts: LinemodWriterOptions,
    created: Mutex<HashSet<u32>>,
    folders: Mutex<BTreeMap<u32, Folder>>,
    frames: AtomicU64,
    depth_out_of_range_px: AtomicU64,
}

fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    // A panic elsewhere leaves plain data usable.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// For each object id of the frame, the instance with the largest visible fraction, when it
/// reaches `min_visib_fract` and has a mask: `(obj_id, instance index)`, sorted by id.
pub fn folder_instances(objects: &[LinemodObject], min_visib_fract: f64) -> Vec<(u32, usize)> {
    let mut best: BTreeMap<u32, usize> = BTreeMap::new();
    for (i, o) in objects.iter().enumerate() {
        let id = o.gt.obj_id;
        match best.get(&id) {
            Some(&j) if objects[j].visib_fract >= o.visib_fract => {}
            _ => {
                best.insert(id, i);
            }
        }
    }
    best.into_iter()
        .filter(|&(_, i)| {
            let o = &objects[i];
            o.visib_fract > 0.0 && o.visib_fract >= min_visib_fract && o.mask_visib.is_some()
        })
        .collect()
}

impl LinemodWriter {
    /// Creates `root/data` and `root/models`.
    pub fn create(root: &Path, opts: LinemodWriterOptions) -> Result<LinemodWriter> {
        if !(opts.depth_scale.is_finite() && opts.depth_scale > 0.0) {
            return Err(Error::InvalidOptions(format!(
                "depth_scale must be positive, got {}",
                opts.depth_scale
            )));
        }
        if !(0.0..=1.0).contains(&opts.min_visib_fract) {
            return Err(Error::InvalidOptions(format!(
                "min_visib_fract must be in 0..1, got {}",
                opts.min_visib_fract
            )));
        }
        create_dir_all(&root.join("data"))?;
        create_dir_all(&root.join("models"))?;
        Ok(LinemodWriter {
            root: root.to_path_buf(),
            opts,
            created: Mutex::default(),
            folders: Mutex::default(),
            frames: AtomicU64::new(0),
            depth_out_of_range_px: AtomicU64::new(0),
        })
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    pub fn options(&self) -> &LinemodWriterOptions {
        &self.opts
    }

    /// `data/{obj:02d}`.
    pub fn folder_dir(&self, obj_id: u32) -> PathBuf {
        self.root.join("data").join(folder_name(obj_id))
    }

    /// `models/obj_{id:02d}.ply` (write it with `synthgen_assets::write_ply`, millimetres).
    pub fn model_ply_path(&self, obj_id: u32) -> PathBuf {
        self.root
            .join("models")
            .join(format!("obj_{obj_id:02}.ply"))
    }

    /// Writes `models/models_info.yml`.
    pub fn write_models_info(&self, models: &BTreeMap<u32, ModelInfo>) -> Result<PathBuf> {
        let path = self.root.join("models").join("models_info.yml");
        let text = models_info_yml_text(models).ok_or_else(|| Error::NonFinite {
            what: "model info".into(),
            path: path.clone(),
        })?;
        atomic_write(&path, text.as_bytes())?;
        Ok(path)
    }

    fn ensure_folder(&self, obj_id: u32) -> Result<PathBuf> {
        let dir = self.folder_dir(obj_id);
        if lock(&self.created).contains(&obj_id) {
            return Ok(dir);
        }
        for sub in ["rgb", "depth", "mask"] {
            create_dir_all(&dir.join(sub))?;
        }
        lock(&self.created).insert(obj_id);
        Ok(dir)
    }

    /// A rendered frame as a [`LinemodFrame`] (poses in mm, depth at this writer's scale).
    pub fn frame_from_render(
        &self,
        scene: &FrameScene,
        frame: &RenderedFrame,
        ann: &[ObjectAnnotation],
    ) -> Result<LinemodFrame> {
        let invalid = |message: String| Error::InvalidFrame {
            frame_index: scene.frame_index,
            message,
        };
        if ann.len() != scene.objects.len() {
            return Err(invalid(format!(
                "{} annotations for {} objects",
                ann.len(),
                scene.objects.len()
            )));
        }
        let (depth, overflow) = depth_to_png_values(&frame.depth_m, self.opts.depth_scale);
        self.depth_out_of_range_px
            .fetch_add(overflow, Ordering::Relaxed);
        let mut objects = Vec::with_capacity(ann.len());
        for (i, (o, a)) in scene.objects.iter().zip(ann).enumerate() {
            o.cam_from_obj
                .validate(synthgen_core::pose::rotation_tolerance())
                .map_err(|e| invalid(format!("object {i}: {e}")))?;
            objects.push(LinemodObject {
                gt: LinemodGt {
                    cam_r_m2c: o.cam_from_obj.rotation_row_major().map(no_negative_zero),
                    cam_t_m2c: o.cam_from_obj.translation_mm().map(no_negative_zero),
                    obj_bb: a.info.bbox_obj,
                    obj_id: o.obj_id,
                },
                visib_fract: a.info.visib_fract,
                mask_visib: Some(a.mask_visib.clone()),
            });
        }
        Ok(LinemodFrame {
            frame_id: scene.frame_index,
            width: frame.width,
            height: frame.height,
            cam_k: scene.intrinsics.k_row_major(),
            rgb: frame.rgb.clone(),
            depth,
            objects,
        })
    }

    /// Writes the images of a frame into the folder of each object visible enough and
    /// returns its YAML entries; hand them to [`add_record`](Self::add_record).
    pub fn write_frame(&self, frame: &LinemodFrame, list: ListFile) -> Result<LinemodRecord> {
        let (w, h) = (frame.width, frame.height);
        let n = w as usize * h as usize;
        let invalid = |message: String| Error::InvalidFrame {
            frame_index: frame.frame_id,
            message,
        };
        if frame.rgb.len() != n * 3 || frame.depth.len() != n {
            return Err(invalid(
                "rgb or depth buffer does not match the image size".into(),
            ));
        }
        if frame.cam_k.iter().any(|v| !v.is_finite()) {
            return Err(invalid("non-finite intrinsics".into()));
        }
        let chosen = folder_instances(&frame.objects, self.opts.min_visib_fract);
        let c = self.opts.png_compression;
        let name = frame_file(frame.frame_id);
        let mut encoded: Option<(Vec<u8>, Vec<u8>)> = None;
        let mut folders = Vec::with_capacity(chosen.len());
        for &(obj_id, idx) in &chosen {
            let dir = self.ensure_folder(obj_id)?;
            let rgb_path = dir.join("rgb").join(&name);
            let depth_path = dir.join("depth").join(&name);
            if encoded.is_none() {
                encoded = Some((
                    encode_rgb_png(&frame.rgb, w, h, c, &rgb_path)?,
                    encode_gray16_png(&frame.depth, w, h, c, &depth_path)?,
                ));
            }
            if let Some((rgb, depth)) = &encoded {
                atomic_write(&rgb_path, rgb)?;
                atomic_write(&depth_path, depth)?;
            }
            let mask_path = dir.join("mask").join(&name);
            let mask = frame.objects[idx].mask_visib.as_deref().unwrap_or(&[]);
            if mask.len() != n {
                return Err(invalid("a mask does not match the image size".into()));
            }
            atomic_write(&mask_path, &encode_gray8_png(mask, w, h, c, &mask_path)?)?;
            let mut list_gt = vec![frame.objects[idx].gt];
            list_gt.extend(
                frame
                    .objects
                    .iter()
                    .enumerate()
                    .filter(|&(i, _)| i != idx)
                    .map(|(_, o)| o.gt),
            );
            folders.push((obj_id, list_gt));
        }
        Ok(LinemodRecord {
            frame_id: frame.frame_id,
            list,
            info: LinemodInfo {
                cam_k: frame.cam_k,
                depth_scale: self.opts.depth_scale,
            },
            folders,
            depth_out_of_range_px: 0,
        })
    }

    /// Adds a written frame's entries to its folders.
    pub fn add_record(&self, record: LinemodRecord) {
        let mut folders = lock(&self.folders);
        for (obj_id, gt) in record.folders {
            let f = folders.entry(obj_id).or_default();
            f.gt.insert(record.frame_id, gt);
            f.info.insert(record.frame_id, record.info);
            match record.list {
                ListFile::Train => f.train.insert(record.frame_id),
                ListFile::Test => f.test.insert(record.frame_id),
            };
        }
        self.frames.fetch_add(1, Ordering::Relaxed);
        self.depth_out_of_range_px
            .fetch_add(record.depth_out_of_range_px, Ordering::Relaxed);
    }

    /// Writes every folder's `gt.yml`, `info.yml`, `train.txt` and `test.txt`.
    pub fn finish(self) -> Result<LinemodSummary> {
        let folders = lock(&self.folders);
        for (&obj_id, f) in folders.iter() {
            let dir = self.folder_dir(obj_id);
            create_dir_all(&dir)?;
            let non_finite = |p: &Path| Error::NonFinite {
                what: "a pose or camera".into(),
                path: p.to_path_buf(),
            };
            let p = dir.join("info.yml");
            atomic_write(
                &p,
                info_yml_text(&f.info)
                    .ok_or_else(|| non_finite(&p))?
                    .as_bytes(),
            )?;
            let p = dir.join("gt.yml");
            atomic_write(
                &p,
                gt_yml_text(&f.gt).ok_or_else(|| non_finite(&p))?.as_bytes(),
            )?;
            for (file, ids) in [("train.txt", &f.train), ("test.txt", &f.test)] {
                let text: String = ids.iter().map(|i| format!("{i:04}\n")).collect();
                atomic_write(&dir.join(file), text.as_bytes())?;
            }
        }
        Ok(LinemodSummary {
            frames: self.frames.load(Ordering::Relaxed),
            folders: folders.keys().copied().collect(),
            depth_out_of_range_px: self.depth_out_of_range_px.load(Ordering::Relaxed),
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn obj(obj_id: u32, visib_fract: f64) -> LinemodObject {
        LinemodObject {
            gt: LinemodGt {
                cam_r_m2c: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                cam_t_m2c: [0.0, 0.0, 500.0 + visib_fract],
                obj_bb: [0, 0, 1, 1],
                obj_id,
            },
            visib_fract,
            mask_visib: Some(vec![255; 4]),
        }
    }

    #[test]
    fn the_most_visible_instance_of_each_id_gets_the_folder() {
        let objects = [
            obj(5, 0.3),
            obj(2, 0.05),
            obj(5, 0.8),
            obj(7, 0.1),
            obj(9, 0.0),
        ];
        assert_eq!(folder_instances(&objects, 0.1), [(5, 2), (7, 3)]);
        assert_eq!(folder_instances(&objects, 0.0), [(2, 1), (5, 2), (7, 3)]);
    }

    #[test]
    fn frames_go_to_visible_objects_folders_with_their_object_first() {
        let d = tempfile::tempdir().unwrap();
        let w = LinemodWriter::create(d.path(), LinemodWriterOptions::default()).unwrap();
        let frame = LinemodFrame {
            frame_id: 12,
            width: 2,
            height: 2,
            cam_k: [100.0, 0.0, 1.0, 0.0, 100.0, 1.0, 0.0, 0.0, 1.0],
            rgb: vec![7; 12],
            depth: vec![500; 4],
            objects: vec![obj(1, 0.5), obj(2, 0.9), obj(3, 0.01)],
        };
        let rec = w.write_frame(&frame, ListFile::Test).unwrap();
        w.add_record(rec);
        let s = w.finish().unwrap();
        assert_eq!(s.folders, [1, 2]);
        let gt = crate::linemod::read_gt_yml(&d.path().join("data/02/gt.yml")).unwrap();
        let ids: Vec<u32> = gt[&12].iter().map(|g| g.obj_id).collect();
        assert_eq!(ids, [2, 1, 3]);
        assert!(d.path().join("data/01/mask/0012.png").exists());
        assert!(!d.path().join("data/03").exists());
        let test = std::fs::read_to_string(d.path().join("data/01/test.txt")).unwrap();
        assert_eq!(test, "0012\n");
        assert_eq!(
            std::fs::read_to_string(d.path().join("data/01/train.txt")).unwrap(),
            ""
        );
    }
}
