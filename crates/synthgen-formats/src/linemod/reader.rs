//! Reading the Linemod layout: the YAML files with errors that name the file, line and
//! column (a missing key, a wrong type), the id lists and the image paths of each folder.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;

use super::{folder_name, frame_file, LinemodGt, LinemodInfo};
use crate::bop::reader::check_finite;
use crate::bop::ModelInfo;
use crate::error::{Error, Result};
use crate::io;

fn read_yaml<T: DeserializeOwned>(path: &Path) -> Result<T> {
    let bytes = io::read(path)?;
    serde_yaml_ng::from_slice(&bytes).map_err(|e| Error::yaml(path, e))
}

/// Reads `gt.yml` (frame id → objects). Checks types, keys and finiteness; rotations are
/// checked by the caller (the converter refuses bad ones, `validate` reports them).
pub fn read_gt_yml(path: &Path) -> Result<BTreeMap<u64, Vec<LinemodGt>>> {
    // An empty file is an empty map (a folder with no frames).
    let m: Option<BTreeMap<u64, Option<Vec<LinemodGt>>>> = read_yaml(path)?;
    let mut out = BTreeMap::new();
    for (frame, gts) in m.unwrap_or_default() {
        let gts = gts.unwrap_or_default();
        for g in &gts {
            check_finite(path, &format!("frame {frame}"), &g.cam_r_m2c)?;
            check_finite(path, &format!("frame {frame}"), &g.cam_t_m2c)?;
        }
        out.insert(frame, gts);
    }
    Ok(out)
}

/// Reads `info.yml` (frame id → camera).
pub fn read_info_yml(path: &Path) -> Result<BTreeMap<u64, LinemodInfo>> {
    let m: Option<BTreeMap<u64, LinemodInfo>> = read_yaml(path)?;
    let m = m.unwrap_or_default();
    for (frame, i) in &m {
        check_finite(path, &format!("frame {frame}"), &i.cam_k)?;
        if !(i.depth_scale.is_finite() && i.depth_scale > 0.0) {
            return Err(Error::malformed(
                path,
                format!("depth_scale of frame {frame} must be positive"),
            ));
        }
    }
    Ok(m)
}

/// Reads `models_info.yml` (object id → extents and diameter in mm).
pub fn read_models_info_yml(path: &Path) -> Result<BTreeMap<u32, ModelInfo>> {
    let m: Option<BTreeMap<u32, ModelInfo>> = read_yaml(path)?;
    Ok(m.unwrap_or_default())
}

/// Reads `train.txt` / `test.txt`: one frame id per line (`0042`); blank lines ignored.
pub fn read_id_list(path: &Path) -> Result<Vec<u64>> {
    let bytes = io::read(path)?;
    let text = String::from_utf8_lossy(&bytes);
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let id = line.parse::<u64>().map_err(|_| {
            Error::malformed(path, format!("line {}: {line:?} is not a frame id", n + 1))
        })?;
        out.push(id);
    }
    Ok(out)
}

/// A Linemod dataset on disk.
#[derive(Debug, Clone)]
pub struct LinemodDataset {
    pub root: PathBuf,
    /// Object folders under `data/` (`01`, `02`, ...), sorted.
    pub objects: Vec<u32>,
    /// `models/models_info.yml`, when present.
    pub models_info: Option<BTreeMap<u32, ModelInfo>>,
}

/// One object folder, its YAML read.
#[derive(Debug, Clone)]
pub struct LinemodFolder {
    pub obj_id: u32,
    pub dir: PathBuf,
    pub gt: BTreeMap<u64, Vec<LinemodGt>>,
    pub info: BTreeMap<u64, LinemodInfo>,
    pub train: Vec<u64>,
    pub test: Vec<u64>,
}

impl LinemodFolder {
    pub fn rgb_path(&self, frame_id: u64) -> PathBuf {
        self.dir.join("rgb").join(frame_file(frame_id))
    }

    pub fn depth_path(&self, frame_id: u64) -> PathBuf {
        self.dir.join("depth").join(frame_file(frame_id))
    }

    pub fn mask_path(&self, frame_id: u64) -> PathBuf {
        self.dir.join("mask").join(frame_file(frame_id))
    }

    /// The entry of `gt.yml` the folder's mask belongs to: the first with the folder's id.
    pub fn folder_gt(&self, frame_id: u64) -> Option<&LinemodGt> {
        self.gt
            .get(&frame_id)?
            .iter()
            .find(|g| g.obj_id == self.obj_id)
    }
}

