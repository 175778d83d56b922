//! `synthgen stats` and `synthgen preview` end to end.

use serde_json::Value;

use crate::common::{run, stderr, synthgen};
use crate::mix::render_tiny;

#[test]
fn stats_table_json_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "ds", 12, 5);
    let o = run(synthgen().current_dir(d).args(["stats", "ds"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("frames     12 (train_pbr 12)"), "{text}");
    assert!(text.contains("visib_fract"), "{text}");
    assert!(
        text.contains("camera elevation (deg, above the world xy plane)"),
        "{text}"
    );

    let o = run(synthgen()
        .current_dir(d)
        .args(["stats", "ds", "--json", "--plot", "plots"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["frames"], 12);
    assert_eq!(v["objects"][0]["instances"], 12);
    let dist = &v["distance_m"];
    assert!(dist["min"].as_f64().unwrap() > 0.1, "{dist}");
    let hist: u64 = v["visib_fract"]["counts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_u64().unwrap())
        .sum();
    assert_eq!(hist, 12);
    for f in [
        "visib_fract.png",
        "distance_m.png",
        "elevation_deg.png",
        "instances_per_object.png",
    ] {
        assert!(d.join("plots").join(f).is_file(), "{f}");
    }
}

#[test]
fn stats_and_preview_name_the_broken_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "ds", 4, 5);
    let o = run(synthgen().current_dir(d).args([
        "preview",
        "ds",
        "--count",
        "4",
        "--out",
        "sheet.png",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(d.join("sheet.png")).unwrap();
    assert_eq!((img.width(), img.height()), (2 * 324 + 4, 2 * 244 + 4));

    std::fs::write(d.join("ds/train_pbr/000000/scene_gt_info.json"), "[1, 2").unwrap();
    let o = run(synthgen().current_dir(d).args(["stats", "ds"]));
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("malformed scene_gt_info.json")
            && e.contains("ds/train_pbr/000000/scene_gt_info.json"),
        "{e}"
    );

    std::fs::remove_file(d.join("ds/models/models_info.json")).unwrap();
    let o = run(synthgen().current_dir(d).args(["preview", "ds"]));
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("missing file: ") && stderr(&o).contains("models_info.json"),
        "{}",
        stderr(&o)
    );
}
