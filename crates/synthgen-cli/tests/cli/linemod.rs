//! The Linemod layout, `synthgen convert` and `synthgen validate` end to end, on tiny datasets
//! rendered here from two boxes.

use std::path::{Path, PathBuf};
use std::process::Command;

use synthgen_formats::bop::image::{read_depth_raw, read_mask, read_rgb};
use synthgen_formats::bop::BopDataset;

use crate::common::{run, stderr, synthgen};
use crate::render::write_box_ply;

/// Renders `frames` frames of two boxes (ids 1 and 2) into `out` with extra flags.
fn render(dir: &Path, out: &str, extra: &[&str]) -> PathBuf {
    let a = dir.join("obj_01.ply");
    let b = dir.join("obj_02.ply");
    write_box_ply(&a);
    write_box_ply(&b);
    let out = dir.join(out);
    let o = run(synthgen()
        .args(["-q", "render", "--objects"])
        .arg(&a)
        .arg(&b)
        .args([
            "--frames",
            "3",
            "--image-size",
            "160,120",
            "--camera-k",
            "150,150,80,60",
            "--distance-m",
            "0.3..0.45",
            "--out",
        ])
        .arg(&out)
        .args(extra));
    assert!(o.status.success(), "{}", stderr(&o));
    out
}

fn validate(dir: &Path, extra: &[&str]) -> (i32, String, String) {
    let o = run(synthgen().arg("validate").arg(dir).args(extra));
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        stderr(&o),
    )
}

fn convert(from: &Path, to: &Path, format: &str) {
    let o = run(synthgen()
        .args(["-q", "convert", "--to", format])
        .arg(from)
        .arg(to));
    assert!(o.status.success(), "{}", stderr(&o));
}

const PY_CHECK: &str = r#"
import sys, yaml, pathlib
root = pathlib.Path(sys.argv[1])
folders = sorted(p for p in (root / 'data').iterdir() if p.is_dir())
assert folders, 'no folders'
for d in folders:
    obj = int(d.name)
    gt = yaml.safe_load(open(d / 'gt.yml'))
    info = yaml.safe_load(open(d / 'info.yml'))
    assert set(gt) == set(info) and gt, d
    ids = [l.strip() for l in open(d / 'train.txt') if l.strip()]
    assert all(len(i) == 4 for i in ids), ids
    assert sorted(int(i) for i in ids) == sorted(gt), d
    for frame, entries in gt.items():
        assert isinstance(frame, int)
        # DenseFusion: the folder's object is entry 0 (and searched by obj_id for object 2).
        assert entries[0]['obj_id'] == obj, (d, frame)
        for e in entries:
            assert set(e) == {'cam_R_m2c', 'cam_t_m2c', 'obj_bb', 'obj_id'}, e
            assert len(e['cam_R_m2c']) == 9 and all(isinstance(v, float) for v in e['cam_R_m2c'])
            assert len(e['cam_t_m2c']) == 3 and all(isinstance(v, float) for v in e['cam_t_m2c'])
            assert len(e['obj_bb']) == 4 and all(isinstance(v, int) for v in e['obj_bb'])
        assert len(info[frame]['cam_K']) == 9 and info[frame]['depth_scale'] == 1.0
        assert (d / 'rgb' / ('%04d.png' % frame)).exists()
models = yaml.safe_load(open(root / 'models' / 'models_info.yml'))
for k, m in models.items():
    assert isinstance(k, int) and isinstance(m['diameter'], float) and 'size_z' in m
    assert (root / 'models' / ('obj_%02d.ply' % k)).exists()
print(len(folders))
"#;

