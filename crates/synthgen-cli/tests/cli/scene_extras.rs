//! View rejection, distractors and truncation end to end: what the written BOP files say.

use std::path::Path;

use serde_json::Value;

use crate::common::{run, stderr, synthgen};
use crate::render::write_box_ply;

/// A small camera (160x120, the Linemod field of view) so the renders are quick.
const SMALL_CAMERA: &str =
    "[camera]\nwidth = 160\nheight = 120\nfx = 143.0\nfy = 143.0\ncx = 80.0\ncy = 60.0\n";

/// Renders `frames` frames of three boxes with `spec` (appended to the small camera's
/// section) and returns the scene folder.
fn render(dir: &Path, name: &str, spec: &str, frames: u32) -> std::path::PathBuf {
    let mesh = dir.join("box.ply");
    if !mesh.exists() {
        write_box_ply(&mesh);
    }
    let spec_path = dir.join(format!("{name}.toml"));
    std::fs::write(&spec_path, format!("{SMALL_CAMERA}{spec}")).unwrap();
    let out = dir.join(name);
    let o = run(synthgen()
        .arg("render")
        .arg("--scene")
        .arg(&spec_path)
        .arg("--objects")
        .args([&mesh, &mesh, &mesh])
        .args([
            "--frames",
            &frames.to_string(),
            "--seed",
            "5",
            "--jobs",
            "2",
        ])
        .arg("--out")
        .arg(&out));
    assert!(o.status.success(), "{name}: {}", stderr(&o));
    let v = run(synthgen().arg("validate").arg(&out));
    assert!(v.status.success(), "{name}: {}", stderr(&v));
    out.join("train_pbr").join("000000")
}

fn json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

/// visib_fract of every annotated object of every frame, in frame order.
fn visib(scene: &Path) -> Vec<Vec<f64>> {
    let info = json(&scene.join("scene_gt_info.json"));
    let mut frames: Vec<(u64, Vec<f64>)> = info
        .as_object()
        .unwrap()
        .iter()
        .map(|(k, v)| {
            let f = v.as_array().unwrap();
            let fr = f.iter().map(|o| o["visib_fract"].as_f64().unwrap());
            (k.parse().unwrap(), fr.collect())
        })
        .collect();
    frames.sort_by_key(|f| f.0);
    frames.into_iter().map(|f| f.1).collect()
}

/// Packed boxes among many distractors, camera low so they hide each other.
const CLUTTER: &str = "[camera_pose]\ndistance_m = [0.5, 0.7]\nelevation_deg = [10.0, 30.0]\n\
    [placement]\narea_m = [0.25, 0.25]\nmin_gap_m = 0.0\nmax_tries = 400\n";
const DISTRACTORS: &str = "[distractors]\ncount = [6, 8]\nsize_m = [0.04, 0.1]\n";

#[test]
fn min_visib_fract_rejects_views_where_a_target_is_hidden() {
    let tmp = tempfile::tempdir().unwrap();
    let free = render(tmp.path(), "free", &format!("{CLUTTER}{DISTRACTORS}"), 10);
    let hidden = visib(&free).iter().flatten().filter(|&&v| v < 0.7).count();
    assert!(
        hidden > 0,
        "no target below 0.7 without rejection: the test shows nothing"
    );
    let spec = format!("min_visib_fract = 0.7\nmax_view_tries = 400\n{CLUTTER}{DISTRACTORS}");
    let kept = render(tmp.path(), "kept", &spec, 10);
    let v = visib(&kept);
    assert_eq!(v.len(), 10);
    for (f, objs) in v.iter().enumerate() {
        assert_eq!(objs.len(), 3);
        for &x in objs {
            assert!(x >= 0.7, "frame {f}: visib_fract {x} < 0.7");
        }
    }
}

#[test]
fn distractors_occlude_targets_but_are_never_annotated() {
    let tmp = tempfile::tempdir().unwrap();
    let plain = render(tmp.path(), "plain", CLUTTER, 8);
    let busy = render(tmp.path(), "busy", &format!("{CLUTTER}{DISTRACTORS}"), 8);
    // Targets are placed before the distractors and the camera has its own stream: same
    // poses, same silhouettes, only what hides them differs.
    for f in ["scene_gt.json", "scene_camera.json"] {
        assert_eq!(json(&plain.join(f)), json(&busy.join(f)), "{f}");
    }
    let gt = json(&busy.join("scene_gt.json"));
    for objs in gt.as_object().unwrap().values() {
        let ids: Vec<u64> = objs
            .as_array()
            .unwrap()
            .iter()
            .map(|o| o["obj_id"].as_u64().unwrap())
            .collect();
        assert_eq!(ids, vec![1, 1, 1], "only the targets are annotated");
    }
    let (a, b) = (visib(&plain), visib(&busy));
    let mut lower = 0;
    for (fa, fb) in a.iter().zip(&b) {
        for (x, y) in fa.iter().zip(fb) {
            assert!(
                y <= x,
                "a distractor made a target more visible ({x} -> {y})"
            );
            lower += usize::from(y < x);
        }
    }
    assert!(lower >= 3, "distractors hid a target in only {lower} cases");
    // Masks of the whole silhouettes are the same, visible masks are not.
    let files = |d: &Path| {
        let mut v: Vec<_> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| std::fs::read(e.unwrap().path()).unwrap())
            .collect();
        v.sort();
        v
    };
    assert_eq!(files(&plain.join("mask")), files(&busy.join("mask")));
    assert_ne!(
        files(&plain.join("mask_visib")),
        files(&busy.join("mask_visib"))
    );
}

/// True when some object's silhouette (bbox_obj, on the 3x canvas) leaves the 160x120 image.
fn truncated(scene: &Path) -> usize {
    let info = json(&scene.join("scene_gt_info.json"));
    info.as_object()
        .unwrap()
        .values()
        .flat_map(|f| f.as_array().unwrap().clone())
        .filter(|o| {
            let b: Vec<i64> = o["bbox_obj"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_i64().unwrap())
                .collect();
            b[0] < 0 || b[1] < 0 || b[0] + b[2] > 159 || b[1] + b[3] > 119
        })
        .count()
}

#[test]
fn truncation_is_rejected_unless_allowed() {
    let tmp = tempfile::tempdir().unwrap();
    let close = "[camera_pose]\ndistance_m = [0.3, 0.5]\n[placement]\narea_m = [0.3, 0.3]\n";
    // allow_truncation = true is the default.
    let allowed = render(tmp.path(), "allowed", close, 10);
    assert!(
        truncated(&allowed) > 0,
        "no truncated object: the test shows nothing"
    );
    // BOP semantics: a truncated object's pixels outside the image count as not visible.
    let v = visib(&allowed);
    assert!(v.iter().flatten().any(|&x| x < 1.0));
    let strict = render(
        tmp.path(),
        "strict",
        &format!("allow_truncation = false\nmax_view_tries = 200\n{close}"),
        10,
    );
    // bbox_obj spans the silhouette on the 3x canvas: inside the image means no pixel out.
    assert_eq!(truncated(&strict), 0);
    assert_eq!(visib(&strict).len(), 10);
}
