//! `synthgen validate`: checks a BOP or Linemod dataset against its format and collects every
//! problem found (one bad file does not stop the run), each naming its file.
//!
//! Checks: every referenced file present and decodable, image sizes equal to the camera's,
//! rotations orthonormal with determinant 1 (within [`Checks::rotation_tolerance`]; those
//! within it but not exact are counted as one warning, as real annotations are), masks
//! non-empty where the object is visible, BOP pixel counts equal to the masks', depth under
//! the visible masks within the object's depth range, object ids known to `models_info` and
//! present as model files.

mod bop;
mod linemod;
mod ycbv;

use std::path::{Path, PathBuf};

use serde::Serialize;
use synthgen_core::{Pose, Progress};

use crate::bop::{ModelInfo, Plane};
use crate::error::Error;
use crate::layout::Layout;

/// One problem found, with the file it is about.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Problem {
    pub path: PathBuf,
    pub message: String,
}

/// Tolerances of the checks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Checks {
    /// Largest |det R − 1| and |R Rᵀ − I| entry accepted (files store 6–17 digits; real
    /// hand-made annotations are off by up to ~1.4e-2). Rotations off by more than
    /// [`synthgen_core::pose::EXACT_ROTATION_TOLERANCE`] but within this are a warning.
    pub rotation_tolerance: f64,
    /// Depth under a visible mask must lie within t_z ± (model radius + this), in mm. The
    /// radius is the farthest corner of the model's box from its origin (models_info); 15 mm is
    /// bop_toolkit's visibility delta.
    pub depth_tolerance_mm: f64,
    /// A mask's depth is reported when more than this fraction of its pixels with depth is out
    /// of range. Real sensors read the background along a visible mask's edges: under the
    /// labels of YCB-Video's thin marker up to 11% of the readings are the table behind it,
    /// while depth in the wrong unit or a misplaced mask is out of range nearly everywhere.
    pub depth_outlier_fraction: f64,
}

impl Default for Checks {
    fn default() -> Self {
        Checks {
            rotation_tolerance: synthgen_core::pose::rotation_tolerance(),
            depth_tolerance_mm: 15.0,
            depth_outlier_fraction: 0.25,
        }
    }
}

/// What [`validate`] found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    pub layout: Layout,
    pub frames: u64,
    pub instances: u64,
    pub images_checked: u64,
    pub problems: Vec<Problem>,
    /// What is accepted but worth knowing (approximate rotations), one entry per kind.
    pub warnings: Vec<Problem>,
}

/// Checks the dataset at `root`, collecting every problem.
pub fn validate(root: &Path, layout: Layout, checks: &Checks, progress: &dyn Progress) -> Report {
    let mut ctx = Ctx {
        root: root.to_path_buf(),
        checks: *checks,
        report: Report {
            layout,
            frames: 0,
            instances: 0,
            images_checked: 0,
            problems: Vec::new(),
            warnings: Vec::new(),
        },
        approximate: ApproximateRotations::default(),
    };
    match layout {
        Layout::Bop => bop::validate(&mut ctx, progress),
        Layout::Linemod => linemod::validate(&mut ctx, progress),
        Layout::Ycbv => ycbv::validate(&mut ctx, progress),
    }
    if let Some(w) = ctx.approximate.warning(ctx.checks.rotation_tolerance) {
        ctx.report.warnings.push(w);
    }
    ctx.report
}

/// Rotations within the tolerance but not exact: counted, the worst one named.
#[derive(Default)]
struct ApproximateRotations {
    checked: u64,
    count: u64,
    worst: Option<(f64, PathBuf, String)>,
}

impl ApproximateRotations {
    fn warning(&self, tol: f64) -> Option<Problem> {
        let (err, path, what) = self.worst.as_ref()?;
        Some(Problem {
            path: path.clone(),
            message: format!(
                "{} of {} rotations are not orthonormal to {:e} but within the tolerance {tol} \
                 (accepted, used as the nearest rotation; the largest deviation, {err:.2e}, is \
                 {what})",
                self.count,
                self.checked,
                synthgen_core::pose::EXACT_ROTATION_TOLERANCE,
            ),
        })
    }
}

