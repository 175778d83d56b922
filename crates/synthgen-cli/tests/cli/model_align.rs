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

/// The dataset form: a folder of scans named by class, aligned onto a dataset's models in one
/// command (a wrong scan refused, the others written, exit 1), then `render --replay
/// --replay-models` renders the real frames with the textured scans: the pudding box, one
/// flat colour in the YCB-Video model, shows its printed texture.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn a_folder_of_scans_aligned_to_a_dataset_and_replayed_textured() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scans = d.join("scans");
    let copy = |from: &str, to: &str| {
        let (s, t) = (
            shared_data().join("ycb_textured").join(from),
            scans.join(to),
        );
        std::fs::create_dir_all(&t).unwrap();
        for f in ["textured.obj", "textured.mtl", "texture_map.jpg"] {
            std::fs::copy(s.join(f), t.join(f)).unwrap();
        }
    };
    copy("008_pudding_box", "008_pudding_box");
    copy("011_banana", "025_mug"); // the wrong object under the mug's name
    let o = run(synthgen()
        .args(["model", "align", "--scans"])
        .arg(&scans)
        .arg("--to-dataset")
        .arg(crate::common::ycbv_real())
        .arg("--out")
        .arg(d.join("tex")));
    let out = String::from_utf8_lossy(&o.stdout).to_string();
    assert_eq!(o.status.code(), Some(1), "{out}{}", stderr(&o));
    assert!(out.contains("| 7 | 008_pudding_box | 0.0"), "{out}");
    assert!(
        out.contains("| 14 | 025_mug | — | — | — | refused |"),
        "{out}"
    );
    assert!(
        out.contains("| 1 | 002_master_chef_can | — | — | — | no scan |"),
        "{out}"
    );
    assert!(d.join("tex/008_pudding_box/textured.obj").is_file());
    assert!(!d.join("tex/025_mug").exists());

    let spread = |data: &Path| -> f64 {
        // The colour spread inside the pudding box (class 7) of frame 1 of scene 2.
        let rgb = image::open(data.join("data/0002/000001-color.png"))
            .unwrap()
            .to_rgb8();
        let label = image::open(data.join("data/0002/000001-label.png"))
            .unwrap()
            .to_luma8();
        let px: Vec<f64> = rgb
            .pixels()
            .zip(label.pixels())
            .filter(|(_, l)| l.0[0] == 7)
            .map(|(p, _)| f64::from(p.0[0]) + f64::from(p.0[1]) + f64::from(p.0[2]))
            .collect();
        assert!(px.len() > 500, "{} pixels", px.len());
        let m = px.iter().sum::<f64>() / px.len() as f64;
        (px.iter().map(|v| (v - m).powi(2)).sum::<f64>() / px.len() as f64).sqrt()
    };
    let replay = |name: &str, extra: &[&str]| {
        let out = d.join(name);
        let o = run(synthgen()
            .args(["render", "-q", "--replay"])
            .arg(crate::common::ycbv_real())
            .args(["--scenes", "2", "--format", "ycbv", "--out"])
            .arg(&out)
            .args(extra));
        assert!(o.status.success(), "{}", stderr(&o));
        out
    };
    let plain = replay("plain", &[]);
    let tex_dir = d.join("tex").display().to_string();
    let textured = replay("textured", &["--replay-models", &tex_dir]);
    let (a, b) = (spread(&plain), spread(&textured));
    assert!(b > 3.0 * a.max(1.0), "colour spread {a} flat, {b} textured");

    // `sensor compare-rgb` measures it: the textured pudding box is closer to the photographs
    // on every score; the flat one has no shading to correlate.
    let compare = |synth: &Path| {
        stdout_json(&run(synthgen()
            .args(["sensor", "compare-rgb", "--json", "--scenes", "2", "--real"])
            .arg(crate::common::ycbv_real())
            .arg("--synth")
            .arg(synth)))
    };
    let (p, t) = (compare(&plain), compare(&textured));
    assert_eq!(p["frames"], 20);
    let score = |r: &serde_json::Value, k: &str| r["objects"]["7"][k].as_f64().unwrap();
    assert_eq!(score(&p, "ncc_intensity"), 0.0, "{}", p["objects"]["7"]);
    for k in ["ncc_intensity", "ncc_gradient"] {
        assert!(
            score(&t, k) > score(&p, k) + 0.1,
            "{k}: {} vs {}",
            t["objects"]["7"],
            p["objects"]["7"]
        );
    }
    assert!(score(&t, "hist_distance") < score(&p, "hist_distance") - 0.1);
    // The mustard bottle (5) keeps its flat dataset model in both: no shading, about the same
    // colours (the frame's gains are fitted over every object, so they move a little).
    let s5 = |r: &serde_json::Value| r["objects"]["5"]["ncc_intensity"].as_f64().unwrap();
    assert_eq!((s5(&p), s5(&t)), (0.0, 0.0));
    let m = |r: &serde_json::Value| r["objects"]["5"]["hist_distance"].as_f64().unwrap();
    assert!((m(&p) - m(&t)).abs() < 0.05, "{} vs {}", m(&p), m(&t));
}

