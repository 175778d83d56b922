//! `synthgen model align`: the YCB google_16k scans (../shared/data/ycb_textured) onto the
//! YCB-Video models their poses refer to.

use std::path::Path;
use std::process::Output;

use crate::common::{run, shared_data, stderr, stdout_json, synthgen};

fn align(scan: &Path, to: &Path, out: &Path, extra: &[&str]) -> Output {
    run(synthgen()
        .args(["model", "align", "--json", "--scan"])
        .arg(scan)
        .arg("--to")
        .arg(to)
        .arg("--out")
        .arg(out)
        .args(extra))
}

fn scan(class: &str) -> std::path::PathBuf {
    shared_data().join(format!("ycb_textured/{class}/textured.obj"))
}

fn model(class: &str) -> std::path::PathBuf {
    shared_data().join(format!("ycbv_real/models/{class}/textured_simple.obj"))
}

/// The cracker box's scan is the YCB-Video model shifted by about (12, 12, −108) mm (the
/// data's README): recovered, the surfaces within a millimetre, the scan written with its
/// material and texture; aligning the written scan again finds nothing left to move.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn a_scan_is_put_on_the_model_its_poses_refer_to() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cracker");
    let c = "003_cracker_box";
    let r = stdout_json(&align(&scan(c), &model(c), &out, &[]));
    let t: Vec<f64> = r["translation_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap() * 1e3)
        .collect();
    for (got, want) in t.iter().zip([12.0, 12.0, -108.0]) {
        assert!((got - want).abs() < 1.5, "translation {t:?} mm");
    }
    assert!(r["median_mm"].as_f64().unwrap() <= 1.0, "{r}");
    assert!(r["scan_to_model"]["p95_mm"].as_f64().unwrap() <= 1.0, "{r}");
    for f in [
        "textured.obj",
        "textured.mtl",
        "texture_map.jpg",
        "align.json",
    ] {
        assert!(out.join(f).is_file(), "{f} written");
    }
    let again = stdout_json(&align(
        &out.join("textured.obj"),
        &model(c),
        &dir.path().join("again"),
        &[],
    ));
    let left: f64 = again["translation_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap().powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(left < 2e-4, "{left} m left to move");
    // An earlier alignment is replaced only with --force.
    let o = align(&scan(c), &model(c), &out, &[]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("--force"), "{}", stderr(&o));
    assert!(align(&scan(c), &model(c), &out, &["--force"])
        .status
        .success());
}

/// Real scans as shipped: NaN normals (the tuna can) are kept for the readers to replace; the
/// wood block's scan lies on its model only after a 12° turn about z (its axes differ: the
/// data's README calls it another mesh, yet the surfaces then agree to 0.01 mm), which is
/// warned about; a different object is refused and nothing is written.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn real_scans_nan_normals_turned_axes_and_other_objects() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let tuna = "007_tuna_fish_can";
    let r = stdout_json(&align(&scan(tuna), &model(tuna), &d.join("tuna"), &[]));
    assert!(r["median_mm"].as_f64().unwrap() <= 1.0, "{r}");

    let wood = "036_wood_block";
    let o = align(&scan(wood), &model(wood), &d.join("wood"), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("needed a 12.2° rotation"),
        "{}",
        stderr(&o)
    );

    let o = align(
        &scan("011_banana"),
        &model("025_mug"),
        &d.join("wrong"),
        &[],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the surfaces do not match"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("wrong").exists(), "nothing written");
}
