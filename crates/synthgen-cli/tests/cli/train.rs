//! `synthgen train` and `synthgen eval` end to end on a tiny rendered dataset.

use std::path::{Path, PathBuf};

use synthgen_dataset::bop::BopDataset;

use crate::common::{repo_root, run, stderr, synthgen};

/// Renders 8 small frames of the sample driller into `dir/drill`.
fn tiny_dataset(dir: &Path) -> PathBuf {
    let out = dir.join("drill");
    let o = run(synthgen()
        .args(["render", "-q", "--objects"])
        .arg(repo_root().join("datasets/meshes/driller.ply"))
        .args([
            "--obj-ids",
            "8",
            "--frames",
            "8",
            "--seed",
            "3",
            "--image-size",
            "320,240",
            "--out",
        ])
        .arg(&out));
    assert!(o.status.success());
    out
}

fn train(data: &Path, out: &Path, epochs: &str, extra: &[&str]) -> std::process::Output {
    run(synthgen()
        .args(["train", "-q", "--data"])
        .arg(data)
        .args([
            "--epochs",
            epochs,
            "--batch",
            "4",
            "--points",
            "64",
            "--width",
            "16",
            "--seed",
            "1",
            "--val-fraction",
            "0.25",
            "--out",
        ])
        .arg(out)
        .args(extra))
}

fn metrics_lines(out: &Path) -> Vec<serde_json::Value> {
    std::fs::read_to_string(out.join("metrics.jsonl"))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn train_resume_and_eval_checkpoint() {
    let dir = tempfile::tempdir().unwrap();
    let data = tiny_dataset(dir.path());
    let out = dir.path().join("run");
    let o = train(&data, &out, "2", &[]);
    assert!(o.status.success());
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("val centre error"), "{stdout}");
    for f in [
        "model.safetensors",
        "config.json",
        "state.json",
        "curve.png",
    ] {
        assert!(out.join(f).is_file(), "missing {f}");
    }
    let lines = metrics_lines(&out);
    assert_eq!(lines.len(), 2);
    for key in [
        "epoch",
        "train_loss",
        "val_loss",
        "val_centre_error_m",
        "lr",
        "seconds",
    ] {
        assert!(lines[1][key].is_number(), "{key} in {}", lines[1]);
    }
    let cfg: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("config.json")).unwrap()).unwrap();
    assert_eq!(cfg["model"], "tnet");
    assert_eq!(cfg["n_points"], 64);
    assert_eq!(cfg["width"], 16);

    // A second run into the same folder needs --resume or --force.
    let o = train(&data, &out, "2", &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("hint: continue it with --resume"),
        "{}",
        stderr(&o)
    );

    let o = train(&data, &out, "3", &["--resume"]);
    assert!(o.status.success());
    let lines = metrics_lines(&out);
    assert_eq!(lines.len(), 3);
    assert_eq!(lines[2]["epoch"], 3);

    let json = dir.path().join("centre.json");
    let o = run(synthgen()
        .args(["eval", "-q", "--checkpoint"])
        .arg(out.join("model.safetensors"))
        .arg("--data")
        .arg(&data)
        .arg("--json")
        .arg(&json));
    assert!(o.status.success());
    assert!(String::from_utf8_lossy(&o.stdout).contains("| all |"));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(j["all"]["n"].as_u64().unwrap() > 0);
    assert!(j["all"]["mean_centre_error_cm"]
        .as_f64()
        .unwrap()
        .is_finite());
}

/// Writes the dataset's GT as a results CSV, optionally moving every estimate along x.
fn gt_as_results(data: &Path, dx_mm: f64) -> String {
    let ds = BopDataset::open(data).unwrap();
    let mut csv = String::from("scene_id,im_id,obj_id,score,R,t,time\n");
    for scene_id in ds.scene_ids("train_pbr").unwrap() {
        let scene = ds.read_scene("train_pbr", scene_id).unwrap();
        for (im, gts) in &scene.gt {
            for g in gts {
                let r: Vec<String> = g.cam_r_m2c.iter().map(|v| v.to_string()).collect();
                let t = g.cam_t_m2c;
                csv += &format!(
                    "{scene_id},{im},{},1.0,{},{} {} {},-1\n",
                    g.obj_id,
                    r.join(" "),
                    t[0] + dx_mm,
                    t[1],
                    t[2]
                );
            }
        }
    }
    csv
}

#[test]
fn eval_results_csv() {
    let dir = tempfile::tempdir().unwrap();
    let data = tiny_dataset(dir.path());
    let csv = dir.path().join("results.csv");

    // Perfect estimates: everything correct, zero errors.
    std::fs::write(&csv, gt_as_results(&data, 0.0)).unwrap();
    let json = dir.path().join("scores.json");
    let o = run(synthgen()
        .args(["eval", "--results"])
        .arg(&csv)
        .arg("--data")
        .arg(&data)
        .arg("--json")
        .arg(&json));
    assert!(o.status.success());
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(stdout.contains("| 8 | ADD |"), "{stdout}");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(j["all"]["add_s_acc"], 1.0);
    assert_eq!(j["all"]["acc_5cm5deg"], 1.0);
    assert!(j["8"]["mean_add_mm"].as_f64().unwrap() < 1e-6);
    for key in [
        "n_gt",
        "n_est",
        "add_s_acc",
        "mean_add_mm",
        "acc_5cm5deg",
        "mean_te_cm",
        "mean_re_deg",
    ] {
        assert!(!j["8"][key].is_null(), "{key}");
    }

    // 60 mm off along x: over 5 cm and over 10% of the driller's 261 mm diameter (26 mm).
    std::fs::write(&csv, gt_as_results(&data, 60.0)).unwrap();
    let o = run(synthgen()
        .args(["eval", "-q", "--results"])
        .arg(&csv)
        .arg("--data")
        .arg(&data)
        .arg("--json")
        .arg(&json));
    assert!(o.status.success());
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(j["all"]["add_s_acc"], 0.0);
    assert_eq!(j["all"]["acc_5cm5deg"], 0.0);
    assert!((j["all"]["mean_te_cm"].as_f64().unwrap() - 6.0).abs() < 1e-6);

    // A broken line names the file and the line.
    std::fs::write(
        &csv,
        "scene_id,im_id,obj_id,score,R,t,time\n0,0,8,1,1 0 0,0 0 500,-1\n",
    )
    .unwrap();
    let o = run(synthgen()
        .args(["eval", "--results"])
        .arg(&csv)
        .arg("--data")
        .arg(&data));
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("results.csv:2: R: expected 9 values"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn unimplemented_model_is_a_user_error() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(synthgen()
        .args(["train", "--model", "full", "--data"])
        .arg(dir.path())
        .arg("--out")
        .arg(dir.path().join("run")));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("not implemented"), "{}", stderr(&o));
}