pub(crate) struct Ctx {
    pub root: PathBuf,
    pub checks: Checks,
    pub report: Report,
    approximate: ApproximateRotations,
}

impl Ctx {
    pub fn problem(&mut self, path: &Path, message: impl Into<String>) {
        self.report.problems.push(Problem {
            path: path.to_path_buf(),
            message: message.into(),
        });
    }

    /// A library error as a problem: its file, and its message without the trailing path.
    pub fn error(&mut self, fallback: &Path, e: &Error) {
        let path = e.path().unwrap_or(fallback).to_path_buf();
        let text = e.to_string();
        let suffix = format!(": {}", path.display());
        let message = text.strip_suffix(&suffix).unwrap_or(&text).to_string();
        self.report.problems.push(Problem { path, message });
    }

    /// Reports a rotation that is not orthonormal with determinant 1 within the tolerance
    /// (a problem), and counts one that is within it but not exact (a warning).
    pub fn check_rotation(&mut self, path: &Path, what: &str, r: &[f64; 9], t: &[f64; 3]) {
        let pose = Pose::from_bop(r, t);
        self.approximate.checked += 1;
        if let Err(e) = pose.validate(self.checks.rotation_tolerance) {
            self.problem(path, format!("{what}: {e}"));
            return;
        }
        let err = pose.orthonormality_error();
        if err > synthgen_core::pose::EXACT_ROTATION_TOLERANCE {
            let a = &mut self.approximate;
            a.count += 1;
            if a.worst.as_ref().is_none_or(|(w, _, _)| err > *w) {
                a.worst = Some((err, path.to_path_buf(), what.to_string()));
            }
        }
    }

    /// Reports depth under `mask` outside `t_z ± (radius + tolerance)`. Only the mask's
    /// interior is judged (pixels at least [`DEPTH_EDGE_PX`] from its edge): a depth sensor's
    /// edge artefacts (mixed and shifted readings, real ones and synthgen's sensor models
    /// alike) are a large share of a small mask. A mask with fewer than
    /// [`MIN_INTERIOR_READINGS`] interior readings (a sliver beside an occluder, which a
    /// sensor's shifted and mixed readings can cover entirely) is judged by the median of all
    /// its readings, and only for a gross error: more than [`GROSS_DEPTH_FACTOR`] times off
    /// t_z either way (a depth unit or scale mistake).
    #[allow(clippy::too_many_arguments)]
    pub fn check_depth(
        &mut self,
        depth_path: &Path,
        mask_name: &str,
        depth: &Plane<u16>,
        depth_scale: f64,
        mask: &[u8],
        t_z_mm: f64,
        model: &ModelInfo,
    ) {
        let range = model_radius_mm(model) + self.checks.depth_tolerance_mm;
        let off = |d: u16| (f64::from(d) * depth_scale - t_z_mm).abs() > range;
        let inner = interior(mask, depth.width as usize, DEPTH_EDGE_PX);
        let (mut n, mut bad) = (0u64, 0u64);
        let mut all: Vec<u16> = Vec::new();
        for ((&d, &m), &i) in depth.data.iter().zip(mask).zip(&inner) {
            if m == 0 || d == 0 {
                continue;
            }
            all.push(d);
            if i {
                n += 1;
                bad += u64::from(off(d));
            }
        }
        let (tol, t_lo, t_hi) = (
            self.checks.depth_tolerance_mm,
            t_z_mm - range,
            t_z_mm + range,
        );
        if n >= MIN_INTERIOR_READINGS {
            if bad as f64 > self.checks.depth_outlier_fraction * n as f64 {
                self.problem(
                    depth_path,
                    format!(
                        "{bad} of {n} depth values inside {mask_name} ({DEPTH_EDGE_PX} px or more from its edge) are outside the object's depth range {t_lo:.1}..{t_hi:.1} mm (t_z ± model radius + {tol} mm)"
                    ),
                );
            }
        } else if !all.is_empty() && t_z_mm > 0.0 {
            let mid = all.len() / 2;
            let median_mm = f64::from(*all.select_nth_unstable(mid).1) * depth_scale;
            let ratio = median_mm / t_z_mm;
            if off(*all.select_nth_unstable(mid).1)
                && !(1.0 / GROSS_DEPTH_FACTOR..=GROSS_DEPTH_FACTOR).contains(&ratio)
            {
                self.problem(
                    depth_path,
                    format!(
                        "the median of the {} depth values under {mask_name}, {median_mm:.1} mm, is {ratio:.2} times t_z, far outside the object's depth range {t_lo:.1}..{t_hi:.1} mm (t_z ± model radius + {tol} mm)",
                        all.len()
                    ),
                );
            }
        }
    }
}

