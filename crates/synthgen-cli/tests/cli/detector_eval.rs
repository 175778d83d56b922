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
    let o = detector_eval(&data, &dets, &["--out", d.join("s.json").to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
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
