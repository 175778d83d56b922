//! `NNNNNN-meta.mat`: reading with checks that name the file and the instance, and writing
//! with the keys, shapes and stored types of YCB-Video's own files (what `scipy.io.loadmat`
//! returns: `cls_indexes` uint8 (N, 1), `factor_depth` uint16 (1, 1), `poses` float64
//! (3, 4, N), `vertmap` float32 (H, W, 3), the rest float64).

use std::io::BufReader;
use std::path::Path;

use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::Pose;

use crate::bop::{GtEntry, SceneCamera};
use crate::error::{Error, Result};
use synthgen_mat::{read_mat, write_mat, MatArray, MatClass, MatData};

/// One pose as `-meta.mat` stores it: `[R | t]`, t in metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct YcbvPose {
    pub r_row_major: [f64; 9],
    pub t_m: [f64; 3],
}

impl YcbvPose {
    pub fn from_pose(p: &Pose) -> YcbvPose {
        YcbvPose {
            r_row_major: p.rotation_row_major(),
            t_m: p.translation_m.to_array(),
        }
    }

    /// A BOP gt entry's pose (the rotation's numbers kept, millimetres to metres).
    pub fn from_gt(g: &GtEntry) -> YcbvPose {
        YcbvPose {
            r_row_major: g.cam_r_m2c,
            t_m: g.cam_t_m2c.map(|v| v / 1000.0),
        }
    }

    /// The pose exactly as stored (the rotation may be approximate).
    pub fn as_stored(&self) -> Pose {
        let r = &self.r_row_major;
        let rotation = DMat3::from_cols(
            DVec3::new(r[0], r[3], r[6]),
            DVec3::new(r[1], r[4], r[7]),
            DVec3::new(r[2], r[5], r[8]),
        );
        Pose::new(rotation, DVec3::from_array(self.t_m))
    }

    /// The BOP gt entry: the rotation's numbers kept, t in millimetres.
    pub fn gt_entry(&self, obj_id: u32) -> GtEntry {
        GtEntry {
            cam_r_m2c: self.r_row_major,
            cam_t_m2c: self.t_m.map(|v| v * 1000.0),
            obj_id,
        }
    }
}

/// What a `-meta.mat` holds, apart from `vertmap`.
#[derive(Debug, Clone, PartialEq)]
pub struct YcbvMeta {
    /// Per instance: its class index (1-based line of classes.txt = BOP obj_id).
    pub cls_indexes: Vec<u32>,
    /// Per instance: `cam_from_obj`.
    pub poses: Vec<YcbvPose>,
    /// Row-major 3x3 K.
    pub intrinsic_matrix: [f64; 9],
    /// Depth PNG value / factor_depth = metres (10000 in YCB-Video).
    pub factor_depth: f64,
    /// Per instance: the projected object origin, px.
    pub center: Option<Vec<[f64; 2]>>,
    /// `cam_from_world` of the video's world frame (z up, the table at z = 0).
    pub rotation_translation_matrix: Option<YcbvPose>,
}

impl YcbvMeta {
    /// The instances as BOP gt entries (list index = gt id).
    pub fn gt(&self) -> Vec<GtEntry> {
        self.poses
            .iter()
            .zip(&self.cls_indexes)
            .map(|(p, &c)| p.gt_entry(c))
            .collect()
    }

    /// The classes with more than one instance in this frame, with their counts: a label
    /// image holds one visible mask per class, so it cannot tell these instances apart.
    pub fn shared_classes(&self) -> Vec<(u32, usize)> {
        let mut n: std::collections::BTreeMap<u32, usize> = std::collections::BTreeMap::new();
        for &c in &self.cls_indexes {
            *n.entry(c).or_default() += 1;
        }
        n.into_iter().filter(|&(_, k)| k > 1).collect()
    }

    /// Millimetres per depth PNG value (BOP's `depth_scale`): 0.1 for factor_depth 10000.
    pub fn depth_scale(&self) -> f64 {
        1000.0 / self.factor_depth
    }

    /// The frame's `scene_camera.json` entry, with the world pose when the file has one.
    pub fn scene_camera(&self) -> SceneCamera {
        let w = self.rotation_translation_matrix;
        SceneCamera {
            cam_k: self.intrinsic_matrix,
            cam_r_w2c: w.map(|p| p.r_row_major),
            cam_t_w2c: w.map(|p| p.t_m.map(|v| v * 1000.0)),
            depth_scale: self.depth_scale(),
        }
    }
}

const WANTED: [&str; 6] = [
    "cls_indexes",
    "poses",
    "intrinsic_matrix",
    "factor_depth",
    "center",
    "rotation_translation_matrix",
];

