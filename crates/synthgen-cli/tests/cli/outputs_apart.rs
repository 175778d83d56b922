//! Issue 50, class 1: one rule for every command. An output that is, lies inside or contains
//! one of the command's inputs is refused before anything is written (`guard::check`), and
//! the inputs are left byte for byte as they were; a file's contents (an MTL's texture
//! names) never decide where a command writes.

use crate::common::{refused, run, stderr, synthgen, tree};

/// Regression (issue 50): `detector run --out` could be the detector's checkpoint or a
/// dataset's scene_gt.json, `scene fit --out` could land inside its dataset; the rule held
/// for some commands only. Each command here is refused, and nothing in the folder changes.
#[test]
fn no_command_writes_into_around_or_over_its_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mesh = crate::common::repo_root().join("datasets/meshes/driller.ply");
    let o = run(synthgen()
        .current_dir(d)
        .arg("render")
        .arg("-q")
        .arg("--objects")
        .arg(&mesh)
        .args(["--frames", "2", "--image-size", "160,120", "--out", "data"]));
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::create_dir_all(d.join("run")).unwrap();
    for f in ["config.json", "model.safetensors"] {
        std::fs::write(d.join("run").join(f), "{}").unwrap();
    }
    std::fs::write(d.join("r.csv"), "scene_id,im_id,obj_id,score,R,t,time\n").unwrap();
    std::fs::copy(&mesh, d.join("mesh.ply")).unwrap();
    let before = tree(d);
    let never = "a command never writes into its inputs";
    let cases: &[(&[&str], &str)] = &[
        (
            &[
                "render",
                "--objects",
                "data/models/obj_000001.ply",
                "--out",
                "data",
                "--force",
            ],
            "contains the object mesh",
        ),
        (
            &["render", "--objects", "mesh.ply", "--out", ".", "--force"],
            "contains the object mesh",
        ),
        (
            &["preview", "data", "--out", "data/sheet.png"],
            "lies inside the dataset",
        ),
        (
            &["stats", "data", "--plot", "data/plots"],
            "lies inside the dataset",
        ),
        (
            &[
                "annotate",
                "data",
                "--compare",
                "--report",
                "data/train_pbr/000000/scene_gt.json",
            ],
            "lies inside the dataset",
        ),
        (
            &["train", "--data", "data", "--out", "data/run"],
            "lies inside the dataset",
        ),
        (
            &[
                "eval",
                "--data",
                "data",
                "--results",
                "r.csv",
                "--json",
                "r.csv",
            ],
            "is the --results",
        ),
        (
            &[
                "eval",
                "--data",
                "data",
                "--checkpoint",
                "run/model.safetensors",
                "--json",
                "run/config.json",
            ],
            "lies inside the checkpoint's run folder",
        ),
        (
            &["merge", "data", "--out", "data/merged"],
            "lies inside the shard",
        ),
        (
            &["detector", "train", "--data", "data", "--out", "data/det"],
            "lies inside the dataset",
        ),
        (
            &[
                "detector",
                "run",
                "--checkpoint",
                "run",
                "--data",
                "data",
                "--out",
                "run/model.safetensors",
            ],
            "lies inside the detector",
        ),
        (
            &[
                "detector",
                "run",
                "--checkpoint",
                "run",
                "--data",
                "data",
                "--out",
                "data/train_pbr/000000/scene_gt.json",
            ],
            "lies inside the dataset",
        ),
        (
            &[
                "experiment",
                "sim2real",
                "--fit",
                "data",
                "--test",
                "data",
                "--out",
                "data/exp",
            ],
            "lies inside the --fit",
        ),
        (
            &[
                "experiment",
                "rgb",
                "--train",
                "data",
                "--test",
                "data",
                "--out",
                ".",
            ],
            "contains the --train",
        ),
        (
            &["sensor", "fit", "--data", "data", "--out", "data/fit.toml"],
            "lies inside the dataset",
        ),
        (
            &[
                "sensor",
                "compare",
                "--real",
                "data",
                "--synth",
                "data",
                "--plot",
                "data/c.png",
            ],
            "lies inside the --real",
        ),
        (
            &["scene", "fit", "--data", "data", "--out", "data/scene.toml"],
            "lies inside the dataset",
        ),
        (
            &[
                "model", "align", "--scan", "mesh.ply", "--to", "mesh.ply", "--out", ".", "--force",
            ],
            "contains the --scan",
        ),
        (
            &["convert", "--to", "linemod", "data", "data/lm"],
            "lies inside the input dataset",
        ),
        (
            &[
                "mix",
                "--real",
                "data",
                "--synth",
                "data",
                "--real-count",
                "1",
                "--synth-count",
                "1",
                "--out",
                "data/mix",
            ],
            "lies inside the real dataset",
        ),
    ];
    for (args, relation) in cases {
        let o = run(synthgen().current_dir(d).args(*args));
        refused(&o, &[never, relation]);
    }
    // A mesh the scene file names is an input too.
    std::fs::write(
        d.join("s.toml"),
        "[[objects]]\npath = \"data/models/obj_000001.ply\"\n",
    )
    .unwrap();
    let o = run(synthgen()
        .current_dir(d)
        .args(["render", "--scene", "s.toml", "--out", "data", "--force"]));
    refused(&o, &["contains the scene object mesh"]);
    std::fs::remove_file(d.join("s.toml")).unwrap();
    // Two outputs on one path.
    let o = run(synthgen().current_dir(d).args([
        "sensor", "fit", "--data", "data", "--out", "s.toml", "--plot", "s.toml",
    ]));
    refused(&o, &["--out and --plot are the same path"]);
    // export coco writes into its dataset by design, but over a COCO file only.
    let o = run(synthgen().current_dir(d).args([
        "export",
        "coco",
        "data",
        "--out",
        "data/train_pbr/000000/scene_gt.json",
    ]));
    refused(&o, &["is not a COCO annotation file"]);
    assert!(before == tree(d), "an input changed");
}
