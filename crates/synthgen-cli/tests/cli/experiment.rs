//! `synthgen experiment mix --quick --real-proxy` end to end on a tiny box mesh: the whole
//! pipeline (render both sets, 7 × mix + train + evaluate, table, plot) and its resume; and
//! with the real YCB-Video frames of `../shared/data/ycbv_real`: a held-out scene as the test
//! split, the synthetic side rendered from the dataset's own models, `--plus-synth` rows.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

use crate::common::{repo_root, run, stderr, synthgen, ycbv_real};
use crate::render::write_box_ply;

fn experiment(mesh: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    run(synthgen()
        .args(["experiment", "mix", "--real-proxy", "--quick", "--objects"])
        .arg(mesh)
        .args(["--seed", "5", "--out"])
        .arg(out)
        .args(extra))
}

fn row_jsons(out: &Path) -> Vec<(String, serde_json::Value, SystemTime)> {
    let mut rows: Vec<_> = std::fs::read_dir(out.join("rows"))
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path().join("row.json");
            let v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
            let mtime = std::fs::metadata(&p).unwrap().modified().unwrap();
            (p.display().to_string(), v, mtime)
        })
        .collect();
    rows.sort_by(|a, b| a.0.cmp(&b.0));
    rows
}

#[test]
fn quick_proxy_experiment_has_seven_rows_one_test_split_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let out = dir.path().join("mix");
    let o = experiment(&mesh, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(stdout.contains("The real side is a PROXY"), "{stdout}");
    assert!(
        stderr(&o).contains("7 computed, 0 skipped"),
        "{}",
        stderr(&o)
    );

    // table.csv: the 7 compositions of 42 frames, finite errors.
    let csv = std::fs::read_to_string(out.join("table.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(lines.len(), 7, "{csv}");
    let counts: Vec<(usize, usize)> = lines
        .iter()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].parse().unwrap(), f[1].parse().unwrap())
        })
        .collect();
    assert_eq!(
        counts,
        [
            (42, 0),
            (35, 7),
            (28, 14),
            (21, 21),
            (14, 28),
            (7, 35),
            (0, 42)
        ]
    );
    for l in &lines {
        let f: Vec<&str> = l.split(',').collect();
        for col in [4, 6] {
            let v: f64 = f[col].parse().unwrap();
            assert!(v.is_finite() && v >= 0.0, "{l}");
        }
        assert_eq!(f[13], "true", "real_is_proxy: {l}");
    }
    let md = std::fs::read_to_string(out.join("table.md")).unwrap();
    // The main table (header + 7 rows), then the per-object one.
    let (main, per_object) = md.split_once("## Test error per object").unwrap();
    assert!(
        md.contains("PROXY") && main.matches("\n| ").count() == 8,
        "{md}"
    );
    assert_eq!(per_object.matches("\n| ").count(), 8, "{md}");
    assert!(image::open(out.join("plot.png")).is_ok());

    // Every row was tested on the same real frames (the mixes' provenance, hashed per row).
    let rows = row_jsons(&out);
    assert_eq!(rows.len(), 7);
    let hash = &rows[0].1["test_split_hash"];
    for (name, v, _) in &rows {
        assert_eq!(&v["test_split_hash"], hash, "{name}");
        assert_eq!(v["test_frames"], 8, "{name}");
        assert!(v["test"]["centre_error_cm"].as_f64().unwrap().is_finite());
    }
    let split: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("test_split.json")).unwrap())
            .unwrap();
    assert_eq!(&split["hash"], hash);
    assert_eq!(split["frames"].as_array().unwrap().len(), 8);

    // A second run keeps every finished row (same files, same times) and renders nothing.
    let o = experiment(&mesh, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("0 computed, 7 skipped"), "{err}");
    assert!(!err.contains("Rendered"), "{err}");
    assert_eq!(row_jsons(&out), rows);

    // An unfinished row (no row.json) is redone, alone.
    let victim = out.join("rows/r00021_s00021/row.json");
    std::fs::remove_file(&victim).unwrap();
    let o = experiment(&mesh, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("1 computed, 6 skipped"),
        "{}",
        stderr(&o)
    );
    let again = row_jsons(&out);
    for (a, b) in rows.iter().zip(&again) {
        if a.0.contains("r00021_s00021") {
            assert_eq!(a.1["test_split_hash"], b.1["test_split_hash"]);
        } else {
            assert_eq!(a, b);
        }
    }

    // Other settings in the same folder are refused, not mixed in.
    let o = experiment(&mesh, &out, &["--epochs", "3"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("other settings"), "{}", stderr(&o));
}

