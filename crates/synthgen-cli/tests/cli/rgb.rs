//! The RGB model (seed 001) end to end: `train --model rgb`, `eval --checkpoint` and
//! `--save-results`, `experiment rgb` (its table, resume and refusals), and on the real
//! YCB-Video frames.

use std::path::{Path, PathBuf};

use crate::common::{refused, repo_root, run, stderr, synthgen, ycbv_real};

/// Renders `frames` small frames of the sample driller as two classes (ids 8 and 9) into
/// `dir/name`.
pub(crate) fn two_class_set(dir: &Path, name: &str, frames: &str, seed: &str) -> PathBuf {
    let out = dir.join(name);
    let mesh = repo_root().join("datasets/meshes/driller.ply");
    let o = run(synthgen()
        .args(["render", "-q", "--objects"])
        .arg(&mesh)
        .arg(&mesh)
        .args([
            "--obj-ids",
            "8,9",
            "--frames",
            frames,
            "--seed",
            seed,
            "--image-size",
            "320,240",
            "--out",
        ])
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

/// `train --model rgb` at tiny sizes (batch 4, width 16, 16-pixel crops unless `extra` says).
fn train_rgb(data: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let crop = if extra.contains(&"--crop-size") {
        &[][..]
    } else {
        &["--crop-size", "16"][..]
    };
    let epochs = if extra.contains(&"--epochs") {
        &[][..]
    } else {
        &["--epochs", "2"][..]
    };
    run(synthgen()
        .args(["train", "-q", "--model", "rgb", "--data"])
        .arg(data)
        .args(crop)
        .args(epochs)
        .args([
            "--batch",
            "4",
            "--width",
            "16",
            "--loss-points",
            "20",
            "--seed",
            "1",
            "--val-fraction",
            "0.25",
            "--out",
        ])
        .arg(out)
        .args(extra))
}

pub(crate) fn json_file(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn rgb_trains_evaluates_and_its_results_score_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_class_set(dir.path(), "set", "8", "3");
    let out = dir.path().join("run");
    let o = train_rgb(&data, &out, &["--translation", "xyz"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let cfg = json_file(&out.join("config.json"));
    assert_eq!(cfg["model"], "rgb");
    assert_eq!(cfg["translation"], "xyz");
    assert_eq!(cfg["classes"], serde_json::json!([8, 9]));
    assert_eq!(cfg["crop_size"], 16);
    let last: serde_json::Value = serde_json::from_str(
        std::fs::read_to_string(out.join("metrics.jsonl"))
            .unwrap()
            .lines()
            .last()
            .unwrap(),
    )
    .unwrap();
    for key in [
        "val_centre_error_m",
        "val_add_s_acc",
        "val_mean_re_deg",
        "val_acc_5cm5deg",
    ] {
        assert!(last[key].is_number(), "{key} in {last}");
    }

    // eval --checkpoint: the seed's metrics per object; --save-results writes the estimates.
    let scores = dir.path().join("scores.json");
    let csv = dir.path().join("results.csv");
    let o = run(synthgen()
        .args(["eval", "--checkpoint"])
        .arg(out.join("model.safetensors"))
        .arg("--data")
        .arg(&data)
        .arg("--json")
        .arg(&scores)
        .arg("--save-results")
        .arg(&csv));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("GT visible box"), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("| 8 | ADD |") && stdout.contains("| 9 | ADD |"),
        "{stdout}"
    );
    let j = json_file(&scores);
    for obj in ["8", "9", "all"] {
        for key in ["acc_5cm5deg", "mean_te_cm", "mean_re_deg", "add_s_acc"] {
            assert!(j[obj][key].is_number(), "{obj}.{key} in {j}");
        }
    }
    // The saved estimates, scored as a results CSV, give the same numbers.
    let again = dir.path().join("again.json");
    let o = run(synthgen()
        .args(["eval", "-q", "--results"])
        .arg(&csv)
        .arg("--data")
        .arg(&data)
        .arg("--json")
        .arg(&again));
    assert!(o.status.success(), "{}", stderr(&o));
    let k = json_file(&again);
    for obj in ["8", "9", "all"] {
        assert_eq!(j[obj]["n_gt"], k[obj]["n_gt"]);
        assert_eq!(j[obj]["acc_5cm5deg"], k[obj]["acc_5cm5deg"]);
        let (a, b) = (
            j[obj]["mean_te_cm"].as_f64().unwrap(),
            k[obj]["mean_te_cm"].as_f64().unwrap(),
        );
        // The CSV stores the pose's decimal digits.
        assert!((a - b).abs() < 1e-6, "{obj}: {a} vs {b}");
    }
}

#[test]
fn rgb_needs_no_depth_and_refuses_what_it_cannot_use() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_class_set(dir.path(), "set", "8", "4");
    // Without depth images the RGB model still trains; the depth models refuse.
    std::fs::remove_dir_all(data.join("train_pbr/000000/depth")).unwrap();
    let out = dir.path().join("run");
    let o = train_rgb(&data, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(synthgen()
        .args(["train", "-q", "--model", "tnet", "--epochs", "1", "--data"])
        .arg(&data)
        .arg("--out")
        .arg(dir.path().join("tnet")));
    refused(&o, &["no depth image"]);

    // A crop too small for the network is refused before anything is read.
    let o = train_rgb(&data, &dir.path().join("small"), &["--crop-size", "8"]);
    refused(&o, &["--crop-size 8"]);

    // A dataset with none of the model's objects: nothing to estimate, said so.
    let other = dir.path().join("other");
    let o = run(synthgen()
        .args(["render", "-q", "--objects"])
        .arg(repo_root().join("datasets/meshes/driller.ply"))
        .args([
            "--obj-ids",
            "3",
            "--frames",
            "2",
            "--image-size",
            "320,240",
            "--out",
        ])
        .arg(&other));
    assert!(o.status.success());
    let o = run(synthgen()
        .args(["eval", "--checkpoint"])
        .arg(out.join("model.safetensors"))
        .arg("--data")
        .arg(&other));
    refused(&o, &["not trained on", "no usable object instances"]);
}

#[test]
fn experiment_rgb_writes_table_1_resumes_and_refuses_other_settings() {
    let dir = tempfile::tempdir().unwrap();
    let train = two_class_set(dir.path(), "train", "8", "5");
    let test = two_class_set(dir.path(), "test", "4", "6");
    let out = dir.path().join("exp");
    let exp = |extra: &[&str]| {
        run(synthgen()
            .args(["experiment", "rgb", "--train"])
            .arg(&train)
            .arg("--test")
            .arg(&test)
            .args([
                "--quick",
                "--crop-size",
                "16",
                "--width",
                "16",
                "--epochs",
                "1",
            ])
            .arg("--out")
            .arg(&out)
            .args(extra))
    };
    let o = exp(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        table.contains(
            "| object | n | centre-tz 5cm5° | centre-tz E_te cm | centre-tz E_re ° | xyz 5cm5° | xyz E_te cm | xyz E_re ° |"
        ),
        "{table}"
    );
    let report = json_file(&out.join("report.json"));
    let n = |obj: &str| report["variants"][0]["objects"][obj]["n"].as_u64().unwrap();
    assert!(n("8") > 0 && n("9") > 0);
    for row in [
        format!("| 8 | {} |", n("8")),
        format!("| 9 | {} |", n("9")),
        format!("| mean | {} |", n("8") + n("9")),
    ] {
        assert!(table.contains(&row), "{row} in {table}");
    }
    assert_eq!(
        std::fs::read_to_string(out.join("table.md")).unwrap(),
        table
    );
    let csv = std::fs::read_to_string(out.join("table.csv")).unwrap();
    assert!(csv.starts_with("variant,group,id,n,acc_5cm5deg,mean_te_cm,mean_re_deg,add_s_acc"));
    assert_eq!(csv.lines().count(), 1 + 2 * (3 + 2));
    assert!(report["verdict"]
        .as_str()
        .unwrap()
        .starts_with("seed 001's finding"));
    assert_eq!(report["variants"].as_array().unwrap().len(), 2);
    assert_eq!(report["variants"][1]["variant"], "xyz");
    for v in ["centre-tz", "xyz"] {
        let run_dir = out.join("variants").join(v).join("train");
        assert!(run_dir.join("model.safetensors").is_file(), "{v}");
        assert_eq!(json_file(&run_dir.join("config.json"))["translation"], v);
    }

    // The same options again: both variants are kept, nothing is trained.
    let scores = out.join("variants/xyz/scores.json");
    let before = std::fs::metadata(&scores).unwrap().modified().unwrap();
    let o = exp(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        stderr(&o).matches("done earlier").count(),
        2,
        "{}",
        stderr(&o)
    );
    assert_eq!(
        std::fs::metadata(&scores).unwrap().modified().unwrap(),
        before
    );
    assert_eq!(String::from_utf8_lossy(&o.stdout), table);

    // Other settings into the same folder: refused unless --force.
    let o = exp(&["--seed", "9"]);
    refused(&o, &["other settings", "--force"]);
    // A test scene the test set does not have, and an output inside an input.
    let o = run(synthgen()
        .args(["experiment", "rgb", "--quick", "--train"])
        .arg(&train)
        .arg("--test")
        .arg(&test)
        .args(["--test-scenes", "7", "--out"])
        .arg(dir.path().join("exp2")));
    refused(&o, &["--test-scenes 7", "no such scene"]);
    let o = run(synthgen()
        .args(["experiment", "rgb", "--quick", "--train"])
        .arg(&train)
        .arg("--test")
        .arg(&test)
        .arg("--out")
        .arg(train.join("inside")));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
}

/// The RGB model reads YCB-Video as it ships: RGB, the label image's visible masks (no
/// scene_gt_info: the box is the mask's), its models in metres.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn rgb_trains_and_evaluates_on_the_real_ycbv_frames() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = train_rgb(&real, &out, &["--epochs", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let classes = json_file(&out.join("config.json"))["classes"].clone();
    assert_eq!(classes.as_array().unwrap().len(), 12, "{classes}");
    let json = dir.path().join("s.json");
    let o = run(synthgen()
        .args(["eval", "-q", "--checkpoint"])
        .arg(out.join("model.safetensors"))
        .arg("--data")
        .arg(&real)
        .arg("--json")
        .arg(&json));
    assert!(o.status.success(), "{}", stderr(&o));
    let j = json_file(&json);
    assert!(j["all"]["n_gt"].as_u64().unwrap() >= 200, "{j}");
    assert!(j["all"]["mean_te_cm"].as_f64().unwrap().is_finite());
}

/// Issue 26: `experiment rgb --train X --test X`, or a copy of X, scored the model on its own
/// training frames; refused as `mix` refuses it, before anything is written.
#[test]
fn experiment_rgb_refuses_to_score_its_own_training_frames() {
    let dir = tempfile::tempdir().unwrap();
    let set = two_class_set(dir.path(), "set", "4", "5");
    let copy = dir.path().join("copy");
    crate::common::copy_dir(&set, &copy, &[]);
    for test in [&set, &copy] {
        let out = dir.path().join("exp");
        let o = run(synthgen()
            .args(["experiment", "rgb", "--quick", "--train"])
            .arg(&set)
            .arg("--test")
            .arg(test)
            .arg("--out")
            .arg(&out));
        refused(&o, &["same images as test frames", "memorized"]);
        assert!(!out.exists(), "nothing written before the refusal");
    }
}

/// Issue 26: `experiment rgb` resumed with the scores of a test set that had been replaced by
/// another under the same path (or lost frames): the inputs are fingerprinted.
#[test]
fn experiment_rgb_refuses_to_resume_when_its_data_changed() {
    let dir = tempfile::tempdir().unwrap();
    let train = two_class_set(dir.path(), "train", "6", "5");
    let test = two_class_set(dir.path(), "test", "3", "6");
    let out = dir.path().join("exp");
    let exp = |extra: &[&str]| {
        run(synthgen()
            .args(["experiment", "rgb", "--quick", "--variants", "xyz"])
            .args([
                "--crop-size",
                "16",
                "--width",
                "16",
                "--epochs",
                "1",
                "--train",
            ])
            .arg(&train)
            .arg("--test")
            .arg(&test)
            .arg("--out")
            .arg(&out)
            .args(extra))
    };
    let o = exp(&[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(out.join("inputs.json").is_file());
    let o = exp(&[]);
    assert!(o.status.success(), "the same data resumes: {}", stderr(&o));
    std::fs::remove_dir_all(&test).unwrap();
    two_class_set(dir.path(), "test", "3", "7"); // another dataset under the same path
    refused(&exp(&[]), &["--test dataset", "changed", "--force"]);
    let o = exp(&["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A frame rewritten in place (here: only its modification time) is a change too.
    std::fs::File::options()
        .write(true)
        .open(train.join("train_pbr/000000/rgb/000005.png"))
        .unwrap()
        .set_modified(std::time::UNIX_EPOCH + std::time::Duration::from_secs(1))
        .unwrap();
    // The same files and bytes: the message says what differs (not "then N, now N").
    refused(
        &exp(&[]),
        &[
            "--train dataset",
            "changed",
            "the same",
            "modification times differ",
        ],
    );
}

/// `train --model rgb-dense` and its evaluation, on renders and on the real Linemod-Occluded
/// photographs of `../shared/data/lmo`, which have neither depth nor visible masks: the model
/// reads only the colour inside `bbox_visib`, and the BOP scores leave VSD out.
#[test]
fn rgb_dense_trains_and_evaluates_on_real_lmo_without_masks_or_depth() {
    let dir = tempfile::tempdir().unwrap();
    // LM-O's own driller (8) and duck (9): a checkpoint names its objects, and one trained on
    // other objects under these ids is refused on LM-O.
    let models = crate::common::shared_data().join("lmo/models");
    let data = dir.path().join("set");
    let o = run(synthgen()
        .args(["render", "-q", "--objects"])
        .arg(models.join("obj_000008.ply"))
        .arg(models.join("obj_000009.ply"))
        .args([
            "--frames",
            "6",
            "--seed",
            "3",
            "--image-size",
            "320,240",
            "--out",
        ])
        .arg(&data));
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("dense");
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
            "--seed",
            "1",
            "--val-fraction",
            "0.25",
            "--out",
        ])
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    let cfg = json_file(&out.join("config.json"));
    assert_eq!(cfg["model"], "rgb-dense");
    assert_eq!(cfg["classes"], serde_json::json!([8, 9]));
    let lmo = crate::common::shared_data().join("lmo");
    let json = dir.path().join("lmo.json");
    let o = run(synthgen()
        .args(["eval", "--checkpoint"])
        .arg(out.join("model.safetensors"))
        .arg("--data")
        .arg(&lmo)
        .args(["--bop", "--json"])
        .arg(&json));
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("bbox_visib; no detector"), "{err}");
    assert!(err.contains("VSD needs depth images"), "{err}");
    let report = json_file(&json);
    let bop = &report["bop"];
    // Every GT instance of objects 8 and 9 in the 82 photographs got an estimate.
    let n: u64 = ["8", "9"]
        .iter()
        .map(|o| report[o]["n_est"].as_u64().unwrap_or(0))
        .sum();
    assert!(n >= 150, "{n} estimates: {report}");
    assert!(bop["mspd"]["mean_recall"].as_f64().is_some(), "{bop}");
    assert!(bop["vsd"].is_null() && bop["ar"].is_null(), "{bop}");
    // A frame set with neither depth nor masks cannot be trained on: no targets.
    let o = run(synthgen()
        .args(["train", "-q", "--model", "rgb-dense", "--data"])
        .arg(&lmo)
        .args(["--crop-size", "16", "--epochs", "1", "--out"])
        .arg(dir.path().join("refused")));
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("no coordinate targets"),
        "{}",
        stderr(&o)
    );
}
