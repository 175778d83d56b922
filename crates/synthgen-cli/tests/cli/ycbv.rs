//! The YCB-Video layout end to end on the real frames in `../shared/data/ycbv_real`: every
//! reading command, conversion both ways, our masks against the dataset authors' labels,
//! `render --format ycbv` against scipy, and bad input.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use synthgen_formats::bop::image::{read_depth_raw, read_label};
use synthgen_formats::bop::BopDataset;
use synthgen_formats::ycbv::read_meta;

use crate::common::{run, stderr, synthgen, ycbv_real, ycbv_small_copy};

fn ok(cmd: &mut Command) -> String {
    let o = run(cmd);
    assert!(o.status.success(), "{}", stderr(&o));
    format!("{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o))
}

fn metas(root: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for scene in std::fs::read_dir(root.join("data")).unwrap().flatten() {
        for f in std::fs::read_dir(scene.path()).unwrap().flatten() {
            if f.file_name().to_string_lossy().ends_with("-meta.mat") {
                out.push(f.path());
            }
        }
    }
    out.sort();
    out
}

/// YCB-Video → BOP (validates) → YCB-Video keeps poses to 1e-6 m, labels, depth and colour.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn real_ycbv_converts_to_bop_validates_and_comes_back_unchanged() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let (bop, back) = (dir.path().join("bop"), dir.path().join("back"));
    let out = ok(synthgen()
        .args(["convert", "--to", "bop"])
        .arg(&real)
        .arg(&bop));
    assert!(
        out.contains("Converted 60 frames (260 object instances, 12 models)"),
        "{out}"
    );
    assert!(
        out.contains("texture not found, using the Kd colour"),
        "{out}"
    );
    let out = ok(synthgen().arg("validate").arg(&bop));
    assert!(out.contains("60 frames, 260 object instances"), "{out}");
    // BOP's ids: scene = video, image = frame, obj_id = class index.
    let gt: Value =
        serde_json::from_slice(&std::fs::read(bop.join("train/000001/scene_gt.json")).unwrap())
            .unwrap();
    let ids: Vec<u64> = gt["5"]
        .as_array()
        .unwrap()
        .iter()
        .map(|g| g["obj_id"].as_u64().unwrap())
        .collect();
    assert_eq!(ids, [1, 2, 3, 5]);

    ok(synthgen()
        .args(["convert", "--to", "ycbv"])
        .arg(&bop)
        .arg(&back));
    ok(synthgen().arg("validate").arg(&back));
    assert_eq!(
        std::fs::read_to_string(back.join("classes.txt")).unwrap(),
        std::fs::read_to_string(real.join("classes.txt")).unwrap()
    );
    let (a_metas, b_metas) = (metas(&real), metas(&back));
    assert_eq!(a_metas.len(), 60);
    assert_eq!(b_metas.len(), 60);
    for (a, b) in a_metas.iter().zip(&b_metas) {
        let (ma, mb) = (read_meta(a, None).unwrap(), read_meta(b, None).unwrap());
        assert_eq!(ma.cls_indexes, mb.cls_indexes, "{}", b.display());
        for (pa, pb) in ma.poses.iter().zip(&mb.poses) {
            assert_eq!(pa.r_row_major, pb.r_row_major);
            for (x, y) in pa.t_m.iter().zip(&pb.t_m) {
                assert!((x - y).abs() < 1e-6, "{}", b.display());
            }
        }
        assert_eq!(ma.intrinsic_matrix, mb.intrinsic_matrix);
        assert_eq!(ma.factor_depth, mb.factor_depth);
        let file =
            |m: &Path, s: &str| PathBuf::from(m.display().to_string().replace("-meta.mat", s));
        assert_eq!(
            read_label(&file(a, "-label.png")).unwrap(),
            read_label(&file(b, "-label.png")).unwrap(),
            "{}",
            b.display()
        );
        assert_eq!(
            read_depth_raw(&file(a, "-depth.png")).unwrap(),
            read_depth_raw(&file(b, "-depth.png")).unwrap()
        );
    }
}