fn dims_text(dims: &[usize]) -> String {
    dims.iter()
        .map(usize::to_string)
        .collect::<Vec<_>>()
        .join("x")
}

/// `[R | t]` of a 3x4 block of a column-major array, starting at linear index `base`.
fn pose_at(v: &[f64], base: usize) -> YcbvPose {
    let at = |r: usize, c: usize| v[base + r + 3 * c];
    YcbvPose {
        r_row_major: [
            at(0, 0),
            at(0, 1),
            at(0, 2),
            at(1, 0),
            at(1, 1),
            at(1, 2),
            at(2, 0),
            at(2, 1),
            at(2, 2),
        ],
        t_m: [at(0, 3), at(1, 3), at(2, 3)],
    }
}

/// Reads a `-meta.mat`. `n_classes` (the lines of classes.txt), when given, bounds the class
/// indexes. Errors name the file and, for a pose, the instance; rotations must be within
/// [`synthgen_core::pose::rotation_tolerance`].
pub fn read_meta(path: &Path, n_classes: Option<usize>) -> Result<YcbvMeta> {
    read_meta_with(path, n_classes, true)
}

/// [`read_meta`], with the rotation check left to the caller when not `check_rotations`
/// (`validate` reports every bad rotation, not only the first).
pub(crate) fn read_meta_with(
    path: &Path,
    n_classes: Option<usize>,
    check_rotations: bool,
) -> Result<YcbvMeta> {
    let file = std::fs::File::open(path).map_err(|e| Error::io("read", path, e))?;
    let vars = read_mat(BufReader::new(file), Some(&WANTED))
        .map_err(|e| Error::malformed(path, e.to_string()))?;
    let bad = |m: String| Error::malformed(path, m);
    let get = |name: &str| {
        vars.get(name)
            .ok_or_else(|| bad(format!("no variable '{name}'")))
    };
    let finite = |name: &str, v: &[f64]| {
        if v.iter().all(|x| x.is_finite()) {
            Ok(())
        } else {
            Err(bad(format!("non-finite value in '{name}'")))
        }
    };

    let poses_var = get("poses")?;
    let pv = poses_var.to_f64();
    let n = match poses_var.dims.as_slice() {
        [3, 4] => 1,
        [3, 4, n] => *n,
        _ if pv.is_empty() => 0,
        d => return Err(bad(format!("'poses' is {}, expected 3x4xN", dims_text(d)))),
    };
    finite("poses", &pv)?;
    let cls_var = get("cls_indexes")?;
    let cls = cls_var.to_f64();
    if cls.len() != n {
        return Err(bad(format!(
            "'cls_indexes' has {} entries but 'poses' has {n}",
            cls.len()
        )));
    }
    let mut cls_indexes = Vec::with_capacity(n);
    for (i, &c) in cls.iter().enumerate() {
        let known = n_classes.is_none_or(|k| c <= k as f64);
        if !(c.fract() == 0.0 && c >= 1.0 && c <= f64::from(u32::MAX) && known) {
            let range = n_classes.map_or(String::new(), |k| {
                format!(" is outside classes.txt ({k} classes)")
            });
            return Err(bad(format!(
                "instance {i}: class index {c}{range}{}",
                if range.is_empty() {
                    " is not a positive integer"
                } else {
                    ""
                }
            )));
        }
        cls_indexes.push(c as u32);
    }
    let tol = synthgen_core::pose::rotation_tolerance();
    let mut poses = Vec::with_capacity(n);
    for (i, c) in cls_indexes.iter().enumerate() {
        let p = pose_at(&pv, 12 * i);
        if check_rotations {
            p.as_stored()
                .validate(tol)
                .map_err(|e| bad(format!("poses of instance {i} (class {c}): {e}")))?;
        }
        poses.push(p);
    }

    let k_var = get("intrinsic_matrix")?;
    if k_var.dims != [3, 3] {
        return Err(bad(format!(
            "'intrinsic_matrix' is {}, expected 3x3",
            dims_text(&k_var.dims)
        )));
    }
    let k = k_var.to_f64();
    finite("intrinsic_matrix", &k)?;
    // Column-major to row-major.
    let intrinsic_matrix = [k[0], k[3], k[6], k[1], k[4], k[7], k[2], k[5], k[8]];
    if !(intrinsic_matrix[0] > 0.0 && intrinsic_matrix[4] > 0.0) {
        return Err(bad("'intrinsic_matrix' has a focal length <= 0".into()));
    }
    let factor_depth = match get("factor_depth")?.to_f64().as_slice() {
        [f] if f.is_finite() && *f > 0.0 => *f,
        v => {
            return Err(bad(format!(
                "'factor_depth' must be one positive number, found {v:?}"
            )))
        }
    };
    let center = match vars.get("center") {
        Some(c) if c.len() == 2 * n => {
            let v = c.to_f64();
            finite("center", &v)?;
            Some((0..n).map(|i| [v[i], v[i + n]]).collect())
        }
        Some(c) => {
            return Err(bad(format!(
                "'center' is {}, expected {n}x2",
                dims_text(&c.dims)
            )))
        }
        None => None,
    };
    let rotation_translation_matrix = match vars.get("rotation_translation_matrix") {
        Some(w) if w.dims == [3, 4] => {
            let v = w.to_f64();
            finite("rotation_translation_matrix", &v)?;
            let p = pose_at(&v, 0);
            if check_rotations {
                p.as_stored()
                    .validate(tol)
                    .map_err(|e| bad(format!("rotation_translation_matrix: {e}")))?;
            }
            Some(p)
        }
        Some(w) => {
            return Err(bad(format!(
                "'rotation_translation_matrix' is {}, expected 3x4",
                dims_text(&w.dims)
            )))
        }
        None => None,
    };
    Ok(YcbvMeta {
        cls_indexes,
        poses,
        intrinsic_matrix,
        factor_depth,
        center,
        rotation_translation_matrix,
    })
}

