//! Where each Linemod frame goes in BOP terms: one rule for `convert --to bop` and for reading
//! a Linemod dataset as frames ([`crate::source::FrameSource`]), so that a Linemod dataset and
//! its BOP conversion give the same (split, scene, image, gt id) for every instance.

use std::collections::{BTreeMap, BTreeSet};

use super::{LinemodFolder, LinemodGt};
use crate::error::{Error, Result};

/// One image in BOP terms and the folders that hold it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinemodImage {
    /// `test` when any folder lists the frame in `test.txt`, else `train`.
    pub split: &'static str,
    pub scene_id: u32,
    pub im_id: u32,
    pub frame_id: u64,
    /// Indices into the folder list; the first provides rgb, depth, camera and the gt list.
    pub folders: Vec<usize>,
}

/// Whether the folders share frame ids for the same images (as synthgen writes them): every
/// frame id found in several folders has the same objects and poses there. Real
/// Linemod_preprocessed folders are separate sequences whose ids overlap with other content.
pub fn folders_share_frames(folders: &[LinemodFolder]) -> bool {
    let canonical = |v: &[LinemodGt]| {
        let mut v = v.to_vec();
        v.sort_by(|a, b| {
            a.obj_id.cmp(&b.obj_id).then(
                a.cam_t_m2c
                    .partial_cmp(&b.cam_t_m2c)
                    .unwrap_or(std::cmp::Ordering::Equal),
            )
        });
        v
    };
    let mut seen: BTreeMap<u64, Vec<LinemodGt>> = BTreeMap::new();
    for f in folders {
        for (&frame, gts) in &f.gt {
            let c = canonical(gts);
            match seen.get(&frame) {
                Some(prev) if *prev != c => return false,
                Some(_) => {}
                None => {
                    seen.insert(frame, c);
                }
            }
        }
    }
    true
}

/// The images of a Linemod dataset, sorted by (frame, folder) for shared frames or (folder,
/// frame) for separate sequences. Folders that share frame ids (synthgen's) become one scene
/// per 1000 frames (`scene = id / 1000`, `im = id % 1000`); separate sequences (real Linemod)
/// one scene per object folder (`scene` = object id, `im` = frame id). Returns whether the
/// frames are shared (then [`image_gts`] sorts each frame's objects by id).
pub fn plan_images(folders: &[LinemodFolder]) -> Result<(bool, Vec<LinemodImage>)> {
    let shared = folders_share_frames(folders);
    let split_of = |f: &LinemodFolder, frame: u64| {
        if f.test.contains(&frame) {
            "test"
        } else {
            "train"
        }
    };
    let too_large = |f: &LinemodFolder, frame: u64| {
        Error::malformed(
            &f.dir.join("gt.yml"),
            format!("frame id {frame} is too large"),
        )
    };
    let mut images = Vec::new();
    if shared {
        let mut by_frame: BTreeMap<u64, Vec<usize>> = BTreeMap::new();
        for (i, f) in folders.iter().enumerate() {
            for &frame in f.gt.keys() {
                by_frame.entry(frame).or_default().push(i);
            }
        }
        for (frame, idx) in by_frame {
            let test = idx.iter().any(|&i| split_of(&folders[i], frame) == "test");
            let scene_id =
                u32::try_from(frame / 1000).map_err(|_| too_large(&folders[idx[0]], frame))?;
            images.push(LinemodImage {
                split: if test { "test" } else { "train" },
                scene_id,
                im_id: (frame % 1000) as u32,
                frame_id: frame,
                folders: idx,
            });
        }
    } else {
        for (i, f) in folders.iter().enumerate() {
            for &frame in f.gt.keys() {
                let im_id = u32::try_from(frame).map_err(|_| too_large(f, frame))?;
                images.push(LinemodImage {
                    split: split_of(f, frame),
                    scene_id: f.obj_id,
                    im_id,
                    frame_id: frame,
                    folders: vec![i],
                });
            }
        }
    }
    Ok((shared, images))
}

/// The gt list of an image in BOP order (list index = gt id) and, per entry, the folder whose
/// `mask/` image is that entry's visible mask (the folder's own entry: same id and pose), if
/// any.
pub fn image_gts(
    folders: &[LinemodFolder],
    image: &LinemodImage,
    shared: bool,
) -> Vec<(LinemodGt, Option<usize>)> {
    let frame = image.frame_id;
    let mut gts: Vec<LinemodGt> = image
        .folders
        .first()
        .and_then(|&i| folders[i].gt.get(&frame).cloned())
        .unwrap_or_default();
    if shared {
        gts.sort_by_key(|g| g.obj_id);
    }
    let mut used = BTreeSet::new();
    gts.into_iter()
        .map(|g| {
            let owner = image.folders.iter().copied().find(|&i| {
                !used.contains(&i)
                    && folders[i]
                        .folder_gt(frame)
                        .is_some_and(|fg| fg.obj_id == g.obj_id && fg.cam_t_m2c == g.cam_t_m2c)
            });
            if let Some(i) = owner {
                used.insert(i);
            }
            (g, owner)
        })
        .collect()
}

/// Every GT rotation of the folders is a rotation (within
/// [`synthgen_core::pose::rotation_tolerance`]); the error names the folder's gt.yml, the
/// frame and the entry.
pub fn validate_gt_rotations(folders: &[super::LinemodFolder]) -> crate::error::Result<()> {
    let tol = synthgen_core::pose::rotation_tolerance();
    for f in folders {
        for (frame, gts) in &f.gt {
            for (i, g) in gts.iter().enumerate() {
                g.cam_from_obj_as_stored().validate(tol).map_err(|e| {
                    crate::error::Error::malformed(
                        &f.dir.join("gt.yml"),
                        format!("frame {frame}, entry {i}: {e}"),
                    )
                })?;
            }
        }
    }
    Ok(())
}
