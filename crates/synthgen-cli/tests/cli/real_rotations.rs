//! Real annotation files store approximate rotations: BOP's LM-O test GT has |det R − 1| up
//! to 1.4e-2 and about 6 significant digits. Every command that reads annotations must accept
//! them (regression: `eval` and `annotate` on real LM-O stopped with "rotation determinant
//! 1.002888 != 1"), keep the file's numbers when it copies them, and still refuse a rotation
//! beyond the tolerance with the file, image and gt index named.

use std::path::Path;

use serde_json::Value;

use crate::common::{run, stderr, synthgen};
use crate::mix::render_tiny;
use crate::train::train;

/// Six significant digits, as real BOP files store rotations.
fn round6(v: f64) -> f64 {
    format!("{v:.5e}").parse().unwrap()
}

/// Scales every rotation of the dataset's scene_gt.json files so that det R = `det` and
/// rounds it to 6 significant digits, as hand-made annotations are; returns how many.
fn perturb_scene_gt(root: &Path, det: f64) -> usize {
    let s = det.cbrt();
    let mut n = 0;
    for split in std::fs::read_dir(root).unwrap().flatten() {
        for scene in std::fs::read_dir(split.path())
            .into_iter()
            .flatten()
            .flatten()
        {
            let p = scene.path().join("scene_gt.json");
            if !p.is_file() {
                continue;
            }
            let mut v: Value = serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
            for gts in v.as_object_mut().unwrap().values_mut() {
                for g in gts.as_array_mut().unwrap() {
                    for r in g["cam_R_m2c"].as_array_mut().unwrap() {
                        *r = round6(r.as_f64().unwrap() * s).into();
                    }
                    n += 1;
                }
            }
            std::fs::write(&p, serde_json::to_vec(&v).unwrap()).unwrap();
        }
    }
    n
}

/// A discrete symmetry (180° about z) in models_info.json, perturbed the same way.
fn add_perturbed_symmetry(root: &Path) {
    let p = root.join("models/models_info.json");
    let mut v: Value = serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
    let s = 1.01f64.cbrt();
    let m = [
        -s, 0.0, 0.0, 0.0, 0.0, -s, 0.0, 0.0, 0.0, 0.0, s, 0.0, 0.0, 0.0, 0.0, 1.0,
    ];
    for info in v.as_object_mut().unwrap().values_mut() {
        info["symmetries_discrete"] = serde_json::json!([m.map(round6)]);
    }
    std::fs::write(&p, serde_json::to_vec(&v).unwrap()).unwrap();
}

fn first_gt(root: &Path) -> Value {
    let p = root.join("train_pbr/000000/scene_gt.json");
    let v: Value = serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap();
    v["0"][0]["cam_R_m2c"].clone()
}

fn ok(args: &[&str], dir: &Path) -> String {
    let o = run(synthgen().current_dir(dir).args(args));
    assert!(o.status.success(), "synthgen {args:?}: {}", stderr(&o));
    format!("{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o))
}

#[test]
fn every_reading_command_accepts_real_world_rotations() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "real", 60, 11);
    render_tiny(d, "synth", 60, 12);
    assert!(perturb_scene_gt(&d.join("real"), 1.01) > 0);
    add_perturbed_symmetry(&d.join("real"));
    let stored = first_gt(&d.join("real"));

    // validate: approximate rotations are one warning with a count, not problems.
    let out = ok(&["validate", "real"], d);
    assert!(
        out.contains("60 of 60 rotations are not orthonormal") && out.contains("warning:"),
        "{out}"
    );
    ok(&["stats", "real"], d);
    ok(&["stats", "real", "synth"], d);
    ok(
        &["preview", "real", "--out", "sheet.png", "--count", "4"],
        d,
    );

    // convert keeps the file's numbers, both ways.
    ok(&["convert", "--to", "linemod", "real", "lm"], d);
    ok(&["validate", "lm"], d);
    ok(&["stats", "lm"], d);
    ok(&["convert", "--to", "bop", "lm", "back"], d);
    let back: Value =
        serde_json::from_slice(&std::fs::read(d.join("back/train/000000/scene_gt.json")).unwrap())
            .unwrap();
    let first = back.as_object().unwrap().values().next().unwrap();
    assert_eq!(first[0]["cam_R_m2c"], stored);

    // mix copies the real annotations as they are.
    ok(
        &[
            "mix",
            "--real",
            "real",
            "--synth",
            "synth",
            "--real-count",
            "20",
            "--synth-count",
            "10",
            "--test-count",
            "6",
            "--out",
            "mixed",
        ],
        d,
    );
    ok(&["validate", "mixed"], d);

    // annotate renders at the nearest rotations and agrees with the masks it replaces.
    let out = ok(&["annotate", "real"], d);
    assert!(out.contains("annotated 60 frames"), "{out}");

    // train, eval with a checkpoint and with a results CSV whose rotations are rounded too.
    let o = train(&d.join("real"), &d.join("run"), "1", &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    ok(
        &[
            "eval",
            "--checkpoint",
            "run/model.safetensors",
            "--data",
            "real",
        ],
        d,
    );
    // The GT as estimates: rotations with the same 6 digits and det 1.01.
    let csv = crate::train::gt_as_results(&d.join("real"), 0.0);
    std::fs::write(d.join("results.csv"), csv).unwrap();
    let out = ok(
        &[
            "eval",
            "--results",
            "results.csv",
            "--data",
            "real",
            "--json",
            "scores.json",
        ],
        d,
    );
    let scores: Value =
        serde_json::from_slice(&std::fs::read(d.join("scores.json")).unwrap()).unwrap();
    assert_eq!(scores["all"]["add_s_acc"], 1.0, "{out}");

    // experiment mix reads the real set through the same readers.
    ok(
        &[
            "experiment",
            "mix",
            "--real",
            "real",
            "--synth",
            "synth",
            "--quick",
            "--total",
            "12",
            "--test-count",
            "6",
            "--ratios",
            "12/0,0/12",
            "--epochs",
            "1",
            "--out",
            "exp",
        ],
        d,
    );
}

