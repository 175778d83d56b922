//! `synthgen annotate`: regenerate the masks and scene_gt_info.json of a rendered Linemod
//! dataset from its poses alone and compare with what `render` wrote.

use std::path::Path;

use serde_json::Value;
use synthgen_formats::bop::read_mask;

use crate::common::{run, shared_data, stderr, synthgen};

fn read_json(p: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn annotate_reproduces_render_annotations() {
    let data = shared_data();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let models = data.join("lmo/models");
    let o = run(synthgen()
        .current_dir(d)
        .args(["render", "-q", "--objects"])
        .arg(models.join("obj_000001.ply"))
        .arg(models.join("obj_000005.ply"))
        .args(["--frames", "3", "--seed", "11", "--out", "orig"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let orig = d.join("orig/train_pbr/000000");

    for (name, keep_depth) in [("with_depth", true), ("no_depth", false)] {
        // A "real" dataset: rgb, depth, poses; the models exactly as render loaded them.
        let real = d.join(name);
        let scene = real.join("train_pbr/000000");
        std::fs::create_dir_all(scene.join("rgb")).unwrap();
        std::fs::create_dir_all(real.join("models")).unwrap();
        std::fs::copy(d.join("orig/camera.json"), real.join("camera.json")).unwrap();
        for id in [1, 5] {
            let f = format!("obj_{id:06}.ply");
            std::fs::copy(models.join(&f), real.join("models").join(&f)).unwrap();
        }
        std::fs::copy(
            d.join("orig/models/models_info.json"),
            real.join("models/models_info.json"),
        )
        .unwrap();
        for f in ["scene_camera.json", "scene_gt.json"] {
            std::fs::copy(orig.join(f), scene.join(f)).unwrap();
        }
        for im in 0..3 {
            let f = format!("{im:06}.png");
            std::fs::copy(orig.join("rgb").join(&f), scene.join("rgb").join(&f)).unwrap();
            if keep_depth {
                std::fs::create_dir_all(scene.join("depth")).unwrap();
                std::fs::copy(orig.join("depth").join(&f), scene.join("depth").join(&f)).unwrap();
            }
        }
        let o = run(synthgen().args(["annotate"]).arg(&real));
        assert!(o.status.success(), "{}", stderr(&o));
        let want = read_json(&orig.join("scene_gt_info.json"));
        let got = read_json(&scene.join("scene_gt_info.json"));
        for im in 0..3 {
            for gt in 0..2 {
                let (w, g) = (&want[im.to_string()][gt], &got[im.to_string()][gt]);
                assert_eq!(w["bbox_obj"], g["bbox_obj"], "{name} image {im} gt {gt}");
                assert_eq!(
                    w["px_count_all"], g["px_count_all"],
                    "{name} image {im} gt {gt}"
                );
                let f = format!("{im:06}_{gt:06}.png");
                assert_eq!(
                    read_mask(&orig.join("mask").join(&f)).unwrap(),
                    read_mask(&scene.join("mask").join(&f)).unwrap(),
                    "{name} mask {f}"
                );
                if keep_depth {
                    // The depth PNG is quantized to 0.1 mm; visibility may move by a pixel.
                    let (a, b) = (
                        w["px_count_visib"].as_i64().unwrap(),
                        g["px_count_visib"].as_i64().unwrap(),
                    );
                    assert!(
                        (a - b).abs() <= 2 + a / 200,
                        "{name} image {im} gt {gt}: {a} vs {b}"
                    );
                    assert_eq!(w["bbox_visib"].is_null(), g["bbox_visib"].is_null());
                }
            }
        }
    }

    // A missing model names the file.
    std::fs::remove_file(d.join("no_depth/models/obj_000005.ply")).unwrap();
    let o = run(synthgen().args(["annotate"]).arg(d.join("no_depth")));
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("obj_000005.ply"), "{e}");
}
