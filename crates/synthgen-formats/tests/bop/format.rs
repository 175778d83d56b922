//! The JSON text, byte for byte, in bop_toolkit's `save_json` layout.

use synthgen_core::annotate::DEFAULT_VISIB_DELTA_M;
use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::symmetry::ContinuousSymmetry;
use synthgen_core::{annotate, AloneDepth, Intrinsics, Pose, RenderedFrame, Symmetries};
use synthgen_formats::bop::{BopWriter, BopWriterOptions, ModelInfo};

use crate::common::{instance, options, scene, write_frames};

fn read(p: &std::path::Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

#[test]
fn scene_json_text_matches_bop_toolkit() {
    let k = Intrinsics {
        width: 4,
        height: 3,
        fx: 30.5,
        fy: 31.25,
        cx: 1.5,
        cy: 1.0,
    };
    // Object 7 covers a 2x2 square; an unannotated occluder hides one of its pixels.
    let alone = vec![AloneDepth {
        x0: 1,
        y0: 0,
        width: 2,
        height: 2,
        depth_m: vec![0.8; 4],
    }];
    let mut depth = vec![1.0f32; 12];
    for p in [1, 2, 5] {
        depth[p] = 0.8;
    }
    depth[6] = 0.5;
    let ann = annotate(&k, &depth, &alone, DEFAULT_VISIB_DELTA_M);
    let rotation = DMat3::from_cols(DVec3::Y, -DVec3::X, DVec3::Z);
    let mut s = scene(
        1002,
        vec![instance(
            7,
            Pose::new(rotation, DVec3::new(0.0123, -0.05, 0.8)),
        )],
    );
    s.intrinsics = k;
    s.world_from_cam = Pose::new(
        DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0)),
        DVec3::new(0.0, 0.0, 1.0),
    );
    let frame = RenderedFrame {
        width: 4,
        height: 3,
        rgb: vec![128; 36],
        depth_m: depth,
        instance: vec![0; 12],
        alone,
    };

    let dir = tempfile::tempdir().unwrap();
    let writer = BopWriter::create(dir.path(), BopWriterOptions::new(k)).unwrap();
    writer.write_camera_json().unwrap();
    let rec = writer.write_frame(1002, &s, &frame, &ann).unwrap();
    assert_eq!((rec.scene_id, rec.im_id), (1, 2));
    writer.add_record(rec).unwrap();
    writer.finish().unwrap();

    let scene_dir = dir.path().join("train_pbr/000001");
    assert_eq!(
        read(&scene_dir.join("scene_gt.json")),
        "{\n  \"2\": [{\"cam_R_m2c\": [0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0], \
         \"cam_t_m2c\": [12.3, -50.0, 800.0], \"obj_id\": 7}]\n}"
    );
    assert_eq!(
        read(&scene_dir.join("scene_camera.json")),
        "{\n  \"2\": {\"cam_K\": [30.5, 0.0, 1.5, 0.0, 31.25, 1.0, 0.0, 0.0, 1.0], \
         \"cam_R_w2c\": [1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0], \
         \"cam_t_w2c\": [0.0, 0.0, 1000.0], \"depth_scale\": 0.1}\n}"
    );
    assert_eq!(
        read(&scene_dir.join("scene_gt_info.json")),
        "{\n  \"2\": [{\"bbox_obj\": [1, 0, 1, 1], \"bbox_visib\": [1, 0, 1, 1], \
         \"px_count_all\": 4, \"px_count_valid\": 4, \"px_count_visib\": 3, \
         \"visib_fract\": 0.75}]\n}"
    );
    assert_eq!(
        read(&dir.path().join("camera.json")),
        "{\n  \"cx\": 1.5,\n  \"cy\": 1.0,\n  \"depth_scale\": 0.1,\n  \"fx\": 30.5,\n  \
         \"fy\": 31.25,\n  \"height\": 3,\n  \"width\": 4\n}"
    );
}

#[test]
fn image_ids_sorted_numerically() {
    let dir = tempfile::tempdir().unwrap();
    let writer = BopWriter::create(dir.path(), options(20)).unwrap();
    write_frames(&writer, &(0..12).collect::<Vec<_>>());
    writer.finish().unwrap();
    for name in ["scene_gt.json", "scene_camera.json", "scene_gt_info.json"] {
        let text = read(&dir.path().join("train_pbr/000000").join(name));
        let keys: Vec<&str> = text
            .lines()
            .filter_map(|l| l.strip_prefix("  \"")?.split('"').next())
            .collect();
        let want: Vec<String> = (0..12).map(|i| i.to_string()).collect();
        assert_eq!(keys, want, "{name}");
    }
}

#[test]
fn models_info_text() {
    let dir = tempfile::tempdir().unwrap();
    let writer = BopWriter::create(dir.path(), options(10)).unwrap();
    let info = |d: f64| ModelInfo {
        diameter: d,
        min_x: -37.9343,
        min_y: -38.7996,
        min_z: -45.8845,
        size_x: 75.8686,
        size_y: 77.5992,
        size_z: 91.769,
        symmetries: Symmetries::default(),
    };
    let mut sym = info(50.0);
    sym.symmetries.symmetries_continuous = vec![ContinuousSymmetry {
        axis: [0.0, 0.0, 1.0],
        offset: [0.0, 0.0, 0.0],
    }];
    let mut identity = [0.0; 16];
    for i in [0, 5, 10, 15] {
        identity[i] = 1.0;
    }
    sym.symmetries.symmetries_discrete = vec![identity];
    let p = writer
        .write_models_info(&[(10, sym), (2, info(102.099))])
        .unwrap();
    assert_eq!(
        read(&p),
        "{\n  \"2\": {\"diameter\": 102.099, \"min_x\": -37.9343, \"min_y\": -38.7996, \
         \"min_z\": -45.8845, \"size_x\": 75.8686, \"size_y\": 77.5992, \"size_z\": 91.769},\n  \
         \"10\": {\"diameter\": 50.0, \"min_x\": -37.9343, \"min_y\": -38.7996, \
         \"min_z\": -45.8845, \"size_x\": 75.8686, \"size_y\": 77.5992, \"size_z\": 91.769, \
         \"symmetries_continuous\": [{\"axis\": [0.0, 0.0, 1.0], \"offset\": [0.0, 0.0, 0.0]}], \
         \"symmetries_discrete\": [[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, \
         0.0, 0.0, 0.0, 1.0]]}\n}"
    );
    assert_eq!(
        writer.model_ply_path(3).unwrap(),
        dir.path().join("models/obj_000003.ply")
    );
    let mut nan = info(1.0);
    nan.size_x = f64::NAN;
    let e = writer
        .write_models_info(&[(4, nan)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("non-finite") && e.contains("entry 4"), "{e}");
    assert!(e.ends_with("models_info.json"), "{e}");
}