/// Our visible masks (bop19 from the real depth) and our render of the annotated models
/// against YCB-Video's own label.png, per scene and per object (the figures in
/// docs/real_data.md).
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn computed_masks_agree_with_the_ycbv_labels() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("iou.json");
    let out = ok(synthgen()
        .args(["annotate", "--compare", "--report"])
        .arg(&report)
        .arg("--overlay")
        .arg(dir.path().join("ov"))
        .arg(&real));
    println!("{out}");
    let r: Value = serde_json::from_slice(&std::fs::read(&report).unwrap()).unwrap();
    let all = &r["all"];
    assert_eq!(all["n"], 260);
    let f = |v: &Value| v.as_f64().unwrap();
    // Measured: bop19 median 0.994, p10 0.942; the render alone 0.998 and 0.996.
    assert!(f(&all["median_iou"]) > 0.98, "{all}");
    assert!(f(&all["p10_iou"]) > 0.9, "{all}");
    assert!(f(&all["median_iou_rendered"]) > 0.99, "{all}");
    assert!(f(&all["p10_iou_rendered"]) > 0.98, "{all}");
    assert_eq!(r["scenes"].as_object().unwrap().len(), 3);
    assert_eq!(r["objects"].as_object().unwrap().len(), 12);
    for (k, s) in r["objects"].as_object().unwrap() {
        assert!(f(&s["median_iou"]) > 0.85, "object {k}: {s}");
    }
    assert_eq!(
        std::fs::read_dir(dir.path().join("ov")).unwrap().count(),
        12
    );
    // annotate without --compare writes into BOP datasets only.
    let o = run(synthgen().arg("annotate").arg(&real));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("convert --to bop"), "{}", stderr(&o));
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn reading_commands_take_the_ycbv_layout() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = ok(synthgen().arg("validate").arg(&real));
    assert!(out.contains("OK: YCB-Video dataset"), "{out}");
    let out = ok(synthgen().arg("stats").arg(&real));
    assert!(
        out.contains("frames     60 (train 60)") && out.contains("in-plane rotation"),
        "{out}"
    );
    ok(synthgen()
        .arg("preview")
        .arg(&real)
        .args(["--count", "3", "--out"])
        .arg(d.join("sheet.png")));
    assert!(d.join("sheet.png").is_file());
    // A synthetic set of the same objects beside the real frames.
    let models = real.join("models");
    ok(synthgen()
        .args([
            "render",
            "-q",
            "--camera",
            "ycbv",
            "--frames",
            "40",
            "--objects",
        ])
        .arg(models.join("002_master_chef_can/textured_simple.obj"))
        .arg(models.join("003_cracker_box/textured_simple.obj"))
        .arg("--out")
        .arg(d.join("synth")));
    let out = ok(synthgen()
        .arg("stats")
        .arg(&real)
        .arg(d.join("synth"))
        .arg("--plot")
        .arg(d.join("plots")));
    assert!(out.contains("[1]") && out.contains("[2]"), "{out}");
    assert!(d.join("plots/inplane_deg.png").is_file());
    let json = ok(synthgen()
        .arg("stats")
        .arg(&real)
        .arg(d.join("synth"))
        .arg("--json")
        .arg("-q"));
    let v: Value = serde_json::from_str(&json).unwrap();
    assert_eq!(v.as_array().unwrap().len(), 2);
    // The rendered objects got YCB-Video's class indexes, so they mix with the real frames.
    assert!(d.join("synth/models/obj_000002.ply").is_file());
    ok(synthgen()
        .arg("mix")
        .arg("--real")
        .arg(&real)
        .arg("--synth")
        .arg(d.join("synth"))
        .args([
            "--real-count",
            "30",
            "--synth-count",
            "20",
            "--test-count",
            "10",
            "--out",
        ])
        .arg(d.join("mix")));
    // The real frames' mask/ and scene_gt_info were computed: the mix is complete BOP.
    let out = ok(synthgen().arg("validate").arg(d.join("mix")));
    assert!(out.contains("OK: BOP dataset"), "{out}");
    assert!(d.join("mix/models/obj_000021.ply").is_file());
    let out = ok(synthgen().arg("stats").arg(d.join("mix")));
    assert!(
        !out.contains("  -\n"),
        "every object has a mean visib_fract: {out}"
    );
    // experiment mix converts the YCB-Video set to BOP once and mixes it with the rendered one.
    let out = ok(synthgen()
        .args([
            "experiment",
            "mix",
            "--quick",
            "--ratios",
            "30/0,0/30",
            "--epochs",
            "1",
        ])
        .args(["--test-count", "10", "--real"])
        .arg(&real)
        .arg("--synth")
        .arg(d.join("synth"))
        .arg("--out")
        .arg(d.join("exp")));
    assert!(
        out.contains("the real set is not in the BOP layout"),
        "{out}"
    );
    assert!(d
        .join("exp/sources/real_bop/train/000002/scene_gt_info.json")
        .is_file());
    assert!(d.join("exp/table.csv").is_file());
    let o = crate::train::train(&real, &d.join("run"), "1", &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = ok(synthgen()
        .args(["eval", "--checkpoint"])
        .arg(d.join("run/model.safetensors"))
        .arg("--data")
        .arg(&real));
    assert!(out.contains("centre"), "{out}");
}

