//! `synthgen render --backend blender` (only with the `blender` feature): the same BOP
//! layout and annotations as the CPU backend, pixels from Cycles.

use crate::common::{run, stderr, synthgen};

/// The tests that call it are ignored where the build script found no bpy venv.
fn require_bpy() {
    let venv = synthgen_blender::venv::resolve_venv(None).unwrap();
    if let Err(e) = synthgen_blender::venv::bpy_site_packages(&venv) {
        panic!("{e} (the venv was there when the tests were built, or SYNTHGEN_REQUIRE_BLENDER=1)");
    }
}

#[test]
#[cfg_attr(
    not(has_bpy),
    ignore = "needs the bpy venv: scripts/setup-blender.sh (probed when the crate was built)"
)]
fn blender_backend_writes_the_same_bop_layout() {
    require_bpy();
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    crate::render::write_box_ply(&mesh);
    let render = |backend: &str| {
        let out_dir = dir.path().join(backend);
        let out = run(synthgen()
            .args(["render", "--backend", backend, "--objects"])
            .arg(&mesh)
            .args(["--frames", "2", "--seed", "4", "--image-size", "96,72"])
            .args([
                "--camera-k",
                "110,111,47.5,35.5",
                "--distance-m",
                "0.4..0.5",
            ])
            .args(if backend == "blender" {
                &["--samples", "4"][..]
            } else {
                &[]
            })
            .arg("--out")
            .arg(&out_dir));
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        out_dir
    };
    let (b, c) = (render("blender"), render("cpu"));
    let manifest = std::fs::read_to_string(b.join("synthgen.json")).unwrap();
    assert!(manifest.contains("\"blender\""), "{manifest}");
    // Same poses and annotations (the full masks come from the raster backend at the same
    // pose; visible masks from Cycles' depth), different pixels.
    for f in ["scene_gt.json", "scene_camera.json"] {
        let p = format!("train_pbr/000000/{f}");
        assert_eq!(
            std::fs::read_to_string(b.join(&p)).unwrap(),
            std::fs::read_to_string(c.join(&p)).unwrap(),
            "{p}"
        );
    }
    for i in 0..2 {
        let name = format!("train_pbr/000000/mask/{i:06}_000000.png");
        assert_eq!(
            std::fs::read(b.join(&name)).unwrap(),
            std::fs::read(c.join(&name)).unwrap()
        );
        let rgb = format!("train_pbr/000000/rgb/{i:06}.png");
        assert_ne!(
            std::fs::read(b.join(&rgb)).unwrap(),
            std::fs::read(c.join(&rgb)).unwrap()
        );
    }
    let out = run(synthgen().arg("validate").arg(&b));
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
}

#[test]
fn missing_bpy_says_how_to_install_it() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    crate::render::write_box_ply(&mesh);
    let out = run(synthgen()
        .args(["render", "--backend", "blender", "--objects"])
        .arg(&mesh)
        .arg("--blender-venv")
        .arg(dir.path().join("no-venv"))
        .arg("--out")
        .arg(dir.path().join("o")));
    assert_eq!(out.status.code(), Some(1));
    let e = stderr(&out);
    assert!(
        e.contains("bpy not found") && e.contains("setup-blender.sh"),
        "{e}"
    );
}

/// `render --replay --backend blender --replay-lit`: the real frames' poses through Cycles,
/// lit as the realistic raster's replay is (the Cycles row of `sensor compare-rgb`): the
/// same poses and ids as the raster replay, the backend recorded, other pixels.
#[test]
#[cfg_attr(
    not(all(has_bpy, has_shared_data)),
    ignore = "needs the bpy venv (scripts/setup-blender.sh) and ../shared/data (probed when the crate was built)"
)]
fn a_replay_renders_through_cycles() {
    require_bpy();
    let real = crate::common::ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let replay = |backend: &str| {
        let out_dir = dir.path().join(backend);
        let out = run(synthgen()
            .args(["render", "--replay"])
            .arg(&real)
            .args(["--scenes", "1", "--replay-lit", "--backend", backend])
            .args(if backend == "blender" {
                &["--samples", "1"][..]
            } else {
                &[]
            })
            .arg("--out")
            .arg(&out_dir));
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        assert!(
            stderr(&out).contains(if backend == "blender" {
                "Blender Cycles"
            } else {
                "embedded CPU renderer"
            }),
            "{}",
            stderr(&out)
        );
        out_dir
    };
    let (b, c) = (replay("blender"), replay("cpu"));
    let manifest = std::fs::read_to_string(b.join("synthgen.json")).unwrap();
    assert!(manifest.contains("\"backend\": \"blender\""), "{manifest}");
    let scene = b.join("train/000001");
    let gt = |root: &std::path::Path| {
        std::fs::read_to_string(root.join("train/000001/scene_gt.json")).unwrap()
    };
    assert_eq!(gt(&b), gt(&c));
    let mut differ = 0;
    for entry in std::fs::read_dir(scene.join("rgb")).unwrap() {
        let name = entry.unwrap().file_name();
        let cycles = std::fs::read(scene.join("rgb").join(&name)).unwrap();
        let raster = std::fs::read(c.join("train/000001/rgb").join(&name)).unwrap();
        differ += usize::from(cycles != raster);
    }
    assert_eq!(differ, 20);
    let out = run(synthgen().arg("validate").arg(&b));
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
}

/// Issue 29: `experiment sim2real --model rgb-dense` renders its Cycles row through the
/// Blender backend (`--cycles-frames`), trains on it and scores it on the real photographs.
#[test]
#[cfg_attr(
    any(not(has_bpy), not(has_shared_data)),
    ignore = "needs the bpy venv (scripts/setup-blender.sh) and ../shared/data (probed when the crate was built)"
)]
fn sim2real_rgb_trains_a_cycles_row() {
    require_bpy();
    let lmo = crate::common::shared_data().join("lmo");
    let scene = crate::common::repo_root().join("scenes/linemod_rgb.toml");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s2r");
    let o = run(synthgen()
        .args(["experiment", "sim2real", "--quick", "--model", "rgb-dense"])
        .arg("--scene")
        .arg(&scene)
        .arg("--test")
        .arg(&lmo)
        .args(["--cycles-frames", "2", "--rows", "synth_cycles", "--out"])
        .arg(&out));
    assert!(o.status.success(), "{}", stderr(&o));
    let done = std::fs::read_to_string(out.join("sources/synth_cycles.done")).unwrap();
    assert!(done.contains("\"backend\": \"blender\""), "{done}");
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let row = &r["rows"]["synth_cycles"];
    assert_eq!(row["frames"], 2, "{row}");
    assert_eq!(row["all"]["n"], 627);
    assert!(row["what"].as_str().unwrap().contains("Cycles"));
}
