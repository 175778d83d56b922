//! `synthgen train` and `synthgen eval` end to end on a tiny rendered dataset.

use std::path::{Path, PathBuf};

use synthgen_formats::bop::BopDataset;

use crate::common::{refused, repo_root, run, stderr, synthgen};

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

/// The full model at the tiny sizes these tests train with.
pub(crate) const FULL_MODEL_ARGS: [&str; 6] = [
    "--model",
    "full",
    "--crop-size",
    "16",
    "--loss-points",
    "20",
];

/// `synthgen train` with tiny settings (batch 4, 64 points, width 16, seed 1).
pub(crate) fn train(data: &Path, out: &Path, epochs: &str, extra: &[&str]) -> std::process::Output {
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
    // Status lines go to stderr (and -q silences them): stdout is for data asked for.
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
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

#[test]
fn per_object_tnet_records_its_classes_and_evaluates() {
    let dir = tempfile::tempdir().unwrap();
    let data = tiny_dataset(dir.path());
    let out = dir.path().join("run");
    let o = train(&data, &out, "1", &["--per-object"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cfg: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("config.json")).unwrap()).unwrap();
    assert_eq!(cfg["classes"], serde_json::json!([8]));
    // The class vector is a variable of the checkpoint.
    let tensors = std::fs::read(out.join("model.safetensors")).unwrap();
    assert!(
        String::from_utf8_lossy(&tensors[..4096.min(tensors.len())]).contains("h1_class"),
        "no class weights in the checkpoint"
    );
    let o = run(synthgen()
        .args(["eval", "-q", "--checkpoint"])
        .arg(out.join("model.safetensors"))
        .arg("--data")
        .arg(&data));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("| all |"));
    // Resuming keeps the classes without the flag.
    let o = train(&data, &out, "2", &["--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cfg: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("config.json")).unwrap()).unwrap();
    assert_eq!(cfg["classes"], serde_json::json!([8]));
    // Other models have no class input.
    let o = train(
        &data,
        &dir.path().join("rnet"),
        "1",
        &["--model", "rnet", "--crop-size", "16", "--per-object"],
    );
    refused(&o, &["--per-object is a TNet option"]);
}

/// Writes the dataset's GT as a results CSV, optionally moving every estimate along x.
/// The GT of `data`'s train_pbr split as a results CSV, shifted `dx_mm` along x.
pub(crate) fn gt_as_results(data: &Path, dx_mm: f64) -> String {
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
        "median_te_cm",
        "median_re_deg",
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
    // The file's only row is bad: there is nothing to score.
    let err = stderr(&o);
    assert!(
        err.contains("results.csv:2:") && err.contains("R: expected 9 values"),
        "{err}"
    );
}

/// Makes frames 1..4 of scene 0 copies of frame 0 (images, masks, annotations): a static
/// object seen four times.
fn repeat_frame_zero(data: &Path) {
    let scene = data.join("train_pbr/000000");
    for im in 1..4 {
        for (dir, name) in [
            ("rgb", format!("{im:06}.png")),
            ("depth", format!("{im:06}.png")),
            ("mask", format!("{im:06}_000000.png")),
            ("mask_visib", format!("{im:06}_000000.png")),
        ] {
            let from = name.replacen(&format!("{im:06}"), "000000", 1);
            let src = scene.join(dir).join(&from);
            if src.is_file() {
                std::fs::copy(&src, scene.join(dir).join(&name)).unwrap();
            }
        }
    }
    for file in ["scene_gt.json", "scene_camera.json", "scene_gt_info.json"] {
        let path = scene.join(file);
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
        let first = v["0"].clone();
        for im in 1..4 {
            v[im.to_string()] = first.clone();
        }
        std::fs::write(&path, serde_json::to_string(&v).unwrap()).unwrap();
    }
}

#[test]
fn full_model_trains_from_tnet_and_evaluates_with_stability() {
    let dir = tempfile::tempdir().unwrap();
    let data = tiny_dataset(dir.path());
    let tnet = dir.path().join("tnet");
    assert!(train(&data, &tnet, "1", &[]).status.success());
    let full = dir.path().join("full");
    let o = train(
        &data,
        &full,
        "2",
        &[
            &FULL_MODEL_ARGS[..],
            &["--init", tnet.join("model.safetensors").to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let lines = metrics_lines(&full);
    assert!(lines[0]["val_add_s_acc"].is_number(), "{:?}", lines[0]);
    assert_eq!(lines.len(), 2);
    for key in ["val_add_s_acc", "val_mean_re_deg", "val_centre_error_m"] {
        assert!(lines[1][key].is_number(), "{key} in {}", lines[1]);
    }
    let cfg: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(full.join("config.json")).unwrap()).unwrap();
    assert_eq!(cfg["model"], "full");
    assert_eq!(cfg["crop_size"], 16);
    assert!(full.join("curve.png").is_file());

    let json = dir.path().join("full.json");
    let eval = |flags: &[&str], model: &Path| {
        run(synthgen()
            .args(["eval", "-q"])
            .args(flags)
            .arg("--checkpoint")
            .arg(model.join("model.safetensors"))
            .arg("--data")
            .arg(&data)
            .arg("--json")
            .arg(&json))
    };
    let o = eval(&[], &full);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("| 8 | ADD |"));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let n_gt = j["all"]["n_gt"].as_u64().unwrap();
    assert!((1..=8).contains(&n_gt), "{j}");
    for key in ["add_s_acc", "acc_5cm5deg", "mean_re_deg", "mean_te_cm"] {
        assert!(j["all"][key].is_number(), "{key} in {j}");
    }
    // The same predictions scored with BOP's AR.
    let o = eval(&["--bop"], &full);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("| object | AR | AR_VSD |"));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let ar = j["bop"]["ar"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&ar), "{j}");
    assert_eq!(
        j["bop"]["mssd"]["recall_per_threshold"]
            .as_array()
            .unwrap()
            .len(),
        10
    );
    // A tnet checkpoint predicts no rotation: --bop is refused.
    let o = eval(&["--bop"], &tnet);
    refused(&o, &["--bop", "tnet"]);

    // No repeated GT pose yet: --stability is a user error; with frame 0 repeated it reports.
    let stab = |json: &Path| {
        run(synthgen()
            .args(["eval", "-q", "--stability", "--checkpoint"])
            .arg(full.join("model.safetensors"))
            .arg("--data")
            .arg(&data)
            .arg("--json")
            .arg(json))
    };
    let o = stab(&dir.path().join("s0.json"));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    repeat_frame_zero(&data);
    let sj = dir.path().join("s.json");
    let o = stab(&sj);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&sj).unwrap()).unwrap();
    let groups = j["stability"].as_array().unwrap();
    assert_eq!(groups.len(), 1, "{j}");
    assert_eq!(groups[0]["n"], 4);
    assert_eq!(groups[0]["cov_t_mm2"].as_array().unwrap().len(), 3);
    assert_eq!(groups[0]["cov_q"].as_array().unwrap().len(), 4);
    assert!(groups[0]["t_spread_mm"].as_f64().unwrap().is_finite());
}

