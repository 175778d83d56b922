//! `render --replay`: the synthetic twin of real frames (`../shared/data/ycbv_real`) keeps
//! their ids, poses and masks; `--sensor` chooses its depth; bad input is refused. And
//! `render --sensor` on a sampled render.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;
use synthgen_formats::annotate::{annotate_frame, mask_iou};
use synthgen_formats::bop::image::{read_depth_raw, read_mask};
use synthgen_formats::layout::open_source;
use synthgen_formats::source::SourceFrame;
use synthgen_render::ObjectRenderer;

use crate::common::{refused, run, stderr, synthgen, ycbv_real};
use crate::mix::render_tiny;
use crate::render::write_box_ply;

fn ok(cmd: &mut Command) -> String {
    let o = run(cmd);
    assert!(o.status.success(), "{}", stderr(&o));
    stderr(&o)
}

/// Exit 1 with every one of `words` in the message.
fn replay(real: &Path, out: &Path, extra: &[&str]) -> Output {
    run(synthgen()
        .args(["render", "-q", "--replay"])
        .arg(real)
        .arg("--out")
        .arg(out)
        .args(extra))
}

fn frames_of(root: &Path, scenes: &[u32]) -> Vec<SourceFrame> {
    let mut f = open_source(root).unwrap().frames(&[]).unwrap();
    f.retain(|f| scenes.contains(&f.location.scene_id));
    f
}