#[test]
fn render_format_linemod_writes_what_pyyaml_and_densefusion_read() {
    let dir = tempfile::tempdir().unwrap();
    let out = render(dir.path(), "lm", &["--format", "linemod"]);
    for f in [
        "gt.yml",
        "info.yml",
        "train.txt",
        "test.txt",
        "mask/0000.png",
    ] {
        assert!(out.join("data/01").join(f).exists(), "{f}");
    }
    let gt = std::fs::read_to_string(out.join("data/01/gt.yml")).unwrap();
    assert!(gt.starts_with("0:\n- cam_R_m2c: ["), "{gt}");
    let depth = read_depth_raw(&out.join("data/01/depth/0000.png")).unwrap();
    let t_z: f64 = gt
        .split("cam_t_m2c: [")
        .nth(1)
        .unwrap()
        .split(']')
        .next()
        .unwrap()
        .split(", ")
        .nth(2)
        .unwrap()
        .parse()
        .unwrap();
    let mask = read_mask(&out.join("data/01/mask/0000.png")).unwrap();
    // Depth in millimetres (depth_scale 1.0) near the object's distance.
    let under: Vec<u16> = depth
        .data
        .iter()
        .zip(&mask.data)
        .filter(|(_, m)| **m > 0)
        .map(|(d, _)| *d)
        .collect();
    assert!(!under.is_empty());
    assert!(
        under.iter().all(|&d| (d as f64 - t_z).abs() < 60.0),
        "{t_z} {under:?}"
    );
}

#[test]
#[cfg_attr(
    not(has_pyyaml),
    ignore = "needs python3 with PyYAML: pip install pyyaml (probed when the crate was built)"
)]
fn render_format_linemod_loads_in_pyyaml_as_densefusion_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = render(dir.path(), "lm", &["--format", "linemod"]);
    let o = Command::new("python3")
        .args(["-c", PY_CHECK])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(String::from_utf8_lossy(&o.stdout).trim(), "2");
}

#[test]
fn validate_passes_on_what_render_writes_in_both_layouts() {
    let dir = tempfile::tempdir().unwrap();
    for (name, extra) in [("bop", &[][..]), ("lm", &["--format", "linemod"][..])] {
        let out = render(dir.path(), name, extra);
        let (code, stdout, err) = validate(&out, &[]);
        assert_eq!(code, 0, "{stdout}{err}");
        assert!(stdout.is_empty(), "{stdout}");
        assert!(err.contains("OK: "), "{err}");
        assert!(err.contains("no problems"), "{err}");
    }
    let (code, stdout, _) = validate(&dir.path().join("lm"), &["--json"]);
    assert_eq!(code, 0);
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["layout"], "linemod");
    assert_eq!(v["problems"].as_array().unwrap().len(), 0);
}

#[test]
fn bop_to_linemod_to_bop_keeps_poses_k_masks_and_depth() {
    let dir = tempfile::tempdir().unwrap();
    // depth_scale 1.0 so the Linemod depth (1 mm) holds the BOP depth exactly.
    let bop = render(dir.path(), "bop", &["--depth-scale", "1.0"]);
    let lm = dir.path().join("lm");
    let back = dir.path().join("back");
    convert(&bop, &lm, "linemod");
    convert(&lm, &back, "bop");
    for d in [&lm, &back] {
        let (code, stdout, err) = validate(d, &[]);
        assert_eq!(code, 0, "{stdout}{err}");
    }
    let a = BopDataset::open(&bop).unwrap();
    let b = BopDataset::open(&back).unwrap();
    assert_eq!(a.camera, b.camera);
    assert_eq!(a.models_info, b.models_info);
    let sa = a.read_scene("train_pbr", 0).unwrap();
    let sb = b.read_scene("train", 0).unwrap();
    assert_eq!(sa.camera.len(), 3);
    let info = sa.gt_info.as_ref().unwrap();
    // A frame where no object reaches visib_fract 0.1 has no Linemod folder to go to.
    let kept: Vec<u32> = sa
        .im_ids()
        .filter(|im| info[im].iter().any(|i| i.visib_fract >= 0.1))
        .collect();
    assert!(kept.len() >= 2, "{kept:?}");
    assert_eq!(kept, sb.im_ids().collect::<Vec<_>>());
    let mut masks_compared = 0;
    for im in kept {
        assert_eq!(sa.camera[&im].cam_k, sb.camera[&im].cam_k);
        // Linemod keeps no gt order: instances come back sorted by object id.
        let mut order: Vec<usize> = (0..sa.gt[&im].len()).collect();
        order.sort_by_key(|&i| sa.gt[&im][i].obj_id);
        let want: Vec<_> = order.iter().map(|&i| sa.gt[&im][i]).collect();
        assert_eq!(want, sb.gt[&im], "image {im}: poses differ");
        assert_eq!(
            read_depth_raw(&sa.depth_path(im)).unwrap(),
            read_depth_raw(&sb.depth_path(im)).unwrap()
        );
        assert_eq!(
            read_rgb(sa.rgb_path(im).unwrap()).unwrap(),
            read_rgb(sb.rgb_path(im).unwrap()).unwrap()
        );
        for (new_gt, &old_gt) in order.iter().enumerate() {
            if info[&im][old_gt].visib_fract < 0.1 {
                continue;
            }
            assert_eq!(
                read_mask(&sa.mask_visib_path(im, old_gt)).unwrap(),
                read_mask(&sb.mask_visib_path(im, new_gt)).unwrap(),
                "image {im}, gt {old_gt}"
            );
            masks_compared += 1;
        }
    }
    assert!(masks_compared >= 3, "{masks_compared}");
}

