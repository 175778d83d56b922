//! Issue 50, round three of careless and hostile use, classes 2 and 4 beyond the detector
//! (detector.rs) and the path rule (outputs_apart.rs): no silent wrong output, no
//! misleading refusal. Each test is named after what it pins.

use std::path::{Path, PathBuf};

use crate::common::{refused, repo_root, run, stderr, synthgen};

fn driller() -> PathBuf {
    repo_root().join("datasets/meshes/driller.ply")
}

fn render(d: &Path, out: &str, frames: &str, seed: &str, extra: &[&str]) -> std::process::Output {
    run(synthgen()
        .current_dir(d)
        .args(["render", "-q", "--objects"])
        .arg(driller())
        .args([
            "--frames",
            frames,
            "--seed",
            seed,
            "--image-size",
            "160,120",
            "--out",
            out,
        ])
        .args(extra))
}

/// A set with one usable frame trained as "diverged, lower --lr" (the empty validation
/// split's loss was NaN); it says how many frames it needs.
#[test]
fn training_on_one_frame_says_it_needs_two_not_diverged() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(render(d, "one", "1", "0", &[]).status.success());
    let o = run(synthgen()
        .current_dir(d)
        .args(["train", "--data", "one", "--epochs", "1", "--out", "run"]));
    refused(&o, &["1 frame with usable instances", "needs at least 2"]);
    assert!(!stderr(&o).contains("diverged"), "{}", stderr(&o));
}

