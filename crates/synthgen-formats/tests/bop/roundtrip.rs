use std::collections::BTreeMap;

use synthgen_core::Pose;
use synthgen_formats::bop::{
    read_mask, read_rgb, BopDataset, BopScene, BopWriter, RgbFormat, SCENE_GT,
};
use synthgen_formats::Error;

use crate::common::{all_files, intrinsics, options, test_frame, write_frames};

fn assert_pose_close(a: &Pose, b: &Pose, what: &str) {
    let dr = (a.rotation - b.rotation)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |m, v| m.max(v.abs()));
    let dt = (a.translation_m - b.translation_m).abs().max_element();
    assert!(dr < 1e-6 && dt < 1e-6, "{what}: |dR| {dr}, |dt| {dt} m");
}

fn check_frame(scene: &BopScene, i: u64, im: u32, depth_tol_m: f32) {
    let t = test_frame(i);
    let cam = &scene.camera[&im];
    assert_eq!(cam.cam_k, intrinsics().k_row_major());
    assert_pose_close(
        &cam.cam_from_world().unwrap(),
        &t.scene.world_from_cam.inverse(),
        "cam_from_world",
    );
    let gts = &scene.gt[&im];
    assert_eq!(gts.len(), 2);
    for (gt_id, (g, o)) in gts.iter().zip(&t.scene.objects).enumerate() {
        assert_eq!(g.obj_id, o.obj_id);
        assert_pose_close(&g.cam_from_obj(), &o.cam_from_obj, "cam_from_obj");
        let info = &scene.gt_info.as_ref().unwrap()[&im][gt_id];
        assert_eq!(*info, t.ann[gt_id].info);
        assert_eq!(
            read_mask(&scene.mask_path(im, gt_id)).unwrap().data,
            t.ann[gt_id].mask
        );
        assert_eq!(
            read_mask(&scene.mask_visib_path(im, gt_id)).unwrap().data,
            t.ann[gt_id].mask_visib
        );
    }
    let rgb = read_rgb(scene.rgb_path(im).unwrap()).unwrap();
    assert_eq!(rgb.rgb, t.frame.rgb);
    let depth = scene.read_depth_m(im).unwrap();
    assert_eq!((depth.width, depth.height), (t.frame.width, t.frame.height));
    for (p, (&got, &want)) in depth.data.iter().zip(&t.frame.depth_m).enumerate() {
        let want = if want > 6.5535 { 0.0 } else { want };
        assert!(
            (got - want).abs() <= depth_tol_m,
            "pixel {p}: {got} vs {want}"
        );
    }
}

#[test]
fn round_trip_across_chunk_boundary() {
    let dir = tempfile::tempdir().unwrap();
    let mut opts = options(2);
    opts.frame_range = Some(0..5);
    let writer = BopWriter::create(dir.path(), opts).unwrap();
    writer.write_camera_json().unwrap();
    write_frames(&writer, &[4, 2, 0, 3, 1]);
    let summary = writer.finish().unwrap();
    assert_eq!(summary.frames, 5);
    assert_eq!(summary.scenes, [0, 1, 2]);
    assert_eq!(summary.depth_out_of_range_px, 1);

    let ds = BopDataset::open(dir.path()).unwrap();
    assert_eq!(ds.splits, ["train_pbr"]);
    assert_eq!(ds.scene_ids("train_pbr").unwrap(), [0, 1, 2]);
    assert_eq!(ds.camera.intrinsics(), intrinsics());
    assert_eq!(ds.camera.depth_scale, 0.1);
    assert!(ds.models_info.is_none());
    let scenes: BTreeMap<u32, BopScene> = (0..3)
        .map(|s| (s, ds.read_scene("train_pbr", s).unwrap()))
        .collect();
    assert_eq!(scenes[&2].im_ids().collect::<Vec<_>>(), [0]);
    for i in 0..5u64 {
        let scene = &scenes[&((i / 2) as u32)];
        assert_eq!(scene.camera[&((i % 2) as u32)].depth_scale, 0.1);
        // 0.1 mm steps: half a step plus f32 rounding.
        check_frame(scene, i, (i % 2) as u32, 0.05e-3 + 2e-6);
    }

    let files = all_files(dir.path());
    assert!(
        files
            .iter()
            .all(|f| !f.to_string_lossy().contains("synthgen-tmp")),
        "temp files left: {files:?}"
    );
    // camera.json + per scene 3 JSON + per frame rgb, depth, 2 x (mask, mask_visib).
    assert_eq!(files.len(), 1 + 3 * 3 + 5 * 6, "{files:?}");
}

