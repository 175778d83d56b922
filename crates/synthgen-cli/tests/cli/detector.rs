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

/// `synthgen detector run --checkpoint DET --data DATA --out OUT`.
fn detector_run(
    det: impl AsRef<std::ffi::OsStr>,
    data: impl AsRef<std::ffi::OsStr>,
    out: impl AsRef<std::ffi::OsStr>,
) -> std::process::Output {
    run(synthgen()
        .args(["detector", "run", "--checkpoint"])
        .arg(det)
        .arg("--data")
        .arg(data)
        .arg("--out")
        .arg(out))
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
    let resume = |extra: &[&str]| {
        run(synthgen()
            .args(["detector", "train", "--resume", "--out"])
            .arg(&det)
            .args(extra))
    };
    let o = resume(&["--epochs", "2"]);
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
    let o = detector_run(&det, &data, &found);
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

    // Regression (issue 50): an empty detections list is a score, every instance a miss,
    // not "check rgb/ and mask_visib/".
    std::fs::write(&gt_dets, "[]").unwrap();
    let (none, log) = eval(&["--detections".as_ref(), gt_dets.as_os_str()], "none.json");
    assert!(log.contains("holds no detections"), "{log}");
    assert_eq!(none["all"]["n_est"].as_u64().unwrap_or(0), 0, "{none}");
    assert_eq!(none["all"]["n_gt"], with_gt["all"]["n_gt"]);
    // Boxes off the image or absurdly wide are skipped and counted, not NaN poses.
    let mut bad = gt_detections(&data, 0);
    let list = bad.as_array_mut().unwrap();
    list[0]["bbox"] = serde_json::json!([0.0, 0.0, 1e308, 40.0]);
    list[1]["bbox"] = serde_json::json!([5000.0, 10.0, 20.0, 20.0]);
    std::fs::write(&gt_dets, bad.to_string()).unwrap();
    let (skipped, log) = eval(&["--detections".as_ref(), gt_dets.as_os_str()], "bad.json");
    assert!(
        log.contains("2 of") && log.contains("with a box off the image"),
        "{log}"
    );
    assert!(!skipped.to_string().contains("NaN") && !skipped.to_string().contains("null,"));
    // Detections of another dataset whose ids coincide (same frames, other renders) are
    // refused by their provenance; those of no frame here are refused too.
    let other = two_class_set(dir.path(), "other", "8", "4");
    let other_dets = dir.path().join("other_det.json");
    let o = detector_run(&det, &other, &other_dets);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("other_det.provenance.json").is_file());
    let o = run(synthgen()
        .args(["eval", "--checkpoint"])
        .arg(dense.join("model.safetensors"))
        .arg("--data")
        .arg(&data)
        .arg("--detections")
        .arg(&other_dets));
    refused(&o, &["are of other frames", "the same ids, other images"]);
    std::fs::write(
        &gt_dets,
        r#"[{"scene_id": 7, "image_id": 0, "category_id": 8, "score": 1, "bbox": [1, 2, 30, 40]}]"#,
    )
    .unwrap();
    let o = run(synthgen()
        .args(["eval", "--checkpoint"])
        .arg(dense.join("model.safetensors"))
        .arg("--data")
        .arg(&data)
        .arg("--detections")
        .arg(&gt_dets));
    refused(&o, &["none of the 1 detections", "another dataset"]);
    // A detector's run folder given to eval, a pose model's to detector run: named as such.
    let o = run(synthgen()
        .args(["eval", "--checkpoint"])
        .arg(det.join("model.safetensors"))
        .arg("--data")
        .arg(&data));
    refused(&o, &["a detector's run", "detector run --checkpoint"]);
    let o = detector_run(&dense, &data, dir.path().join("x.json"));
    refused(&o, &["a pose model's run", "eval --checkpoint"]);
}

/// A cube of side `mm` millimetres as an OBJ: another object than the driller.
fn cube(dir: &Path, mm: f64) -> std::path::PathBuf {
    let h = mm / 2.0;
    let mut s = String::new();
    for z in [-h, h] {
        for y in [-h, h] {
            for x in [-h, h] {
                s += &format!("v {x} {y} {z}\n");
            }
        }
    }
    s += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    let p = dir.join("cube.obj");
    std::fs::write(&p, s).unwrap();
    p
}

