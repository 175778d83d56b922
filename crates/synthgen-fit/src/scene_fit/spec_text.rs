//! The fitted scene as a TOML scene spec: only the derived sections, each value with a comment
//! giving what was observed; model and sensor paths relative to the file.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Component, Path, PathBuf};

use synthgen_core::SceneSpec;

use super::{Observed, SceneFit, ANGLE_MARGIN_DEG, LENGTH_MARGIN};
use synthgen_formats::{Error, Result};

/// `to` relative to the folder `from_dir` (both resolved through the file system, so they
/// must exist); `to` made absolute when they share no folder below the root (`/tmp/x` and
/// `/work/y`: a relative path through `/` would break when either moves).
pub fn relative_path(from_dir: &Path, to: &Path) -> PathBuf {
    let (Ok(from), Ok(target)) = (from_dir.canonicalize(), to.canonicalize()) else {
        return std::path::absolute(to).unwrap_or_else(|_| to.to_path_buf());
    };
    let a: Vec<Component> = from.components().collect();
    let b: Vec<Component> = target.components().collect();
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if !a[..common]
        .iter()
        .any(|c| matches!(c, Component::Normal(_)))
    {
        return target;
    }
    let mut out = PathBuf::new();
    for _ in common..a.len() {
        out.push("..");
    }
    for c in &b[common..] {
        out.push(c.as_os_str());
    }
    out
}

/// A TOML basic string (JSON's escapes are TOML's).
fn quoted(s: &str) -> String {
    serde_json::to_string(s).unwrap_or_else(|_| format!("{s:?}"))
}

/// A path as a TOML string with `/` separators; an error for a path that is not UTF-8.
fn path_string(p: &Path) -> Result<String> {
    let s = p.to_str().ok_or_else(|| {
        Error::InvalidRequest(format!(
            "cannot write a path that is not UTF-8 into the scene file: {}",
            p.display()
        ))
    })?;
    Ok(quoted(&s.replace('\\', "/")))
}

fn range(r: [f64; 2]) -> String {
    format!("[{:?}, {:?}]", r[0], r[1])
}

fn spread(o: &Observed, scale: f64, digits: usize, unit: &str) -> String {
    format!(
        "{:.d$}–{:.d$}{unit} (median {:.d$}{unit})",
        o.min * scale,
        o.max * scale,
        o.median * scale,
        d = digits
    )
}