fn mat_err(path: &Path, e: synthgen_mat::MatError) -> Error {
    Error::Encode {
        message: e.to_string(),
        path: path.to_path_buf(),
    }
}

/// A 3x4 `[R | t]` as a column-major double array.
fn pose_array(p: &YcbvPose) -> Vec<f64> {
    let r = &p.r_row_major;
    let mut v = Vec::with_capacity(12);
    for c in 0..3 {
        for row in 0..3 {
            v.push(r[3 * row + c]);
        }
    }
    v.extend_from_slice(&p.t_m);
    v
}

/// The `-meta.mat` bytes: YCB-Video's variables in its order. `vertmap` is row-major
/// (y, x, xyz) of `width` x `height` (model coordinates of the visible surface, metres, 0
/// elsewhere); `rotation_translation_matrix` is left out when `meta` has none. `path` only
/// names the file in errors.
pub fn encode_meta(
    meta: &YcbvMeta,
    vertmap: &[f32],
    width: u32,
    height: u32,
    path: &Path,
) -> Result<Vec<u8>> {
    let n = meta.poses.len();
    let err = |e| mat_err(path, e);
    let max_cls = meta.cls_indexes.iter().copied().max().unwrap_or(0);
    // MATLAB stores small integers of a double array narrowed; so do the real files.
    let cls_data = if max_cls <= u32::from(u8::MAX) {
        MatData::U8(meta.cls_indexes.iter().map(|&c| c as u8).collect())
    } else if max_cls <= u32::from(u16::MAX) {
        MatData::U16(meta.cls_indexes.iter().map(|&c| c as u16).collect())
    } else {
        MatData::F64(meta.cls_indexes.iter().map(|&c| f64::from(c)).collect())
    };
    let cls = MatArray::double(vec![n, 1], cls_data).map_err(err)?;
    let f = meta.factor_depth;
    let factor = if f.fract() == 0.0 && (0.0..=65535.0).contains(&f) {
        MatData::U16(vec![f as u16])
    } else {
        MatData::F64(vec![f])
    };
    let factor = MatArray::double(vec![1, 1], factor).map_err(err)?;
    let k = &meta.intrinsic_matrix;
    let k_col = vec![k[0], k[3], k[6], k[1], k[4], k[7], k[2], k[5], k[8]];
    let k = MatArray::double(vec![3, 3], MatData::F64(k_col)).map_err(err)?;
    let world = match &meta.rotation_translation_matrix {
        Some(w) => Some(MatArray::double(vec![3, 4], MatData::F64(pose_array(w))).map_err(err)?),
        None => None,
    };
    let (w, h) = (width as usize, height as usize);
    if vertmap.len() != w * h * 3 {
        return Err(Error::Encode {
            message: format!("vertmap has {} values for {w}x{h}x3", vertmap.len()),
            path: path.to_path_buf(),
        });
    }
    let mut vm = vec![0f32; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                vm[y + h * x + h * w * c] = vertmap[(y * w + x) * 3 + c];
            }
        }
    }
    let vertmap = MatArray::new(vec![h, w, 3], MatClass::Single, MatData::F32(vm)).map_err(err)?;
    let poses: Vec<f64> = meta.poses.iter().flat_map(pose_array).collect();
    let poses = MatArray::double(vec![3, 4, n], MatData::F64(poses)).map_err(err)?;
    let centers = meta.center.clone().unwrap_or_default();
    let mut c = vec![0.0; 2 * n];
    for (i, p) in centers.iter().enumerate().take(n) {
        c[i] = p[0];
        c[i + n] = p[1];
    }
    let center = MatArray::double(vec![n, 2], MatData::F64(c)).map_err(err)?;
    let mut vars: Vec<(&str, &MatArray)> = vec![
        ("cls_indexes", &cls),
        ("factor_depth", &factor),
        ("intrinsic_matrix", &k),
    ];
    if let Some(w) = &world {
        vars.push(("rotation_translation_matrix", w));
    }
    vars.extend([
        ("vertmap", &vertmap),
        ("poses", &poses),
        ("center", &center),
    ]);
    let mut out = Vec::new();
    write_mat(&mut out, &vars, true).map_err(err)?;
    Ok(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn meta(n: usize) -> YcbvMeta {
        let p = Pose::new(
            DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
            DVec3::new(0.01, -0.02, 0.6),
        );
        YcbvMeta {
            cls_indexes: (1..=n as u32).collect(),
            poses: vec![YcbvPose::from_pose(&p); n],
            intrinsic_matrix: synthgen_core::Intrinsics::YCBV.k_row_major(),
            factor_depth: 10000.0,
            center: Some(vec![[300.5, 200.25]; n]),
            rotation_translation_matrix: Some(YcbvPose::from_pose(&p.inverse())),
        }
    }

    #[test]
    fn meta_round_trip() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("000001-meta.mat");
        let m = meta(3);
        let (w, h) = (4u32, 3u32);
        let vm: Vec<f32> = (0..w * h * 3).map(|i| i as f32 * 0.5).collect();
        std::fs::write(&path, encode_meta(&m, &vm, w, h, &path).unwrap()).unwrap();
        assert_eq!(read_meta(&path, Some(21)).unwrap(), m);
        // The vertmap is stored column-major as MATLAB's (H, W, 3).
        let f = std::fs::File::open(&path).unwrap();
        let vars = read_mat(f, Some(&["vertmap"])).unwrap();
        let v = &vars["vertmap"];
        assert_eq!(v.dims, [3, 4, 3]);
        assert_eq!(
            v.get_f64(&[2, 1, 2]),
            Some(f64::from(vm[(2 * 4 + 1) * 3 + 2]))
        );
        let e = read_meta(&path, Some(2)).unwrap_err().to_string();
        assert!(
            e.contains("instance 2: class index 3 is outside classes.txt (2 classes)")
                && e.contains("000001-meta.mat"),
            "{e}"
        );
    }

    /// YCB-Video poses are checked like BOP's: a rotation rounded to 6 digits with det 1.01 is
    /// read (its numbers kept), one with det 1.05 is an error naming the instance.
    #[test]
    fn approximate_rotations_are_read_as_stored() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("000003-meta.mat");
        let mut m = meta(2);
        let s = 1.01f64.cbrt();
        let round6 = |v: f64| -> f64 { format!("{v:.5e}").parse().unwrap() };
        m.poses[1].r_row_major = m.poses[1].r_row_major.map(|v| round6(v * s));
        let vm = vec![0f32; 12];
        std::fs::write(&path, encode_meta(&m, &vm, 2, 2, &path).unwrap()).unwrap();
        let back = read_meta(&path, None).unwrap();
        assert_eq!(back.poses[1], m.poses[1]);
        let e = back.poses[1].as_stored().orthonormality_error();
        assert!(e > 9e-3 && e < 2e-2, "{e}");
        let s = 1.05f64.cbrt();
        m.poses[1].r_row_major = meta(2).poses[1].r_row_major.map(|v| v * s);
        std::fs::write(&path, encode_meta(&m, &vm, 2, 2, &path).unwrap()).unwrap();
        let e = read_meta(&path, None).unwrap_err().to_string();
        assert!(
            e.contains("poses of instance 1 (class 2)") && e.contains("determinant 1.05"),
            "{e}"
        );
    }

    #[test]
    fn bad_poses_are_named() {
        let d = tempfile::tempdir().unwrap();
        let path = d.path().join("000002-meta.mat");
        let mut m = meta(2);
        m.poses[1].r_row_major[0] = 2.0;
        let vm = vec![0f32; 12];
        std::fs::write(&path, encode_meta(&m, &vm, 2, 2, &path).unwrap()).unwrap();
        let e = read_meta(&path, None).unwrap_err().to_string();
        assert!(e.contains("poses of instance 1 (class 2)"), "{e}");
        // Without 'poses'.
        let k = MatArray::double(vec![3, 3], MatData::F64(vec![1.0; 9])).unwrap();
        let mut bytes = Vec::new();
        write_mat(&mut bytes, &[("intrinsic_matrix", &k)], true).unwrap();
        std::fs::write(&path, bytes).unwrap();
        let e = read_meta(&path, None).unwrap_err().to_string();
        assert!(e.contains("no variable 'poses'"), "{e}");
    }
}
