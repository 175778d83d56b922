//! YCB-Video's own layout, as PoseCNN and DenseFusion read it: `data/NNNN/NNNNNN-color.png`,
//! `-depth.png` (uint16, metres = value / `factor_depth`), `-label.png` (per-pixel class
//! index = the visible masks), `-meta.mat` (MAT v5: `poses` 3x4xN object-to-camera in metres,
//! `cls_indexes`, `intrinsic_matrix`, `factor_depth`, `center`, `vertmap`,
//! `rotation_translation_matrix`), `-box.txt`; `classes.txt`; `models/<class>/`
//! `textured_simple.obj` (metres) and `points.xyz`; `image_sets/*.txt`.
//!
//! In BOP terms (as BOP's own `ycbv`): class index i = obj_id i, scene id = the video number,
//! image id = the frame number (`0049/000012` → scene 49, image 12).

mod meta;
pub mod source;
pub mod writer;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub(crate) use meta::read_meta_with;
pub use meta::{encode_meta, read_meta, YcbvMeta, YcbvPose};
pub use source::YcbvSource;
pub use writer::{YcbvFrame, YcbvObject, YcbvWriter, YcbvWriterOptions};

use crate::error::{Error, Result};
use crate::io;

/// YCB-Video's 21 classes in `classes.txt` order: line i (1-based) is class index i, which
/// is BOP `ycbv` obj_id i.
pub const YCBV_CLASSES: [&str; 21] = [
    "002_master_chef_can",
    "003_cracker_box",
    "004_sugar_box",
    "005_tomato_soup_can",
    "006_mustard_bottle",
    "007_tuna_fish_can",
    "008_pudding_box",
    "009_gelatin_box",
    "010_potted_meat_can",
    "011_banana",
    "019_pitcher_base",
    "021_bleach_cleanser",
    "024_bowl",
    "025_mug",
    "035_power_drill",
    "036_wood_block",
    "037_scissors",
    "040_large_marker",
    "051_large_clamp",
    "052_extra_large_clamp",
    "061_foam_brick",
];

pub const CLASSES_FILE: &str = "classes.txt";
/// The model file of a class, under `models/<class>/`.
pub const MODEL_FILE: &str = "textured_simple.obj";
/// YCB-Video's own evaluation points of a class (metres, one `x y z` per line).
pub const POINTS_FILE: &str = "points.xyz";

/// Where one frame's files are: `data/{scene:04}/{im:06}-*`.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct YcbvFrameFiles {
    pub split: String,
    pub scene_id: u32,
    pub im_id: u32,
    /// `data/NNNN` (the folder name as found, e.g. `0049`).
    pub dir: PathBuf,
}

impl YcbvFrameFiles {
    fn file(&self, suffix: &str) -> PathBuf {
        self.dir.join(format!("{:06}-{suffix}", self.im_id))
    }

    /// `-color.png`, or `-color.jpg` where only that exists.
    pub fn color_path(&self) -> PathBuf {
        let png = self.file("color.png");
        if !png.is_file() {
            let jpg = self.file("color.jpg");
            if jpg.is_file() {
                return jpg;
            }
        }
        png
    }

    pub fn depth_path(&self) -> PathBuf {
        self.file("depth.png")
    }

    pub fn label_path(&self) -> PathBuf {
        self.file("label.png")
    }

    pub fn meta_path(&self) -> PathBuf {
        self.file("meta.mat")
    }

    pub fn box_path(&self) -> PathBuf {
        self.file("box.txt")
    }
}

/// Frames listed in a test list (`keyframe.txt`, `val.txt`, `test*.txt`, as YCB-Video's
/// keyframes and validation frames are its test set) form split `test`; the other lists
/// (`train.txt`, `trainval.txt`, ...) split `train`.
fn list_is_test(stem: &str) -> bool {
    let s = stem.to_ascii_lowercase();
    s == "keyframe" || s == "val" || s.starts_with("test")
}

/// A YCB-Video dataset on disk: its classes and frames (files not read yet).
#[derive(Debug, Clone)]
pub struct YcbvDataset {
    pub root: PathBuf,
    /// `classes.txt`, line order: `classes[i - 1]` is class index i.
    pub classes: Vec<String>,
    /// Sorted by (split, scene, image).
    pub frames: Vec<YcbvFrameFiles>,
    /// Frames on disk that are not read (no `-meta.mat`, or in no image list).
    pub left_out: LeftOutFrames,
}