impl LinemodDataset {
    /// Lists `data/NN` folders and reads `models/models_info.yml` if present.
    pub fn open(root: &Path) -> Result<LinemodDataset> {
        let data = root.join("data");
        let entries = std::fs::read_dir(&data).map_err(|e| Error::io("read", &data, e))?;
        let mut objects = Vec::new();
        for entry in entries {
            let entry = entry.map_err(|e| Error::io("list directory", &data, e))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            // Follows links: scene folders may be symlinks to where the frames live.
            let is_dir = std::fs::metadata(entry.path()).is_ok_and(|m| m.is_dir());
            if is_dir && !name.is_empty() && name.bytes().all(|b| b.is_ascii_digit()) {
                if let Ok(id) = name.parse::<u32>() {
                    objects.push(id);
                }
            }
        }
        objects.sort_unstable();
        let info_path = Self::models_info_path_of(root);
        let models_info = if info_path.exists() {
            Some(read_models_info_yml(&info_path)?)
        } else {
            None
        };
        Ok(LinemodDataset {
            root: root.to_path_buf(),
            objects,
            models_info,
        })
    }

    fn models_info_path_of(root: &Path) -> PathBuf {
        root.join("models").join("models_info.yml")
    }

    pub fn models_info_path(&self) -> PathBuf {
        Self::models_info_path_of(&self.root)
    }

    /// `models/obj_{id:02d}.ply`.
    pub fn model_ply_path(&self, obj_id: u32) -> PathBuf {
        self.root
            .join("models")
            .join(format!("obj_{obj_id:02}.ply"))
    }

    pub fn folder_dir(&self, obj_id: u32) -> PathBuf {
        self.root.join("data").join(folder_name(obj_id))
    }

    /// Reads a folder's `gt.yml`, `info.yml` and id lists (a missing list is empty).
    pub fn read_folder(&self, obj_id: u32) -> Result<LinemodFolder> {
        let dir = self.folder_dir(obj_id);
        let gt = read_gt_yml(&dir.join("gt.yml"))?;
        let info = read_info_yml(&dir.join("info.yml"))?;
        let list = |name: &str| {
            let p = dir.join(name);
            if p.exists() {
                read_id_list(&p)
            } else {
                Ok(Vec::new())
            }
        };
        let (train, test) = (list("train.txt")?, list("test.txt")?);
        if let Some(f) = gt.keys().find(|f| !info.contains_key(f)) {
            return Err(Error::malformed(
                &dir.join("gt.yml"),
                format!("frame {f} is not in info.yml"),
            ));
        }
        Ok(LinemodFolder {
            obj_id,
            dir,
            gt,
            info,
            train,
            test,
        })
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_key_names_the_key_line_and_file() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("gt.yml");
        std::fs::write(
            &p,
            "0:\n- cam_R_m2c: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n  cam_t_m2c: [0.0, 0.0, 500.0]\n  obj_id: 1\n",
        )
        .unwrap();
        let e = read_gt_yml(&p).unwrap_err().to_string();
        assert!(e.starts_with("malformed gt.yml: "), "{e}");
        assert!(e.contains("missing field `obj_bb`"), "{e}");
        assert!(e.contains("line 2"), "{e}");
        assert!(e.ends_with(&p.display().to_string()), "{e}");
    }

    #[test]
    fn real_shape_and_empty_files_read() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("gt.yml");
        // As in Linemod_preprocessed: 8-decimal fixed floats, integer boxes.
        std::fs::write(
            &p,
            "0:\n- cam_R_m2c: [0.09630630, 0.99404401, 0.05100790, 0.57332098, -0.01350810, -0.81922001, -0.81365103, 0.10814000, -0.57120699]\n  cam_t_m2c: [-105.35775150, -117.52119142, 1014.87701320]\n  obj_bb: [244, 150, 44, 58]\n  obj_id: 1\n",
        )
        .unwrap();
        let gt = read_gt_yml(&p).unwrap();
        assert_eq!(gt[&0][0].obj_bb, [244, 150, 44, 58]);
        assert_eq!(gt[&0][0].cam_t_m2c[2], 1014.8770132);
        std::fs::write(&p, "").unwrap();
        assert!(read_gt_yml(&p).unwrap().is_empty());
        let l = d.path().join("train.txt");
        std::fs::write(&l, "0000\n0012\n\n").unwrap();
        assert_eq!(read_id_list(&l).unwrap(), [0, 12]);
        std::fs::write(&l, "0000\nabc\n").unwrap();
        let e = read_id_list(&l).unwrap_err().to_string();
        assert!(e.contains("line 2: \"abc\" is not a frame id"), "{e}");
    }
}