/// `render --format ycbv` of the mug and the banana (3 frames) into `out`.
fn render_ycbv_mug_and_banana(real: &Path, out: &Path) {
    let models = real.join("models");
    ok(synthgen()
        .args([
            "render",
            "-q",
            "--format",
            "ycbv",
            "--camera",
            "ycbv",
            "--frames",
            "3",
            "--objects",
        ])
        .arg(models.join("025_mug/textured_simple.obj"))
        .arg(models.join("011_banana/textured_simple.obj"))
        .arg("--out")
        .arg(out));
}

/// `render --format ycbv` validates, names its classes as YCB-Video does, and the YCB models
/// (MTL `Tr 1.000000`) are opaque.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn rendered_ycbv_has_the_real_layout_and_opaque_models() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ycbv");
    render_ycbv_mug_and_banana(&real, &out);
    ok(synthgen().arg("validate").arg(&out));
    let classes = std::fs::read_to_string(out.join("classes.txt")).unwrap();
    assert_eq!(classes.lines().nth(13), Some("025_mug"));
    assert!(out.join("models/025_mug/points.xyz").is_file());
    let meta = metas(&out);
    assert_eq!(meta.len(), 3);
    for m in &meta {
        let label = read_label(&PathBuf::from(
            m.display().to_string().replace("-meta.mat", "-label.png"),
        ))
        .unwrap();
        let mug = label.data.iter().filter(|&&v| v == 14).count();
        assert!(
            mug > 500,
            "the mug must be visible: {mug} label pixels in {}",
            m.display()
        );
    }
}

/// `render --format ycbv` writes -meta.mat files that scipy.io.loadmat reads with the keys,
/// shapes and dtypes of YCB-Video's own.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
#[cfg_attr(
    not(has_scipy),
    ignore = "needs python3 with scipy: pip install scipy (probed when the crate was built)"
)]
fn rendered_ycbv_meta_loads_in_scipy_like_the_real_files() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ycbv");
    render_ycbv_mug_and_banana(&real, &out);
    let meta = metas(&out);
    let script = r#"
import sys, scipy.io as sio
a = sio.loadmat(sys.argv[1]); b = sio.loadmat(sys.argv[2])
ka = sorted(k for k in a if not k.startswith('__')); kb = sorted(k for k in b if not k.startswith('__'))
assert ka == kb, (ka, kb)
for k in ka:
    sa, sb = a[k].shape, b[k].shape
    n = len(b['cls_indexes'])
    if k in ('poses',): sa, sb = sa[:2], sb[:2]
    if k in ('cls_indexes', 'center'): sa, sb = sa[1:], sb[1:]
    assert sa == sb and a[k].dtype == b[k].dtype, (k, a[k].shape, b[k].shape, a[k].dtype, b[k].dtype)
assert b['poses'].shape[2] == b['cls_indexes'].shape[0] == 2 and b['factor_depth'][0, 0] == 10000
print('scipy ok', ka)
"#;
    let o = Command::new("python3")
        .args(["-c", script])
        .arg(real.join("data/0000/000001-meta.mat"))
        .arg(&meta[0])
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
}

