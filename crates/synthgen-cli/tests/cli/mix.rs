//! `synthgen mix` end to end on two tiny rendered datasets.

use std::path::Path;

use serde_json::Value;
use synthgen_formats::bop::BopDataset;

use crate::common::{run, stderr, synthgen};
use crate::render::write_box_ply;

/// Renders `frames` frames of the box into `out` (80x60, fast).
pub fn render_tiny(dir: &Path, out: &str, frames: u32, seed: u32) {
    let mesh = dir.join("box.ply");
    if !mesh.exists() {
        write_box_ply(&mesh);
    }
    let o = run(synthgen()
        .current_dir(dir)
        .args(["render", "-q", "--objects", "box.ply", "--units", "m"])
        .args(["--image-size", "80,60", "--camera-k", "80,80,40,30"])
        .args(["--frames", &frames.to_string(), "--seed", &seed.to_string()])
        .args(["--out", out]));
    assert!(o.status.success(), "{}", stderr(&o));
}

fn read_json(p: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap()
}

/// (origin, source scene, source image) of each frame of `split` in provenance.json.
fn provenance(out: &Path, split: &str) -> Vec<(String, u64, u64)> {
    let v = read_json(&out.join("provenance.json"));
    v.as_array()
        .unwrap()
        .iter()
        .filter(|e| e["split"] == split)
        .map(|e| {
            (
                e["origin"].as_str().unwrap().to_string(),
                e["source_scene_id"].as_u64().unwrap(),
                e["source_im_id"].as_u64().unwrap(),
            )
        })
        .collect()
}

fn setup() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    render_tiny(dir.path(), "real", 30, 1);
    render_tiny(dir.path(), "synth", 20, 2);
    dir
}