/// Pixels of a mask this close to its edge are not judged by the depth check.
pub const DEPTH_EDGE_PX: usize = 2;
/// Fewer interior readings than this: the depth check judges the median of all of them.
pub const MIN_INTERIOR_READINGS: u64 = 20;
/// A small mask's median depth this many times off t_z (either way) is an error.
pub const GROSS_DEPTH_FACTOR: f64 = 2.0;

/// Mask pixels whose (2r+1)² neighbourhood lies inside the mask and the image.
fn interior(mask: &[u8], width: usize, r: usize) -> Vec<bool> {
    let w = width.max(1);
    let h = mask.len() / w;
    // Horizontal then vertical run tests: a pixel is interior when r pixels on each side are.
    let inside = |x: usize, y: usize| mask[y * w + x] > 0;
    let mut rows = vec![false; mask.len()];
    for y in 0..h {
        for x in r..w.saturating_sub(r) {
            rows[y * w + x] = (x - r..=x + r).all(|xx| inside(xx, y));
        }
    }
    let mut out = vec![false; mask.len()];
    for y in r..h.saturating_sub(r) {
        for x in 0..w {
            out[y * w + x] = (y - r..=y + r).all(|yy| rows[yy * w + x]);
        }
    }
    out
}

/// Distance from the model origin to the farthest corner of its bounding box, mm.
pub fn model_radius_mm(m: &ModelInfo) -> f64 {
    let far = |min: f64, size: f64| min.abs().max((min + size).abs());
    let (x, y, z) = (
        far(m.min_x, m.size_x),
        far(m.min_y, m.size_y),
        far(m.min_z, m.size_z),
    );
    (x * x + y * y + z * z).sqrt()
}

/// Number of non-zero pixels.
pub(crate) fn count_nonzero(mask: &[u8]) -> u64 {
    mask.iter().filter(|&&v| v > 0).count() as u64
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn interior_keeps_pixels_two_from_every_edge() {
        // A 6x5 block in a 10x8 image: its interior is the 2x1 centre.
        let (w, h) = (10, 8);
        let mut m = vec![0u8; w * h];
        for y in 1..6 {
            for x in 2..8 {
                m[y * w + x] = 255;
            }
        }
        let inner = interior(&m, w, 2);
        let got: Vec<(usize, usize)> = (0..w * h)
            .filter(|&i| inner[i])
            .map(|i| (i % w, i / w))
            .collect();
        assert_eq!(got, vec![(4, 3), (5, 3)]);
        // A mask filling a 3x3 image: the border pixels' neighbourhoods leave the image.
        let full = interior(&[255; 9], 3, 1);
        assert_eq!(full.iter().filter(|&&b| b).count(), 1);
        assert!(full[4]);
    }

    #[test]
    fn radius_is_the_farthest_corner() {
        let m = ModelInfo {
            diameter: 1.0,
            min_x: -3.0,
            min_y: 0.0,
            min_z: -1.0,
            size_x: 4.0,
            size_y: 4.0,
            size_z: 1.0,
            symmetries: Default::default(),
        };
        assert!((model_radius_mm(&m) - (9.0f64 + 16.0 + 1.0).sqrt()).abs() < 1e-12);
    }
}