#[test]
fn rotations_beyond_the_tolerance_are_named_and_the_tolerance_is_settable() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "bad", 4, 3);
    perturb_scene_gt(&d.join("bad"), 1.05);
    let o = run(synthgen().current_dir(d).args(["stats", "bad"]));
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(
        err.contains("scene_gt.json")
            && err.contains("cam_R_m2c of image 0, gt 0")
            && err.contains("tolerance 0.02")
            && err.contains("--rotation-tolerance"),
        "{err}"
    );
    let o = run(synthgen().current_dir(d).args(["validate", "bad"]));
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stdout).contains("rotation determinant 1.05"),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    ok(&["--rotation-tolerance", "0.1", "stats", "bad"], d);
    ok(&["stats", "bad", "--rotation-tolerance", "0.1"], d);
    let o = run(synthgen()
        .current_dir(d)
        .args(["--rotation-tolerance=-1", "stats", "bad"]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
}

/// Issue 26: eval scored ADD(-S) and 5cm5° against each GT's nearest proper rotation, while
/// bop_toolkit's pose_error (and PoseCNN's, DenseFusion's evaluations) use the file's matrices.
/// GT rotations scaled to det 1.018 (within the reading tolerance), the exact rotations as
/// estimates: bop_toolkit's re is arccos((3/s − 1)/2) = 7.6° (s = 1.018^(1/3)), so 5cm5°
/// fails; against the nearest rotations it is 0°.
#[test]
fn eval_scores_the_files_rotations_as_bop_toolkit_and_the_nearest_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "ds", 6, 5);
    std::fs::write(
        d.join("exact.csv"),
        crate::train::gt_as_results(&d.join("ds"), 0.0),
    )
    .unwrap();
    assert!(perturb_scene_gt(&d.join("ds"), 1.018) > 0);
    let score = |extra: &[&str]| -> Value {
        let mut a = vec![
            "eval",
            "--results",
            "exact.csv",
            "--data",
            "ds",
            "--json",
            "s.json",
        ];
        a.extend_from_slice(extra);
        ok(&a, d);
        serde_json::from_slice(&std::fs::read(d.join("s.json")).unwrap()).unwrap()
    };
    let stored = score(&[]);
    let want = ((3.0 / 1.018f64.cbrt() - 1.0) / 2.0).acos().to_degrees();
    let re = stored["all"]["mean_re_deg"].as_f64().unwrap();
    assert!((re - want).abs() < 0.01, "mean re {re}, want {want}");
    assert_eq!(stored["all"]["acc_5cm5deg"], 0.0);
    // The scaled matrices move the model points by under a millimetre: ADD holds.
    assert_eq!(stored["all"]["add_s_acc"], 1.0);
    assert_eq!(stored, score(&["--rotations", "as-stored"]));
    let nearest = score(&["--rotations", "nearest"]);
    assert_eq!(nearest["all"]["acc_5cm5deg"], 1.0);
    assert!(nearest["all"]["mean_re_deg"].as_f64().unwrap() < 1e-3);
}