/// Each kind of broken YCB-Video file: `convert` exits 1 naming the file and writes nothing;
/// `validate` names it too.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn broken_ycbv_files_are_named_and_nothing_is_written() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    type Break = fn(&Path) -> PathBuf;
    let cases: [(&str, Break, &str); 4] = [
        (
            "truncated mat",
            |d| {
                let p = d.join("data/0000/000002-meta.mat");
                let b = std::fs::read(&p).unwrap();
                std::fs::write(&p, &b[..b.len() / 3]).unwrap();
                p
            },
            "truncated",
        ),
        (
            "no poses",
            |d| {
                use synthgen_mat::{read_mat, write_mat};
                let p = d.join("data/0000/000002-meta.mat");
                let mut vars = read_mat(std::fs::File::open(&p).unwrap(), None).unwrap();
                vars.remove("poses");
                let list: Vec<(&str, &_)> = vars.iter().map(|(k, v)| (k.as_str(), v)).collect();
                let mut bytes = Vec::new();
                write_mat(&mut bytes, &list, true).unwrap();
                std::fs::write(&p, bytes).unwrap();
                p
            },
            "no variable 'poses'",
        ),
        (
            "class outside classes.txt",
            |d| {
                let p = d.join("classes.txt");
                let text = std::fs::read_to_string(&p).unwrap();
                let first: Vec<&str> = text.lines().take(20).collect();
                std::fs::write(&p, first.join("\n")).unwrap();
                d.join("data/0000/000001-meta.mat")
            },
            "class index 21 is outside classes.txt (20 classes)",
        ),
        (
            "depth of the wrong size",
            |d| {
                let p = d.join("data/0000/000002-depth.png");
                let png = synthgen_formats::bop::image::encode_gray16_png(
                    &vec![1000u16; 320 * 240],
                    320,
                    240,
                    synthgen_formats::bop::PngCompression::Fast,
                    &p,
                )
                .unwrap();
                std::fs::write(&p, png).unwrap();
                p
            },
            "is 320x240",
        ),
    ];
    for (k, (what, breaks, message)) in cases.into_iter().enumerate() {
        let ds = dir.path().join(format!("case{k}"));
        ycbv_small_copy(&real, &ds);
        let bad = breaks(&ds);
        let out = dir.path().join(format!("out{k}"));
        let o = run(synthgen()
            .args(["convert", "--to", "bop"])
            .arg(&ds)
            .arg(&out));
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{what}: {err}");
        assert!(
            err.contains(message) && err.contains(&bad.display().to_string()),
            "{what}: {err}"
        );
        assert!(
            !out.exists(),
            "{what}: a failed convert left {}",
            out.display()
        );
        let o = run(synthgen().arg("validate").arg(&ds));
        let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
        assert_eq!(o.status.code(), Some(1), "{what}: {stdout}");
        assert!(
            stdout.contains(&bad.display().to_string()),
            "{what}: {stdout}"
        );
    }
}

/// The GT of a BOP dataset's `split` as a results CSV, every rotation turned by `deg` about
/// the model's x axis (R · Rx).
fn turned_gt(data: &Path, split: &str, deg: f64) -> String {
    let (s, c) = deg.to_radians().sin_cos();
    let ds = BopDataset::open(data).unwrap();
    let mut csv = String::from("scene_id,im_id,obj_id,score,R,t,time\n");
    for scene_id in ds.scene_ids(split).unwrap() {
        let scene = ds.read_scene(split, scene_id).unwrap();
        for (im, gts) in &scene.gt {
            for g in gts {
                let r = g.cam_r_m2c;
                let rx = [1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c];
                let m: Vec<String> = (0..9)
                    .map(|k| {
                        let (i, j) = (k / 3, k % 3);
                        (0..3)
                            .map(|l| r[i * 3 + l] * rx[l * 3 + j])
                            .sum::<f64>()
                            .to_string()
                    })
                    .collect();
                let t = g.cam_t_m2c;
                csv += &format!(
                    "{scene_id},{im},{},1.0,{},{} {} {},-1\n",
                    g.obj_id,
                    m.join(" "),
                    t[0],
                    t[1],
                    t[2]
                );
            }
        }
    }
    csv
}

