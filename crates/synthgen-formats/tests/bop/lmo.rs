//! The real Linemod-Occluded files in `shared/data/lmo` (camera.json, models_info.json).

use std::path::PathBuf;

use synthgen_core::Intrinsics;
use synthgen_formats::bop::reader::{read_camera_info, read_models_info};
use synthgen_formats::bop::{BopDataset, BopWriter, BopWriterOptions};

use crate::common::{options, write_frames};

/// `../shared/data/lmo` (the tests that use it are ignored without the shared data).
fn lmo_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/lmo");
    assert!(
        dir.join("camera.json").exists() && dir.join("models/models_info.json").exists(),
        "no lmo reference data at {}",
        dir.display()
    );
    dir
}

/// The reference files have CRLF line ends (from the download); ours have LF.
fn read_lf(p: &std::path::Path) -> String {
    std::fs::read_to_string(p).unwrap().replace("\r\n", "\n")
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn reads_lmo_camera_and_models_info() {
    let lmo = lmo_dir();
    let cam = read_camera_info(&lmo.join("camera.json")).unwrap();
    assert_eq!(cam.intrinsics(), Intrinsics::LINEMOD);
    assert_eq!(cam.depth_scale, 1.0);

    let info_path = lmo.join("models/models_info.json");
    let info = read_models_info(&info_path).unwrap();
    assert_eq!(
        info.keys().copied().collect::<Vec<_>>(),
        [1, 5, 6, 8, 9, 10, 11, 12]
    );
    for (id, m) in &info {
        let n = m.symmetries.symmetries_discrete.len();
        assert_eq!(n, usize::from(*id == 10 || *id == 11), "object {id}");
        assert!(m.symmetries.symmetries_continuous.is_empty());
    }
    assert_eq!(info[&10].symmetries.symmetries_discrete[0][0], -0.999964);
    assert_eq!(info[&11].symmetries.symmetries_discrete[0][15], 1.0);
    // Diameters as the file has them, read independently.
    let raw: serde_json::Value = serde_json::from_str(&read_lf(&info_path)).unwrap();
    for (id, m) in &info {
        assert_eq!(raw[id.to_string()]["diameter"].as_f64(), Some(m.diameter));
    }
    assert_eq!(info[&1].diameter, 102.099);
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn writes_lmo_files_byte_for_byte() {
    let lmo = lmo_dir();
    let dir = tempfile::tempdir().unwrap();
    let mut opts = BopWriterOptions::new(Intrinsics::LINEMOD);
    opts.depth_scale = 1.0;
    let writer = BopWriter::create(dir.path(), opts).unwrap();
    let cam = writer.write_camera_json().unwrap();
    assert_eq!(read_lf(&cam), read_lf(&lmo.join("camera.json")));

    let info = read_models_info(&lmo.join("models/models_info.json")).unwrap();
    let entries: Vec<_> = info.into_iter().collect();
    let p = writer.write_models_info(&entries).unwrap();
    // The reference stores the symmetry matrices' last row as ints; we write floats, as
    // bop_toolkit does for numpy arrays.
    let want = read_lf(&lmo.join("models/models_info.json"))
        .replace(", 0, 0, 0, 1]", ", 0.0, 0.0, 0.0, 1.0]");
    assert_eq!(read_lf(&p), want);
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn opens_copy_of_lmo_with_generated_scene() {
    let lmo = lmo_dir();
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("models")).unwrap();
    for f in ["camera.json", "models/models_info.json"] {
        std::fs::copy(lmo.join(f), dir.path().join(f)).unwrap();
    }
    let writer = BopWriter::create(dir.path(), options(2)).unwrap();
    write_frames(&writer, &[0, 1, 2]);
    writer.finish().unwrap();

    let ds = BopDataset::open(dir.path()).unwrap();
    assert_eq!(ds.camera.intrinsics(), Intrinsics::LINEMOD);
    assert_eq!(ds.models_info.as_ref().map(|m| m.len()), Some(8));
    assert_eq!(ds.splits, ["train_pbr"]);
    assert_eq!(ds.scene_ids("train_pbr").unwrap(), [0, 1]);
    assert_eq!(ds.read_scene("train_pbr", 1).unwrap().gt.len(), 1);
    assert_eq!(
        ds.model_ply_path(5),
        dir.path().join("models/obj_000005.ply")
    );
}