#[test]
fn mix_long_and_short_forms() {
    let dir = setup();
    let d = dir.path();
    let o = run(synthgen().current_dir(d).args([
        "mix",
        "--real",
        "real",
        "--synth",
        "synth",
        "--real-count",
        "10",
        "--synth-count",
        "5",
        "--test-count",
        "6",
        "--seed",
        "4",
        "--out",
        "mix_a",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    let out = d.join("mix_a");
    let ds = BopDataset::open(&out).unwrap();
    assert_eq!(ds.splits, vec!["test".to_string(), "train".to_string()]);
    assert_eq!(ds.read_scene("train", 0).unwrap().im_ids().count(), 15);
    let test = ds.read_scene("test", 0).unwrap();
    assert_eq!(test.im_ids().count(), 6);
    assert!(test.gt_info.is_some());
    assert!(test.mask_visib_path(0, 0).is_file());
    assert_eq!(ds.models_info.as_ref().unwrap().len(), 1);
    let train = provenance(&out, "train");
    assert_eq!(train.iter().filter(|p| p.0 == "real").count(), 10);
    assert_eq!(train.iter().filter(|p| p.0 == "synth").count(), 5);
    let test_a = provenance(&out, "test");
    for t in &test_a {
        assert!(!train.contains(t), "test frame {t:?} also in training");
    }
    let manifest = read_json(&out.join("synthgen.json"));
    assert_eq!(manifest["frames"], 21);
    assert_eq!(manifest["extra"]["mix"]["provenance"], "provenance.json");

    // Short form, paths from synthgen.toml, a different ratio: same test split.
    std::fs::write(
        d.join("synthgen.toml"),
        "[mix]\nreal = \"real\"\nsynth = \"synth\"\nout = \"mix_b\"\n",
    )
    .unwrap();
    let sub = d.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    let o = run(synthgen().current_dir(&sub).args([
        "mix",
        "--real",
        "4",
        "--synth",
        "20",
        "--test-count",
        "6",
        "--seed",
        "4",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(provenance(&d.join("mix_b"), "test"), test_a);

    // Same seed and inputs: byte-identical manifest and provenance.
    let o = run(synthgen().current_dir(&sub).args([
        "mix",
        "--real",
        "4",
        "--synth",
        "20",
        "--test-count",
        "6",
        "--seed",
        "4",
        "--out",
        "../mix_c",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    for f in ["provenance.json", "train/000000/scene_gt.json"] {
        assert_eq!(
            std::fs::read(d.join("mix_b").join(f)).unwrap(),
            std::fs::read(d.join("mix_c").join(f)).unwrap(),
            "{f}"
        );
    }

    // The same command twice: byte-identical manifest.
    let args = [
        "mix",
        "--real",
        "real",
        "--synth",
        "synth",
        "--real-count",
        "7",
        "--synth-count",
        "3",
        "--seed",
        "9",
        "--force",
        "--out",
        "mix_e",
    ];
    let mut manifests = Vec::new();
    for _ in 0..2 {
        let o = run(synthgen().current_dir(d).args(args));
        assert!(o.status.success(), "{}", stderr(&o));
        manifests.push(std::fs::read(d.join("mix_e/synthgen.json")).unwrap());
    }
    assert_eq!(manifests[0], manifests[1]);

    // Ratio form.
    let o = run(synthgen().current_dir(d).args([
        "mix", "--real", "real", "--synth", "synth", "--ratio", "0.5", "--total", "20", "--out",
        "mix_d",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    let train = provenance(&d.join("mix_d"), "train");
    assert_eq!(train.iter().filter(|p| p.0 == "synth").count(), 10);
    // Default test split: 10% of 30.
    assert_eq!(provenance(&d.join("mix_d"), "test").len(), 3);
}

#[test]
fn mix_errors() {
    let dir = setup();
    let d = dir.path();
    // Counts without a configured folder.
    let o = run(synthgen()
        .current_dir(d)
        .env_remove("SYNTHGEN_REAL")
        .env_remove("SYNTHGEN_SYNTH")
        .args(["mix", "--real", "10", "--synth", "5"]));
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(e.contains("no real dataset folder is configured"), "{e}");
    assert!(
        e.contains("SYNTHGEN_REAL") && e.contains("synthgen.toml"),
        "{e}"
    );

    // The env vars work instead.
    let o = run(synthgen()
        .current_dir(d)
        .env("SYNTHGEN_REAL", d.join("real"))
        .env("SYNTHGEN_SYNTH", d.join("synth"))
        .args(["mix", "--real", "10", "--synth", "5", "--out", "m_env"]));
    assert!(o.status.success(), "{}", stderr(&o));

    // More frames than there are.
    let o = run(synthgen().current_dir(d).args([
        "mix",
        "--real",
        "real",
        "--synth",
        "synth",
        "--real-count",
        "28",
        "--synth-count",
        "1",
        "--test-count",
        "3",
        "--out",
        "m1",
    ]));
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("asked for 28 real training frames but only 27 are available (30 real frames, 3 held out for the test split)"),
        "{e}"
    );

    // Non-empty output without --force; a source as output even with --force.
    std::fs::create_dir_all(d.join("busy")).unwrap();
    std::fs::write(d.join("busy/notes.txt"), "mine").unwrap();
    for (out, force, want) in [
        ("busy", false, "--force"),
        ("real", true, "the output real (--out) is the real dataset"),
        ("synth/sub", true, "lies inside the synthetic dataset"),
    ] {
        let mut cmd = synthgen();
        cmd.current_dir(d).args([
            "mix",
            "--real",
            "real",
            "--synth",
            "synth",
            "--real-count",
            "1",
            "--synth-count",
            "1",
            "--out",
            out,
        ]);
        if force {
            cmd.arg("--force");
        }
        let o = run(&mut cmd);
        assert_eq!(o.status.code(), Some(1));
        assert!(stderr(&o).contains(want), "{}", stderr(&o));
    }
    assert!(d.join("real/train_pbr/000000/scene_gt.json").is_file());

    // Malformed JSON in a source names the file.
    let gt = d.join("synth/train_pbr/000000/scene_gt.json");
    std::fs::write(&gt, "{\"0\": [}").unwrap();
    let o = run(synthgen().current_dir(d).args([
        "mix",
        "--real",
        "real",
        "--synth",
        "synth",
        "--real-count",
        "1",
        "--synth-count",
        "1",
        "--out",
        "m2",
    ]));
    assert_eq!(o.status.code(), Some(1));
    let e = stderr(&o);
    assert!(
        e.contains("malformed scene_gt.json") && e.contains(&gt.display().to_string()),
        "{e}"
    );

    // Missing folder.
    let o = run(synthgen().current_dir(d).args([
        "mix",
        "--real",
        "nope",
        "--synth",
        "synth",
        "--real-count",
        "1",
        "--synth-count",
        "1",
    ]));
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("real dataset folder not found: nope"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn mix_test_scenes_holds_out_whole_scenes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    render_tiny(d, "synth", 5, 2);
    // 30 real frames in three scene folders of 10.
    let o = run(synthgen()
        .current_dir(d)
        .args(["render", "-q", "--objects", "box.ply", "--units", "m"])
        .args(["--image-size", "80,60", "--camera-k", "80,80,40,30"])
        .args(["--frames", "30", "--seed", "1", "--chunk-size", "10"])
        .args(["--out", "real"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let mix = |out: &str, extra: &[&str]| {
        run(synthgen()
            .current_dir(d)
            .args([
                "mix",
                "--real",
                "real",
                "--synth",
                "synth",
                "--synth-count",
                "3",
            ])
            .args(["--seed", "4", "--out", out])
            .args(extra))
    };
    let o = mix("mix_a", &["--real-count", "12", "--test-scenes", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("10 real test frames (every frame of scene(s) 1)"),
        "{}",
        stderr(&o)
    );
    let out = d.join("mix_a");
    let test = provenance(&out, "test");
    assert_eq!(test.len(), 10);
    assert!(test.iter().all(|t| t.1 == 1), "{test:?}");
    let train = provenance(&out, "train");
    assert_eq!(train.iter().filter(|t| t.0 == "real").count(), 12);
    assert!(
        train.iter().all(|t| t.0 == "synth" || t.1 != 1),
        "{train:?}"
    );
    let manifest = read_json(&out.join("synthgen.json"));
    assert_eq!(
        manifest["extra"]["mix"]["test_scenes"],
        serde_json::json!(["1"])
    );

    // Errors: an unknown scene (the message lists the scenes), more real frames than the
    // other scenes hold, and a test count as well.
    let o = mix("mix_b", &["--real-count", "12", "--test-scenes", "5"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o).contains("no scene 5 in the dataset; its scenes are 0, 1, 2"),
        "{}",
        stderr(&o)
    );
    let o = mix("mix_b", &["--real-count", "21", "--test-scenes", "0"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        stderr(&o)
            .contains("only 20 are available (30 real frames, 10 of them in the test scenes 0)"),
        "{}",
        stderr(&o)
    );
    let o = mix(
        "mix_b",
        &[
            "--real-count",
            "2",
            "--test-scenes",
            "0",
            "--test-count",
            "3",
        ],
    );
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("--test-count"), "{}", stderr(&o));
}