/// Regression: `eval` read YCB-Video's models (metres) as millimetres, so its ADD errors on a
/// YCB-Video folder were 1000x too small and every estimate within 10% of the diameter.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn eval_reads_ycbv_models_in_metres() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let bop = dir.path().join("bop");
    let o = run(synthgen()
        .args(["convert", "-q", "--to", "bop"])
        .arg(&real)
        .arg(&bop));
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = dir.path().join("turned.csv");
    std::fs::write(&csv, turned_gt(&bop, "train", 10.0)).unwrap();
    let score = |data: &Path, name: &str| {
        let json = dir.path().join(name);
        let o = run(synthgen()
            .args(["eval", "-q", "--results"])
            .arg(&csv)
            .arg("--data")
            .arg(data)
            .args([
                "--split",
                "train",
                "--min-visib-fract",
                "0",
                "--bop",
                "--json",
            ])
            .arg(&json));
        assert!(o.status.success(), "{}", stderr(&o));
        let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let bop = v.as_object_mut().unwrap().remove("bop").unwrap();
        (v, bop)
    };
    let ((native, native_bop), (converted, converted_bop)) =
        (score(&real, "native.json"), score(&bop, "bop.json"));
    // Regression (issue 29): BOP's MSSD and MSPD read the YCB-Video models' metres as
    // millimetres too (every turned estimate within every threshold).
    for e in ["mssd", "mspd"] {
        let (a, b) = (
            native_bop[e]["mean_recall"].as_f64().unwrap(),
            converted_bop[e]["mean_recall"].as_f64().unwrap(),
        );
        assert!((a - b).abs() < 1e-9, "AR_{e}: {a} native vs {b} converted");
        assert!(a < 0.95, "AR_{e} {a}: 10° turns must miss some thresholds");
    }
    // 10° about x moves the mustard bottle's points by centimetres.
    let mustard = native["5"]["mean_add_mm"].as_f64().unwrap();
    assert!(mustard > 5.0, "mustard ADD {mustard} mm");
    for (id, v) in native.as_object().unwrap() {
        let (a, b) = (
            v["mean_add_mm"].as_f64().unwrap(),
            converted[id]["mean_add_mm"].as_f64().unwrap(),
        );
        assert!(
            (a - b).abs() <= 1e-3 * b.max(1.0),
            "object {id}: {a} vs {b} mm"
        );
        assert_eq!(v["add_s_acc"], converted[id]["add_s_acc"], "object {id}");
    }
}