/// `sensor compare-rgb` paired frames by their ids alone: two unrelated renders were
/// compared as photograph and twin.
#[test]
fn compare_rgb_refuses_frames_that_are_not_twins() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(render(d, "a", "3", "1", &[]).status.success());
    assert!(render(d, "b", "3", "2", &[]).status.success());
    let o = run(synthgen().current_dir(d).args([
        "sensor",
        "compare-rgb",
        "--real",
        "a",
        "--synth",
        "b",
    ]));
    refused(
        &o,
        &["show something else", "not its replay", "render --replay a"],
    );
    // Its own replay is compared.
    let o = run(synthgen()
        .current_dir(d)
        .args(["render", "-q", "--replay", "a", "--out", "twin"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(synthgen().current_dir(d).args([
        "sensor",
        "compare-rgb",
        "--real",
        "a",
        "--synth",
        "twin",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A 60 × 40 × 20 mm box as an OBJ in metres, moved by `dx_m` along x.
fn box_obj(path: &Path, dx_m: f64) {
    let mut s = String::new();
    for z in [-0.01, 0.01] {
        for y in [-0.02, 0.02] {
            for x in [-0.03, 0.03] {
                s += &format!("v {} {y} {z}\n", x + dx_m);
            }
        }
    }
    s += "f 1 3 4 2\nf 5 6 8 7\nf 1 2 6 5\nf 3 7 8 4\nf 1 5 7 3\nf 2 4 8 6\n";
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, s).unwrap();
}

/// `render --replay --replay-models` took a raw scan in its own origin without a check (the
/// labels ~110 px off the objects).
#[test]
fn replay_models_that_do_not_lie_on_the_models_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    box_obj(&d.join("box.obj"), 0.0);
    let o = run(synthgen().current_dir(d).args([
        "render",
        "-q",
        "--objects",
        "box.obj",
        "--frames",
        "2",
        "--image-size",
        "160,120",
        "--out",
        "src",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    // The same box, and the box 80 mm off: a scan in another origin.
    box_obj(&d.join("ok/obj_000001/scan.obj"), 0.0);
    box_obj(&d.join("raw/obj_000001/scan.obj"), 0.08);
    let replay = |models: &str, out: &str| {
        run(synthgen().current_dir(d).args([
            "render",
            "-q",
            "--replay",
            "src",
            "--replay-models",
            models,
            "--out",
            out,
        ]))
    };
    let o = replay("raw", "raw_twin");
    refused(
        &o,
        &[
            "does not lie where object 1's model lies",
            "model align --scans",
        ],
    );
    assert!(!d.join("raw_twin").exists());
    let o = replay("ok", "twin");
    assert!(o.status.success(), "{}", stderr(&o));
}

/// `jpeg_quality = [0.4, 0.4]` meant quality 1; `[sensor.rgb]` options without `enabled`
/// and `metallic` with Phong shading were ignored without a word.
#[test]
fn scene_settings_that_mean_nothing_are_refused_or_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = |name: &str, text: &str| {
        std::fs::write(d.join(name), text).unwrap();
        name.to_string()
    };
    let jpeg = scene(
        "jpeg.toml",
        "[sensor.rgb]\nenabled = true\njpeg_quality = [0.4, 0.4]\n",
    );
    let o = render(d, "o1", "1", "0", &["--scene", &jpeg]);
    refused(&o, &["jpeg_quality", "1 to 100", "not a fraction"]);
    let off = scene("off.toml", "[sensor.rgb]\nwhite_balance = 0.2\n");
    let o = render(d, "o2", "1", "0", &["--scene", &off]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("sensor.rgb.enabled is false"),
        "{}",
        stderr(&o)
    );
    let phong = scene(
        "phong.toml",
        "[materials]\nshading = \"phong\"\nmetallic = [0.5, 0.9]\n",
    );
    let o = render(d, "o3", "1", "0", &["--scene", &phong]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("materials.metallic") && stderr(&o).contains("phong"),
        "{}",
        stderr(&o)
    );
}

/// `experiment sim2real --rows` with an unknown name ran the other rows (exit 0).
#[test]
fn sim2real_refuses_unknown_rows_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(render(d, "real", "2", "1", &[]).status.success());
    assert!(render(d, "fit", "2", "2", &[]).status.success());
    for (model, row, want) in [
        ("tnet", "synth_fited", "no row is called \"synth_fited\""),
        ("tnet", "ablation_physics", "ablation row"),
        (
            "rgb-dense",
            "synth_fitted",
            "no row is called \"synth_fitted\"",
        ),
    ] {
        let o = run(synthgen().current_dir(d).args([
            "experiment",
            "sim2real",
            "--quick",
            "--model",
            model,
            "--fit",
            "fit",
            "--test",
            "real",
            "--rows",
            row,
            "--out",
            "exp",
        ]));
        refused(&o, &[want]);
        assert!(!d.join("exp/fit").exists(), "work done before the refusal");
    }
}

/// `train --resume` ignored `--lr` and the other settings silently; a checkpoint scored on a
/// dataset whose ids are other objects was scored.
#[test]
fn train_resume_refuses_other_settings_and_eval_other_objects() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(render(d, "set", "4", "1", &[]).status.success());
    let train = |extra: &[&str]| {
        run(synthgen()
            .current_dir(d)
            .args([
                "train",
                "-q",
                "--data",
                "set",
                "--model",
                "full",
                "--crop-size",
                "16",
            ])
            .args([
                "--batch", "4", "--points", "32", "--width", "16", "--out", "run",
            ])
            .args(extra))
    };
    assert!(train(&["--epochs", "1"]).status.success());
    let o = train(&["--epochs", "2", "--resume", "--lr", "0.5"]);
    refused(
        &o,
        &["asks for other settings", "--lr 0.5 (the run's: 0.001)"],
    );
    let o = train(&["--epochs", "2", "--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Object 1 of this dataset is a box, not the driller the run learnt.
    box_obj(&d.join("box.obj"), 0.0);
    let o = run(synthgen().current_dir(d).args([
        "render",
        "-q",
        "--objects",
        "box.obj",
        "--frames",
        "2",
        "--image-size",
        "160,120",
        "--out",
        "boxes",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    let o = run(synthgen().current_dir(d).args([
        "eval",
        "--checkpoint",
        "run/model.safetensors",
        "--data",
        "boxes",
    ]));
    refused(
        &o,
        &["trained on other objects", "object 1 is 1 (obj_000001"],
    );
}