/// Regression (issue 50): the detector's weights were unseeded; `--resume` trained on another
/// `--data` while config.json named the first, ignored --lr and the like, and `--epochs`
/// below the epochs done rewrote the config; `detector run --out` could be the detector's own
/// checkpoint or a dataset's scene_gt.json; a detector of other objects ran under the same ids.
#[test]
fn the_detector_is_seeded_resumes_as_configured_and_writes_over_no_input() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_class_set(dir.path(), "set", "6", "3");
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    for out in [&a, &b] {
        let o = train_detector(&data, out, &["--epochs", "1", "--seed", "5"]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let bytes = |p: &Path| std::fs::read(p).unwrap();
    assert!(
        bytes(&a.join("model.safetensors")) == bytes(&b.join("model.safetensors")),
        "the same command and --seed gave two different models"
    );
    let config = bytes(&a.join("config.json"));
    let resume = |extra: &[&str]| {
        run(synthgen()
            .args(["detector", "train", "--resume", "--out"])
            .arg(&a)
            .args(extra))
    };
    let other = two_class_set(dir.path(), "other", "4", "9");
    let o = resume(&["--epochs", "2", "--data", other.to_str().unwrap()]);
    refused(&o, &["--resume continues the run", "its own dataset"]);
    let o = resume(&["--epochs", "2", "--lr", "0.1"]);
    refused(
        &o,
        &["asks for other settings", "--lr 0.1 (the run's: 0.002)"],
    );
    let o = resume(&["--epochs", "1"]);
    refused(&o, &["trained 1 epochs already", "raise --epochs above 1"]);
    assert_eq!(
        bytes(&a.join("config.json")),
        config,
        "config.json rewritten"
    );
    // The same command with --resume (its --data spelled differently) goes on.
    let spelled = std::path::PathBuf::from(format!("{}/", data.display()));
    let o = train_detector(&spelled, &a, &["--epochs", "2", "--seed", "5", "--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));

    // detector run never writes over its inputs.
    let model = bytes(&a.join("model.safetensors"));
    let scene_gt = data.join("train_pbr/000000/scene_gt.json");
    let gt = bytes(&scene_gt);
    for out in [a.join("model.safetensors"), scene_gt.clone(), a.clone()] {
        let o = detector_run(&a, &data, &out);
        refused(&o, &["a command never writes into its inputs"]);
    }
    assert!(bytes(&a.join("model.safetensors")) == model && bytes(&scene_gt) == gt);
    // --out naming a folder gets detections.json in it (was: os error 20).
    let folder = dir.path().join("dets");
    std::fs::create_dir_all(&folder).unwrap();
    let o = detector_run(&a, &data, format!("{}/", folder.display()));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(folder.join("detections.json").is_file());
    let prov = json_file(&folder.join("detections.provenance.json"));
    assert_eq!(prov["objects"].as_array().unwrap().len(), 2, "{prov}");

    // A dataset whose object 8 is a cube, not the driller: refused.
    let cube_set = dir.path().join("cubes");
    let o = run(synthgen()
        .args(["render", "-q", "--objects"])
        .arg(cube(dir.path(), 60.0))
        .args([
            "--obj-ids",
            "8",
            "--frames",
            "2",
            "--image-size",
            "320,240",
            "--out",
        ])
        .arg(&cube_set));
    assert!(o.status.success(), "{}", stderr(&o));
    let o = detector_run(&a, &cube_set, dir.path().join("c.json"));
    refused(
        &o,
        &["trained on other objects", "object 8 is 8 (obj_000008"],
    );
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
    let elsewhere = tempfile::tempdir().unwrap();
    let o = detector_run(
        d.join("no_run"),
        d.join("data"),
        elsewhere.path().join("out.json"),
    );
    refused(&o, &["config.json"]);
    refused(
        &run(synthgen()
            .args(["detector", "train", "--data"])
            .arg(d)
            .args(["--input", "60x48", "--out"])
            .arg(elsewhere.path().join("o"))),
        &["60x48", "multiples of 8"],
    );
}
