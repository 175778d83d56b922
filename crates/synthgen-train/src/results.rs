//! BOP results CSV (`scene_id,im_id,obj_id,score,R,t,time`): R is 9 space-separated values,
//! row-major; t is 3 space-separated values in millimetres; time in seconds (−1 = unknown).

use std::path::Path;

use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::Pose;

use crate::error::{Error, Result};
use crate::metrics::Rotations;

/// A pose as a BOP file stores it: rotation (used as given) and translation in millimetres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawPose {
    pub r: DMat3,
    pub t_mm: DVec3,
}

impl RawPose {
    /// From BOP's row-major `cam_R_m2c` and `cam_t_m2c` (mm).
    pub fn from_bop(r_row_major: &[f64; 9], t_mm: &[f64; 3]) -> RawPose {
        let r = r_row_major;
        RawPose {
            r: DMat3::from_cols(
                DVec3::new(r[0], r[3], r[6]),
                DVec3::new(r[1], r[4], r[7]),
                DVec3::new(r[2], r[5], r[8]),
            ),
            t_mm: DVec3::from_array(*t_mm),
        }
    }

    /// From a pose in metres (what a model predicts).
    pub fn from_pose(p: &synthgen_core::Pose) -> RawPose {
        RawPose::from_bop(&p.rotation_row_major(), &p.translation_mm())
    }

    #[inline(always)]
    pub(crate) fn apply(&self, p: DVec3) -> DVec3 {
        self.r * p + self.t_mm
    }
}

/// One pose estimate of a results file, converted to metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate {
    pub scene_id: u32,
    pub im_id: u32,
    pub obj_id: u32,
    pub score: f64,
    /// `cam_from_obj`, metres, with the nearest proper rotation.
    pub pose: Pose,
    /// The pose exactly as the file stores it (rotation as given, mm): what BOP's metrics
    /// use, as bop_toolkit does.
    pub stored: RawPose,
    pub time_s: f64,
}

impl Estimate {
    /// The pose the metrics use with `rotations` (metres).
    pub fn pose_for(&self, rotations: Rotations) -> Pose {
        match rotations {
            Rotations::AsStored => Pose::new(self.stored.r, self.stored.t_mm / 1000.0),
            Rotations::Nearest => self.pose,
        }
    }

    /// An estimate of a pose in metres (a model's prediction): stored as it is.
    pub fn new(scene_id: u32, im_id: u32, obj_id: u32, score: f64, pose: Pose) -> Estimate {
        Estimate {
            scene_id,
            im_id,
            obj_id,
            score,
            pose,
            stored: RawPose::from_pose(&pose),
            time_s: -1.0,
        }
    }
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

/// Where each field sits in a row: from the header's names (any order, as bop_toolkit's
/// results are read by name), else the standard order.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Columns {
    scene_id: usize,
    im_id: usize,
    obj_id: usize,
    score: usize,
    r: usize,
    t: usize,
    /// Optional: unknown (−1) when the file has no `time` column.
    time: Option<usize>,
    width: usize,
}

const STANDARD: Columns = Columns {
    scene_id: 0,
    im_id: 1,
    obj_id: 2,
    score: 3,
    r: 4,
    t: 5,
    time: Some(6),
    width: 7,
};

/// The columns a header names; an error names what is missing or repeated.
fn columns_of(header: &str) -> std::result::Result<Columns, String> {
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let find = |name: &str| -> std::result::Result<Option<usize>, String> {
        let at: Vec<usize> = (0..names.len()).filter(|&i| names[i] == name).collect();
        match at.as_slice() {
            [] => Ok(None),
            [i] => Ok(Some(*i)),
            _ => Err(format!("header names column {name:?} twice")),
        }
    };
    let need = |name: &str| {
        find(name)?.ok_or_else(|| format!("header has no column {name:?} (expected {HEADER})"))
    };
    Ok(Columns {
        scene_id: need("scene_id")?,
        im_id: need("im_id")?,
        obj_id: need("obj_id")?,
        score: need("score")?,
        r: need("R")?,
        t: need("t")?,
        time: find("time")?,
        width: names.len(),
    })
}