/// Frames in `data/` that a YCB-Video reader leaves out, as (scene, frame).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LeftOutFrames {
    /// Colour, depth or label images without a `-meta.mat` (no poses to read).
    pub without_meta: Vec<(u32, u32)>,
    /// Frames with a `-meta.mat` in no `image_sets/*.txt` list (only listed frames are read).
    pub unlisted: Vec<(u32, u32)>,
}

impl LeftOutFrames {
    /// One line per kind, with a count and the first frames (`data/0000/000003`).
    pub fn warnings(&self) -> Vec<String> {
        let name = |v: &[(u32, u32)]| -> String {
            let mut s: Vec<String> = v
                .iter()
                .take(5)
                .map(|(sc, im)| format!("data/{sc:04}/{im:06}"))
                .collect();
            if v.len() > 5 {
                s.push(format!("... ({} more)", v.len() - 5));
            }
            s.join(", ")
        };
        let mut out = Vec::new();
        if !self.without_meta.is_empty() {
            out.push(format!(
                "{} frames have colour, depth or label images but no -meta.mat and are left out: {}",
                self.without_meta.len(),
                name(&self.without_meta)
            ));
        }
        if !self.unlisted.is_empty() {
            out.push(format!(
                "{} frames have a -meta.mat but are in no image_sets/*.txt list and are left out (only listed frames are read): {}",
                self.unlisted.len(),
                name(&self.unlisted)
            ));
        }
        out
    }
}

/// Whether `root` looks like a YCB-Video dataset: `classes.txt` beside a `data/` folder with
/// numbered scene folders.
pub fn is_ycbv(root: &Path) -> bool {
    root.join(CLASSES_FILE).is_file() && root.join("data").is_dir()
}

fn numbered_dirs(dir: &Path) -> Result<Vec<(u32, PathBuf)>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io("read", dir, e))?;
    let mut out = Vec::new();
    for e in entries {
        let e = e.map_err(|e| Error::io("list directory", dir, e))?;
        let name = e.file_name().to_string_lossy().into_owned();
        // Follows links: scene folders may be symlinks to where the frames live.
        let is_dir = std::fs::metadata(e.path()).is_ok_and(|m| m.is_dir());
        if let (true, Some(id)) = (is_dir, parse_number(&name)) {
            out.push((id, e.path()));
        }
    }
    out.sort();
    Ok(out)
}

fn parse_number(s: &str) -> Option<u32> {
    (!s.is_empty() && s.bytes().all(|b| b.is_ascii_digit()))
        .then(|| s.parse().ok())
        .flatten()
}