/// A textured box as a scan: an OBJ (a 60 × 40 × 20 mm box, in metres) whose MTL names its
/// textures as the MTL text `mtl` says, in `dir`.
fn box_scan(dir: &Path, mtl: &str) -> std::path::PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let (x, y, z) = (0.03, 0.02, 0.01);
    let mut s = String::from("mtllib box.mtl\nusemtl m\n");
    for zz in [-z, z] {
        for yy in [-y, y] {
            for xx in [-x, x] {
                s += &format!("v {xx} {yy} {zz}\n");
            }
        }
    }
    s += "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n";
    for f in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        s += &format!("f {}/1 {}/2 {}/3 {}/4\n", f[0], f[1], f[2], f[3]);
    }
    std::fs::write(dir.join("box.obj"), s).unwrap();
    std::fs::write(dir.join("box.mtl"), mtl).unwrap();
    dir.join("box.obj")
}

fn png(path: &Path, rgb: [u8; 3]) {
    image::RgbImage::from_pixel(4, 4, image::Rgb(rgb))
        .save(path)
        .unwrap();
}

/// Regression (issue 50): `map_Kd ../../x.png` was copied to OUT/../../x.png; a texture name
/// leading back to its own file (absolute, or `..` onto it) was copied onto itself and
/// truncated to 0 bytes; `--force` into the scan's own folder deleted the scan; an MTL colour
/// with two numbers panicked in the OBJ parser; `--samples 200000000` aborted.
#[test]
fn a_scans_file_names_never_decide_where_align_writes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scan_dir = d.join("a/b/scan");
    std::fs::create_dir_all(&scan_dir).unwrap();
    png(&d.join("a/x.png"), [200, 10, 10]);
    png(&scan_dir.join("tex.png"), [10, 200, 10]);
    let mtl = format!(
        "newmtl m\nKd 0.5 0.5\nmap_Kd ../../x.png\nmap_Ks {}\n",
        scan_dir.join("tex.png").display()
    );
    let scan = box_scan(&scan_dir, &mtl);
    let before: Vec<(std::path::PathBuf, Vec<u8>)> = [
        d.join("a/x.png"),
        scan_dir.join("tex.png"),
        scan_dir.join("box.mtl"),
        scan.clone(),
    ]
    .into_iter()
    .map(|p| (p.clone(), std::fs::read(&p).unwrap()))
    .collect();
    let unchanged = || {
        for (p, b) in &before {
            assert_eq!(&std::fs::read(p).unwrap(), b, "{} changed", p.display());
        }
    };
    let out = d.join("out");
    let o = align(&scan, &scan, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("MTL line 2: `Kd 0.5 0.5`") && !e.contains("panicked"),
        "{e}"
    );
    unchanged();
    let mut written: Vec<String> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    written.sort();
    assert_eq!(
        written,
        ["align.json", "box.mtl", "box.obj", "tex.png", "x.png"]
    );
    let copied = std::fs::read_to_string(out.join("box.mtl")).unwrap();
    assert!(
        copied.contains("map_Kd x.png\n") && copied.contains("map_Ks tex.png\n"),
        "{copied}"
    );
    // Nothing beside the scan or the output: the folder holds what it held, plus out/.
    let mut top: Vec<String> = std::fs::read_dir(d.join("a"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    top.sort();
    assert_eq!(top, ["b", "x.png"]);

    // In place, over the scan's folder or a folder holding its texture: refused, untouched.
    for bad in [scan_dir.clone(), d.join("a")] {
        let o = align(&scan, &scan, &bad, &["--force"]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("never writes into its inputs"),
            "{}",
            stderr(&o)
        );
        unchanged();
    }
    // A size beyond reason is refused with a message, not an abort.
    let o = align(&scan, &scan, &d.join("big"), &["--samples", "200000000"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--samples 200000000 is outside"),
        "{}",
        stderr(&o)
    );
    assert!(!d.join("big").exists());
    // --force over an earlier alignment replaces it.
    let o = align(&scan, &scan, &out, &["--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    unchanged();
}
