//! The box detector end to end: `detector train` (its run folder, `--resume`, the guard),
//! `detector run` (BOP detections, the recall table), and `eval --detections`: crops from the
//! GT boxes written as detections score exactly as the GT boxes do, and an object without
//! detections gets no estimate.

use std::path::Path;

use serde_json::Value;

use crate::common::{refused, run, stderr, synthgen};
use crate::rgb::{json_file, two_class_set};

fn train_detector(data: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    run(synthgen()
        .args(["detector", "train", "--data"])
        .arg(data)
        .args([
            "--input",
            "64x48",
            "--batch",
            "4",
            "--val-fraction",
            "0.25",
            "--out",
        ])
        .arg(out)
        .args(extra))
}

/// `scene_gt_info.json`'s visible boxes of a BOP dataset's train_pbr scene 0 as BOP
/// detections (COCO's width: bbox_visib's + 1), leaving out object `skip`.
fn gt_detections(data: &Path, skip: u64) -> Value {
    let scene = data.join("train_pbr/000000");
    let gt = json_file(&scene.join("scene_gt.json"));
    let info = json_file(&scene.join("scene_gt_info.json"));
    let mut out = Vec::new();
    for (im, list) in gt.as_object().unwrap() {
        for (g, i) in list
            .as_array()
            .unwrap()
            .iter()
            .zip(info[im].as_array().unwrap())
        {
            let obj = g["obj_id"].as_u64().unwrap();
            let b: Vec<f64> = i["bbox_visib"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            if obj == skip || b[2] < 0.0 {
                continue;
            }
            out.push(serde_json::json!({
                "scene_id": 0, "image_id": im.parse::<u64>().unwrap(), "category_id": obj,
                "score": 1.0, "bbox": [b[0], b[1], b[2] + 1.0, b[3] + 1.0], "time": -1
            }));
        }
    }
    Value::Array(out)
}

#[test]
fn the_detector_trains_resumes_runs_and_feeds_eval() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_class_set(dir.path(), "set", "8", "3");
    let det = dir.path().join("det");
    let o = train_detector(&data, &det, &["--epochs", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cfg = json_file(&det.join("config.json"));
    assert_eq!(cfg["model"], "detector");
    assert_eq!(cfg["classes"], serde_json::json!([8, 9]));
    assert_eq!(cfg["input"], serde_json::json!([64, 48]));
    let lines = |p: &Path| std::fs::read_to_string(p).unwrap().lines().count();
    assert_eq!(lines(&det.join("metrics.jsonl")), 1);
    // A second run into the same folder is refused; --resume goes on to --epochs.
    refused(
        &train_detector(&data, &det, &["--epochs", "1"]),
        &["already holds a run", "--resume"],
    );
    let o = train_detector(&data, &det, &["--epochs", "2", "--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("resumed after epoch 1"),
        "{}",
        stderr(&o)
    );
    assert_eq!(lines(&det.join("metrics.jsonl")), 2);
    let m: Value = serde_json::from_str(
        std::fs::read_to_string(det.join("metrics.jsonl"))
            .unwrap()
            .lines()
            .last()
            .unwrap(),
    )
    .unwrap();
    assert_eq!(m["epoch"], 2);
    assert!(m["val_recall_50"].as_f64().unwrap() >= 0.0 && m["val_boxes"].as_u64().unwrap() > 0);

    // The run over the frames: BOP detections and a recall table of both objects.
    let found = dir.path().join("det.json");
    let o = run(synthgen()
        .args(["detector", "run", "--checkpoint"])
        .arg(&det)
        .arg("--data")
        .arg(&data)
        .arg("--out")
        .arg(&found));
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        table.contains("| 8 |") && table.contains("| 9 |") && table.contains("| all |"),
        "{table}"
    );
    let list = json_file(&found);
    for d in list.as_array().unwrap() {
        assert!(d["score"].as_f64().unwrap() >= 0.05, "{d}");
        let b = d["bbox"].as_array().unwrap();
        assert!(
            b[2].as_f64().unwrap() > 0.0 && b[3].as_f64().unwrap() > 0.0,
            "{d}"
        );
        assert!([8, 9].contains(&d["category_id"].as_u64().unwrap()), "{d}");
    }

    // An rgb-dense model scored from the GT boxes written as detections scores exactly as
    // from the GT boxes; without object 9's detections, 9 gets no estimate.
    let dense = dir.path().join("dense");
    let o = run(synthgen()
        .args(["train", "-q", "--model", "rgb-dense", "--data"])
        .arg(&data)
        .args([
            "--crop-size",
            "16",
            "--epochs",
            "1",
            "--batch",
            "4",
            "--width",
            "16",
            "--out",
        ])
        .arg(&dense));
    assert!(o.status.success(), "{}", stderr(&o));
    let eval = |extra: &[&std::ffi::OsStr], json: &str| {
        let json = dir.path().join(json);
        let o = run(synthgen()
            .args(["eval", "--checkpoint"])
            .arg(dense.join("model.safetensors"))
            .arg("--data")
            .arg(&data)
            .arg("--json")
            .arg(&json)
            .args(extra));
        assert!(o.status.success(), "{}", stderr(&o));
        (json_file(&json), stderr(&o))
    };
    let (with_gt, log) = eval(&[], "gt.json");
    assert!(log.contains("GT visible box"), "{log}");
    let gt_dets = dir.path().join("gt_det.json");
    std::fs::write(&gt_dets, gt_detections(&data, 0).to_string()).unwrap();
    let (from_dets, log) = eval(&["--detections".as_ref(), gt_dets.as_os_str()], "d.json");
    assert!(log.contains("cut around a detection"), "{log}");
    assert!(log.contains("0 without a detection"), "{log}");
    assert_eq!(with_gt, from_dets);
    std::fs::write(&gt_dets, gt_detections(&data, 9).to_string()).unwrap();
    let (no_nine, log) = eval(&["--detections".as_ref(), gt_dets.as_os_str()], "d9.json");
    let n9 = with_gt["9"]["n_gt"].as_u64().unwrap();
    assert!(log.contains(&format!("{n9} without a detection")), "{log}");
    assert_eq!(no_nine["9"]["n_est"].as_u64().unwrap_or(0), 0, "{no_nine}");
    assert_eq!(no_nine["8"], with_gt["8"]);
}

#[test]
fn detections_and_their_box_are_refused_where_they_mean_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let eval = |extra: &[&str]| {
        run(synthgen()
            .args(["eval", "--results"])
            .arg(d.join("r.csv"))
            .arg("--data")
            .arg(d.join("nothing"))
            .args(extra))
    };
    refused(
        &eval(&["--refine", "views", "--visible-box", "detected"]),
        &["--visible-box detected", "--detections"],
    );
    refused(
        &eval(&["--detections", "x.json"]),
        &["--detections", "--checkpoint"],
    );
    std::fs::write(d.join("r.csv"), "scene_id,im_id,obj_id,score,R,t,time\n").unwrap();
    let o = run(synthgen()
        .args(["detector", "run", "--checkpoint"])
        .arg(d.join("no_run"))
        .arg("--data")
        .arg(d)
        .arg("--out")
        .arg(d.join("out.json")));
    refused(&o, &["config.json"]);
    refused(
        &run(synthgen()
            .args(["detector", "train", "--data"])
            .arg(d)
            .args(["--input", "60x48", "--out"])
            .arg(d.join("o"))),
        &["60x48", "multiples of 8"],
    );
}