#[test]
fn experiment_rejects_bad_ratios_and_missing_objects() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(synthgen()
        .args(["experiment", "mix", "--real-proxy", "--quick", "--out"])
        .arg(dir.path().join("a")));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--objects"), "{}", stderr(&o));
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let o = run(synthgen()
        .args([
            "experiment",
            "mix",
            "--real-proxy",
            "--quick",
            "--ratios",
            "10-5",
            "--objects",
        ])
        .arg(&mesh)
        .arg("--out")
        .arg(dir.path().join("b")));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("REAL/SYNTH"), "{}", stderr(&o));
}

/// `../shared/data/ycbv_real`, when present.
fn real_experiment(real: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    run(synthgen()
        .args(["experiment", "mix", "--real"])
        .arg(real)
        .arg("--scene")
        .arg(repo_root().join("scenes/ycbv_like.toml"))
        .args(["--quick", "--epochs", "1", "--seed", "3", "--out"])
        .arg(out)
        .args(extra))
}

fn read_json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn real_ycbv_experiment_tests_on_a_held_out_scene_and_resumes() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mix");
    let extra = [
        "--test-scenes",
        "2",
        "--ratios",
        "6/0,0/6",
        "--plus-synth",
        "1",
        "--repeats",
        "2",
    ];
    let o = real_experiment(&real, &out, &extra);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("6 computed, 0 skipped"), "{err}");
    assert!(
        err.contains("every real frame of scene(s) 2 (20 frames)"),
        "{err}"
    );

    // The synthetic set shows the real set's annotated objects with models, with their ids
    // and in metres (YCB-Video's textured_simple.obj).
    let settings = read_json(&out.join("experiment.json"));
    let argv: Vec<&str> = settings["synth"]["rendered"]["argv"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    let after = |flag: &str| argv[argv.iter().position(|a| *a == flag).unwrap() + 1];
    assert_eq!(after("--obj-ids"), "1,2,3,5,7,8,9,10,14,16,18,21");
    assert_eq!(after("--units"), "m");
    assert!(after("--objects").ends_with("002_master_chef_can/textured_simple.obj"));
    // With real frames --quick keeps the synthetic frames at the scene's size: one camera.json
    // for the mixed dataset (the colour models refuse other sizes).
    assert!(!argv.contains(&"--image-size"), "{argv:?}");
    assert!(!err.contains("image sizes differ"), "{err}");
    assert_eq!(settings["test_scenes"], serde_json::json!(["2"]));
    assert_eq!(settings["plus_real"], 40);
    let synth_models: BTreeSet<String> = std::fs::read_dir(out.join("sources/synth/models"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".ply"))
        .collect();
    assert_eq!(synth_models.len(), 12, "{synth_models:?}");

    // The test split is exactly scene 2's 20 frames; no row trains on a real frame of it.
    let split = read_json(&out.join("test_split.json"));
    let frames: Vec<&str> = split["frames"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    assert_eq!(frames.len(), 20);
    let ims: BTreeSet<u64> = frames
        .iter()
        .map(|f| {
            let parts: Vec<&str> = f.split('|').collect();
            assert_eq!(parts[2], "2", "{f}");
            parts[3].parse().unwrap()
        })
        .collect();
    assert_eq!(ims, (1..=20).collect());
    // 3 rows × 2 repeats (training seeds 3 and 4), all on the same test split.
    let rows = row_jsons(&out);
    assert_eq!(rows.len(), 6);
    for (name, v, _) in &rows {
        assert_eq!(v["test_frames"], 20, "{name}");
        assert_eq!(v["test_split_hash"], split["hash"], "{name}");
        // Scene 2's objects, each scored.
        let objects: Vec<u64> = v["test_per_object"]
            .as_array()
            .unwrap()
            .iter()
            .map(|o| {
                assert!(o["n"].as_u64().unwrap() > 0, "{o}");
                assert!(o["centre_error_cm"].as_f64().unwrap().is_finite(), "{o}");
                o["obj_id"].as_u64().unwrap()
            })
            .collect();
        assert_eq!(objects, [5, 7, 9, 10, 16, 18], "{name}");
        let prov = read_json(&Path::new(name).with_file_name("mix/provenance.json"));
        for e in prov.as_array().unwrap() {
            let scene = e["source_scene_id"].as_u64().unwrap();
            match (e["split"].as_str().unwrap(), e["origin"].as_str().unwrap()) {
                ("test", _) => assert_eq!(scene, 2, "{e}"),
                ("train", "real") => assert_ne!(scene, 2, "{e}"),
                _ => {}
            }
        }
    }
    let plus = &rows
        .iter()
        .find(|r| r.0.contains("r00040_s00040_x1_rep1"))
        .unwrap()
        .1;
    assert_eq!(
        (&plus["real"], &plus["synth"], &plus["plus_synth"]),
        (
            &serde_json::json!(40),
            &serde_json::json!(40),
            &serde_json::json!(1)
        )
    );
    assert_eq!(plus["train_seed"], 4);
    // Mustard (5) occurs in scene 1 too, the marker (18) only in scene 2.
    let obj = |id: u64| {
        plus["test_per_object"]
            .as_array()
            .unwrap()
            .iter()
            .find(|o| o["obj_id"] == id)
            .unwrap()
            .clone()
    };
    assert!(obj(5)["n_train_real"].as_u64().unwrap() > 0);
    assert_eq!(obj(18)["n_train_real"], 0);
    assert!(obj(18)["n_train_synth"].as_u64().unwrap() > 0);

    let md = std::fs::read_to_string(out.join("table.md")).unwrap();
    for s in [
        "| real 40 + 1× synth 40 | 40 | 40 | 50 |",
        " ± ",
        "held-out scene(s) 2 (20 frames",
        "## Test error per object",
        "obj 18 (n ",
    ] {
        assert!(md.contains(s), "{s}: {md}");
    }
    let objects_csv = std::fs::read_to_string(out.join("table_objects.csv")).unwrap();
    assert_eq!(objects_csv.lines().count(), 1 + 3 * 6, "{objects_csv}");

    // Resuming keeps every row and converts and renders nothing again.
    let o = real_experiment(&real, &out, &extra);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("0 computed, 6 skipped"), "{err}");
    assert!(err.contains("converted earlier"), "{err}");
    assert!(!err.contains("Rendered"), "{err}");
    assert_eq!(row_jsons(&out), rows);
}

