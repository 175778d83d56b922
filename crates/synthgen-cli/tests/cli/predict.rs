//! `synthgen predict`: the detector and a pose model on frames with no GT. Its results score
//! as `eval --detections` scores the same detector's boxes (on a copy of the dataset with the
//! GT files removed, so predict cannot have read them); photographs with a camera file give
//! the same poses as the dataset's frames; a line per frame; the depth models' centres; bad
//! input named.

use std::path::{Path, PathBuf};

use serde_json::Value;

use crate::common::{copy_dir, refused, run, stderr, synthgen};
use crate::rgb::{json_file, two_class_set};

fn train(args: &[&str], data: &Path, out: &Path) {
    let o = run(synthgen()
        .args(args)
        .arg("--data")
        .arg(data)
        .arg("--out")
        .arg(out));
    assert!(o.status.success(), "{}", stderr(&o));
}

fn predict(
    model: &Path,
    det: &Path,
    input: &[&std::ffi::OsStr],
    out: &Path,
) -> std::process::Output {
    run(synthgen()
        .args(["predict", "--model"])
        .arg(model)
        .arg("--detector")
        .arg(det)
        .args(input)
        .arg("--out")
        .arg(out))
}

/// The scores of `eval` with `extra`, as its --json.
fn scores(data: &Path, extra: &[&std::ffi::OsStr], json: &Path) -> Value {
    let o = run(synthgen()
        .args(["eval", "-q", "--data"])
        .arg(data)
        .arg("--json")
        .arg(json)
        .args(extra));
    assert!(o.status.success(), "{}", stderr(&o));
    json_file(json)
}

/// results.csv rows: (scene, image, object) → the 12 numbers of R and t.
fn rows(path: &Path) -> std::collections::BTreeMap<(u32, u32, u32), Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = std::collections::BTreeMap::new();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let nums = f[4]
            .split_whitespace()
            .chain(f[5].split_whitespace())
            .map(|v| v.parse().unwrap())
            .collect();
        out.insert(
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
            ),
            nums,
        );
    }
    out
}

