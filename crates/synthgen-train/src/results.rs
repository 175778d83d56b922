//! BOP results CSV (`scene_id,im_id,obj_id,score,R,t,time`): R is 9 space-separated values,
//! row-major; t is 3 space-separated values in millimetres; time in seconds (−1 = unknown).

use std::path::Path;

use synthgen_core::Pose;

use crate::error::{Error, Result};

/// One pose estimate of a results file, converted to metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub scene_id: u32,
    pub im_id: u32,
    pub obj_id: u32,
    pub score: f64,
    /// `cam_from_obj`, metres.
    pub pose: Pose,
    pub time_s: f64,
}

pub const HEADER: &str = "scene_id,im_id,obj_id,score,R,t,time";

fn floats<const N: usize>(field: &str, what: &str) -> std::result::Result<[f64; N], String> {
    let vals: Vec<f64> = field
        .split_whitespace()
        .map(|v| {
            v.parse::<f64>()
                .map_err(|_| format!("{what}: not a number: {v:?}"))
        })
        .collect::<std::result::Result<_, _>>()?;
    if vals.iter().any(|v| !v.is_finite()) {
        return Err(format!("{what}: non-finite value"));
    }
    vals.try_into()
        .map_err(|v: Vec<f64>| format!("{what}: expected {N} values, found {}", v.len()))
}

fn parse_line(line: &str) -> std::result::Result<Estimate, String> {
    let f: Vec<&str> = line.split(',').map(str::trim).collect();
    if f.len() != 7 {
        return Err(format!(
            "expected 7 comma-separated fields ({HEADER}), found {}",
            f.len()
        ));
    }
    let id = |s: &str, what: &str| {
        s.parse::<u32>()
            .map_err(|_| format!("{what}: not a non-negative integer: {s:?}"))
    };
    let score: f64 = f[3]
        .parse()
        .map_err(|_| format!("score: not a number: {:?}", f[3]))?;
    let r = floats::<9>(f[4], "R")?;
    let t = floats::<3>(f[5], "t")?;
    let time_s: f64 = f[6]
        .parse()
        .map_err(|_| format!("time: not a number: {:?}", f[6]))?;
    // Estimates, like annotations, may store rotations with a few digits: accepted within the
    // reading tolerance, scored with the nearest proper rotation.
    let pose = Pose::from_bop(&r, &t);
    pose.validate(synthgen_core::pose::rotation_tolerance())
        .map_err(|e| format!("R: {e}"))?;
    let pose = pose.orthonormalized();
    Ok(Estimate {
        scene_id: id(f[0], "scene_id")?,
        im_id: id(f[1], "im_id")?,
        obj_id: id(f[2], "obj_id")?,
        score,
        pose,
        time_s,
    })
}

/// Parses a results CSV; the header line is optional, blank lines are skipped. Errors name
/// the file and the 1-based line.
pub fn parse_results_csv(text: &str, path: &Path) -> Result<Vec<Estimate>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || (i == 0 && line.starts_with("scene_id")) {
            continue;
        }
        out.push(parse_line(line).map_err(|message| Error::Csv {
            path: path.to_path_buf(),
            line: i + 1,
            message,
        })?);
    }
    Ok(out)
}

pub fn read_results_csv(path: &Path) -> Result<Vec<Estimate>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io("read", path, e))?;
    parse_results_csv(&text, path)
}

/// One CSV line for an estimate (no newline), as bop_toolkit writes them.
pub fn format_estimate(e: &Estimate) -> String {
    let r = e.pose.rotation_row_major().map(|v| v.to_string()).join(" ");
    let t = e.pose.translation_mm().map(|v| v.to_string()).join(" ");
    format!(
        "{},{},{},{},{r},{t},{}",
        e.scene_id, e.im_id, e.obj_id, e.score, e.time_s
    )
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::{DMat3, DVec3};

    #[test]
    fn round_trip_in_millimetres() {
        let e = Estimate {
            scene_id: 2,
            im_id: 17,
            obj_id: 8,
            score: 0.5,
            pose: Pose::new(DMat3::from_rotation_z(0.3), DVec3::new(0.01, -0.02, 0.9)),
            time_s: -1.0,
        };
        let line = format_estimate(&e);
        assert!(line.contains(",10 -20 900,"), "{line}");
        let back = parse_results_csv(&format!("{HEADER}\n{line}\n"), Path::new("r.csv")).unwrap();
        assert_eq!(back.len(), 1);
        assert!((back[0].pose.translation_m - e.pose.translation_m).length() < 1e-12);
        assert_eq!(back[0].obj_id, 8);
    }

    #[test]
    fn errors_name_file_and_line() {
        let text =
            format!("{HEADER}\n1,2,3,1.0,1 0 0 0 1 0 0 0 1,0 0 500,-1\n1,2,3,1.0,1 0 0,0 0 1,-1\n");
        let err = parse_results_csv(&text, Path::new("res.csv")).unwrap_err();
        let msg = err.to_string();
        assert!(msg.starts_with("res.csv:3: R: expected 9 values"), "{msg}");
        let err = parse_results_csv("1,2,x,1,1 0 0 0 1 0 0 0 1,0 0 1,-1", Path::new("a.csv"))
            .unwrap_err();
        assert!(err.to_string().starts_with("a.csv:1: obj_id"), "{err}");
        let err = parse_results_csv("1,2,3,1,2 0 0 0 1 0 0 0 1,0 0 1,-1", Path::new("a.csv"))
            .unwrap_err();
        assert!(
            err.to_string().starts_with("a.csv:1: R: invalid pose"),
            "{err}"
        );
    }
}
