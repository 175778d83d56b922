//! `synthgen experiment mix --quick --real-proxy` end to end on a tiny box mesh: the whole
//! pipeline (render both sets, 7 × mix + train + evaluate, table, plot) and its resume.

use std::path::Path;
use std::time::SystemTime;

use crate::common::{run, stderr, synthgen};
use crate::render::write_box_ply;

fn experiment(mesh: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    run(synthgen()
        .args(["experiment", "mix", "--real-proxy", "--quick", "--objects"])
        .arg(mesh)
        .args(["--seed", "5", "--out"])
        .arg(out)
        .args(extra))
}

fn row_jsons(out: &Path) -> Vec<(String, serde_json::Value, SystemTime)> {
    let mut rows: Vec<_> = std::fs::read_dir(out.join("rows"))
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path().join("row.json");
            let v: serde_json::Value =
                serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
            let mtime = std::fs::metadata(&p).unwrap().modified().unwrap();
            (p.display().to_string(), v, mtime)
        })
        .collect();
    rows.sort_by(|a, b| a.0.cmp(&b.0));
    rows
}

#[test]
fn quick_proxy_experiment_has_seven_rows_one_test_split_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let out = dir.path().join("mix");
    let o = experiment(&mesh, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(stdout.contains("The real side is a PROXY"), "{stdout}");
    assert!(
        stderr(&o).contains("7 computed, 0 skipped"),
        "{}",
        stderr(&o)
    );

    // table.csv: the 7 compositions of 42 frames, finite errors.
    let csv = std::fs::read_to_string(out.join("table.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(lines.len(), 7, "{csv}");
    let counts: Vec<(usize, usize)> = lines
        .iter()
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].parse().unwrap(), f[1].parse().unwrap())
        })
        .collect();
    assert_eq!(
        counts,
        [
            (42, 0),
            (35, 7),
            (28, 14),
            (21, 21),
            (14, 28),
            (7, 35),
            (0, 42)
        ]
    );
    for l in &lines {
        let f: Vec<&str> = l.split(',').collect();
        for col in [4, 6] {
            let v: f64 = f[col].parse().unwrap();
            assert!(v.is_finite() && v >= 0.0, "{l}");
        }
        assert_eq!(f[13], "true", "real_is_proxy: {l}");
    }
    let md = std::fs::read_to_string(out.join("table.md")).unwrap();
    assert!(
        md.contains("PROXY") && md.matches("\n| ").count() == 8,
        "{md}"
    );
    assert!(image::open(out.join("plot.png")).is_ok());

    // Every row was tested on the same real frames (the mixes' provenance, hashed per row).
    let rows = row_jsons(&out);
    assert_eq!(rows.len(), 7);
    let hash = &rows[0].1["test_split_hash"];
    for (name, v, _) in &rows {
        assert_eq!(&v["test_split_hash"], hash, "{name}");
        assert_eq!(v["test_frames"], 8, "{name}");
        assert!(v["test"]["centre_error_cm"].as_f64().unwrap().is_finite());
    }
    let split: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("test_split.json")).unwrap())
            .unwrap();
    assert_eq!(&split["hash"], hash);
    assert_eq!(split["frames"].as_array().unwrap().len(), 8);

    // A second run keeps every finished row (same files, same times) and renders nothing.
    let o = experiment(&mesh, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("0 computed, 7 skipped"), "{err}");
    assert!(!err.contains("Rendered"), "{err}");
    assert_eq!(row_jsons(&out), rows);

    // An unfinished row (no row.json) is redone, alone.
    let victim = out.join("rows/r00021_s00021/row.json");
    std::fs::remove_file(&victim).unwrap();
    let o = experiment(&mesh, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("1 computed, 6 skipped"),
        "{}",
        stderr(&o)
    );
    let again = row_jsons(&out);
    for (a, b) in rows.iter().zip(&again) {
        if a.0.contains("r00021_s00021") {
            assert_eq!(a.1["test_split_hash"], b.1["test_split_hash"]);
        } else {
            assert_eq!(a, b);
        }
    }

    // Other settings in the same folder are refused, not mixed in.
    let o = experiment(&mesh, &out, &["--epochs", "3"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("other settings"), "{}", stderr(&o));
}

#[test]
fn experiment_rejects_bad_ratios_and_missing_objects() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(synthgen()
        .args(["experiment", "mix", "--real-proxy", "--quick", "--out"])
        .arg(dir.path().join("a")));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--objects"), "{}", stderr(&o));
    let mesh = dir.path().join("box.ply");
    write_box_ply(&mesh);
    let o = run(synthgen()
        .args([
            "experiment",
            "mix",
            "--real-proxy",
            "--quick",
            "--ratios",
            "10-5",
            "--objects",
        ])
        .arg(&mesh)
        .arg("--out")
        .arg(dir.path().join("b")));
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("REAL/SYNTH"), "{}", stderr(&o));
}
