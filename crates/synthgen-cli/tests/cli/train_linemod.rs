//! `synthgen train` and `synthgen eval` on the Linemod layout: the same frames in Linemod and
//! in BOP (converted) give the same instances, losses and scores.

use std::path::{Path, PathBuf};

use synthgen_formats::layout::open_source;

use crate::common::{repo_root, run, stderr, synthgen};
use crate::render::write_box_ply;
use crate::train::FULL_MODEL_ARGS;

/// Renders 8 small driller frames in the Linemod layout into `dir/lm` and converts them to BOP
/// in `dir/bop`.
fn driller_both_layouts(dir: &Path) -> (PathBuf, PathBuf) {
    let lm = dir.join("lm");
    let o = run(synthgen()
        .args(["render", "-q", "--format", "linemod", "--objects"])
        .arg(repo_root().join("datasets/meshes/driller.ply"))
        .args([
            "--obj-ids",
            "8",
            "--frames",
            "8",
            "--seed",
            "3",
            "--image-size",
            "320,240",
            "--out",
        ])
        .arg(&lm));
    assert!(o.status.success(), "{}", stderr(&o));
    let bop = dir.join("bop");
    let o = run(synthgen()
        .args(["-q", "convert", "--to", "bop"])
        .arg(&lm)
        .arg(&bop));
    assert!(o.status.success(), "{}", stderr(&o));
    (lm, bop)
}

/// One epoch of `synthgen train` with the tiny settings of the train tests.
fn train(data: &Path, out: &Path, extra: &[&str]) {
    let o = crate::train::train(data, out, "1", extra);
    assert!(o.status.success(), "{}", stderr(&o));
}

fn eval(ckpt: &Path, data: &Path, json: &Path) -> serde_json::Value {
    let o = run(synthgen()
        .args(["eval", "-q", "--checkpoint"])
        .arg(ckpt)
        .arg("--data")
        .arg(data)
        .arg("--json")
        .arg(json));
    assert!(o.status.success(), "{}", stderr(&o));
    serde_json::from_str(&std::fs::read_to_string(json).unwrap()).unwrap()
}

fn metrics(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("metrics.jsonl")).unwrap();
    serde_json::from_str(text.lines().last().unwrap()).unwrap()
}

/// Every number in `a` within `tol` (relative) of the one at the same place in `b`.
fn assert_close(a: &serde_json::Value, b: &serde_json::Value, tol: f64, at: &str) {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => {
            let (x, y) = (x.as_f64().unwrap(), y.as_f64().unwrap());
            assert!(
                (x - y).abs() <= tol * x.abs().max(y.abs()).max(1e-12),
                "{at}: {x} vs {y}"
            );
        }
        (Value::Object(x), Value::Object(y)) => {
            assert_eq!(
                x.keys().collect::<Vec<_>>(),
                y.keys().collect::<Vec<_>>(),
                "{at}"
            );
            for (k, v) in x {
                assert_close(v, &y[k], tol, &format!("{at}.{k}"));
            }
        }
        _ => assert_eq!(a, b, "{at}"),
    }
}

