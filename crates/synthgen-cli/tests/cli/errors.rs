//! Bad input gets a clear message naming the file, a hint, and exit code 1.

use crate::common::{run, stderr, synthgen};

#[test]
fn missing_mesh_names_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(synthgen().current_dir(dir.path()).args([
        "render",
        "--objects",
        "nope.ply",
        "--frames",
        "1",
        "-q",
    ]));
    assert_eq!(out.status.code(), Some(1));
    let e = stderr(&out);
    assert!(e.contains("nope.ply"), "{e}");
}

#[test]
fn broken_mesh_is_an_error_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("broken.ply");
    std::fs::write(
        &mesh,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n",
    )
    .unwrap();
    let out_dir = dir.path().join("out");
    let out = run(synthgen()
        .args(["render", "--objects"])
        .arg(&mesh)
        .arg("--out")
        .arg(&out_dir));
    assert_eq!(out.status.code(), Some(1));
    let e = stderr(&out);
    assert!(e.contains("broken.ply"), "{e}");
    assert!(!out_dir.join("synthgen.json").exists());
}

#[test]
fn no_objects_gives_a_hint() {
    let out = run(synthgen().args(["render", "--frames", "1"]));
    assert_eq!(out.status.code(), Some(1));
    let e = stderr(&out);
    assert!(e.contains("no objects") && e.contains("hint:"), "{e}");
}

#[test]
#[cfg(not(feature = "blender"))]
fn blender_backend_says_how_to_enable_it() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    crate::render::write_box_ply(&mesh);
    let out = run(synthgen()
        .args(["render", "--backend", "blender", "--objects"])
        .arg(&mesh)
        .arg("--out")
        .arg(dir.path().join("o")));
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("blender"), "{}", stderr(&out));
}

#[test]
fn non_empty_output_folder_needs_force() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    crate::render::write_box_ply(&mesh);
    let out_dir = dir.path().join("o");
    std::fs::create_dir_all(&out_dir).unwrap();
    std::fs::write(out_dir.join("keep.txt"), "mine").unwrap();
    let out = run(synthgen()
        .args(["render", "--objects"])
        .arg(&mesh)
        .arg("--out")
        .arg(&out_dir));
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("--force"), "{}", stderr(&out));
    assert_eq!(
        std::fs::read_to_string(out_dir.join("keep.txt")).unwrap(),
        "mine"
    );
}

#[test]
fn malformed_scene_spec_names_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let spec = dir.path().join("bad.toml");
    std::fs::write(&spec, "[camera_pose]\ndistance_m = [2.0, 1.0]\n").unwrap();
    let mesh = dir.path().join("box.ply");
    crate::render::write_box_ply(&mesh);
    let out = run(synthgen()
        .args(["render", "--objects"])
        .arg(&mesh)
        .arg("--scene")
        .arg(&spec));
    assert_eq!(out.status.code(), Some(1));
    let e = stderr(&out);
    assert!(e.contains("distance_m"), "{e}");
    let spec2 = dir.path().join("syntax.toml");
    std::fs::write(&spec2, "[camera\n").unwrap();
    let out = run(synthgen()
        .args(["render", "--objects"])
        .arg(&mesh)
        .arg("--scene")
        .arg(&spec2));
    assert_eq!(out.status.code(), Some(1));
    assert!(stderr(&out).contains("syntax.toml"), "{}", stderr(&out));
}