#[test]
fn no_symmetric_loss_is_recorded_and_kept_on_resume() {
    let dir = tempfile::tempdir().unwrap();
    let data = tiny_dataset(dir.path());
    let out = dir.path().join("plain");
    let full = FULL_MODEL_ARGS;
    let o = train(
        &data,
        &out,
        "1",
        &[&full[..], &["--no-symmetric-loss"]].concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let cfg = |p: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(p.join("config.json")).unwrap()).unwrap()
    };
    assert_eq!(cfg(&out)["plain_add_loss"], true);
    assert!(train(&data, &out, "2", &["--resume"]).status.success());
    assert_eq!(cfg(&out)["plain_add_loss"], true);
    // The default (symmetric) loss writes no such key.
    let sym = dir.path().join("sym");
    assert!(train(&data, &sym, "1", &full).status.success());
    assert!(cfg(&sym).get("plain_add_loss").is_none());
}

/// Issue 26: `eval --results` (and `--bop`) refused a BOP set without rgb/ although no metric
/// reads colour (bop_toolkit needs only the GT, the cameras, the models and, for VSD, depth).
#[test]
fn eval_results_needs_no_colour_images() {
    let dir = tempfile::tempdir().unwrap();
    let data = tiny_dataset(dir.path());
    let csv = dir.path().join("results.csv");
    std::fs::write(&csv, gt_as_results(&data, 0.0)).unwrap();
    for scene in std::fs::read_dir(data.join("train_pbr")).unwrap().flatten() {
        std::fs::remove_dir_all(scene.path().join("rgb")).unwrap();
    }
    let json = dir.path().join("s.json");
    let o = run(synthgen()
        .args(["eval", "--bop", "--results"])
        .arg(&csv)
        .arg("--data")
        .arg(&data)
        .arg("--json")
        .arg(&json));
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(j["all"]["add_s_acc"], 1.0, "{j}");
    assert_eq!(j["bop"]["mssd"]["mean_recall"], 1.0, "{j}");
    // What needs the images still says so.
    let o = run(synthgen()
        .arg("preview")
        .arg(&data)
        .arg("--out")
        .arg(dir.path().join("p.png")));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("rgb"), "{}", stderr(&o));
}