#[test]
fn linemod_and_its_bop_conversion_train_and_evaluate_alike() {
    let dir = tempfile::tempdir().unwrap();
    let (lm, bop) = driller_both_layouts(dir.path());
    let timing = ["seconds"];
    for (model, extra) in [("tnet", &[][..]), ("full", &FULL_MODEL_ARGS[..])] {
        let run_lm = dir.path().join(format!("{model}_lm"));
        let run_bop = dir.path().join(format!("{model}_bop"));
        train(&lm, &run_lm, extra);
        train(&bop, &run_bop, extra);
        let (mut m_lm, mut m_bop) = (metrics(&run_lm), metrics(&run_bop));
        for k in timing {
            m_lm.as_object_mut().unwrap().remove(k);
            m_bop.as_object_mut().unwrap().remove(k);
        }
        assert!(m_lm["train_loss"].as_f64().unwrap().is_finite(), "{m_lm}");
        assert_close(&m_lm, &m_bop, 1e-5, &format!("{model} metrics"));

        // Each checkpoint scores the same on either layout, and the two runs score alike.
        let ckpt = run_lm.join("model.safetensors");
        let on_lm = eval(&ckpt, &lm, &dir.path().join(format!("{model}_a.json")));
        let on_bop = eval(&ckpt, &bop, &dir.path().join(format!("{model}_b.json")));
        assert_close(&on_lm, &on_bop, 1e-9, &format!("{model} eval"));
        let other = eval(
            &run_bop.join("model.safetensors"),
            &bop,
            &dir.path().join(format!("{model}_c.json")),
        );
        assert_close(
            &on_lm,
            &other,
            1e-5,
            &format!("{model} eval of the BOP run"),
        );
        let n = if model == "tnet" {
            &on_lm["all"]["n"]
        } else {
            &on_lm["all"]["n_gt"]
        };
        assert!(n.as_u64().unwrap() >= 6, "{model}: {on_lm}");
    }
}

#[test]
fn linemod_frames_are_numbered_as_their_bop_conversion() {
    // Two boxes in shared frames: the gt order and the mask of each entry must match.
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("obj_01.ply"), dir.path().join("obj_02.ply"));
    write_box_ply(&a);
    write_box_ply(&b);
    let lm = dir.path().join("lm");
    let o = run(synthgen()
        .args(["-q", "render", "--format", "linemod", "--objects"])
        .arg(&a)
        .arg(&b)
        .args([
            "--frames",
            "4",
            "--image-size",
            "160,120",
            "--camera-k",
            "150,150,80,60",
            "--distance-m",
            "0.3..0.45",
            "--out",
        ])
        .arg(&lm));
    assert!(o.status.success(), "{}", stderr(&o));
    let bop = dir.path().join("bop");
    let o = run(synthgen()
        .args(["-q", "convert", "--to", "bop"])
        .arg(&lm)
        .arg(&bop));
    assert!(o.status.success(), "{}", stderr(&o));

    let (s_lm, s_bop) = (open_source(&lm).unwrap(), open_source(&bop).unwrap());
    assert_eq!(s_lm.splits(), s_bop.splits());
    assert_eq!(s_lm.camera(), s_bop.camera());
    assert_eq!(s_lm.models_info(), s_bop.models_info());
    assert!(s_lm.model_path(1).unwrap().ends_with("models/obj_01.ply"));
    let (f_lm, f_bop) = (s_lm.frames(&[]).unwrap(), s_bop.frames(&[]).unwrap());
    // A frame where neither box is visible enough has no folder entry, so at most 4.
    assert!((2..=4).contains(&f_lm.len()), "{}", f_lm.len());
    assert_eq!(f_lm.len(), f_bop.len());
    let bytes = |p: &Option<PathBuf>| p.as_ref().map(|p| std::fs::read(p).unwrap());
    for (x, y) in f_lm.iter().zip(&f_bop) {
        assert_eq!(x.location, y.location);
        assert_eq!(x.camera, y.camera);
        assert_eq!(x.gt, y.gt);
        assert_eq!(
            std::fs::read(&x.rgb).unwrap(),
            std::fs::read(&y.rgb).unwrap()
        );
        assert_eq!(bytes(&x.depth), bytes(&y.depth));
        for (g, (mx, my)) in x.masks_visib.iter().zip(&y.masks_visib).enumerate() {
            // The conversion writes an empty mask where Linemod has none.
            if mx.is_some() {
                let path = |m: &Option<synthgen_formats::source::MaskRef>| {
                    m.as_ref().map(|m| m.path().to_path_buf())
                };
                assert_eq!(
                    bytes(&path(mx)),
                    bytes(&path(my)),
                    "{:?} gt {g}",
                    x.location
                );
            }
        }
    }
}
