//! YAML text of `gt.yml`, `info.yml` and `models_info.yml` in the shape of the real
//! Linemod_preprocessed files (block maps keyed by integer, flow lists of numbers). Written by
//! hand, like the BOP JSON, so the layout is exact; read with `serde_yaml_ng`.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::{LinemodGt, LinemodInfo};
use crate::bop::json::py_float_repr;
use crate::bop::ModelInfo;

/// A float as YAML that both YAML 1.1 (PyYAML) and 1.2 read back as the same float:
/// shortest round-trip digits, always with a `.` (PyYAML reads `1e-05` as a string).
/// `None` for NaN and infinities.
pub fn yaml_float(x: f64) -> Option<String> {
    // -0.0 comes out of inversions; files show 0.0.
    let s = py_float_repr(x + 0.0)?;
    Some(match s.split_once('e') {
        Some((m, e)) if !m.contains('.') => format!("{m}.0e{e}"),
        _ => s,
    })
}

fn floats(out: &mut String, values: &[f64]) -> Option<()> {
    out.push('[');
    for (i, v) in values.iter().enumerate() {
        if i > 0 {
            out.push_str(", ");
        }
        out.push_str(&yaml_float(*v)?);
    }
    out.push(']');
    Some(())
}

/// `gt.yml`: `frame:` then one `- cam_R_m2c: [...]` block per object. `None` when a value is
/// not finite.
pub fn gt_yml_text(gt: &BTreeMap<u64, Vec<LinemodGt>>) -> Option<String> {
    let mut out = String::new();
    for (frame, entries) in gt {
        let _ = writeln!(out, "{frame}:");
        if entries.is_empty() {
            // An empty list must be spelled out, or the key would map to null.
            out.truncate(out.len() - 1);
            out.push_str(" []\n");
            continue;
        }
        for g in entries {
            out.push_str("- cam_R_m2c: ");
            floats(&mut out, &g.cam_r_m2c)?;
            out.push_str("\n  cam_t_m2c: ");
            floats(&mut out, &g.cam_t_m2c)?;
            let [x, y, w, h] = g.obj_bb;
            let _ = writeln!(out, "\n  obj_bb: [{x}, {y}, {w}, {h}]");
            let _ = writeln!(out, "  obj_id: {}", g.obj_id);
        }
    }
    Some(out)
}

/// `info.yml`: `frame:` then `cam_K` and `depth_scale`.
pub fn info_yml_text(info: &BTreeMap<u64, LinemodInfo>) -> Option<String> {
    let mut out = String::new();
    for (frame, i) in info {
        let _ = write!(out, "{frame}:\n  cam_K: ");
        floats(&mut out, &i.cam_k)?;
        let _ = writeln!(out, "\n  depth_scale: {}", yaml_float(i.depth_scale)?);
    }
    Some(out)
}

/// `models_info.yml`: one flow map per object id (symmetries are not part of this format).
pub fn models_info_yml_text(models: &BTreeMap<u32, ModelInfo>) -> Option<String> {
    let mut out = String::new();
    for (id, m) in models {
        let fields = [
            ("diameter", m.diameter),
            ("min_x", m.min_x),
            ("min_y", m.min_y),
            ("min_z", m.min_z),
            ("size_x", m.size_x),
            ("size_y", m.size_y),
            ("size_z", m.size_z),
        ];
        let _ = write!(out, "{id}: {{");
        for (i, (k, v)) in fields.iter().enumerate() {
            if i > 0 {
                out.push_str(", ");
            }
            let _ = write!(out, "{k}: {}", yaml_float(*v)?);
        }
        out.push_str("}\n");
    }
    Some(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn floats_always_have_a_dot() {
        assert_eq!(yaml_float(1e-5).unwrap(), "1.0e-05");
        assert_eq!(yaml_float(1.5e-5).unwrap(), "1.5e-05");
        assert_eq!(yaml_float(1e16).unwrap(), "1.0e+16");
        assert_eq!(yaml_float(-0.0).unwrap(), "0.0");
        assert_eq!(yaml_float(572.4114).unwrap(), "572.4114");
        assert_eq!(yaml_float(f64::NAN), None);
    }

    #[test]
    fn gt_text_has_the_real_shape_and_reads_back() {
        let g = LinemodGt {
            cam_r_m2c: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            cam_t_m2c: [-105.35775150, 1e-7, 1014.877],
            obj_bb: [244, 150, 44, 58],
            obj_id: 1,
        };
        let map = BTreeMap::from([(0u64, vec![g, g]), (3, vec![])]);
        let text = gt_yml_text(&map).unwrap();
        assert!(text.starts_with(
            "0:\n- cam_R_m2c: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]\n  cam_t_m2c: [-105.3577515, 1.0e-07, 1014.877]\n  obj_bb: [244, 150, 44, 58]\n  obj_id: 1\n- cam_R_m2c"
        ), "{text}");
        assert!(text.ends_with("3: []\n"), "{text}");
        let back: BTreeMap<u64, Vec<LinemodGt>> = serde_yaml_ng::from_str(&text).unwrap();
        assert_eq!(back, map);
    }

    #[test]
    fn info_and_models_info_read_back() {
        let info = BTreeMap::from([(
            7u64,
            LinemodInfo {
                cam_k: [
                    572.4114, 0.0, 325.2611, 0.0, 573.57043, 242.04899, 0.0, 0.0, 1.0,
                ],
                depth_scale: 1.0,
            },
        )]);
        let text = info_yml_text(&info).unwrap();
        assert_eq!(text, "7:\n  cam_K: [572.4114, 0.0, 325.2611, 0.0, 573.57043, 242.04899, 0.0, 0.0, 1.0]\n  depth_scale: 1.0\n");
        let back: BTreeMap<u64, LinemodInfo> = serde_yaml_ng::from_str(&text).unwrap();
        assert_eq!(back, info);
        let m = ModelInfo {
            diameter: 102.099,
            min_x: -37.9343,
            min_y: -38.7996,
            min_z: -45.8845,
            size_x: 75.8686,
            size_y: 77.5992,
            size_z: 91.769,
            symmetries: Default::default(),
        };
        let text = models_info_yml_text(&BTreeMap::from([(1, m.clone())])).unwrap();
        assert_eq!(text, "1: {diameter: 102.099, min_x: -37.9343, min_y: -38.7996, min_z: -45.8845, size_x: 75.8686, size_y: 77.5992, size_z: 91.769}\n");
        let back: BTreeMap<u32, ModelInfo> = serde_yaml_ng::from_str(&text).unwrap();
        assert_eq!(back[&1], m);
    }
}