/// Issue 26 papercut: `--image-size` alone scaled a camera preset but not a scene file's
/// `[camera]` K, so the same camera at half size was cropped or refused.
#[test]
fn image_size_scales_a_scene_files_camera_too() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    crate::render::write_box_ply(&d.join("box.ply"));
    std::fs::write(
        d.join("cam.toml"),
        "[camera]\nwidth = 640\nheight = 480\nfx = 572.4114\nfy = 573.57043\ncx = 325.2611\ncy = 242.04899\n",
    )
    .unwrap();
    let render = |out: &str, extra: &[&str]| {
        let o = run(synthgen()
            .current_dir(d)
            .args([
                "render",
                "-q",
                "--objects",
                "box.ply",
                "--units",
                "m",
                "--frames",
                "1",
            ])
            .args(["--image-size", "320,240", "--out", out])
            .args(extra));
        assert!(o.status.success(), "{out}: {}", stderr(&o));
        let cams: serde_json::Value = serde_json::from_slice(
            &std::fs::read(d.join(out).join("train_pbr/000000/scene_camera.json")).unwrap(),
        )
        .unwrap();
        cams["0"]["cam_K"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect::<Vec<f64>>()
    };
    let from_file = render("file", &["--scene", "cam.toml"]);
    let from_preset = render("preset", &["--camera", "linemod"]);
    for (a, b) in from_file.iter().zip(&from_preset) {
        assert!((a - b).abs() < 1e-9, "{from_file:?} vs {from_preset:?}");
    }
    assert!((from_file[0] - 572.4114 / 2.0).abs() < 1e-9);
    // With --camera-k, K is used as given.
    let given = render(
        "given",
        &["--scene", "cam.toml", "--camera-k", "300,300,160,120"],
    );
    assert_eq!(given[0], 300.0);
    assert_eq!(given[2], 160.0);
}

/// Issue 26 papercut: a missing dataset folder was "missing file DIR/camera.json".
#[test]
fn a_missing_dataset_folder_is_no_such_dataset() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for args in [
        &["stats", "gone"][..],
        &["preview", "gone", "--out", "p.png"],
        &["annotate", "gone"],
        &["train", "--data", "gone", "--out", "r"],
        &["eval", "--data", "gone", "--results", "r.csv"],
        &["sensor", "fit", "--data", "gone", "--out", "s.toml"],
        &["sensor", "compare", "--real", "gone", "--synth", "gone"],
        &["scene", "fit", "--data", "gone", "--out", "s.toml"],
        &["export", "coco", "gone"],
        &["view", "gone", "--port", "0"],
    ] {
        std::fs::write(d.join("r.csv"), "scene_id,im_id,obj_id,score,R,t,time\n").unwrap();
        let o = run(synthgen().current_dir(d).args(args));
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
        assert!(
            e.contains("no such dataset") && e.contains("gone"),
            "{args:?}: {e}"
        );
        assert!(!e.contains("camera.json"), "{args:?}: {e}");
    }
}

/// Issue 26 papercuts: errors in a sensor file said "scene spec"; `depth = "none"` beside a
/// `[structured_light]` section rendered clean depth without a word.
#[test]
fn sensor_file_errors_name_the_sensor_file_and_unused_sections_warn() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    crate::render::write_box_ply(&d.join("box.ply"));
    let render = |extra: &[&str]| {
        run(synthgen()
            .current_dir(d)
            .args([
                "render",
                "-q",
                "--objects",
                "box.ply",
                "--units",
                "m",
                "--frames",
                "1",
            ])
            .args(["--image-size", "80,60", "--force", "--out", "o"])
            .args(extra))
    };
    for (text, what) in [
        (
            "depth = \"structured_light\"\n[structured_light]\nbaseline_m = 99\n",
            "invalid",
        ),
        ("depth = \n", "malformed"),
    ] {
        std::fs::write(d.join("bad.toml"), text).unwrap();
        for args in [&["--sensor", "bad.toml"][..], &["--scene", "scene.toml"]] {
            std::fs::write(d.join("scene.toml"), "[sensor]\nfile = \"bad.toml\"\n").unwrap();
            let o = render(args);
            let e = stderr(&o);
            assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
            assert!(
                e.contains(&format!("{what} sensor file")) && e.contains("bad.toml"),
                "{args:?}: {e}"
            );
            // A scene whose sensor file is bad is an invalid scene: the cause names the file.
            if args[0] == "--sensor" {
                assert!(!e.contains("scene spec"), "{args:?}: {e}");
            }
        }
    }
    let o = render(&["--sensor", "nosuch"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("unknown sensor \"nosuch\""),
        "{}",
        stderr(&o)
    );

    std::fs::write(
        d.join("quiet.toml"),
        "depth = \"none\"\n[structured_light]\ndisparity_sigma_px = 0.3\n",
    )
    .unwrap();
    std::fs::write(
        d.join("quiet_scene.toml"),
        "[sensor]\ndepth = \"none\"\n[sensor.structured_light]\ndisparity_sigma_px = 0.3\n",
    )
    .unwrap();
    for args in [
        &["--sensor", "quiet.toml"][..],
        &["--scene", "quiet_scene.toml"],
    ] {
        let o = render(args);
        let e = stderr(&o);
        assert!(o.status.success(), "{args:?}: {e}");
        assert!(
            e.contains("warning: sensor.structured_light is set but sensor.depth is \"none\""),
            "{args:?}: {e}"
        );
    }
    // A sensor section that the depth model uses is no warning.
    let o = render(&["--sensor", "structured_light"]);
    assert!(
        o.status.success() && !stderr(&o).contains("no effect"),
        "{}",
        stderr(&o)
    );
}

