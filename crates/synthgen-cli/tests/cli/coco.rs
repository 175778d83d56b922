//! `synthgen export coco`: our RLE decoded (by us, and by pycocotools) equals the mask_visib
//! PNGs.

use std::process::Command;

use serde_json::Value;
use synthgen_formats::bop::read_mask;
use synthgen_formats::coco::rle_decode;

use crate::common::{run, stderr, synthgen};
use crate::mix::render_tiny;

const PY_DECODE: &str = r#"
import json, sys
from pycocotools import mask as m
coco = json.load(open(sys.argv[1]))
for a in coco["annotations"]:
    seg = a["segmentation"]
    rle = m.frPyObjects(seg, seg["size"][0], seg["size"][1]) if isinstance(seg["counts"], list) else seg
    d = m.decode(rle)
    assert int(m.area(rle)) == a["area"], (a["id"], int(m.area(rle)), a["area"])
    open("%s/%d.raw" % (sys.argv[2], a["id"]), "wb").write(d.astype("uint8").tobytes(order="C"))
print("decoded", len(coco["annotations"]))
"#;

#[test]
fn coco_rle_round_trips_to_the_masks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "ds", 6, 9);
    for rle in ["uncompressed", "compressed"] {
        let o = run(synthgen()
            .current_dir(d)
            .args(["export", "coco", "ds", "--rle", rle]));
        assert!(o.status.success(), "{}", stderr(&o));
        let scene = d.join("ds/train_pbr/000000");
        let path = scene.join("scene_gt_coco.json");
        let coco: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        assert_eq!(coco["images"].as_array().unwrap().len(), 6);
        assert_eq!(coco["categories"][0]["id"], 1);
        assert_eq!(coco["images"][0]["file_name"], "rgb/000000.png");
        let anns = coco["annotations"].as_array().unwrap();
        assert!(!anns.is_empty());
        let info: Value =
            serde_json::from_slice(&std::fs::read(scene.join("scene_gt_info.json")).unwrap())
                .unwrap();
        for a in anns {
            let im = a["image_id"].as_u64().unwrap();
            let mask = read_mask(&scene.join(format!("mask_visib/{im:06}_000000.png"))).unwrap();
            let want: Vec<u8> = mask.data.iter().map(|&v| u8::from(v != 0)).collect();
            assert_eq!(
                a["area"].as_u64().unwrap() as usize,
                want.iter().filter(|&&v| v == 1).count()
            );
            assert_eq!(a["bbox"], info[im.to_string()][0]["bbox_visib"]);
            if rle == "uncompressed" {
                let counts: Vec<u32> = a["segmentation"]["counts"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|c| c.as_u64().unwrap() as u32)
                    .collect();
                assert_eq!(rle_decode(&counts, 80, 60), want);
            }
        }
    }

    // One merged file, and a split that does not exist.
    let o = run(synthgen()
        .current_dir(d)
        .args(["export", "coco", "ds", "--out", "coco/all.json"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let all: Value =
        serde_json::from_slice(&std::fs::read(d.join("coco/all.json")).unwrap()).unwrap();
    assert_eq!(
        all["images"][0]["file_name"],
        "../ds/train_pbr/000000/rgb/000000.png"
    );
    let o = run(synthgen()
        .current_dir(d)
        .args(["export", "coco", "ds", "--split", "test"]));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("no split \"test\""), "{}", stderr(&o));
}

#[test]
#[cfg_attr(
    not(has_pycocotools),
    ignore = "needs python3 with pycocotools: pip install pycocotools (probed when the crate was built)"
)]
fn coco_rle_decodes_in_pycocotools_to_the_masks() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "ds", 6, 9);
    for rle in ["uncompressed", "compressed"] {
        let o = run(synthgen()
            .current_dir(d)
            .args(["export", "coco", "ds", "--rle", rle]));
        assert!(o.status.success(), "{}", stderr(&o));
        let scene = d.join("ds/train_pbr/000000");
        let path = scene.join("scene_gt_coco.json");
        let coco: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let anns = coco["annotations"].as_array().unwrap();
        assert!(!anns.is_empty());
        let raw = d.join(format!("raw_{rle}"));
        std::fs::create_dir_all(&raw).unwrap();
        let o = run(Command::new("python3")
            .args(["-c", PY_DECODE])
            .arg(&path)
            .arg(&raw));
        assert!(o.status.success(), "{}", stderr(&o));
        for a in anns {
            let im = a["image_id"].as_u64().unwrap();
            let mask = read_mask(&scene.join(format!("mask_visib/{im:06}_000000.png"))).unwrap();
            let want: Vec<u8> = mask.data.iter().map(|&v| u8::from(v != 0)).collect();
            let got = std::fs::read(raw.join(format!("{}.raw", a["id"]))).unwrap();
            assert_eq!(got, want, "annotation {} ({rle})", a["id"]);
        }
    }
}