/// The replay `out` of `scenes` of `real`: validates, has the source's scene and image ids,
/// poses equal to 1e-6, and visible masks that are those `synthgen_formats::annotate`
/// computes for the real frames from the rendered depth (IoU >= 0.99 per instance).
fn check_twin(real: &Path, out: &Path, scenes: &[u32], split: &str) {
    ok(synthgen().arg("validate").arg(out));
    let src = frames_of(real, scenes);
    let twin = frames_of(out, scenes);
    let ids = |f: &[SourceFrame]| -> Vec<(u32, u32)> {
        f.iter()
            .map(|f| (f.location.scene_id, f.location.im_id))
            .collect()
    };
    assert_eq!(ids(&twin), ids(&src));
    assert_eq!(src.len(), 20 * scenes.len());
    assert!(twin.iter().all(|f| f.location.split == split));

    let source = open_source(real).unwrap();
    let (w, h) = (source.camera().width, source.camera().height);
    let obj_ids: BTreeSet<u32> = src.iter().flat_map(|f| f.object_set()).collect();
    let models = obj_ids
        .iter()
        .map(|&id| {
            (
                id,
                source.load_model(id, &synthgen_core::NoProgress).unwrap(),
            )
        })
        .collect();
    let renderer = ObjectRenderer::new(models).unwrap();
    let mut n = 0;
    for (s, t) in src.iter().zip(&twin) {
        assert_eq!(s.gt.len(), t.gt.len());
        for (a, b) in s.gt.iter().zip(&t.gt) {
            assert_eq!(a.obj_id, b.obj_id);
            let (pa, pb) = (a.cam_from_obj(), b.cam_from_obj_as_stored());
            for (x, y) in pa.translation_mm().iter().zip(pb.translation_mm()) {
                assert!((x - y).abs() <= 1e-3, "{x} vs {y} mm");
            }
            for (x, y) in pa.rotation_row_major().iter().zip(pb.rotation_row_major()) {
                assert!((x - y).abs() <= 1e-6, "{x} vs {y}");
            }
        }
        // What `synthgen annotate` computes for the real frame, against the rendered depth
        // (the real depth's holes and noise are not part of a render).
        let clean = SourceFrame {
            depth: None,
            ..s.clone()
        };
        let ann = annotate_frame(&renderer, &clean, w, h, 0.015).unwrap();
        for (g, a) in ann.objects.iter().enumerate() {
            let ours = t.masks_visib[g].as_ref().unwrap().read().unwrap();
            let iou = mask_iou(&ours.data, &a.mask_visib).unwrap_or(1.0);
            assert!(iou >= 0.99, "{:?} gt {g}: IoU {iou}", t.location);
            n += 1;
        }
    }
    assert!(n >= 60, "{n} instances compared");
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn replay_of_ycbv_as_bop_keeps_ids_poses_and_masks_and_clean_depth() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("twin");
    let o = run(synthgen()
        .args(["render", "--replay"])
        .arg(&real)
        .args(["--scenes", "0", "--format", "bop", "--out"])
        .arg(&out));
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(e.contains("sensor: depth none"), "{e}");
    assert!(e.contains("Replayed 20 frames"), "{e}");
    // YCB-Video's frames are split `train` (no image_sets/ here).
    check_twin(&real, &out, &[0], "train");

    // `--sensor none` (the default) writes the clean depth: a reading exactly where an
    // object is.
    let scene = out.join("train/000000");
    for im in [1, 10, 20] {
        let depth = read_depth_raw(&scene.join(format!("depth/{im:06}.png"))).unwrap();
        let mut union = vec![false; depth.data.len()];
        for g in 0..3 {
            let m = read_mask(&scene.join(format!("mask_visib/{im:06}_{g:06}.png"))).unwrap();
            for (u, &v) in union.iter_mut().zip(&m.data) {
                *u |= v > 0;
            }
        }
        assert!(union.iter().any(|&u| u));
        for (&d, &u) in depth.data.iter().zip(&union) {
            assert_eq!(d > 0, u);
        }
    }
    let m: Value =
        serde_json::from_slice(&std::fs::read(out.join("synthgen.json")).unwrap()).unwrap();
    assert_eq!(m["scene_spec"]["sensor"]["depth"], "none");
    assert_eq!(m["extra"]["replay"]["frames"], 20);
    assert_eq!(
        m["extra"]["replay"]["source"].as_str().map(PathBuf::from),
        Some(real.clone())
    );
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn a_lit_replay_keeps_the_annotations_and_shades_the_objects() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let (flat, lit) = (dir.path().join("flat"), dir.path().join("lit"));
    let args = ["--scenes", "1", "--format", "ycbv"];
    let o = replay(&real, &flat, &args);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = replay(&real, &lit, &[&args[..], &["--replay-lit"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    check_twin(&real, &lit, &[1], "train");
    let (mut same, mut differ) = (0, 0);
    for entry in std::fs::read_dir(flat.join("data/0001")).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        let (a, b) = (
            std::fs::read(flat.join("data/0001").join(&name)).unwrap(),
            std::fs::read(lit.join("data/0001").join(&name)).unwrap(),
        );
        if name.ends_with("-color.png") {
            differ += usize::from(a != b);
        } else if name.ends_with("-depth.png") || name.ends_with("-label.png") {
            assert_eq!(a, b, "{name}: the lighting changes colours only");
            same += 1;
        }
    }
    assert!(same >= 40 && differ >= 20, "{same} same, {differ} differ");
    // The replay flags need --replay (they were silently ignored beside --objects).
    for flag in [&["--replay-lit"][..], &["--replay-models", "m"][..]] {
        let o = run(synthgen().args(["render", "--objects", "x.ply"]).args(flag));
        refused(&o, &["apply only to --replay"]);
    }
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn replay_of_ycbv_as_ycbv_keeps_ids_poses_and_masks() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("twin");
    let o = replay(&real, &out, &["--scenes", "1", "--format", "ycbv"]);
    assert!(o.status.success(), "{}", stderr(&o));
    check_twin(&real, &out, &[1], "train");
    assert_eq!(
        std::fs::read_to_string(out.join("classes.txt")).unwrap(),
        std::fs::read_to_string(real.join("classes.txt"))
            .unwrap()
            .lines()
            .take(5)
            .map(|l| format!("{l}\n"))
            .collect::<String>()
    );
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn replay_sensor_d455_makes_holes_and_the_same_seed_the_same_bytes() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = ["--scenes", "2", "--sensor", "d455", "--seed", "3"];
    for out in ["a", "b"] {
        let o = run(synthgen()
            .args(["render", "--replay"])
            .arg(&real)
            .arg("--out")
            .arg(d.join(out))
            .args(args));
        let e = stderr(&o);
        assert!(o.status.success(), "{e}");
        assert!(e.contains("sensor: depth d455"), "{e}");
    }
    let o = replay(&real, &d.join("clean"), &["--scenes", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));

    let scene = |out: &str| d.join(out).join("train/000002");
    let mut holes = 0;
    let mut changed = 0;
    for im in 1..=20 {
        let name = format!("{im:06}.png");
        for sub in ["rgb", "depth"] {
            assert_eq!(
                std::fs::read(scene("a").join(sub).join(&name)).unwrap(),
                std::fs::read(scene("b").join(sub).join(&name)).unwrap(),
                "{sub}/{name}"
            );
        }
        let noisy = read_depth_raw(&scene("a").join("depth").join(&name)).unwrap();
        let clean = read_depth_raw(&scene("clean").join("depth").join(&name)).unwrap();
        for (&n, &c) in noisy.data.iter().zip(&clean.data) {
            holes += usize::from(c > 0 && n == 0);
            changed += usize::from(c > 0 && n > 0 && n != c);
        }
    }
    assert!(holes > 100, "{holes} holes");
    assert!(changed > 1000, "{changed} noisy readings");
    // Masks and GT come from the clean render.
    for f in ["scene_gt.json", "scene_gt_info.json"] {
        assert_eq!(
            std::fs::read(scene("a").join(f)).unwrap(),
            std::fs::read(scene("clean").join(f)).unwrap()
        );
    }
    for out in ["a", "b"] {
        let m: Value =
            serde_json::from_slice(&std::fs::read(d.join(out).join("synthgen.json")).unwrap())
                .unwrap();
        assert_eq!(m["scene_spec"]["sensor"]["depth"], "d455");
    }
}

/// Frames without GT poses are skipped and counted; ids of the others are kept, `--split`
/// renames the split; a dataset without any GT pose is refused.
#[test]
fn replay_skips_frames_without_gt_and_refuses_a_dataset_without_any() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "synth", 3, 1);
    let gt_path = d.join("synth/train_pbr/000000/scene_gt.json");
    let mut gt: Value = serde_json::from_slice(&std::fs::read(&gt_path).unwrap()).unwrap();
    gt.as_object_mut().unwrap().remove("1");
    std::fs::write(&gt_path, serde_json::to_vec(&gt).unwrap()).unwrap();

    let o = run(synthgen().current_dir(d).args([
        "render", "--replay", "synth", "--split", "test", "--out", "twin",
    ]));
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("1 frame of synth without GT poses is skipped"),
        "{e}"
    );
    assert!(e.contains("Replayed 2 frames"), "{e}");
    let twin = open_source(&d.join("twin")).unwrap().frames(&[]).unwrap();
    let ids: Vec<(&str, u32, u32)> = twin
        .iter()
        .map(|f| {
            (
                f.location.split.as_str(),
                f.location.scene_id,
                f.location.im_id,
            )
        })
        .collect();
    assert_eq!(ids, [("test", 0, 0), ("test", 0, 2)]);
    ok(synthgen().arg("validate").arg(d.join("twin")));

    std::fs::write(&gt_path, "{}").unwrap();
    let o = run(synthgen()
        .current_dir(d)
        .args(["render", "--replay", "synth", "--out", "twin2"]));
    refused(&o, &["no frame of synth has annotated objects"]);
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn replay_bad_input_is_refused_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir_all(d.join("not_a_dataset")).unwrap();
    std::fs::write(d.join("not_a_dataset/notes.txt"), "hello").unwrap();
    refused(
        &replay(&d.join("not_a_dataset"), &d.join("o1"), &[]),
        &["not a dataset synthgen reads", "not_a_dataset"],
    );
    assert!(!d.join("o1").exists());
    refused(
        &replay(&d.join("nowhere"), &d.join("o1"), &[]),
        &["no such dataset folder", "nowhere"],
    );

    let real = ycbv_real();
    let o = replay(&real, &d.join("o2"), &["--objects", "box.ply"]);
    refused(&o, &["--replay", "--objects"]);
    let o = replay(&real, &d.join("o2"), &["--frames", "5"]);
    refused(&o, &["--replay", "--frames"]);
    let o = replay(&real, &d.join("o2"), &["--scene", "tabletop.toml"]);
    refused(&o, &["--scene does not apply to --replay", "--sensor"]);
    // Cycles' flags need the Blender backend, as they do for a sampled render.
    let o = replay(&real, &d.join("o2"), &["--samples", "4"]);
    refused(&o, &["apply only to --backend blender"]);
    assert!(!d.join("o2").exists());
    let o = replay(&real, &d.join("o2"), &["--scenes", "0,7"]);
    refused(&o, &["no scene 7", "its scenes are 0, 1, 2"]);
    let o = run(synthgen().args(["render", "--scenes", "1", "--objects", "box.ply"]));
    refused(&o, &["--scenes applies only to --replay"]);

    // One real YCB-Video frame whose mug model (object 14) is missing.
    let broken = d.join("broken");
    let copy = |from: &Path, to: &Path| {
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(from, to).unwrap();
    };
    copy(&real.join("classes.txt"), &broken.join("classes.txt"));
    for suffix in ["color.png", "depth.png", "label.png", "meta.mat", "box.txt"] {
        let name = format!("data/0000/000001-{suffix}");
        copy(&real.join(&name), &broken.join(&name));
    }
    let gelatin = "models/009_gelatin_box";
    for f in std::fs::read_dir(real.join(gelatin)).unwrap().flatten() {
        copy(&f.path(), &broken.join(gelatin).join(f.file_name()));
    }
    let o = replay(&broken, &d.join("o3"), &[]);
    refused(&o, &["object 14", "025_mug", "textured_simple.obj"]);
    assert!(!d.join("o3").exists());
    // The output may not lie inside the dataset it replays.
    let o = replay(&broken, &broken.join("twin"), &[]);
    refused(&o, &["lies inside the --replay dataset"]);
    assert!(!broken.join("twin").exists());
}

