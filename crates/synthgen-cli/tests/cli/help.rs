//! `--help` output is part of the interface: snapshot it. Regenerate with SYNTHGEN_BLESS=1.

use crate::common::{run, synthgen};

fn check_snapshot(name: &str, args: &[&str]) {
    let out = run(synthgen().args(args).env("COLUMNS", "100"));
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout).replace("synthgen.exe", "synthgen");
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/snapshots")
        .join(name);
    if std::env::var_os("SYNTHGEN_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(&path, &text).unwrap();
        return;
    }
    let want = std::fs::read_to_string(&path).unwrap_or_else(|_| {
        panic!(
            "missing snapshot {}; run with SYNTHGEN_BLESS=1 to create it",
            path.display()
        )
    });
    assert_eq!(
        text,
        want,
        "help changed; if intended, re-run with SYNTHGEN_BLESS=1 ({})",
        path.display()
    );
}

#[test]
fn top_level_help() {
    check_snapshot("help.txt", &["--help"]);
}

#[test]
fn render_help() {
    check_snapshot("render_help.txt", &["render", "--help"]);
}

#[test]
fn mix_help() {
    check_snapshot("mix_help.txt", &["mix", "--help"]);
}

#[test]
fn stats_help() {
    check_snapshot("stats_help.txt", &["stats", "--help"]);
}

#[test]
fn preview_help() {
    check_snapshot("preview_help.txt", &["preview", "--help"]);
}

#[test]
fn export_coco_help() {
    check_snapshot("export_coco_help.txt", &["export", "coco", "--help"]);
}

#[test]
fn annotate_help() {
    check_snapshot("annotate_help.txt", &["annotate", "--help"]);
}

#[test]
fn convert_help() {
    check_snapshot("convert_help.txt", &["convert", "--help"]);
}

#[test]
fn validate_help() {
    check_snapshot("validate_help.txt", &["validate", "--help"]);
}

#[test]
fn train_help() {
    check_snapshot("train_help.txt", &["train", "--help"]);
}

#[test]
fn predict_help() {
    check_snapshot("predict_help.txt", &["predict", "--help"]);
}

#[test]
fn ros_help() {
    check_snapshot("ros_help.txt", &["ros", "--help"]);
}

#[test]
fn eval_help() {
    check_snapshot("eval_help.txt", &["eval", "--help"]);
}

#[test]
fn experiment_mix_help() {
    check_snapshot("experiment_mix_help.txt", &["experiment", "mix", "--help"]);
}

#[test]
fn scene_fit_help() {
    check_snapshot("scene_fit_help.txt", &["scene", "fit", "--help"]);
}

#[test]
fn experiment_sim2real_help() {
    check_snapshot(
        "experiment_sim2real_help.txt",
        &["experiment", "sim2real", "--help"],
    );
}

#[test]
fn view_help() {
    check_snapshot("view_help.txt", &["view", "--help"]);
}

#[test]
fn experiment_rgb_help() {
    check_snapshot("experiment_rgb_help.txt", &["experiment", "rgb", "--help"]);
}

#[test]
fn detector_train_help() {
    check_snapshot("detector_train_help.txt", &["detector", "train", "--help"]);
}

#[test]
fn detector_run_help() {
    check_snapshot("detector_run_help.txt", &["detector", "run", "--help"]);
}

#[test]
fn detector_eval_help() {
    check_snapshot("detector_eval_help.txt", &["detector", "eval", "--help"]);
}

#[test]
fn model_align_help() {
    check_snapshot("model_align_help.txt", &["model", "align", "--help"]);
}

#[test]
fn sensor_compare_rgb_help() {
    check_snapshot(
        "sensor_compare_rgb_help.txt",
        &["sensor", "compare-rgb", "--help"],
    );
}

#[test]
fn experiment_help() {
    check_snapshot("experiment_help.txt", &["experiment", "--help"]);
}

/// `train --help` and `experiment --help` lead to the RGB-only dense model, the detector and
/// `experiment sim2real` (issue 50: they named none of them).
#[test]
fn train_and_experiment_help_name_rgb_dense_the_detector_and_sim2real() {
    for cmd in ["train", "experiment"] {
        let out = run(synthgen().args([cmd, "--help"]));
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        let text = text.split_whitespace().collect::<Vec<_>>().join(" ");
        for words in [
            "rgb-dense",
            "synthgen detector train|run",
            "experiment sim2real",
        ] {
            assert!(
                text.contains(words),
                "`{cmd} --help` lacks {words:?}: {text}"
            );
        }
    }
}
