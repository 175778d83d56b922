//! What a careless user did to synthgen (issue 13): no silent wrong output, no lost data.
//! One test per item, named after it; each failed before its fix.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::common::{refused, run, stderr, synthgen};
use crate::mix::render_tiny;
use crate::render::write_box_ply;

fn stdout(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A render of `frames` boxes at 96x72 into `out`.
fn render(dir: &Path, out: &str, frames: u32, extra: &[&str]) -> std::process::Output {
    let mesh = dir.join("box.ply");
    if !mesh.exists() {
        write_box_ply(&mesh);
    }
    run(synthgen()
        .current_dir(dir)
        .args(["render", "-q", "--objects", "box.ply", "--units", "m"])
        .args(["--image-size", "96,72", "--camera-k", "96,96,48,36"])
        .args(["--frames", &frames.to_string(), "--out", out])
        .args(extra))
}

/// Item 1: two renders into one --out both exited 0 with frames of one run and annotations
/// of the other. The second writer is refused; kill -9 of the first leaves no stuck lock.
#[test]
fn two_writers_to_one_output_the_second_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_box_ply(&d.join("box.ply"));
    // Slow enough to be caught mid-run: many large frames on one thread.
    let mut first = Command::new(env!("CARGO_BIN_EXE_synthgen"))
        .current_dir(d)
        .args(["render", "-q", "--objects", "box.ply", "--units", "m"])
        .args(["--frames", "3000", "--seed", "1", "-j", "1", "--out", "o"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let started = Instant::now();
    while !d.join("o/train_pbr/000000/rgb/000001.png").exists() {
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "the first render never started"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let o = render(d, "o", 3, &["--seed", "2", "--force"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("another synthgen process is writing to this folder"),
        "{}",
        stderr(&o)
    );
    first.kill().unwrap(); // SIGKILL: no destructor runs
    first.wait().unwrap();
    // The kernel released the lock with the process: the folder can be written again
    // (scale::killed_at_random_points_then_resumed_is_byte_identical resumes after kill -9).
    let o = render(d, "o", 3, &["--seed", "2", "--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Item 2: `convert --to linemod bc bc --force` wrote Linemod folders into its own BOP
/// input. No command writes into, inside or around one of its inputs.
#[test]
fn output_equal_to_input_is_refused_and_a_failed_convert_leaves_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "bc", 6, 1);
    for (out, relation) in [
        ("bc", "is the input"),
        ("bc/lm", "lies inside"),
        (".", "contains"),
    ] {
        let o = run(synthgen()
            .current_dir(d)
            .args(["convert", "--to", "linemod", "bc", out, "--force"]));
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(stderr(&o).contains(relation), "{out}: {}", stderr(&o));
    }
    let o = run(synthgen().current_dir(d).args(["validate", "bc"]));
    assert!(o.status.success(), "the input was touched: {}", stdout(&o));
    render_tiny(d, "other", 6, 2);
    let o = run(synthgen()
        .current_dir(d)
        .args([
            "mix",
            "--real",
            "bc",
            "--synth",
            "other",
            "--real-count",
            "2",
        ])
        .args([
            "--synth-count",
            "2",
            "--test-count",
            "1",
            "--out",
            "other/mix",
            "--force",
        ]));
    assert!(
        stderr(&o).contains("lies inside the synthetic dataset"),
        "{}",
        stderr(&o)
    );
    let o = run(synthgen().current_dir(d).args([
        "train", "-q", "--data", "bc", "--out", "bc/run", "--epochs", "1",
    ]));
    assert!(
        stderr(&o).contains("lies inside the dataset"),
        "{}",
        stderr(&o)
    );
    // A conversion that fails half-way removes what it wrote.
    std::fs::remove_file(d.join("bc/train_pbr/000000/depth/000004.png")).unwrap();
    let o = run(synthgen()
        .current_dir(d)
        .args(["convert", "--to", "linemod", "bc", "lm"]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!d.join("lm").exists(), "a failed convert left lm/ behind");
}

/// Item 3: `mix --real X --synth X` put held-out test frames into training. The same folder,
/// a hard-linked copy or a byte copy is refused; `--exclude-shared` leaves them out, loudly.
#[test]
fn mix_refuses_training_frames_shared_with_the_test_split() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "x", 20, 3);
    let copy = |from: &str, to: &str, link: bool| {
        for e in walk(&d.join(from)) {
            let rel = e.strip_prefix(d.join(from)).unwrap();
            let dst = d.join(to).join(rel);
            std::fs::create_dir_all(dst.parent().unwrap()).unwrap();
            if link {
                std::fs::hard_link(&e, &dst).unwrap();
            } else {
                std::fs::copy(&e, &dst).unwrap();
            }
        }
    };
    copy("x", "linked", true);
    copy("x", "copied", false);
    for synth in ["x", "linked", "copied"] {
        let o = run(synthgen()
            .current_dir(d)
            .args(["mix", "--real", "x", "--synth", synth, "--real-count", "8"])
            .args(["--synth-count", "8", "--test-count", "4", "--out", "m"]));
        assert_eq!(o.status.code(), Some(1), "{synth}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("same images as held-out test frames"),
            "{synth}: {}",
            stderr(&o)
        );
    }
    let o = run(synthgen()
        .current_dir(d)
        .args([
            "mix",
            "--real",
            "x",
            "--synth",
            "copied",
            "--real-count",
            "8",
        ])
        .args(["--synth-count", "8", "--test-count", "4", "--out", "m"])
        .arg("--exclude-shared"));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("training frames out"), "{}", stderr(&o));
    // No training image is a test image.
    let test: Vec<Vec<u8>> = walk(&d.join("m/test"))
        .into_iter()
        .filter(|p| p.to_string_lossy().contains("/rgb/"))
        .map(|p| std::fs::read(p).unwrap())
        .collect();
    for p in walk(&d.join("m/train"))
        .into_iter()
        .filter(|p| p.to_string_lossy().contains("/rgb/"))
    {
        assert!(
            !test.contains(&std::fs::read(&p).unwrap()),
            "{} is a test image",
            p.display()
        );
    }
    // experiment mix goes through the same check (17 of the 20 frames drawn as synthetic
    // cannot all miss the 4 test frames).
    let o = run(synthgen().current_dir(d).args([
        "experiment",
        "mix",
        "--real",
        "x",
        "--synth",
        "x",
        "--quick",
        "--total",
        "8",
        "--ratios",
        "0/17",
        "--test-count",
        "4",
        "--epochs",
        "1",
        "--out",
        "exp",
    ]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("same images as held-out test frames"),
        "{}",
        stderr(&o)
    );
}

fn walk(root: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![root.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// Item 4: a BOP dataset without depth/ converted to Linemod with all-zero depth, and without
/// masks to no frames at all, both with exit 0.
#[test]
fn convert_without_depth_or_masks_is_an_error_not_zeros() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "nodepth", 4, 4);
    std::fs::remove_dir_all(d.join("nodepth/train_pbr/000000/depth")).unwrap();
    let o = run(synthgen()
        .current_dir(d)
        .args(["convert", "--to", "linemod", "nodepth", "lm1"]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("missing file") && stderr(&o).contains("depth"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("lm1").exists());
    let o = run(synthgen().current_dir(d).args(["validate", "nodepth"]));
    assert_eq!(o.status.code(), Some(1));
    assert!(stdout(&o).contains("there is no depth/"), "{}", stdout(&o));

    render_tiny(d, "nomasks", 4, 5);
    std::fs::remove_dir_all(d.join("nomasks/train_pbr/000000/mask_visib")).unwrap();
    let o = run(synthgen()
        .current_dir(d)
        .args(["convert", "--to", "linemod", "nomasks", "lm2"]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("synthgen annotate"), "{}", stderr(&o));
}

/// Item 5: a zero-area mesh or a camera a million km away wrote datasets where nothing is
/// visible, with exit 0. Render checks what it wrote.
#[test]
fn render_where_nothing_is_visible_fails_with_a_hint() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = render(d, "far", 4, &["--distance-m", "1e9..1e9"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("4 of the 4 frames rendered show no target"),
        "{err}"
    );
    assert!(err.contains("check the units"), "{err}");
    // A flat mesh: every triangle has zero area.
    std::fs::write(
        d.join("flat.ply"),
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
         element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n0.1 0 0\n0.2 0 0\n3 0 1 2\n",
    )
    .unwrap();
    let o = run(synthgen()
        .current_dir(d)
        .args([
            "render",
            "-q",
            "--objects",
            "flat.ply",
            "--units",
            "m",
            "--frames",
            "3",
        ])
        .args([
            "--image-size",
            "96,72",
            "--camera-k",
            "96,96,48,36",
            "--out",
            "flat",
        ]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    // A normal render passes the check.
    let o = render(d, "ok", 3, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// Item 6: `train --lr 1e9` gave NaN losses, exit 0, a NaN checkpoint and a NaN eval table;
/// a negative or NaN --lr was accepted.
#[test]
fn diverged_training_stops_with_an_error_and_bad_hyperparameters_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "data", 12, 6);
    let o = crate::train::train(&d.join("data"), &d.join("run"), "2", &["--lr", "1e9"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(
        err.contains("training diverged") && err.contains("at epoch 1"),
        "{err}"
    );
    assert!(
        !d.join("run/model.safetensors").exists(),
        "a diverged checkpoint was written"
    );
    for lr in ["-1", "NaN", "0"] {
        let o = crate::train::train(&d.join("data"), &d.join("run2"), "1", &["--lr", lr]);
        assert_eq!(o.status.code(), Some(1), "--lr {lr}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("--lr must be a positive number"),
            "{}",
            stderr(&o)
        );
    }
}

/// Item 7: `export coco` with an object missing from models_info wrote a category_id with no
/// category.
#[test]
fn export_coco_with_an_unlisted_object_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "ds", 3, 7);
    std::fs::write(d.join("ds/models/models_info.json"), "{}").unwrap();
    let o = run(synthgen().current_dir(d).args(["export", "coco", "ds"]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("object 1 is not in models/models_info.json"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("ds/train_pbr/000000/scene_gt_coco.json").exists());
}

/// Item 8: a results CSV with swapped header columns failed, an empty one scored 0% with exit
/// 0, a NaN score was accepted, and one bad row sank the file.
#[test]
fn results_csv_by_name_empty_refused_bad_rows_skipped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "ds", 3, 8);
    // R and t of the first GT instance, from the GT written as a results CSV.
    let row = crate::train::gt_as_results(&d.join("ds"), 0.0);
    let fields: Vec<String> = row
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .map(String::from)
        .collect();
    let (r, t) = (&fields[4], &fields[5]);
    let eval = |text: &str| {
        std::fs::write(d.join("r.csv"), text).unwrap();
        run(synthgen()
            .current_dir(d)
            .args(["eval", "--results", "r.csv", "--data", "ds"]))
    };
    let o = eval(&format!(
        "im_id,scene_id,obj_id,score,R,t,time\n0,0,1,0.9,{r},{t},-1\n"
    ));
    assert!(o.status.success(), "{}", stderr(&o));
    let o = eval("");
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("no estimates"), "{}", stderr(&o));
    let o = eval(&format!(
        "scene_id,im_id,obj_id,score,R,t,time\n0,0,1,nan,{r},{t},-1\n0,0,1,0.9,{r},{t},-1\n0,1,1,0.5,1 2,{t},-1\n"
    ));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("r.csv:2: score: not a finite number"), "{err}");
    assert!(
        err.contains("2 of 3 rows of r.csv could not be read"),
        "{err}"
    );
    assert!(
        stdout(&o).contains("| all |"),
        "the good row is scored: {}",
        stdout(&o)
    );
}

/// Item 9: `--elevation-deg -10..30` failed with "unexpected argument '-1' found".
#[test]
fn negative_values_are_accepted_where_numbers_go() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = render(d, "neg", 2, &["--elevation-deg", "-10..30"]);
    let err = stderr(&o);
    assert!(!err.contains("unexpected argument"), "{err}");
    assert_ne!(o.status.code(), Some(2), "{err}");
    let o = run(synthgen()
        .current_dir(d)
        .args(["train", "--data", "neg", "--lr", "-1"]));
    assert!(
        stderr(&o).contains("--lr must be a positive number"),
        "{}",
        stderr(&o)
    );
}

/// Item 10: usage errors exited 2, which the help calls an internal error.
#[test]
fn usage_errors_exit_1_and_help_exits_0() {
    let o = run(synthgen().args(["render", "--no-such-flag"]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let o = run(synthgen().args(["render", "--frames", "many"]));
    assert_eq!(o.status.code(), Some(1));
    let o = run(&mut synthgen());
    assert_eq!(o.status.code(), Some(1));
    for args in [&["--help"][..], &["--version"], &["render", "--help"]] {
        let o = run(synthgen().args(args));
        assert_eq!(o.status.code(), Some(0), "{args:?}");
    }
    let o = run(synthgen().arg("--help"));
    assert!(stdout(&o).contains("Exit status:") && stdout(&o).contains("2  internal error"));
}

/// Item 11: preview, mix, export, annotate and train printed status lines on stdout.
#[test]
fn status_lines_go_to_stderr_data_to_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "a", 12, 9);
    render_tiny(d, "b", 12, 10);
    let quiet_stdout = |args: &[&str]| {
        let o = run(synthgen().current_dir(d).args(args));
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        assert!(
            o.stdout.is_empty(),
            "{args:?} printed on stdout: {}",
            stdout(&o)
        );
        assert!(!o.stderr.is_empty(), "{args:?} said nothing");
    };
    quiet_stdout(&["preview", "a", "--out", "p.png", "--count", "2"]);
    quiet_stdout(&[
        "mix",
        "--real",
        "a",
        "--synth",
        "b",
        "--real-count",
        "4",
        "--synth-count",
        "4",
        "--test-count",
        "2",
        "--out",
        "m",
    ]);
    quiet_stdout(&["export", "coco", "a"]);
    quiet_stdout(&["annotate", "a"]);
    quiet_stdout(&[
        "train", "--data", "a", "--out", "run", "--epochs", "1", "--batch", "4", "--points", "32",
        "--width", "8",
    ]);
    let o = run(synthgen().current_dir(d).args(["stats", "a"]));
    assert!(
        stdout(&o).contains("frames"),
        "stats is data: {}",
        stdout(&o)
    );
}

/// Item 12: a scene with 100000 instances printed 1.2 MB of object names.
#[test]
fn summaries_of_many_objects_are_bounded() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_box_ply(&d.join("box.ply"));
    std::fs::write(
        d.join("crowd.toml"),
        "[[objects]]\npath = \"box.ply\"\nunits = \"m\"\ncount = 400\n[placement]\narea_m = [0.1, 0.1]\nmax_tries = 2\n",
    )
    .unwrap();
    let o = run(synthgen()
        .current_dir(d)
        .args([
            "render",
            "--scene",
            "crowd.toml",
            "--frames",
            "1",
            "--out",
            "c",
        ])
        .args(["--image-size", "96,72", "--camera-k", "96,96,48,36"]));
    let err = stderr(&o);
    assert!(err.contains("box ×400"), "{err}");
    assert!(err.len() < 4000, "{} bytes of messages", err.len());
}

/// Item 13: after Ctrl-C, "the folder is not empty" did not say how to go on.
#[test]
fn not_empty_output_hint_names_resume() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(render(d, "o", 2, &[]).status.success());
    let o = render(d, "o", 2, &[]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--resume"), "{}", stderr(&o));
}

/// A render that cannot start (a missing mesh) leaves no empty output folder behind, and
/// never touches a folder that existed.
#[test]
fn a_render_that_cannot_start_leaves_no_empty_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let o = run(synthgen().current_dir(d).args([
        "render",
        "-q",
        "--objects",
        "missing.ply",
        "--out",
        "a/b",
    ]));
    refused(&o, &["cannot load object missing.ply"]);
    assert!(!d.join("a").exists(), "a/b and a were created and removed");
    std::fs::create_dir(d.join("kept")).unwrap();
    let o = run(synthgen().current_dir(d).args([
        "render",
        "-q",
        "--objects",
        "missing.ply",
        "--out",
        "kept/new",
    ]));
    refused(&o, &["cannot load object missing.ply"]);
    assert!(d.join("kept").is_dir() && !d.join("kept/new").exists());
}
