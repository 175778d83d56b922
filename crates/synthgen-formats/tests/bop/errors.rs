//! Reader errors name the file and the problem.

use std::path::{Path, PathBuf};

use synthgen_formats::bop::{BopDataset, BopWriter};
use synthgen_formats::Error;

use crate::common::{options, write_frames};

/// A two-image dataset; returns (temp dir, scene folder).
fn dataset() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let writer = BopWriter::create(dir.path(), options(10)).unwrap();
    writer.write_camera_json().unwrap();
    write_frames(&writer, &[0, 1]);
    writer.finish().unwrap();
    let scene = dir.path().join("train_pbr/000000");
    (dir, scene)
}

fn read_scene_err(root: &Path) -> Error {
    BopDataset::open(root)
        .unwrap()
        .read_scene("train_pbr", 0)
        .unwrap_err()
}

fn edit(path: &Path, f: impl FnOnce(String) -> String) {
    let text = std::fs::read_to_string(path).unwrap();
    std::fs::write(path, f(text)).unwrap();
}

/// Replaces the first number after `key` with `with`.
fn replace_first_number(text: &str, key: &str, with: &str) -> String {
    let start = text.find(key).unwrap() + key.len();
    let from = start
        + text[start..]
            .find(|c: char| c == '-' || c.is_ascii_digit())
            .unwrap();
    let to = from + text[from..].find([',', ']', '}']).unwrap();
    format!("{}{with}{}", &text[..from], &text[to..])
}

#[test]
fn malformed_json_names_file_line_and_column() {
    let (dir, scene) = dataset();
    let gt = scene.join("scene_gt.json");
    edit(&gt, |t| t[..t.len() - 20].to_string());
    let e = read_scene_err(dir.path());
    assert!(matches!(e, Error::Json { .. }), "{e:?}");
    let msg = e.to_string();
    assert!(msg.starts_with("malformed scene_gt.json: "), "{msg}");
    assert!(msg.contains("line 3 column"), "{msg}");
    assert!(msg.ends_with(&gt.display().to_string()), "{msg}");
    assert_eq!(e.path(), Some(gt.as_path()));
}

#[test]
fn missing_rgb_file() {
    let (dir, scene) = dataset();
    let rgb = scene.join("rgb/000001.png");
    std::fs::remove_file(&rgb).unwrap();
    let e = read_scene_err(dir.path());
    assert!(matches!(e, Error::MissingFile { .. }), "{e:?}");
    assert_eq!(e.to_string(), format!("missing file: {}", rgb.display()));
}

#[test]
fn nan_in_rotation() {
    let (dir, scene) = dataset();
    let gt = scene.join("scene_gt.json");
    // Python's json.dump writes NaN as a bare `NaN`, which is not JSON.
    edit(&gt, |t| replace_first_number(&t, "\"cam_R_m2c\": [", "NaN"));
    let msg = read_scene_err(dir.path()).to_string();
    assert!(msg.starts_with("malformed scene_gt.json: "), "{msg}");
    assert!(msg.contains("line 2"), "{msg}");
    assert!(msg.ends_with(&gt.display().to_string()), "{msg}");
}

#[test]
fn rotation_not_orthonormal() {
    let (dir, scene) = dataset();
    let gt = scene.join("scene_gt.json");
    edit(&gt, |t| replace_first_number(&t, "\"cam_R_m2c\": [", "0.9"));
    let e = read_scene_err(dir.path());
    assert!(matches!(e, Error::Malformed { .. }), "{e:?}");
    let msg = e.to_string();
    assert!(msg.contains("cam_R_m2c of image 0, gt 0"), "{msg}");
    assert!(msg.ends_with(&gt.display().to_string()), "{msg}");
}

#[test]
fn negative_obj_id() {
    let (dir, scene) = dataset();
    let gt = scene.join("scene_gt.json");
    edit(&gt, |t| t.replacen("\"obj_id\": 1", "\"obj_id\": -1", 1));
    let msg = read_scene_err(dir.path()).to_string();
    assert!(
        msg.contains("invalid value: integer `-1`, expected u32"),
        "{msg}"
    );
    assert!(msg.ends_with(&gt.display().to_string()), "{msg}");
}

#[test]
fn wrong_type_and_counts() {
    let (dir, scene) = dataset();
    let gt = scene.join("scene_gt.json");
    let original = std::fs::read_to_string(&gt).unwrap();
    edit(&gt, |t| {
        t.replacen("\"1\": [", "\"1\": {\"x\": [", 1)
            .replacen("]\n}", "]}\n}", 1)
    });
    let msg = read_scene_err(dir.path()).to_string();
    assert!(
        msg.contains("invalid type: map, expected a sequence"),
        "{msg}"
    );

    // Drop image 1's second object from scene_gt: counts no longer match scene_gt_info.
    let cut = original.rfind(", {\"cam_R_m2c\"").unwrap();
    std::fs::write(&gt, format!("{}]\n}}", &original[..cut])).unwrap();
    let e = read_scene_err(dir.path());
    let msg = e.to_string();
    assert!(
        msg.starts_with(
            "malformed scene_gt_info.json: image 1 has 2 entries but scene_gt.json has 1"
        ),
        "{msg}"
    );
}

#[test]
fn missing_camera_json() {
    let (dir, _) = dataset();
    let cam = dir.path().join("camera.json");
    std::fs::remove_file(&cam).unwrap();
    let e = BopDataset::open(dir.path()).unwrap_err();
    assert_eq!(e.to_string(), format!("missing file: {}", cam.display()));
}

#[test]
fn missing_scene_folder() {
    let (dir, _) = dataset();
    let ds = BopDataset::open(dir.path()).unwrap();
    let e = ds.read_scene("train_pbr", 7).unwrap_err();
    assert!(e.to_string().starts_with("missing file: "), "{e}");
    assert!(e.to_string().ends_with("000007/scene_camera.json"), "{e}");
}