/// `render --sensor`: a built-in name or a file replaces the scene's [sensor] (keeping its
/// RGB noise), is recorded in the manifest, works with --resume, and bad values name the file.
#[test]
fn render_sensor_flag_sets_the_manifest_sensor_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_box_ply(&d.join("box.ply"));
    std::fs::write(d.join("rgb.toml"), "[sensor.rgb]\nenabled = true\n").unwrap();
    let render = |out: &str, extra: &[&str]| {
        run(synthgen()
            .current_dir(d)
            .args(["render", "-q", "--objects", "box.ply", "--units", "m"])
            .args(["--image-size", "96,72", "--camera-k", "96,96,48,36"])
            .args(["--frames", "2", "--scene", "rgb.toml", "--out", out])
            .args(extra))
    };
    let manifest = |out: &str| -> Value {
        serde_json::from_slice(&std::fs::read(d.join(out).join("synthgen.json")).unwrap()).unwrap()
    };
    let o = render("a", &["--sensor", "d455"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = manifest("a");
    assert_eq!(m["scene_spec"]["sensor"]["depth"], "d455");
    assert_eq!(m["scene_spec"]["sensor"]["rgb"]["enabled"], true);
    ok(synthgen().arg("validate").arg(d.join("a")));
    // The same flags resume; another sensor does not.
    let o = render("a", &["--sensor", "d455", "--resume"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = render("a", &["--sensor", "tof", "--resume"]);
    refused(&o, &["scene_spec.sensor.depth differs"]);

    // A sensor file without [rgb] keeps the scene's RGB noise; one with [rgb] replaces it.
    std::fs::write(d.join("xtion.toml"), "depth = \"structured_light\"\n").unwrap();
    let o = render("b", &["--sensor", "xtion.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = manifest("b");
    assert_eq!(m["scene_spec"]["sensor"]["depth"], "structured_light");
    assert_eq!(m["scene_spec"]["sensor"]["rgb"]["enabled"], true);
    std::fs::write(
        d.join("noisy.toml"),
        "depth = \"tof\"\n[rgb]\nenabled = true\nread_noise = 0.01\n",
    )
    .unwrap();
    let o = render("c", &["--sensor", "noisy.toml"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let m = manifest("c");
    assert_eq!(m["scene_spec"]["sensor"]["depth"], "tof");
    assert_eq!(m["scene_spec"]["sensor"]["rgb"]["read_noise"], 0.01);

    refused(
        &render("e", &["--sensor", "missing.toml"]),
        &["--sensor", "missing.toml"],
    );
    std::fs::write(
        d.join("bad.toml"),
        "depth = \"d455\"\n[d455]\nbaseline_m = -1.0\n",
    )
    .unwrap();
    refused(
        &render("e", &["--sensor", "bad.toml"]),
        &["bad.toml", "baseline_m"],
    );
}