/// A YCB-Video folder that is ycbv_real without the model of `missing` (a class folder).
/// Issue 54: the mixing table of the Full model (colour + points) on real frames, one
/// command: its rows read the colour crops of mixed datasets, so every frame of a mix must
/// have the mix's image size (a --quick render at a quarter of it failed every mixed row).
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn real_ycbv_mix_of_the_full_model_reports_add_on_the_real_test_scene() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("mix_full");
    let o = real_experiment(
        &real,
        &out,
        &[
            "--test-scenes",
            "2",
            "--ratios",
            "6/0,3/3,0/6",
            "--model",
            "full",
        ],
    );
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    let md = String::from_utf8_lossy(&o.stdout);
    assert!(md.contains("test ADD(-S) acc %"), "{md}");
    for row in ["real 6 + synth 0", "real 3 + synth 3", "real 0 + synth 6"] {
        assert!(md.contains(&format!("| {row} |")), "{row}: {md}");
    }
}

fn ycbv_without_model(real: &Path, dir: &Path, missing: &str) -> PathBuf {
    let root = dir.join(format!("ycbv_without_{missing}"));
    std::fs::create_dir_all(root.join("models")).unwrap();
    for f in ["data", "classes.txt"] {
        std::os::unix::fs::symlink(real.join(f), root.join(f)).unwrap();
    }
    for e in std::fs::read_dir(real.join("models")).unwrap() {
        let e = e.unwrap();
        if e.file_name() != missing {
            std::os::unix::fs::symlink(e.path(), root.join("models").join(e.file_name())).unwrap();
        }
    }
    root
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn real_experiment_rejects_unknown_scenes_too_many_frames_and_scored_objects_without_models() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");

    let o = real_experiment(&real, &out, &["--test-scenes", "7"]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(
        err.contains("no scene 7") && err.contains("its scenes are 0, 1, 2"),
        "{err}"
    );

    let o = real_experiment(&real, &out, &["--test-scenes", "1", "--ratios", "41/0"]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(
        err.contains("up to 41 real training frames, but only 40 real frames lie outside the test scene(s) 1"),
        "{err}"
    );

    let o = real_experiment(&real, &out, &["--test-scenes", "1", "--test-count", "5"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--test-count"), "{}", stderr(&o));

    // The marker (18) is only in scene 2: scored there, so its missing model is an error...
    let no_marker = ycbv_without_model(&real, dir.path(), "040_large_marker");
    let o = real_experiment(&no_marker, &out, &["--test-scenes", "2", "--total", "6"]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(
        err.contains("objects 18 are annotated in the test scene(s) 2 but have no model file"),
        "{err}"
    );
    // ... and so it is with a seeded frame split, which may draw any frame.
    let o = real_experiment(&no_marker, &out, &["--total", "6"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("objects 18 are annotated"),
        "{}",
        stderr(&o)
    );
    // Held out elsewhere, it is only trained on: left out of the synthetic set, with a warning
    // (the missing --scene then stops the run before anything is rendered).
    let o = run(synthgen()
        .args([
            "experiment",
            "mix",
            "--quick",
            "--test-scenes",
            "0",
            "--total",
            "6",
        ])
        .arg("--real")
        .arg(&no_marker)
        .arg("--scene")
        .arg(dir.path().join("missing.toml"))
        .arg("--out")
        .arg(&out));
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(
        err.contains("objects 18 have no model file")
            && err.contains("left out of the synthetic set"),
        "{err}"
    );
    assert!(err.contains("--scene not found"), "{err}");
}
