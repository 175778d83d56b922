//! What a dataset's ids stand for, so that files joined by ids alone (a detector's classes,
//! a detections file, a checkpoint) can be refused when the ids are another dataset's.
//!
//! - [`ObjectIdentity`]: an object id with its model's name, diameter and extents. Ids are
//!   only numbers: obj 5 is LM-O's can and YCB-Video's mustard bottle. Two models are the
//!   same object when their diameters and extents agree within [`SAME_OBJECT_TOLERANCE`]
//!   (a textured scan aligned onto a model, or a model rewritten in another layout, agree to
//!   well under 1 %); names are shown, not compared (BOP's `obj_000005` and YCB-Video's
//!   `006_mustard_bottle` are one object).
//! - [`FramesKey`]: the frames of a split, their image size and their colour files' sizes,
//!   hashed: equal for copies of a dataset, different for another rendering with the same
//!   ids.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

use crate::fingerprint::fnv1a;
use crate::source::{FrameSource, SourceFrame};

/// Relative difference of diameter and extents up to which two models are one object.
pub const SAME_OBJECT_TOLERANCE: f64 = 0.05;

/// An object id and what its model is.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObjectIdentity {
    pub id: u32,
    /// The model's name in its dataset (`obj_000005`, `006_mustard_bottle`).
    pub name: String,
    pub diameter_mm: f64,
    /// The model's bounding box, x y z.
    pub size_mm: [f64; 3],
}

impl ObjectIdentity {
    /// Whether `other` is the same object (ids aside): diameter and extents within
    /// [`SAME_OBJECT_TOLERANCE`] (1 mm at least).
    pub fn same_object(&self, other: &ObjectIdentity) -> bool {
        let close = |a: f64, b: f64| {
            (a - b).abs() <= (SAME_OBJECT_TOLERANCE * a.abs().max(b.abs())).max(1.0)
        };
        close(self.diameter_mm, other.diameter_mm)
            && self
                .size_mm
                .iter()
                .zip(&other.size_mm)
                .all(|(&a, &b)| close(a, b))
    }

    /// "5 (obj_000005, 201 mm)".
    pub fn describe(&self) -> String {
        format!("{} ({}, {:.0} mm)", self.id, self.name, self.diameter_mm)
    }
}

/// How a dataset names object `id`'s model: YCB-Video's class folder
/// (`models/<class>/textured_simple.obj`), else the file stem (`obj_000005`).
pub fn model_name(source: &dyn FrameSource, id: u32) -> String {
    let file = source.model_file(id);
    let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned());
    match (stem.as_deref(), file.parent().and_then(|p| p.file_name())) {
        (Some("textured_simple" | "textured"), Some(class)) => class.to_string_lossy().into_owned(),
        (Some(stem), _) => stem.to_string(),
        _ => format!("obj_{id:06}"),
    }
}

/// The identity of every object of `source` with a model (from its `models_info`).
pub fn dataset_objects(source: &dyn FrameSource) -> BTreeMap<u32, ObjectIdentity> {
    source
        .models_info()
        .map(|info| {
            info.iter()
                .map(|(&id, m)| {
                    (
                        id,
                        ObjectIdentity {
                            id,
                            name: model_name(source, id),
                            diameter_mm: m.diameter,
                            size_mm: [m.size_x, m.size_y, m.size_z],
                        },
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The objects of `expected` whose id `source` has for another object: (expected, the
/// dataset's). Ids the dataset has no model of are not compared.
pub fn mismatched_objects(
    expected: &[ObjectIdentity],
    source: &dyn FrameSource,
) -> Vec<(ObjectIdentity, ObjectIdentity)> {
    let here = dataset_objects(source);
    expected
        .iter()
        .filter_map(|e| {
            here.get(&e.id)
                .filter(|h| !e.same_object(h))
                .map(|h| (e.clone(), h.clone()))
        })
        .collect()
}

/// A one-line account of mismatched objects: "object 5 is 5 (obj_000005, 120 mm) there and
/// 5 (006_mustard_bottle, 203 mm) here; ...".
pub fn describe_mismatches(m: &[(ObjectIdentity, ObjectIdentity)]) -> String {
    let mut s = String::new();
    for (i, (there, here)) in m.iter().enumerate().take(4) {
        if i > 0 {
            s.push_str("; ");
        }
        let _ = write!(
            s,
            "object {} is {} there and {} here",
            there.id,
            there.describe(),
            here.describe()
        );
    }
    if m.len() > 4 {
        let _ = write!(s, "; and {} more", m.len() - 4);
    }
    s
}

/// The frames of one split as files that name frames by ids must match them.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct FramesKey {
    pub frames: usize,
    /// `camera.json`'s image size.
    pub image_size: [u32; 2],
    /// FNV-1a of the sorted "scene im rgb_bytes" lines, hex.
    pub hash: String,
}

/// The [`FramesKey`] of `frames` (their colour files' sizes are read with one `stat` each).
pub fn frames_key(frames: &[SourceFrame], image_size: [u32; 2]) -> FramesKey {
    let mut lines: Vec<String> = frames
        .iter()
        .map(|f| {
            let bytes = std::fs::metadata(&f.rgb).map_or(0, |m| m.len());
            format!("{} {} {bytes}", f.location.scene_id, f.location.im_id)
        })
        .collect();
    lines.sort();
    FramesKey {
        frames: frames.len(),
        image_size,
        hash: format!("{:016x}", fnv1a(lines.join("\n").as_bytes())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obj(id: u32, d: f64, s: [f64; 3]) -> ObjectIdentity {
        ObjectIdentity {
            id,
            name: format!("obj_{id:06}"),
            diameter_mm: d,
            size_mm: s,
        }
    }

    #[test]
    fn same_object_within_tolerance_other_objects_apart() {
        let can = obj(5, 201.4, [100.8, 181.8, 193.7]);
        let scan = obj(5, 203.0, [101.5, 182.0, 195.0]);
        let mustard = obj(5, 196.5, [90.0, 60.0, 190.0]);
        assert!(can.same_object(&scan));
        assert!(!can.same_object(&mustard));
        let text = describe_mismatches(&[(can, mustard)]);
        assert!(
            text.contains("object 5 is 5 (obj_000005, 201 mm) there"),
            "{text}"
        );
    }
}