#[test]
fn depth_scale_one_and_jpeg() {
    let dir = tempfile::tempdir().unwrap();
    let mut opts = options(10);
    opts.depth_scale = 1.0;
    opts.rgb_format = RgbFormat::Jpg { quality: 95 };
    let writer = BopWriter::create(dir.path(), opts).unwrap();
    writer.write_camera_json().unwrap();
    let t = test_frame(3);
    let rec = writer.write_frame(3, &t.scene, &t.frame, &t.ann).unwrap();
    assert_eq!(rec.depth_out_of_range_px, 0, "7 m fits at 1 mm steps");
    writer.add_record(rec).unwrap();
    writer.finish().unwrap();
    let ds = BopDataset::open(dir.path()).unwrap();
    let scene = ds.read_scene("train_pbr", 0).unwrap();
    let rgb_path = scene.rgb_path(3).unwrap();
    assert_eq!(rgb_path.extension().unwrap(), "jpg");
    let rgb = read_rgb(rgb_path).unwrap();
    assert_eq!(
        (rgb.width, rgb.height, rgb.rgb.len()),
        (32, 24, 32 * 24 * 3)
    );
    let depth = scene.read_depth_m(3).unwrap();
    assert!(depth
        .data
        .iter()
        .zip(&t.frame.depth_m)
        .all(|(a, b)| (a - b).abs() <= 0.5e-3 + 1e-5));
}

#[test]
fn chunk_written_as_soon_as_complete() {
    let dir = tempfile::tempdir().unwrap();
    let writer = BopWriter::create(dir.path(), options(2)).unwrap();
    let add = |i: u64| {
        let t = test_frame(i);
        let rec = writer.write_frame(i, &t.scene, &t.frame, &t.ann).unwrap();
        writer.add_record(rec).unwrap()
    };
    assert_eq!(add(1), None);
    assert_eq!(add(2), None);
    let gt = writer.scene_dir(0).join(SCENE_GT);
    assert!(!gt.exists());
    assert_eq!(add(0), Some(0));
    assert!(gt.exists(), "scene 0 complete, written before finish");
    // A late duplicate of a written chunk is merged, not lost.
    assert_eq!(add(1), Some(0));
    let summary = writer.finish().unwrap();
    assert_eq!(summary.scenes, [0, 1]);
    let ds_scene = synthgen_formats::bop::reader::read_scene_gt(&gt).unwrap();
    assert_eq!(ds_scene.keys().copied().collect::<Vec<_>>(), [0, 1]);
}

#[test]
fn resume_merges_existing_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let mut first = options(5);
    first.frame_range = Some(0..3);
    let writer = BopWriter::create(dir.path(), first).unwrap();
    writer.write_camera_json().unwrap();
    write_frames(&writer, &[0, 1, 2]);
    writer.finish().unwrap();
    let ds = BopDataset::open(dir.path()).unwrap();
    let before = ds.read_scene("train_pbr", 0).unwrap();
    assert_eq!(before.gt.len(), 3);

    let mut second = options(5);
    second.frame_range = Some(3..5);
    second.merge_existing = true;
    let writer = BopWriter::create(dir.path(), second).unwrap();
    write_frames(&writer, &[3, 4]);
    let summary = writer.finish().unwrap();
    assert_eq!(summary.scenes, [0]);
    let after = ds.read_scene("train_pbr", 0).unwrap();
    assert_eq!(after.im_ids().collect::<Vec<_>>(), [0, 1, 2, 3, 4]);
    assert_eq!(after.gt[&1], before.gt[&1]);
    for i in 0..5 {
        check_frame(&after, i, i as u32, 0.05e-3 + 2e-6);
    }
}

#[test]
fn invalid_frames_are_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let writer = BopWriter::create(dir.path(), options(10)).unwrap();
    let mut t = test_frame(0);
    let e = writer
        .write_frame(0, &t.scene, &t.frame, &t.ann[..1])
        .unwrap_err();
    assert!(
        matches!(e, Error::InvalidFrame { frame_index: 0, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("1 annotations for 2 objects"), "{e}");
    t.scene.objects[1].cam_from_obj.translation_m.x = f64::NAN;
    let e = writer
        .write_frame(0, &t.scene, &t.frame, &t.ann)
        .unwrap_err();
    assert!(e.to_string().contains("object 1"), "{e}");
    let mut bad = options(0);
    assert!(BopWriter::create(dir.path(), bad.clone()).is_err());
    bad.chunk_size = 1;
    bad.split = "../x".into();
    let e = BopWriter::create(dir.path(), bad).err().unwrap();
    assert!(e.to_string().contains("split name"), "{e}");
}

#[test]
fn writer_is_shareable_across_threads() {
    fn assert_send_sync<T: Send + Sync>() {}
    assert_send_sync::<BopWriter>();
}