/// Issue 26: `convert --to ycbv --classes F` with one name on two lines wrote both meshes into
/// one models/<name>/ (the second overwrote the first) and `validate` said OK.
#[test]
fn duplicate_class_names_are_refused_before_anything_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    crate::render::write_box_ply(&d.join("a.ply"));
    std::fs::copy(d.join("a.ply"), d.join("b.ply")).unwrap();
    let o = run(synthgen()
        .current_dir(d)
        .args([
            "render",
            "-q",
            "--objects",
            "a.ply",
            "b.ply",
            "--units",
            "m",
        ])
        .args(["--image-size", "80,60", "--camera-k", "80,80,40,30"])
        .args(["--frames", "2", "--out", "bop"]));
    assert!(o.status.success(), "{}", stderr(&o));
    for (list, words) in [
        (
            "box\nbox\n",
            &["dup.txt", "\"box\"", "line 2", "repeats line 1"][..],
        ),
        ("box\n..\n", &["dup.txt", "line 2", "bad class name"][..]),
    ] {
        std::fs::write(d.join("dup.txt"), list).unwrap();
        let o = run(synthgen().current_dir(d).args([
            "convert",
            "--to",
            "ycbv",
            "bop",
            "y",
            "--classes",
            "dup.txt",
        ]));
        crate::common::refused(&o, words);
        assert!(!d.join("y").exists(), "nothing written");
    }
    // A YCB-Video folder whose classes.txt repeats a name is a problem for validate.
    std::fs::write(d.join("ok.txt"), "box_a\nbox_b\n").unwrap();
    let o = run(synthgen().current_dir(d).args([
        "convert",
        "--to",
        "ycbv",
        "bop",
        "y",
        "--classes",
        "ok.txt",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(d.join("y/models/box_a").is_dir() && d.join("y/models/box_b").is_dir());
    std::fs::write(d.join("y/classes.txt"), "box_a\nbox_a\n").unwrap();
    let o = run(synthgen().current_dir(d).args(["validate", "y"]));
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let all = format!("{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    assert!(all.contains("repeats line 1"), "{all}");
}

/// Issue 26: two mugs in one frame both got the whole label of class 14 as their visible mask,
/// silently. validate warns; readers give them no visible mask; `convert --to bop` splits the
/// label along the render at the GT poses.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn two_instances_of_one_class_are_warned_about_and_split_by_the_render() {
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let ds = dir.path().join("ycbv");
    ycbv_small_copy(&real, &ds);
    let p = ds.join("data/0000/000001-meta.mat");
    let mut m = read_meta(&p, None).unwrap();
    let i = m.cls_indexes.iter().position(|&c| c == 14).unwrap();
    let mut twin = m.poses[i];
    twin.t_m[0] += 0.15; // a second mug, 15 cm aside
    m.cls_indexes.push(14);
    m.poses.push(twin);
    if let Some(c) = &mut m.center {
        let ci = c[i];
        c.push(ci);
    }
    let vertmap = vec![0f32; 640 * 480 * 3];
    let bytes = synthgen_formats::ycbv::encode_meta(&m, &vertmap, 640, 480, &p).unwrap();
    std::fs::write(&p, bytes).unwrap();
    let o = run(synthgen().arg("validate").arg(&ds));
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("two or more instances of one class")
            && e.contains("data/0000/000001 (class 14 x2)"),
        "{e}"
    );
    let bop = dir.path().join("bop");
    let o = run(synthgen()
        .args(["convert", "--to", "bop"])
        .arg(&ds)
        .arg(&bop));
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(e.contains("split along the render at the GT poses"), "{e}");
    let px = |g: usize| {
        synthgen_formats::bop::read_mask(
            &bop.join(format!("train/000000/mask_visib/000001_{g:06}.png")),
        )
        .unwrap()
        .data
        .iter()
        .filter(|&&v| v > 0)
        .count()
    };
    let (mug, twin) = (px(i), px(3));
    assert!(mug > 500 && twin * 10 < mug, "mug {mug} px, twin {twin} px");
}

/// Issue 26: label values that are no class of the frame, images without a -meta.mat and
/// frames in no image list were skipped without a word; validate named only the first stray
/// value.
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn frames_and_label_values_left_out_are_counted_and_named() {
    use synthgen_formats::bop::image::encode_gray8_png;
    use synthgen_formats::bop::PngCompression;
    let real = ycbv_real();
    let dir = tempfile::tempdir().unwrap();
    let ds = dir.path().join("ycbv");
    ycbv_small_copy(&real, &ds);
    let lp = ds.join("data/0000/000001-label.png");
    let mut l = read_label(&lp).unwrap();
    l.data[..200].fill(3);
    l.data[640 * 479..].fill(7); // classes 3 and 7 are not in this frame (8, 14, 21)
    let b: Vec<u8> = l.data.iter().map(|&v| v as u8).collect();
    std::fs::write(
        &lp,
        encode_gray8_png(&b, 640, 480, PngCompression::Fast, &lp).unwrap(),
    )
    .unwrap();
    for s in ["color.png", "depth.png", "label.png"] {
        // Frame 3's images without its -meta.mat.
        std::fs::copy(
            real.join(format!("data/0000/000003-{s}")),
            ds.join(format!("data/0000/000003-{s}")),
        )
        .unwrap();
    }
    let o = run(synthgen().arg("validate").arg(&ds));
    let (out, err) = (String::from_utf8_lossy(&o.stdout).into_owned(), stderr(&o));
    assert_eq!(o.status.code(), Some(1), "{out}{err}");
    assert!(out.contains("label values 3 (200 px), 7 (640 px)"), "{out}");
    assert!(
        err.contains("1 frames have colour, depth or label images but no -meta.mat")
            && err.contains("data/0000/000003"),
        "{err}"
    );
    std::fs::create_dir_all(ds.join("image_sets")).unwrap();
    std::fs::write(ds.join("image_sets/train.txt"), "0000/000001\n").unwrap();
    let o = run(synthgen()
        .args(["convert", "--to", "bop"])
        .arg(&ds)
        .arg(dir.path().join("bop")));
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    for w in [
        "but no -meta.mat",
        "data/0000/000003",
        "in no image_sets/*.txt list",
        "data/0000/000002",
        "values 3 (200 px), 7 (640 px)",
    ] {
        assert!(err.contains(w), "{w:?} not in: {err}");
    }
}