/// The scene file for `fit`, to be written at `out` (whose folder must exist: paths are made
/// relative to it). `sensor`: a sensor file for `[sensor] file`; without it the file has no
/// `[sensor]` section and says how to add one.
pub fn spec_toml(fit: &SceneFit, out: &Path, sensor: Option<&Path>) -> Result<String> {
    let dir = match out.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let s = &fit.spec;
    let n = fit.frames_used;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "# A scene fitted by `synthgen scene fit` (synthgen {}) to the real frames of",
        synthgen_core::VERSION
    );
    let _ = writeln!(
        t,
        "# {}: {n} frames used of {}{}{}.",
        fit.data.display(),
        fit.frames_total,
        if fit.scenes.is_empty() {
            String::new()
        } else {
            format!(
                " in scenes {}",
                fit.scenes
                    .iter()
                    .map(u32::to_string)
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        },
        if fit.frames_skipped.is_empty() {
            String::new()
        } else {
            format!(" ({} skipped: no table plane)", fit.frames_skipped.len())
        }
    );
    if fit.frames_plane_from_poses > 0 {
        let _ = writeln!(
            t,
            "# {} of them without depth: their table plane is where the objects' lowest points",
            fit.frames_plane_from_poses
        );
        let _ = writeln!(t, "# lie at the GT poses.");
    }
    let _ = writeln!(
        t,
        "# Render it: synthgen render --scene {} --frames 1000 --out data/synth",
        out.file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .unwrap_or_default()
    );
    let _ = writeln!(
        t,
        "# Only the sections below were derived; the others (ground, lights, background,\n\
         # materials, ...) keep their defaults. Ranges are the observed ones widened by\n\
         # {ANGLE_MARGIN_DEG}° (angles) or {:.0} % (lengths). Method: docs/scenes.md, \"Fitting a scene to\n\
         # real frames\".",
        LENGTH_MARGIN * 100.0
    );
    if sensor.is_none() {
        let _ = writeln!(
            t,
            "# No [sensor] section: fit one with `synthgen sensor fit --data {} --out sensor.toml`\n\
             # and add `[sensor]` with `file = \"sensor.toml\"` (or pass --sensor to scene fit).",
            fit.data.display()
        );
    }

    let k = fit.camera.intrinsics;
    t.push_str("\n[camera]\n");
    let _ = writeln!(
        t,
        "# The intrinsics of {} of the {n} frames{}.",
        fit.camera.frames,
        if fit.camera.others.is_empty() {
            String::new()
        } else {
            format!(" (the others have {} other K)", fit.camera.others.len())
        }
    );
    let _ = writeln!(
        t,
        "width = {}\nheight = {}\nfx = {:?}\nfy = {:?}\ncx = {:?}\ncy = {:?}",
        k.width, k.height, k.fx, k.fy, k.cx, k.cy
    );

    let c = &s.camera_pose;
    t.push_str("\n[camera_pose]\n");
    let _ = writeln!(
        t,
        "# Angle between the optical axis and the table: observed {}\n# over {n} frames.",
        spread(&fit.elevation_deg, 1.0, 1, "°")
    );
    let _ = writeln!(t, "elevation_deg = {}", range(c.elevation_deg));
    let _ = writeln!(
        t,
        "# Camera to the look-at point (where the optical axis passes the height of the\n\
         # objects' mean centre, as the sampler aims): observed {}.\n\
         # (Camera to the objects' mean centre: {}.\n\
         # Camera height above the table: {}.)",
        spread(&fit.distance_m, 1.0, 3, " m"),
        spread(&fit.centre_distance_m, 1.0, 3, " m"),
        spread(&fit.camera_height_m, 1.0, 3, " m")
    );
    let _ = writeln!(t, "distance_m = {}", range(c.distance_m));
    let _ = writeln!(
        t,
        "# Not identifiable from a few videos of static scenes: all around."
    );
    let _ = writeln!(t, "azimuth_deg = {}", range(c.azimuth_deg));
    let _ = writeln!(
        t,
        "# Roll about the optical axis (0: the table's up is up in the image):\n# observed {}.",
        spread(&fit.roll_deg, 1.0, 1, "°")
    );
    let _ = writeln!(t, "inplane_deg = {}", range(c.inplane_deg));
    let _ = writeln!(
        t,
        "# Horizontal offset of the look-at point from the objects' mean centre:\n\
         # observed {}; the largest, widened.",
        spread(&fit.look_at_offset_m, 1.0, 3, " m")
    );
    let _ = writeln!(t, "look_at_jitter_m = {:?}", c.look_at_jitter_m);

    let p = &s.placement;
    t.push_str("\n[placement]\n");
    t.push_str("orientation = \"upright\"\n");
    let mut hist: BTreeMap<usize, usize> = BTreeMap::new();
    for f in &fit.frames {
        *hist.entry(f.objects.len()).or_default() += 1;
    }
    let _ = writeln!(
        t,
        "# Annotated objects per frame: {}.",
        hist.iter()
            .map(|(k, v)| format!("{k} in {v} frame{}", if *v == 1 { "" } else { "s" }))
            .collect::<Vec<_>>()
            .join(", ")
    );
    if let Some([lo, hi]) = p.objects_per_frame {
        let _ = writeln!(t, "objects_per_frame = [{lo}, {hi}]");
    }
    let _ = writeln!(
        t,
        "# Extent of the object centres on the table along their principal axes: at most\n\
         # {:.3} x {:.3} m; the sampler grows the area when the objects do not fit.",
        fit.extent_m[0], fit.extent_m[1]
    );
    let _ = writeln!(t, "area_m = {}", range(p.area_m));
    if fit.off_table[1] > 0 {
        let _ = writeln!(
            t,
            "# Instances resting off the table (lowest point over {:.0} cm up: on another object):\n\
             # {} of {}.",
            crate::scene_fit::OFF_TABLE_M * 100.0,
            fit.off_table[0],
            fit.off_table[1]
        );
    }
    if p.stack_prob > 0.0 {
        let _ = writeln!(t, "stack_prob = {}", p.stack_prob);
    }
    if let Some(o) = &fit.occlusion {
        let _ = writeln!(
            t,
            "# Occlusion (not fitted; `camera.min_visib_fract` can bound it): visib_fract mean\n\
             # {:.2}, min {:.2}, {:.0} % of {} instances below 0.5\n\
             # (from {}).",
            o.visib_fract.mean,
            o.visib_fract.min,
            o.share_below_half * 100.0,
            o.visib_fract.count,
            o.source
        );
    }

    if let Some(sensor) = sensor {
        t.push_str("\n[sensor]\n");
        let _ = writeln!(t, "file = {}", path_string(&relative_path(&dir, sensor))?);
    }

    t.push_str(
        "\n# One entry per annotated object. `up`: the model axis along the table's normal in\n\
         # most frames; `tilt_deg`: the largest angle between them, rounded up (the sampler draws\n\
         # a tilt in 0..tilt_deg). Model paths are relative to this file.\n",
    );
    for (o, spec) in fit.objects.iter().zip(&s.objects) {
        t.push_str("\n[[objects]]\n");
        let _ = writeln!(
            t,
            "# {}: in {} frames; up {} in {}; tilt {:.1}° mean, {:.1}° max.\n\
             # Model origin {:.1} cm above the table; lowest point {}{}.",
            o.name,
            o.frames,
            o.up,
            o.up_frames,
            o.tilt_deg.mean,
            o.tilt_deg.max,
            o.centre_height_m.mean * 100.0,
            o.lowest_point_m
                .as_ref()
                .map_or("unknown".into(), |l| format!(
                    "{:.1} cm ({:.1}..{:.1})",
                    l.mean * 100.0,
                    l.min * 100.0,
                    l.max * 100.0
                )),
            o.visib_fract.as_ref().map_or(String::new(), |v| format!(
                "; visib_fract mean {:.2}",
                v.mean
            ))
        );
        if o.off_table() {
            t.push_str(
                "# It does not stand on the table (on another object?): see stack_prob in [placement].\n",
            );
        }
        let _ = writeln!(t, "path = {}", path_string(&relative_path(&dir, &o.model))?);
        if let Some(id) = spec.obj_id {
            let _ = writeln!(t, "obj_id = {id}");
        }
        if let Some(u) = &spec.units {
            let _ = writeln!(t, "units = {}", quoted(u));
        }
        if spec.count != 1 {
            let _ = writeln!(t, "count = {}", spec.count);
        }
        let _ = writeln!(t, "up = {}", quoted(spec.up.as_str()));
        let _ = writeln!(t, "tilt_deg = {:?}", spec.tilt_deg);
    }
    Ok(t)
}

