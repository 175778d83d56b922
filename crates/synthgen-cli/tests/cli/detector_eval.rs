//! `synthgen detector eval`: BOP detections scored as bop_toolkit's eval_bop22_coco.py
//! scores them. The GT's own boxes and masks as detections score AP 1 for boxes and masks; an
//! object left out scores 0 and halves the mean; bad files are named with their entry. (The
//! numbers against pycocotools on imperfect detections: python/tests/test_coco_eval.py.)

use std::path::Path;

use serde_json::{json, Value};
use synthgen_formats::bop::read_mask;
use synthgen_formats::coco::Rle;

use crate::common::{refused, run, stderr, synthgen};
use crate::rgb::{json_file, two_class_set};

fn detector_eval(data: &Path, dets: &Path, extra: &[&str]) -> std::process::Output {
    run(synthgen()
        .args(["-q", "detector", "eval", "--data"])
        .arg(data)
        .arg("--detections")
        .arg(dets)
        .args(extra))
}

/// The GT of train_pbr scene 0 as detections: the full mask's bounds (amodal, COCO's
/// width; the visible mask's with `modal`) and the visible mask as RLE, leaving out object
/// `skip`.
fn gt_as_detections(data: &Path, skip: u64, modal: bool) -> Value {
    let scene = data.join("train_pbr/000000");
    let gt = json_file(&scene.join("scene_gt.json"));
    let mut out = Vec::new();
    for (im, list) in gt.as_object().unwrap() {
        let im: u32 = im.parse().unwrap();
        for (g, inst) in list.as_array().unwrap().iter().enumerate() {
            let obj = inst["obj_id"].as_u64().unwrap();
            let stem = format!("{im:06}_{g:06}.png");
            let visib = read_mask(&scene.join("mask_visib").join(&stem)).unwrap();
            let full = read_mask(&scene.join("mask").join(&stem)).unwrap();
            let boxed = if modal { &visib } else { &full };
            let b = synthgen_core::annotate::mask_bbox(&boxed.data, boxed.width);
            if obj == skip || !visib.data.iter().any(|&v| v > 0) {
                continue;
            }
            let rle = Rle::from_mask(&visib.data, visib.width, visib.height);
            out.push(json!({
                "scene_id": 0, "image_id": im, "category_id": obj, "score": 0.9,
                "bbox": [b[0], b[1], b[2] + 1, b[3] + 1], "segmentation": rle, "time": 0.01
            }));
        }
    }
    Value::Array(out)
}