fn parse_line(line: &str, c: &Columns) -> std::result::Result<Estimate, String> {
    let f: Vec<&str> = line.split(',').map(str::trim).collect();
    if f.len() != c.width {
        return Err(format!(
            "expected {} comma-separated fields, found {}",
            c.width,
            f.len()
        ));
    }
    let id = |s: &str, what: &str| {
        s.parse::<u32>()
            .map_err(|_| format!("{what}: not a non-negative integer: {s:?}"))
    };
    let score: f64 = f[c.score]
        .parse()
        .map_err(|_| format!("score: not a number: {:?}", f[c.score]))?;
    if !score.is_finite() {
        return Err(format!("score: not a finite number: {:?}", f[c.score]));
    }
    let r = floats::<9>(f[c.r], "R")?;
    let t = floats::<3>(f[c.t], "t")?;
    let time_s: f64 = match c.time {
        Some(i) => f[i]
            .parse()
            .map_err(|_| format!("time: not a number: {:?}", f[i]))?,
        None => -1.0,
    };
    // Estimates, like annotations, may store rotations with a few digits: accepted within the
    // reading tolerance, scored with the nearest proper rotation.
    let stored = RawPose::from_bop(&r, &t);
    let pose = Pose::from_bop(&r, &t);
    pose.validate(synthgen_core::pose::rotation_tolerance())
        .map_err(|e| format!("R: {e}"))?;
    let pose = pose.orthonormalized();
    Ok(Estimate {
        scene_id: id(f[c.scene_id], "scene_id")?,
        im_id: id(f[c.im_id], "im_id")?,
        obj_id: id(f[c.obj_id], "obj_id")?,
        score,
        pose,
        stored,
        time_s,
    })
}

/// A row that could not be read, skipped.
#[derive(Debug, Clone, PartialEq)]
pub struct RowProblem {
    /// 1-based line in the file.
    pub line: usize,
    pub message: String,
}

/// What a results file holds: the rows that parse, and the ones that did not (each skipped,
/// as ripgrep goes on past a bad file: one bad row must not sink the others).
#[derive(Debug, Clone, PartialEq)]
pub struct ResultsFile {
    pub estimates: Vec<Estimate>,
    pub skipped: Vec<RowProblem>,
}

/// Parses a results CSV. The header line (`scene_id,im_id,obj_id,score,R,t,time`, columns
/// in any order, `time` optional) is read by name; without one the columns are in that
/// order. Blank lines are skipped; a bad row is recorded in `skipped`. A file with no
/// estimate at all is an error, naming the file (and its first bad row).
pub fn parse_results_csv(text: &str, path: &Path) -> Result<ResultsFile> {
    let mut estimates = Vec::new();
    let mut skipped = Vec::new();
    let mut columns: Option<Columns> = None;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let c = match columns {
            Some(c) => c,
            // The first line is a header when its first field is not a number.
            None if line
                .split(',')
                .next()
                .is_some_and(|f| f.trim().parse::<f64>().is_err()) =>
            {
                let c = columns_of(line).map_err(|message| Error::Csv {
                    path: path.to_path_buf(),
                    line: i + 1,
                    message,
                })?;
                columns = Some(c);
                continue;
            }
            None => {
                columns = Some(STANDARD);
                STANDARD
            }
        };
        match parse_line(line, &c) {
            Ok(e) => estimates.push(e),
            Err(message) => skipped.push(RowProblem {
                line: i + 1,
                message,
            }),
        }
    }
    if estimates.is_empty() {
        let message = match skipped.first() {
            Some(p) => format!(
                "no estimate can be read ({} bad rows; the first, line {}: {})",
                skipped.len(),
                p.line,
                p.message
            ),
            None => "no estimates: the file has no rows".to_string(),
        };
        return Err(Error::Csv {
            path: path.to_path_buf(),
            line: skipped.first().map_or(1, |p| p.line),
            message,
        });
    }
    Ok(ResultsFile { estimates, skipped })
}

