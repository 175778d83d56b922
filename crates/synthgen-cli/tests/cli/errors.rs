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