/// Reads the written file back and checks that it holds what was fitted (camera, camera
/// pose, placement, objects with their model files).
pub fn check_written(fit: &SceneFit, path: &Path) -> Result<SceneSpec> {
    let back = SceneSpec::from_toml_file(path).map_err(|e| {
        Error::InvalidRequest(format!(
            "the written scene does not read back (please report this): {e}"
        ))
    })?;
    let want = &fit.spec;
    let same_objects = back.objects.len() == want.objects.len()
        && back.objects.iter().zip(&want.objects).all(|(b, w)| {
            let same_file = match (b.path.canonicalize(), w.path.canonicalize()) {
                (Ok(x), Ok(y)) => x == y,
                _ => false,
            };
            same_file
                && (b.obj_id, &b.units, b.count, b.up, b.tilt_deg)
                    == (w.obj_id, &w.units, w.count, w.up, w.tilt_deg)
        });
    let mismatch = if back.camera != want.camera {
        Some("camera")
    } else if back.camera_pose != want.camera_pose {
        Some("camera_pose")
    } else if back.placement != want.placement {
        Some("placement")
    } else if !same_objects {
        Some("objects")
    } else {
        None
    };
    match mismatch {
        Some(what) => Err(Error::InvalidRequest(format!(
            "the written scene's [{what}] does not read back as fitted (please report this): {}",
            path.display()
        ))),
        None => Ok(back),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_walk_up_and_down() {
        let d = tempfile::tempdir().unwrap();
        let a = d.path().join("out/scenes");
        let b = d.path().join("data/models/x");
        std::fs::create_dir_all(&a).unwrap();
        std::fs::create_dir_all(&b).unwrap();
        std::fs::write(b.join("m.obj"), "").unwrap();
        assert_eq!(
            relative_path(&a, &b.join("m.obj")),
            PathBuf::from("../../data/models/x/m.obj")
        );
        assert_eq!(relative_path(&b, &b.join("m.obj")), PathBuf::from("m.obj"));
        assert_eq!(quoted("a\"b\\c"), r#""a\"b\\c""#);
    }
}
