//! Scene presets and sensor models end to end: noise changes depth and RGB, never the
//! annotations; every preset in scenes/ renders and validates.

use std::path::Path;

use crate::common::{repo_root, run, stderr, synthgen};
use crate::render::write_box_ply;

fn render(out: &Path, mesh: &Path, scene: &Path, frames: &str) {
    let o = run(synthgen()
        .arg("render")
        .arg("--scene")
        .arg(scene)
        .arg("--objects")
        .arg(mesh)
        .arg(mesh)
        .args(["--frames", frames, "--seed", "4", "--jobs", "2", "--out"])
        .arg(out));
    assert!(o.status.success(), "{}", stderr(&o));
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path();
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                std::fs::read(&p).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn sensor_noise_changes_depth_and_rgb_but_not_masks_or_gt() {
    let tmp = tempfile::tempdir().unwrap();
    let mesh = tmp.path().join("box.ply");
    write_box_ply(&mesh);
    let base = "[camera]\npreset = \"d455\"\n[camera_pose]\ndistance_m = [0.7, 0.9]\n";
    let clean_spec = tmp.path().join("clean.toml");
    std::fs::write(&clean_spec, base).unwrap();
    let noisy_spec = tmp.path().join("noisy.toml");
    std::fs::write(
        &noisy_spec,
        format!("{base}[sensor]\ndepth = \"d455\"\n[sensor.rgb]\nenabled = true\n"),
    )
    .unwrap();
    let (clean, noisy, again) = (
        tmp.path().join("clean"),
        tmp.path().join("noisy"),
        tmp.path().join("again"),
    );
    render(&clean, &mesh, &clean_spec, "3");
    render(&noisy, &mesh, &noisy_spec, "3");
    render(&again, &mesh, &noisy_spec, "3");
    let scene = |d: &Path| d.join("train_pbr").join("000000");
    for f in ["scene_gt.json", "scene_gt_info.json", "scene_camera.json"] {
        assert_eq!(
            std::fs::read(scene(&clean).join(f)).unwrap(),
            std::fs::read(scene(&noisy).join(f)).unwrap(),
            "{f} changed with sensor noise"
        );
    }
    for d in ["mask", "mask_visib"] {
        assert_eq!(files(&scene(&clean).join(d)), files(&scene(&noisy).join(d)));
    }
    for d in ["depth", "rgb"] {
        assert_ne!(files(&scene(&clean).join(d)), files(&scene(&noisy).join(d)));
        // Same seed, same noise.
        assert_eq!(files(&scene(&noisy).join(d)), files(&scene(&again).join(d)));
    }
}

#[test]
fn every_preset_renders_and_validates() {
    let tmp = tempfile::tempdir().unwrap();
    let mesh = tmp.path().join("box.ply");
    write_box_ply(&mesh);
    let dir = repo_root().join("scenes");
    let mut presets: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    presets.sort();
    assert!(presets.len() >= 4, "{presets:?}");
    for p in presets {
        let name = p.file_stem().unwrap().to_string_lossy().into_owned();
        let out = tmp.path().join(&name);
        render(&out, &mesh, &p, "2");
        let o = run(synthgen().arg("validate").arg(&out));
        assert!(o.status.success(), "{name}: {}", stderr(&o));
    }
}

/// The realistic defaults change colours only: the same seed with `scenes/plain.toml` (every
/// realism option off) gives the same poses, masks and depth, other RGB.
#[test]
fn the_realistic_defaults_change_colours_only() {
    let tmp = tempfile::tempdir().unwrap();
    let mesh = tmp.path().join("box.ply");
    write_box_ply(&mesh);
    let defaults = tmp.path().join("defaults.toml");
    std::fs::write(&defaults, "[camera_pose]\ndistance_m = [0.5, 0.7]\n").unwrap();
    let plain = tmp.path().join("plain.toml");
    let plain_spec = std::fs::read_to_string(repo_root().join("scenes/plain.toml")).unwrap();
    std::fs::write(
        &plain,
        format!("[camera_pose]\ndistance_m = [0.5, 0.7]\n{plain_spec}"),
    )
    .unwrap();
    let (a, b) = (tmp.path().join("realistic"), tmp.path().join("plain"));
    render(&a, &mesh, &defaults, "3");
    render(&b, &mesh, &plain, "3");
    let scene = |root: &Path| root.join("train_pbr/000000");
    for f in ["scene_gt.json", "scene_gt_info.json", "scene_camera.json"] {
        assert_eq!(
            std::fs::read(scene(&a).join(f)).unwrap(),
            std::fs::read(scene(&b).join(f)).unwrap(),
            "{f}"
        );
    }
    for d in ["mask", "mask_visib", "depth"] {
        assert_eq!(files(&scene(&a).join(d)), files(&scene(&b).join(d)), "{d}");
    }
    let (ra, rb) = (files(&scene(&a).join("rgb")), files(&scene(&b).join("rgb")));
    assert_eq!(ra.len(), 3);
    for ((name, x), (_, y)) in ra.iter().zip(&rb) {
        assert_ne!(x, y, "{name}: the realistic look is not the plain one");
    }
}