impl YcbvDataset {
    /// Reads `classes.txt` and lists the frames: those of `image_sets/*.txt` when the folder
    /// has lists, else every `data/NNNN/NNNNNN-meta.mat` (split `train`).
    pub fn open(root: &Path) -> Result<YcbvDataset> {
        let classes_path = root.join(CLASSES_FILE);
        let text = io::read(&classes_path)?;
        let mut classes: Vec<String> = String::from_utf8_lossy(&text)
            .lines()
            .map(|l| l.trim().to_string())
            .collect();
        while classes.last().is_some_and(String::is_empty) {
            classes.pop();
        }
        if classes.is_empty() {
            return Err(Error::malformed(&classes_path, "no class names"));
        }
        check_class_names(&classes).map_err(|m| Error::malformed(&classes_path, m))?;
        let data = root.join("data");
        let scenes: BTreeMap<u32, PathBuf> = numbered_dirs(&data)?.into_iter().collect();
        let sets = root.join("image_sets");
        let lists = list_files(&sets)?;
        let mut frames = Vec::new();
        let mut left_out = LeftOutFrames::default();
        let mut on_disk: BTreeMap<u32, BTreeMap<u32, OnDisk>> = BTreeMap::new();
        for (&scene_id, dir) in &scenes {
            on_disk.insert(scene_id, scan_scene(dir)?);
        }
        for (&scene_id, ids) in &on_disk {
            for (&im_id, d) in ids {
                if !d.meta {
                    left_out.without_meta.push((scene_id, im_id));
                }
            }
        }
        if lists.is_empty() {
            for (&scene_id, dir) in &scenes {
                for (&im_id, d) in &on_disk[&scene_id] {
                    if d.meta {
                        frames.push(YcbvFrameFiles {
                            split: "train".into(),
                            scene_id,
                            im_id,
                            dir: dir.clone(),
                        });
                    }
                }
            }
        } else {
            let mut split_of: BTreeMap<(u32, u32), bool> = BTreeMap::new();
            for (stem, path) in &lists {
                let test = list_is_test(stem);
                for (scene_id, im_id) in read_list(path)? {
                    let e = split_of.entry((scene_id, im_id)).or_insert(test);
                    *e |= test;
                }
            }
            for (&scene_id, ids) in &on_disk {
                for (&im_id, d) in ids {
                    if d.meta && !split_of.contains_key(&(scene_id, im_id)) {
                        left_out.unlisted.push((scene_id, im_id));
                    }
                }
            }
            for ((scene_id, im_id), test) in split_of {
                let dir = scenes
                    .get(&scene_id)
                    .cloned()
                    .unwrap_or_else(|| data.join(format!("{scene_id:04}")));
                let f = YcbvFrameFiles {
                    split: if test { "test" } else { "train" }.into(),
                    scene_id,
                    im_id,
                    dir,
                };
                if !f.meta_path().is_file() {
                    return Err(Error::MissingFile {
                        path: f.meta_path(),
                    });
                }
                frames.push(f);
            }
        }
        if frames.is_empty() {
            return Err(Error::malformed(
                &data,
                "no frames (expected data/NNNN/NNNNNN-meta.mat)",
            ));
        }
        frames.sort();
        Ok(YcbvDataset {
            root: root.to_path_buf(),
            classes,
            frames,
            left_out,
        })
    }

    /// The class name of an object id (class index), when `classes.txt` has it.
    pub fn class_name(&self, obj_id: u32) -> Option<&str> {
        let i = usize::try_from(obj_id).ok()?.checked_sub(1)?;
        self.classes.get(i).map(String::as_str)
    }

    /// `models/<class>/textured_simple.obj` (present or not); `None` for an unknown id.
    pub fn model_path(&self, obj_id: u32) -> Option<PathBuf> {
        let class = self.class_name(obj_id)?;
        Some(self.root.join("models").join(class).join(MODEL_FILE))
    }

    /// Reads a frame's `-meta.mat`, checking its class indexes against `classes.txt`.
    pub fn read_meta(&self, frame: &YcbvFrameFiles) -> Result<YcbvMeta> {
        read_meta(&frame.meta_path(), Some(self.classes.len()))
    }
}

/// `image_sets/*.txt` by file stem, sorted.
fn list_files(dir: &Path) -> Result<Vec<(String, PathBuf)>> {
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io("read", dir, e))?;
    let mut out = Vec::new();
    for e in entries {
        let e = e.map_err(|e| Error::io("list directory", dir, e))?;
        let name = e.file_name().to_string_lossy().into_owned();
        if let Some(stem) = name.strip_suffix(".txt") {
            if !stem.starts_with('.') {
                out.push((stem.to_string(), e.path()));
            }
        }
    }
    out.sort();
    Ok(out)
}

/// The `scene/frame` lines of an image set (`0048/000001`).
fn read_list(path: &Path) -> Result<Vec<(u32, u32)>> {
    let text = io::read(path)?;
    let mut out = Vec::new();
    for (i, line) in String::from_utf8_lossy(&text).lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let parsed = line
            .split_once('/')
            .and_then(|(s, f)| Some((parse_number(s)?, parse_number(f)?)));
        match parsed {
            Some(p) => out.push(p),
            None => {
                return Err(Error::malformed(
                    path,
                    format!(
                        "line {}: expected SCENE/FRAME like 0048/000001, found {line:?}",
                        i + 1
                    ),
                ))
            }
        }
    }
    Ok(out)
}