pub fn read_results_csv(path: &Path) -> Result<ResultsFile> {
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

/// Writes `estimates` as a BOP results CSV (with bop_toolkit's header), atomically.
pub fn write_results_csv(path: &Path, estimates: &[Estimate]) -> Result<()> {
    let mut text = String::from("scene_id,im_id,obj_id,score,R,t,time\n");
    for e in estimates {
        text += &format_estimate(e);
        text.push('\n');
    }
    synthgen_core::atomic::write_atomic(path, text.as_bytes(), false)
        .map_err(|(_, e)| Error::io("write", path, e))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use synthgen_core::glam::{DMat3, DVec3};

    #[test]
    fn round_trip_in_millimetres() {
        let e = Estimate::new(
            2,
            17,
            8,
            0.5,
            Pose::new(DMat3::from_rotation_z(0.3), DVec3::new(0.01, -0.02, 0.9)),
        );
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        write_results_csv(&path, &[e, e]).unwrap();
        let back = read_results_csv(&path).unwrap();
        assert_eq!(back.estimates.len(), 2);
        assert!(back.skipped.is_empty());
        assert!((back.estimates[1].pose.translation_m - e.pose.translation_m).length() < 1e-12);
        let line = format_estimate(&e);
        assert!(line.contains(",10 -20 900,"), "{line}");
        let back = parse_results_csv(&format!("{HEADER}\n{line}\n"), Path::new("r.csv"))
            .unwrap()
            .estimates;
        assert_eq!(back.len(), 1);
        assert!((back[0].pose.translation_m - e.pose.translation_m).length() < 1e-12);
        assert_eq!(back[0].obj_id, 8);
    }

    #[test]
    fn bad_rows_are_skipped_and_named() {
        let text =
            format!("{HEADER}\n1,2,3,1.0,1 0 0 0 1 0 0 0 1,0 0 500,-1\n1,2,3,1.0,1 0 0,0 0 1,-1\n");
        let r = parse_results_csv(&text, Path::new("res.csv")).unwrap();
        assert_eq!(r.estimates.len(), 1);
        assert_eq!(r.skipped[0].line, 3);
        assert!(
            r.skipped[0].message.starts_with("R: expected 9 values"),
            "{:?}",
            r.skipped
        );
        let bad = |text: &str| {
            parse_results_csv(
                &format!("{text}\n1,2,3,1,1 0 0 0 1 0 0 0 1,0 0 1,-1"),
                Path::new("a.csv"),
            )
            .unwrap()
            .skipped[0]
                .message
                .clone()
        };
        assert!(bad("1,2,x,1,1 0 0 0 1 0 0 0 1,0 0 1,-1").starts_with("obj_id"));
        assert!(bad("1,2,3,1,2 0 0 0 1 0 0 0 1,0 0 1,-1").starts_with("R: invalid pose"));
    }

    /// Issue 13, item 8: a header with swapped columns was read by position ("score: not a
    /// number: \"score\""); it is read by name, as bop_toolkit reads it.
    #[test]
    fn results_csv_columns_are_read_by_name() {
        let text = "im_id,scene_id,score,obj_id,t,R\n2,1,0.9,3,0 0 500,1 0 0 0 1 0 0 0 1\n";
        let r = parse_results_csv(text, Path::new("swapped.csv")).unwrap();
        assert!(r.skipped.is_empty(), "{:?}", r.skipped);
        let e = &r.estimates[0];
        assert_eq!(
            (e.scene_id, e.im_id, e.obj_id, e.score, e.time_s),
            (1, 2, 3, 0.9, -1.0)
        );
        assert!((e.pose.translation_m.z - 0.5).abs() < 1e-12);
        let e = parse_results_csv("scene_id,im_id,score,R,t\n", Path::new("h.csv")).unwrap_err();
        assert!(e.to_string().contains("no column \"obj_id\""), "{e}");
    }

    /// Issue 13, item 8: an empty file scored 0% everywhere with exit 0; a NaN score was
    /// accepted.
    #[test]
    fn results_csv_empty_or_nan_score_is_refused() {
        for text in ["", "scene_id,im_id,obj_id,score,R,t,time\n", "\n\n"] {
            let e = parse_results_csv(text, Path::new("empty.csv")).unwrap_err();
            assert!(e.to_string().contains("no estimates"), "{e}");
        }
        let text = format!("{HEADER}\n1,2,3,NaN,1 0 0 0 1 0 0 0 1,0 0 1,-1\n");
        let e = parse_results_csv(&text, Path::new("nan.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("score: not a finite number"), "{e}");
        let text = format!("{text}1,2,3,0.5,1 0 0 0 1 0 0 0 1,0 0 1,-1\n");
        let r = parse_results_csv(&text, Path::new("nan.csv")).unwrap();
        assert_eq!((r.estimates.len(), r.skipped.len()), (1, 1));
    }
}