/// Replaces the first `[...]` after `key` in a text file.
fn replace_list_after(path: &Path, key: &str, with: &str) {
    let text = std::fs::read_to_string(path).unwrap();
    let at = text.find(key).unwrap() + key.len();
    let open = at + text[at..].find('[').unwrap();
    let close = open + text[open..].find(']').unwrap();
    let new = format!("{}{with}{}", &text[..open], &text[close + 1..]);
    std::fs::write(path, new).unwrap();
}

fn truncate(path: &Path) {
    let bytes = std::fs::read(path).unwrap();
    std::fs::write(path, &bytes[..bytes.len() / 2]).unwrap();
}

#[test]
fn validate_names_the_file_of_each_planted_linemod_problem() {
    let dir = tempfile::tempdir().unwrap();
    let lm = render(dir.path(), "lm", &["--format", "linemod"]);
    let d1 = lm.join("data/01");
    let d2 = lm.join("data/02");
    let ids: Vec<String> = std::fs::read_to_string(d1.join("train.txt"))
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    let rgb = format!("rgb/{}.png", ids[0]);
    let mask = format!("mask/{}.png", ids[ids.len() - 1]);
    truncate(&d1.join(&rgb));
    std::fs::remove_file(d1.join(&mask)).unwrap();
    replace_list_after(
        &d1.join("gt.yml"),
        "cam_R_m2c:",
        "[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5]",
    );
    let (code, stdout, err) = validate(&lm, &[]);
    assert_eq!(code, 1, "{stdout}{err}");
    let line = |needle: &str, file: &str| {
        stdout
            .lines()
            .find(|l| l.contains(needle))
            .unwrap_or_else(|| panic!("no {needle:?} in\n{stdout}"))
            .starts_with(&d1.join(file).display().to_string())
    };
    assert!(line("cannot decode image", &rgb), "{stdout}");
    assert!(line("missing file", &mask), "{stdout}");
    assert!(line("rotation determinant", "gt.yml"), "{stdout}");
    assert!(stdout.contains("tolerance 0.02"), "{stdout}");
    assert!(err.contains("error: 3 problems"), "{err}");

    // A gt.yml with a missing key: the parse error names the file, the key and the line.
    let text = std::fs::read_to_string(d2.join("gt.yml")).unwrap();
    let first_bb = text.find("  obj_bb:").unwrap();
    let end = first_bb + text[first_bb..].find('\n').unwrap() + 1;
    std::fs::write(
        d2.join("gt.yml"),
        format!("{}{}", &text[..first_bb], &text[end..]),
    )
    .unwrap();
    let (code, stdout, _) = validate(&lm, &["--max-problems", "1"]);
    assert_eq!(code, 1);
    assert!(stdout.contains("... and 3 more"), "{stdout}");
    let (_, stdout, _) = validate(&lm, &[]);
    let bad = stdout
        .lines()
        .find(|l| l.starts_with(&d2.join("gt.yml").display().to_string()))
        .unwrap_or_else(|| panic!("{stdout}"));
    assert!(bad.contains("missing field `obj_bb`"), "{bad}");
    assert!(bad.contains("line"), "{bad}");
}