/// The values of a label image that are not classes of its frame (`cls`), with their pixel
/// counts: those pixels are in no instance's visible mask.
pub fn stray_label_values(label: &[u16], cls: &[u32]) -> BTreeMap<u16, u64> {
    let mut out: BTreeMap<u16, u64> = BTreeMap::new();
    for &v in label {
        if v != 0 && !cls.iter().any(|&c| c == u32::from(v)) {
            *out.entry(v).or_default() += 1;
        }
    }
    out
}

/// `3 (200 px), 7 (640 px)`.
pub fn format_label_values(values: &BTreeMap<u16, u64>) -> String {
    values
        .iter()
        .map(|(v, n)| format!("{v} ({n} px)"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// What a scene folder holds of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct OnDisk {
    /// `NNNNNN-meta.mat`.
    meta: bool,
    /// `NNNNNN-color.png|jpg`, `-depth.png` or `-label.png`.
    images: bool,
}

/// The frames of a scene folder by id: which have a `-meta.mat`, which have images.
fn scan_scene(dir: &Path) -> Result<BTreeMap<u32, OnDisk>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io("read", dir, e))?;
    let mut out: BTreeMap<u32, OnDisk> = BTreeMap::new();
    for e in entries {
        let e = e.map_err(|e| Error::io("list directory", dir, e))?;
        let name = e.file_name().to_string_lossy().into_owned();
        let Some((id, kind)) = name
            .split_once('-')
            .and_then(|(id, kind)| Some((parse_number(id)?, kind)))
        else {
            continue;
        };
        match kind {
            "meta.mat" => out.entry(id).or_default().meta = true,
            "color.png" | "color.jpg" | "depth.png" | "label.png" => {
                out.entry(id).or_default().images = true
            }
            _ => {}
        }
    }
    Ok(out)
}

/// Checks a class list as `classes.txt` and `models/<class>/` need it: each name a plain folder
/// name (non-empty, without '/', '\\' or a line break, not "." or "..") used once — two
/// classes of one name would share one model folder. The message names 1-based lines.
pub fn check_class_names(classes: &[String]) -> std::result::Result<(), String> {
    let mut first: BTreeMap<&str, usize> = BTreeMap::new();
    for (i, c) in classes.iter().enumerate() {
        if c.is_empty() || c == "." || c == ".." || c.contains(['/', '\\', '\n']) {
            return Err(format!(
                "line {}: bad class name {c:?} (it names a folder under models/)",
                i + 1
            ));
        }
        if let Some(j) = first.insert(c, i) {
            return Err(format!(
                "line {}: class name {c:?} repeats line {} (each class has its own models/<class>/ folder)",
                i + 1,
                j + 1
            ));
        }
    }
    Ok(())
}

/// The class list a YCB-Video dataset written from BOP object ids needs: line i names
/// obj_id i. Known ids keep YCB-Video's class names when `ycbv_names` (the objects are
/// YCB-Video's), others are `obj_NNNNNN`; ids up to the largest one are listed.
pub fn class_list(obj_ids: &[u32], ycbv_names: bool) -> Vec<String> {
    let max = obj_ids.iter().copied().max().unwrap_or(0);
    (1..=max)
        .map(|id| {
            let known = ycbv_names
                .then(|| YCBV_CLASSES.get(id as usize - 1))
                .flatten();
            known.map_or_else(|| format!("obj_{id:06}"), |s| s.to_string())
        })
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn test_lists_and_class_names() {
        assert!(list_is_test("keyframe") && list_is_test("val") && list_is_test("test_real"));
        assert!(!list_is_test("train") && !list_is_test("trainval"));
        assert_eq!(
            class_list(&[2, 3], true),
            ["002_master_chef_can", "003_cracker_box", "004_sugar_box"]
        );
        assert_eq!(class_list(&[2, 30], false)[29], "obj_000030");
        assert_eq!(class_list(&[22], true)[21], "obj_000022");
    }

    #[test]
    fn image_set_lines_are_checked() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("train.txt");
        std::fs::write(&p, "0048/000001\n\n0049/000012\n").unwrap();
        assert_eq!(read_list(&p).unwrap(), [(48, 1), (49, 12)]);
        std::fs::write(&p, "0048/000001\n0048-000002\n").unwrap();
        let e = read_list(&p).unwrap_err().to_string();
        assert!(e.contains("line 2") && e.contains("train.txt"), "{e}");
    }
}
