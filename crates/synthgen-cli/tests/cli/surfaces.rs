//! Ground and wall textures from image folders, end to end: bad folders are clear errors
//! (exit 1, naming the file or folder); textured frames are deterministic.

use std::path::Path;

use crate::common::{repo_root, run, stderr, synthgen};
use crate::render::write_box_ply;

fn render(dir: &Path, spec: &str, out: &str) -> std::process::Output {
    let mesh = dir.join("box.ply");
    write_box_ply(&mesh);
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, spec).unwrap();
    run(synthgen()
        .arg("render")
        .arg("--scene")
        .arg(&scene)
        .arg("--objects")
        .arg(&mesh)
        .args(["--frames", "3", "--seed", "9", "--jobs", "2", "--out"])
        .arg(dir.join(out)))
}

#[test]
fn bad_texture_folders_are_errors_naming_the_file() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // Missing folder.
    let o = render(dir, "[ground]\ntexture_dir = \"nowhere\"\n", "a");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("ground.texture_dir is not a folder"),
        "{}",
        stderr(&o)
    );
    assert!(stderr(&o).contains("nowhere"), "{}", stderr(&o));
    // Empty folder.
    std::fs::create_dir(dir.join("empty")).unwrap();
    let o = render(
        dir,
        "[walls]\ncount = [1, 2]\ntexture_dir = \"empty\"\n",
        "b",
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("no PNG or JPEG images in walls.texture_dir"),
        "{}",
        stderr(&o)
    );
    // A file that does not decode, next to a good one.
    let bad = dir.join("bad");
    std::fs::create_dir(&bad).unwrap();
    std::fs::copy(
        repo_root().join("textures/ground/wood.png"),
        bad.join("a_wood.png"),
    )
    .unwrap();
    std::fs::write(bad.join("broken.png"), b"not a png").unwrap();
    let o = render(dir, "[ground]\ntexture_dir = \"bad\"\n", "c");
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("broken.png"), "{}", stderr(&o));
    assert!(!dir.join("c").join("train_pbr").exists());
}

#[test]
fn textured_ground_and_walls_render_deterministically() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let root = repo_root();
    let spec = format!(
        "[camera_pose]\nelevation_deg = [5.0, 15.0]\n[ground]\ntexture_dir = \"{}\"\n\
         [walls]\ncount = [4, 4]\ndistance_m = [1.5, 1.5]\ntexture_dir = \"{}\"\n",
        root.join("textures/ground").display(),
        root.join("textures/walls").display()
    );
    for out in ["a", "b"] {
        let o = render(dir, &spec, out);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let rgb = |out: &str, i: u32| {
        std::fs::read(
            dir.join(out)
                .join(format!("train_pbr/000000/rgb/{i:06}.png")),
        )
        .unwrap()
    };
    for i in 0..3 {
        assert_eq!(rgb("a", i), rgb("b", i), "frame {i} differs between runs");
    }
    let v = run(synthgen().arg("validate").arg(dir.join("a")));
    assert!(v.status.success(), "{}", stderr(&v));
}