/// Issue 26 papercut: `sensor compare --plot` into a missing folder failed, where `sensor fit
/// --out` creates it.
#[test]
fn sensor_compare_plot_creates_missing_folders() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    crate::mix::render_tiny(d, "a", 4, 1);
    crate::mix::render_tiny(d, "b", 4, 2);
    let o = run(synthgen().current_dir(d).args([
        "sensor",
        "compare",
        "--real",
        "a",
        "--synth",
        "b",
        "--plot",
        "plots/new/cmp.png",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("plots/new/cmp.png").is_file());
}

/// Issue 26: `render --force` / `convert --force` into a folder holding another dataset left
/// a mix of both. --force now replaces an output synthgen wrote, refuses a folder it did not
/// write (keeping its files), and validate names files that no image owns.
#[test]
fn force_replaces_a_synthgen_output_and_refuses_other_folders() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    crate::mix::render_tiny(d, "o", 6, 1);
    let render = |out: &str, frames: &str| {
        run(synthgen()
            .current_dir(d)
            .args(["render", "-q", "--objects", "box.ply", "--units", "m"])
            .args(["--image-size", "80,60", "--camera-k", "80,80,40,30"])
            .args(["--frames", frames, "--seed", "2", "--force", "--out", out]))
    };
    let o = render("o", "2");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        !d.join("o/train_pbr/000000/rgb/000005.png").exists(),
        "frames of the earlier render were left"
    );
    let v = run(synthgen().current_dir(d).args(["validate", "o"]));
    assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stdout));
    // convert --force over a conversion of another dataset: only the new one is there.
    crate::mix::render_tiny(d, "big", 6, 3);
    for src in ["big", "o"] {
        let o = run(synthgen()
            .current_dir(d)
            .args(["convert", "--to", "linemod", "--force", src, "lm"]));
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let v = run(synthgen().current_dir(d).args(["validate", "lm"]));
    assert!(v.status.success(), "{}", String::from_utf8_lossy(&v.stdout));
    // Files no image owns are named by validate.
    std::fs::copy(
        d.join("o/train_pbr/000000/rgb/000000.png"),
        d.join("o/train_pbr/000000/rgb/000009.png"),
    )
    .unwrap();
    let v = run(synthgen().current_dir(d).args(["validate", "o"]));
    assert_eq!(v.status.code(), Some(1));
    let out = String::from_utf8_lossy(&v.stdout);
    assert!(
        out.contains("rgb: 1 files belong to no image") && out.contains("000009.png"),
        "{out}"
    );
    // A folder synthgen did not write: refused even with --force, its files kept.
    std::fs::create_dir_all(d.join("mine")).unwrap();
    std::fs::write(d.join("mine/notes.txt"), "x").unwrap();
    crate::common::refused(
        &render("mine", "1"),
        &["--force replaces an output synthgen wrote", "mine"],
    );
    let o = run(synthgen()
        .current_dir(d)
        .args(["convert", "--to", "linemod", "--force", "o", "mine"]));
    crate::common::refused(&o, &["--force replaces"]);
    assert_eq!(
        std::fs::read_to_string(d.join("mine/notes.txt")).unwrap(),
        "x"
    );
    assert_eq!(std::fs::read_dir(d.join("mine")).unwrap().count(), 1);
}