#[test]
fn the_gt_as_detections_scores_one_and_a_missing_object_zero() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = two_class_set(d, "set", "4", "5");
    let dets = d.join("dets.json");
    std::fs::write(&dets, gt_as_detections(&data, 0, false).to_string()).unwrap();
    let pictures = d.join("pictures");
    let o = detector_eval(
        &data,
        &dets,
        &[
            "--out",
            d.join("s.json").to_str().unwrap(),
            "--draw",
            pictures.to_str().unwrap(),
            "--draw-count",
            "2",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    // Two of the four frames, drawn at the frames' size.
    let drawn: Vec<_> = std::fs::read_dir(&pictures).unwrap().collect();
    assert_eq!(drawn.len(), 2);
    let png = synthgen_formats::bop::image::read_rgb(&pictures.join("000000_000000.png")).unwrap();
    assert_eq!((png.width, png.height), (320, 240));
    let table = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(table.contains("| AP | 1.000 | 1.000 |"), "{table}");
    let s = json_file(&d.join("s.json"));
    for kind in ["bbox", "segm"] {
        // 1 - 2e-16: pycocotools divides by tp + fp + eps.
        assert!(
            (s[kind]["stats"]["AP"].as_f64().unwrap() - 1.0).abs() < 1e-12,
            "{s}"
        );
        assert!((s[kind]["stats"]["AR100"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    }
    assert_eq!(s["images_with_rendered_masks"], 0);
    assert_eq!(s["bbox_type"], "amodal");

    // Modal: the GT boxes are the visible masks' bounds, which score 1 there.
    let modal = |dets_json: Value, name: &str| {
        std::fs::write(&dets, dets_json.to_string()).unwrap();
        let out = d.join(name);
        let o = detector_eval(
            &data,
            &dets,
            &["--bbox-type", "modal", "--out", out.to_str().unwrap()],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        json_file(&out)["bbox"]["stats"]["AP"].as_f64().unwrap()
    };
    assert!((modal(gt_as_detections(&data, 0, true), "m.json") - 1.0).abs() < 1e-12);

    // Object 9 left out: its AP is 0, the mean over the two objects about a half.
    std::fs::write(&dets, gt_as_detections(&data, 9, false).to_string()).unwrap();
    let o = detector_eval(
        &data,
        &dets,
        &["--out", d.join("s9.json").to_str().unwrap()],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let s = json_file(&d.join("s9.json"));
    assert_eq!(s["bbox"]["objects"]["9"]["AP"], 0.0);
    assert!((s["bbox"]["objects"]["8"]["AP"].as_f64().unwrap() - 1.0).abs() < 1e-12);
    assert!(
        (s["segm"]["stats"]["AP"].as_f64().unwrap() - 0.5).abs() < 1e-12,
        "{s}"
    );
}

#[test]
fn bad_detections_and_outputs_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = two_class_set(d, "set", "2", "6");
    let dets = d.join("dets.json");
    let entry = |segm: Value| {
        json!([{"scene_id": 0, "image_id": 0, "category_id": 8, "score": 0.5,
                "bbox": [1, 2, 30, 40], "segmentation": segm}])
        .to_string()
    };
    // A mask of another image size.
    std::fs::write(&dets, entry(json!({"size": [48, 64], "counts": [3072]}))).unwrap();
    refused(
        &detector_eval(&data, &dets, &[]),
        &["entry 0", "64x48", "320x240"],
    );
    // Runs that do not fill the size; a string that is no RLE.
    std::fs::write(&dets, entry(json!({"size": [240, 320], "counts": [5, 6]}))).unwrap();
    refused(
        &detector_eval(&data, &dets, &[]),
        &["dets.json", "entry 0", "cover 11 pixels"],
    );
    std::fs::write(&dets, entry(json!({"size": [240, 320], "counts": "~~"}))).unwrap();
    refused(
        &detector_eval(&data, &dets, &[]),
        &["dets.json", "entry 0", "compressed RLE"],
    );
    // A NaN box.
    std::fs::write(
        &dets,
        r#"[{"scene_id": 0, "image_id": 0, "category_id": 8, "score": 0.5, "bbox": [1, 2, 3, NaN]}]"#,
    )
    .unwrap();
    refused(&detector_eval(&data, &dets, &[]), &["dets.json"]);
    // A box off the image is scored (a false positive, as bop_toolkit) and counted, not silent.
    std::fs::write(
        &dets,
        r#"[{"scene_id": 0, "image_id": 0, "category_id": 8, "score": 0.5, "bbox": [900, 20, 30, 40]}]"#,
    )
    .unwrap();
    let out = d.join("off.json");
    let o = detector_eval(&data, &dets, &["--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("1 detections in") && stderr(&o).contains("off the 320x240"),
        "{}",
        stderr(&o)
    );
    assert_eq!(json_file(&out)["off_image"], 1);
    // Outputs onto the inputs; a targets file of other frames.
    std::fs::write(&dets, "[]").unwrap();
    refused(
        &detector_eval(&data, &dets, &["--out", dets.to_str().unwrap()]),
        &["--out"],
    );
    refused(
        &detector_eval(
            &data,
            &dets,
            &["--gt-out", data.join("gt.json").to_str().unwrap()],
        ),
        &["--gt-out"],
    );
    refused(
        &detector_eval(
            &data,
            &dets,
            &["--draw", data.join("pics").to_str().unwrap()],
        ),
        &["--draw"],
    );
    let targets = d.join("targets.json");
    std::fs::write(
        &targets,
        r#"[{"scene_id": 7, "im_id": 1, "obj_id": 8, "inst_count": 1}]"#,
    )
    .unwrap();
    refused(
        &detector_eval(&data, &dets, &["--targets", targets.to_str().unwrap()]),
        &["targets.json", "names none of the frames"],
    );
    assert!(std::fs::read_dir(&data)
        .unwrap()
        .all(|e| e.unwrap().file_name() != "gt.json"));
}

#[test]
fn a_trained_detector_gives_masks_that_score_and_none_without_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = two_class_set(d, "set", "6", "7");
    for (run_name, extra) in [("det", &[][..]), ("boxes", &["--no-masks"][..])] {
        let out = d.join(run_name);
        let o = run(synthgen()
            .args(["-q", "detector", "train", "--data"])
            .arg(&data)
            .args(["--input", "64x48", "--epochs", "2", "--batch", "3", "--out"])
            .arg(&out)
            .args(extra));
        assert!(o.status.success(), "{}", stderr(&o));
        let cfg = json_file(&out.join("config.json"));
        assert_eq!(cfg["masks"], extra.is_empty());
        let dets = d.join(format!("{run_name}.json"));
        let o = run(synthgen()
            .args(["-q", "detector", "run", "--checkpoint"])
            .arg(&out)
            .arg("--data")
            .arg(&data)
            .args(["--min-score", "0.0", "--per-class", "3", "--out"])
            .arg(&dets));
        assert!(o.status.success(), "{}", stderr(&o));
        let list = json_file(&dets);
        let list = list.as_array().unwrap();
        assert!(!list.is_empty());
        for e in list {
            if extra.is_empty() {
                // The frame's size, as COCO RLE reads it; inside the detection's box.
                let rle: Rle = serde_json::from_value(e["segmentation"].clone()).unwrap();
                assert_eq!((rle.width, rle.height), (320, 240));
                let (b, m) = (e["bbox"].as_array().unwrap(), rle.bbox());
                if rle.area() > 0 {
                    assert!(
                        m[0] + 1.0 >= b[0].as_f64().unwrap()
                            && m[1] + 1.0 >= b[1].as_f64().unwrap()
                    );
                    assert!(m[0] + m[2] <= b[0].as_f64().unwrap() + b[2].as_f64().unwrap() + 1.0);
                }
            } else {
                assert!(e.get("segmentation").is_none(), "{e}");
            }
        }
        let scores = d.join(format!("{run_name}_scores.json"));
        let o = detector_eval(&data, &dets, &["--out", scores.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        let s = json_file(&scores);
        let ap = s["bbox"]["stats"]["AP"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&ap), "{s}");
        assert_eq!(s["segm"].is_null(), !extra.is_empty(), "{s}");
    }
}

#[test]
fn the_depth_models_read_their_points_from_the_detections_masks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = two_class_set(d, "set", "6", "8");
    let run_dir = d.join("tnet");
    let o = run(synthgen()
        .args(["-q", "train", "--model", "tnet", "--epochs", "1", "--data"])
        .arg(&data)
        .arg("--out")
        .arg(&run_dir));
    assert!(o.status.success(), "{}", stderr(&o));
    let eval = |dets: Option<&Path>, json: &str| {
        let mut c = synthgen();
        c.args(["-q", "eval", "--checkpoint"])
            .arg(run_dir.join("model.safetensors"))
            .arg("--data")
            .arg(&data)
            .arg("--json")
            .arg(d.join(json));
        if let Some(p) = dets {
            c.arg("--detections").arg(p);
        }
        run(&mut c)
    };
    let o = eval(None, "gt.json");
    assert!(o.status.success(), "{}", stderr(&o));
    // The GT's own visible masks as detections: the same points, the same scores.
    let dets = d.join("dets.json");
    std::fs::write(&dets, gt_as_detections(&data, 0, false).to_string()).unwrap();
    let o = eval(Some(&dets), "det.json");
    assert!(o.status.success(), "{}", stderr(&o));
    let (gt, det) = (
        json_file(&d.join("gt.json")),
        json_file(&d.join("det.json")),
    );
    assert_eq!(gt["all"]["n"], 12, "{gt}");
    assert_eq!(gt, det);
    // Object 9 without detections: its instances are misses.
    std::fs::write(&dets, gt_as_detections(&data, 9, false).to_string()).unwrap();
    let o = eval(Some(&dets), "det9.json");
    assert!(o.status.success(), "{}", stderr(&o));
    let det9 = json_file(&d.join("det9.json"));
    assert_eq!(det9["8"], gt["8"]);
    assert_ne!(det9["9"], gt["9"], "{det9}");
    // Boxes without masks tell a depth model nothing: refused.
    let mut boxes_only = gt_as_detections(&data, 0, false);
    for e in boxes_only.as_array_mut().unwrap() {
        e.as_object_mut().unwrap().remove("segmentation");
    }
    std::fs::write(&dets, boxes_only.to_string()).unwrap();
    refused(
        &eval(Some(&dets), "no.json"),
        &["dets.json", "segmentation", "mask"],
    );
}