#[test]
fn validate_names_the_file_of_each_planted_bop_problem() {
    let dir = tempfile::tempdir().unwrap();
    let bop = render(dir.path(), "bop", &[]);
    let scene = bop.join("train_pbr/000000");
    // px_count_visib that disagrees with the mask.
    let info_path = scene.join("scene_gt_info.json");
    let text = std::fs::read_to_string(&info_path).unwrap();
    let at = text.find("\"px_count_visib\": ").unwrap() + "\"px_count_visib\": ".len();
    let end = at + text[at..].find(',').unwrap();
    std::fs::write(
        &info_path,
        format!("{}{}{}", &text[..at], "1", &text[end..]),
    )
    .unwrap();
    // Depth far behind the objects.
    let depth_path = scene.join("depth/000001.png");
    let d = read_depth_raw(&depth_path).unwrap();
    let far: Vec<u16> = d
        .data
        .iter()
        .map(|&v| if v > 0 { 60000 } else { 0 })
        .collect();
    let png = synthgen_formats::bop::image::encode_gray16_png(
        &far,
        d.width,
        d.height,
        Default::default(),
        &depth_path,
    )
    .unwrap();
    std::fs::write(&depth_path, png).unwrap();
    std::fs::remove_file(scene.join("mask_visib/000002_000001.png")).unwrap();
    truncate(&scene.join("rgb/000002.png"));
    replace_list_after(
        &scene.join("scene_gt.json"),
        "cam_R_m2c",
        "[2.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]",
    );

    let (code, stdout, _) = validate(&bop, &["--json"]);
    assert_eq!(code, 1);
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let problems: Vec<(String, String)> = v["problems"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["path"].as_str().unwrap().to_string(),
                p["message"].as_str().unwrap().to_string(),
            )
        })
        .collect();
    let has = |file: &str, needle: &str| {
        let f = scene.join(file).display().to_string();
        problems.iter().any(|(p, m)| *p == f && m.contains(needle))
    };
    assert!(
        has(
            "scene_gt_info.json",
            "px_count_visib is 1 but mask_visib/000000_000000.png has"
        ),
        "{problems:?}"
    );
    assert!(
        has("depth/000001.png", "outside the object's depth range"),
        "{problems:?}"
    );
    assert!(
        has("mask_visib/000002_000001.png", "missing file"),
        "{problems:?}"
    );
    assert!(has("rgb/000002.png", "cannot decode image"), "{problems:?}");
    assert!(
        has("scene_gt.json", "cam_R_m2c of image 0, gt 0"),
        "{problems:?}"
    );
}

#[test]
fn convert_and_validate_refuse_what_they_cannot_read() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(synthgen().arg("validate").arg(dir.path()));
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("cannot tell the layout"),
        "{}",
        stderr(&o)
    );
    assert!(
        stderr(&o).contains("hint: pass --format bop"),
        "{}",
        stderr(&o)
    );
    let bop = render(dir.path(), "bop", &[]);
    let o = run(synthgen()
        .args(["convert", "--to", "bop"])
        .arg(&bop)
        .arg(dir.path().join("x")));
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("is already a BOP dataset"),
        "{}",
        stderr(&o)
    );
    let o = run(synthgen()
        .args(["convert", "--to", "linemod"])
        .arg(&bop)
        .arg(&bop));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("is the input"), "{}", stderr(&o));
}