fn lines(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// The dataset without its GT: scene_gt*.json and the masks removed.
fn without_gt(data: &Path, to: &Path) -> PathBuf {
    copy_dir(data, to, &[]);
    let scene = to.join("train_pbr/000000");
    for f in ["scene_gt.json", "scene_gt_info.json"] {
        std::fs::remove_file(scene.join(f)).unwrap();
    }
    for d in ["mask", "mask_visib"] {
        let _ = std::fs::remove_dir_all(scene.join(d));
    }
    to.to_path_buf()
}

/// A ROS 2 bag (MCAP) of a BOP scene's frames: bgr8 colour on /cam/color/image_raw, 32FC1
/// depth in metres on /cam/depth, one CameraInfo on /cam/color/camera_info; frame i stamped
/// 100 + i/10 s.
fn scene_bag(scene: &Path, out: &Path) {
    use synthgen_ros::rosbag::{cdr, Header, CAMERA_INFO, IMAGE};
    let cams = json_file(&scene.join("scene_camera.json"));
    let f = std::io::BufWriter::new(std::fs::File::create(out).unwrap());
    let mut w = mcap::Writer::new(f).unwrap();
    let none = std::collections::BTreeMap::new();
    let si = w
        .add_schema(IMAGE, "ros2msg", cdr::image_schema().as_bytes())
        .unwrap();
    let sc = w
        .add_schema(CAMERA_INFO, "ros2msg", cdr::camera_info_schema().as_bytes())
        .unwrap();
    let colour = w
        .add_channel(si, "/cam/color/image_raw", "cdr", &none)
        .unwrap();
    let depth = w.add_channel(si, "/cam/depth", "cdr", &none).unwrap();
    let info = w
        .add_channel(sc, "/cam/color/camera_info", "cdr", &none)
        .unwrap();
    let mut put = |chan: u16, seq: u32, t: u64, msg: &[u8]| {
        let h = mcap::records::MessageHeader {
            channel_id: chan,
            sequence: seq,
            log_time: t,
            publish_time: t,
        };
        w.write_to_known_channel(&h, msg).unwrap();
    };
    for i in 0..8u32 {
        let header = Header {
            sec: 100,
            nanosec: i * 100_000_000,
            frame_id: "camera_color_optical_frame".into(),
        };
        let t = 100_000_000_000 + u64::from(i) * 100_000_000;
        let cam = &cams[i.to_string()];
        let k: Vec<f64> = cam["cam_K"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        let rgb = image::open(scene.join(format!("rgb/{i:06}.png")))
            .unwrap()
            .to_rgb8();
        let (width, height) = rgb.dimensions();
        if i == 0 {
            let k: [f64; 9] = std::array::from_fn(|j| k[j]);
            put(info, 0, t, &cdr::camera_info(&header, width, height, &k));
        }
        let bgr: Vec<u8> = rgb.pixels().flat_map(|p| [p[2], p[1], p[0]]).collect();
        put(
            colour,
            i,
            t,
            &cdr::image(&header, width, height, "bgr8", width * 3, &bgr),
        );
        let scale = cam["depth_scale"].as_f64().unwrap();
        let d =
            synthgen_formats::bop::read_depth_m(&scene.join(format!("depth/{i:06}.png")), scale)
                .unwrap();
        let bytes: Vec<u8> = d.data.iter().flat_map(|v| v.to_le_bytes()).collect();
        put(
            depth,
            i,
            t,
            &cdr::image(&header, width, height, "32FC1", width * 4, &bytes),
        );
    }
    w.finish().unwrap();
}

#[test]
fn predict_scores_as_eval_detections_without_reading_gt() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = two_class_set(d, "set", "8", "3");
    let det = d.join("det");
    train(
        &[
            "detector", "train", "-q", "--input", "64x48", "--batch", "4", "--epochs", "6",
        ],
        &data,
        &det,
    );
    let dense = d.join("dense");
    train(
        &[
            "train",
            "-q",
            "--model",
            "rgb-dense",
            "--crop-size",
            "16",
            "--epochs",
            "1",
            "--batch",
            "4",
            "--width",
            "16",
        ],
        &data,
        &dense,
    );
    // The reference: the detector's boxes through `detector run`, then eval --detections.
    let dets = d.join("dets.json");
    let o = run(synthgen()
        .args(["detector", "run", "-q", "--checkpoint"])
        .arg(&det)
        .arg("--data")
        .arg(&data)
        .arg("--out")
        .arg(&dets));
    assert!(o.status.success(), "{}", stderr(&o));
    let saved = d.join("from_dets.csv");
    let reference = scores(
        &data,
        &[
            "--checkpoint".as_ref(),
            dense.join("model.safetensors").as_os_str(),
            "--detections".as_ref(),
            dets.as_os_str(),
            "--save-results".as_ref(),
            saved.as_os_str(),
        ],
        &d.join("ref.json"),
    );

    // predict on a copy without GT, scored against the dataset with it.
    let bare = without_gt(&data, &d.join("bare"));
    let out = d.join("pred");
    let o = predict(&dense, &det, &["--data".as_ref(), bare.as_os_str()], &out);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(
        table.contains("| detect |") && table.contains("8 frames"),
        "{table}"
    );
    let got = scores(
        &data,
        &["--results".as_ref(), out.join("results.csv").as_os_str()],
        &d.join("pred.json"),
    );
    // The same estimates (to float reordering: the pose model runs in other batches).
    let (a, b) = (rows(&saved), rows(&out.join("results.csv")));
    assert!(!a.is_empty());
    for (k, v) in &a {
        let w = b.get(k).unwrap_or_else(|| {
            panic!(
                "no estimate of {k:?} from predict: {}",
                std::fs::read_to_string(&dets).unwrap()
            )
        });
        for (x, y) in v.iter().zip(w) {
            assert!((x - y).abs() < 1e-2, "{k:?}: {v:?} vs {w:?}");
        }
    }
    for key in ["add_s_acc", "acc_5cm5deg", "n_gt"] {
        assert_eq!(
            reference["all"][key], got["all"][key],
            "{key}: {reference} vs {got}"
        );
    }

    // eval --checkpoint --detector is predict followed by scoring: the same scores.
    let via = scores(
        &data,
        &[
            "--checkpoint".as_ref(),
            dense.join("model.safetensors").as_os_str(),
            "--detector".as_ref(),
            det.as_os_str(),
        ],
        &d.join("via.json"),
    );
    assert_eq!(via["all"], got["all"], "{via} vs {got}");

    // --refine edges: the same estimates refined on the image (eval --refine's refinement,
    // kept to each detection's box); its time is the refine stage.
    let refined = d.join("pred_refined");
    let o = predict(
        &dense,
        &det,
        &[
            "--data".as_ref(),
            bare.as_os_str(),
            "--refine".as_ref(),
            "edges".as_ref(),
        ],
        &refined,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (plain, moved) = (
        rows(&out.join("results.csv")),
        rows(&refined.join("results.csv")),
    );
    assert_eq!(
        plain.keys().collect::<Vec<_>>(),
        moved.keys().collect::<Vec<_>>()
    );
    assert!(plain != moved, "the refinement moved no estimate");
    for f in lines(&refined.join("predictions.jsonl")) {
        let n = f["objects"].as_array().unwrap().len();
        let t = f["time"]["refine"].as_f64().unwrap();
        assert!(if n > 0 { t > 0.0 } else { t >= 0.0 }, "{f}");
    }
    refused(
        &predict(
            &dense,
            &det,
            &[
                "--data".as_ref(),
                bare.as_os_str(),
                "--refine-models".as_ref(),
                data.as_os_str(),
            ],
            &d.join("p_rm"),
        ),
        &["--refine-models", "--refine views"],
    );
    let (ra, ga) = (
        reference["all"]["mean_add_mm"].as_f64().unwrap(),
        got["all"]["mean_add_mm"].as_f64().unwrap(),
    );
    assert!((ra - ga).abs() < 1e-2, "{ra} vs {ga}");

    // One line per frame, its objects with R (a rotation, row-major) and t (metres) as in
    // results.csv (millimetres).
    let frames = lines(&out.join("predictions.jsonl"));
    assert_eq!(frames.len(), 8);
    let mut seen = 0;
    for f in &frames {
        assert!(f["frame"].as_str().unwrap().starts_with("000000/"), "{f}");
        assert!(f["time"]["total"].as_f64().unwrap() >= f["time"]["detect"].as_f64().unwrap());
        for o in f["objects"].as_array().unwrap() {
            let r: Vec<f64> = o["R"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            let t: Vec<f64> = o["t"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            for i in 0..3 {
                let n: f64 = (0..3).map(|j| r[3 * i + j] * r[3 * i + j]).sum();
                assert!((n - 1.0).abs() < 1e-4, "{o}");
            }
            let key = (
                0,
                f["image_id"].as_u64().unwrap() as u32,
                o["obj_id"].as_u64().unwrap() as u32,
            );
            let row = &b[&key];
            for j in 0..9 {
                assert!((row[j] - r[j]).abs() < 1e-6, "{o} vs {row:?}");
            }
            for j in 0..3 {
                assert!((row[9 + j] - 1000.0 * t[j]).abs() < 1e-3, "{o} vs {row:?}");
            }
            assert!(
                o["bbox"].as_array().unwrap().len() == 4 && o["score"].as_f64().unwrap() >= 0.05
            );
            seen += 1;
        }
    }
    assert_eq!(seen, b.len());

    // The same frames as photographs with a plain K: the same poses.
    let photos = d.join("photos");
    copy_dir(&data.join("train_pbr/000000/rgb"), &photos, &[]);
    let cam = json_file(&data.join("train_pbr/000000/scene_camera.json"));
    let camera = d.join("camera.json");
    std::fs::write(
        &camera,
        serde_json::json!({ "K": cam["0"]["cam_K"] }).to_string(),
    )
    .unwrap();
    let out2 = d.join("pred_photos");
    let pics = d.join("pictures");
    let o = predict(
        &dense,
        &det,
        &[
            "--images".as_ref(),
            photos.as_os_str(),
            "--camera".as_ref(),
            camera.as_os_str(),
            "--draw".as_ref(),
            pics.as_os_str(),
        ],
        &out2,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(rows(&out2.join("results.csv")), b);
    let names: Vec<String> = lines(&out2.join("predictions.jsonl"))
        .iter()
        .map(|f| f["frame"].as_str().unwrap().to_string())
        .collect();
    assert_eq!(names[0], "000000.png");
    // Names that are not numbers: ids by place in name order.
    let named = d.join("named");
    std::fs::create_dir(&named).unwrap();
    for (i, n) in ["b.png", "a.png"].iter().enumerate() {
        std::fs::copy(photos.join(format!("00000{i}.png")), named.join(n)).unwrap();
    }
    let o = predict(
        &dense,
        &det,
        &[
            "--images".as_ref(),
            named.as_os_str(),
            "--camera".as_ref(),
            camera.as_os_str(),
        ],
        &d.join("pred_named"),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let ids: Vec<(String, u64)> = lines(&d.join("pred_named/predictions.jsonl"))
        .iter()
        .map(|f| {
            (
                f["frame"].as_str().unwrap().to_string(),
                f["image_id"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(ids, [("a.png".to_string(), 0), ("b.png".to_string(), 1)]);

    // The same frames as a ROS 2 bag (bgr8 colour, CameraInfo): the same poses, the frames
    // named and stamped by their headers.
    let bag = d.join("run.mcap");
    scene_bag(&data.join("train_pbr/000000"), &bag);
    let out_bag = d.join("pred_bag");
    let o = predict(
        &dense,
        &det,
        &[
            "--bag".as_ref(),
            bag.as_os_str(),
            "--image-topic".as_ref(),
            "/cam/color/image_raw".as_ref(),
        ],
        &out_bag,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(rows(&out_bag.join("results.csv")), b);
    let bag_lines = lines(&out_bag.join("predictions.jsonl"));
    assert_eq!(bag_lines.len(), 8);
    assert_eq!(
        bag_lines[3]["frame"],
        "camera_color_optical_frame@100.300000000"
    );
    assert!((bag_lines[3]["stamp"].as_f64().unwrap() - 100.3).abs() < 1e-9);
    // A topic the bag does not have: named with the bag's topics.
    refused(
        &predict(
            &dense,
            &det,
            &[
                "--bag".as_ref(),
                bag.as_os_str(),
                "--image-topic".as_ref(),
                "/camera/color/image_raw".as_ref(),
            ],
            &d.join("p_bag_bad"),
        ),
        &[
            "run.mcap",
            "/camera/color/image_raw",
            "/cam/color/image_raw (sensor_msgs/msg/Image, 8)",
        ],
    );
    assert_eq!(std::fs::read_dir(&pics).unwrap().count(), 8);

    // A second run into the same folder is refused; --force replaces it.
    refused(
        &predict(&dense, &det, &["--data".as_ref(), bare.as_os_str()], &out),
        &["already holds predictions", "--force"],
    );
    // An output inside an input is refused before any work.
    refused(
        &predict(
            &dense,
            &det,
            &["--data".as_ref(), bare.as_os_str()],
            &bare.join("p"),
        ),
        &["--out", "inside"],
    );
    // A camera file that is not one, named.
    std::fs::write(d.join("bad.json"), r#"{"K": [1, 2, 3]}"#).unwrap();
    let bad = d.join("bad.json");
    refused(
        &predict(
            &dense,
            &det,
            &[
                "--images".as_ref(),
                photos.as_os_str(),
                "--camera".as_ref(),
                bad.as_os_str(),
            ],
            &d.join("p_bad"),
        ),
        &["bad.json", "nine finite numbers"],
    );
    assert!(!d.join("p_bad/predictions.jsonl").exists());

    // A depth model: TNet's centres from the detections' masks; no whole poses.
    let tnet = d.join("tnet");
    train(
        &[
            "train", "-q", "--model", "tnet", "--epochs", "1", "--batch", "4", "--width", "16",
        ],
        &data,
        &tnet,
    );
    refused(
        &predict(
            &tnet,
            &det,
            &[
                "--images".as_ref(),
                photos.as_os_str(),
                "--camera".as_ref(),
                camera.as_os_str(),
            ],
            &d.join("p_t0"),
        ),
        &["reads depth", "--depth"],
    );
    refused(
        &predict(
            &tnet,
            &det,
            &[
                "--data".as_ref(),
                bare.as_os_str(),
                "--refine".as_ref(),
                "edges".as_ref(),
            ],
            &d.join("p_t_ref"),
        ),
        &["refine the RGB models' estimates", "tnet model"],
    );
    refused(
        &run(synthgen()
            .args(["eval", "-q", "--data"])
            .arg(&data)
            .arg("--checkpoint")
            .arg(tnet.join("model.safetensors"))
            .arg("--detector")
            .arg(&det)),
        &["tnet checkpoint predicts the object centre", "--detections"],
    );
    let boxes_only = d.join("det_boxes");
    train(
        &[
            "detector",
            "train",
            "-q",
            "--input",
            "64x48",
            "--batch",
            "4",
            "--epochs",
            "1",
            "--no-masks",
        ],
        &data,
        &boxes_only,
    );
    refused(
        &predict(
            &tnet,
            &boxes_only,
            &["--data".as_ref(), bare.as_os_str()],
            &d.join("p_t1"),
        ),
        &["points from its mask", "boxes only"],
    );
    let out3 = d.join("pred_tnet");
    let o = predict(&tnet, &det, &["--data".as_ref(), bare.as_os_str()], &out3);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("the centre only"), "{}", stderr(&o));
    assert!(rows(&out3.join("results.csv")).is_empty());
    // Each detection has a centre, or none when its mask held too few depth pixels (this
    // one-epoch detector's masks may be empty), and the table counts those.
    let (mut centres, mut without) = (0, 0);
    for f in lines(&out3.join("predictions.jsonl")) {
        for o in f["objects"].as_array().unwrap() {
            assert!(o["R"].is_null(), "{o}");
            match o["t"].as_array() {
                Some(t) => {
                    assert!(t[2].as_f64().unwrap() > 0.05, "{o}");
                    centres += 1;
                }
                None => without += 1,
            }
        }
    }
    let table = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(centres + without > 0);
    // TNet on the bag's 32FC1 depth (metres, as the dataset's PNGs read): the same centres.
    let out4 = d.join("pred_tnet_bag");
    let o4 = predict(
        &tnet,
        &det,
        &[
            "--bag".as_ref(),
            bag.as_os_str(),
            "--image-topic".as_ref(),
            "/cam/color/image_raw".as_ref(),
            "--depth-topic".as_ref(),
            "/cam/depth".as_ref(),
        ],
        &out4,
    );
    assert!(o4.status.success(), "{}", stderr(&o4));
    let centres_of = |p: &Path| -> Vec<Value> {
        lines(p)
            .iter()
            .flat_map(|f| {
                f["objects"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|o| o["t"].clone())
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    assert_eq!(
        centres_of(&out4.join("predictions.jsonl")),
        centres_of(&out3.join("predictions.jsonl"))
    );
    assert!(
        table.contains(&format!("{without} detections without a pose")),
        "{table}"
    );

    // `synthgen ros` refuses before it joins a DDS domain (no network traffic in this test;
    // the node itself is tested against Cyclone DDS in a private network namespace:
    // python/tests/test_ros_node.py).
    let ros_with = |model: &Path, detector: &Path, extra: &[&std::ffi::OsStr]| {
        run(synthgen()
            .args(["ros", "--model"])
            .arg(model)
            .arg("--detector")
            .arg(detector)
            .args(extra))
    };
    let ros = |model: &Path, extra: &[&std::ffi::OsStr]| ros_with(model, &det, extra);
    refused(
        &ros(&tnet, &[]),
        &["tnet model reads depth", "--depth-topic"],
    );
    refused(
        &ros_with(
            &tnet,
            &boxes_only,
            &["--depth-topic".as_ref(), "/camera/depth".as_ref()],
        ),
        &["points from its mask", "boxes only"],
    );
    let taken = d.join("taken.mcap");
    std::fs::write(&taken, b"not ours").unwrap();
    refused(
        &ros(&dense, &["--record".as_ref(), taken.as_os_str()]),
        &["taken.mcap", "exists", "--force"],
    );
    assert_eq!(std::fs::read(&taken).unwrap(), b"not ours");
    let inside = dense.join("out.mcap");
    refused(
        &ros(&dense, &["--record".as_ref(), inside.as_os_str()]),
        &["--record", "inside"],
    );
    refused(
        &ros(&dense, &["--duration=-1".as_ref()]),
        &["--duration -1", "positive"],
    );
    refused(
        &run(synthgen()
            .env("ROS_DOMAIN_ID", "300")
            .args(["ros", "--model"])
            .arg(&dense)
            .arg("--detector")
            .arg(&det)),
        &["ROS_DOMAIN_ID=\"300\"", "0 to 232"],
    );
}
