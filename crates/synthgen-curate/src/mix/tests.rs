//! Tests of the mix: allocation, errors, strata, and the properties the issue asks for
//! (exact counts, no duplicates, a test split disjoint from training and the same for every
//! ratio, byte-identical output for the same seed).

use super::*;
use proptest::prelude::*;
use std::collections::BTreeSet;

fn p() -> &'static Path {
    Path::new("/data/x")
}

#[test]
fn allocate_is_proportional_and_exact() {
    assert_eq!(allocate(10, &[50, 30, 20]), vec![5, 3, 2]);
    assert_eq!(allocate(3, &[1, 1, 1, 1]), vec![1, 1, 1, 0]);
    assert_eq!(allocate(5, &[5]), vec![5]);
    assert_eq!(allocate(0, &[3, 4]), vec![0, 0]);
    assert_eq!(allocate(2, &[]), Vec::<usize>::new());
}

#[test]
fn too_many_frames_says_how_many_there_are() {
    let real = vec![1u32; 20];
    let synth = vec![1u32; 5];
    let c = MixCounts {
        real: 19,
        synth: 0,
        test: Some(2),
    };
    let e = plan_mix(&real, &synth, c, 0, p(), Path::new("/s")).unwrap_err();
    assert_eq!(
        e.to_string(),
        "asked for 19 real training frames but only 18 are available (20 real frames, 2 held out for the test split): /data/x"
    );
    let c = MixCounts {
        real: 1,
        synth: 6,
        test: Some(2),
    };
    let e = plan_mix(&real, &synth, c, 0, p(), Path::new("/s")).unwrap_err();
    assert_eq!(
        e.to_string(),
        "asked for 6 synthetic frames but only 5 are available: /s"
    );
}

#[test]
fn ratio_gives_counts() {
    let c = MixCounts::from_ratio(0.3, 1500, None).unwrap();
    assert_eq!((c.real, c.synth), (1050, 450));
    assert!(MixCounts::from_ratio(1.5, 10, None).is_err());
}

#[test]
fn strata_keep_their_share() {
    // 60 frames of object 1, 30 of object 2, 10 of both.
    let mut keys = vec![vec![1u32]; 60];
    keys.extend(vec![vec![2u32]; 30]);
    keys.extend(vec![vec![1u32, 2]; 10]);
    let c = MixCounts {
        real: 45,
        synth: 0,
        test: Some(10),
    };
    let plan = plan_mix(&keys, &keys, c, 3, p(), p()).unwrap();
    let count = |ids: &[usize], k: &[u32]| ids.iter().filter(|&&i| keys[i] == k).count();
    assert_eq!(count(&plan.test, &[1]), 6);
    assert_eq!(count(&plan.test, &[2]), 3);
    assert_eq!(count(&plan.test, &[1, 2]), 1);
    let train: Vec<usize> = plan.train.iter().map(|t| t.1).collect();
    assert_eq!(count(&train, &[1]), 27);
    assert_eq!(count(&train, &[2]), 13);
    assert_eq!(count(&train, &[1, 2]), 5);
}

/// An in-memory source whose frames all point at one tiny file.
struct FakeSource {
    root: PathBuf,
    frames: Vec<SourceFrame>,
}

impl FakeSource {
    fn new(root: &Path, objects: &[u32]) -> FakeSource {
        FakeSource::in_scenes(root, objects, 0)
    }

    /// Frames in scenes of `per_scene` consecutive frames (scene 0, 1, ...); 0: one scene.
    fn in_scenes(root: &Path, objects: &[u32], per_scene: usize) -> FakeSource {
        std::fs::create_dir_all(root).unwrap();
        let frames = objects
            .iter()
            .enumerate()
            .map(|(i, &obj_id)| (i, obj_id, root.join(format!("{i:06}.png"))))
            .inspect(|(i, _, rgb)| {
                // A distinct image per frame and dataset: mix refuses frames shared with the
                // test split.
                std::fs::write(rgb, format!("{} {i}", root.display())).unwrap()
            })
            .map(|(i, obj_id, rgb)| SourceFrame {
                location: synthgen_formats::source::FrameLocation {
                    split: "train_pbr".into(),
                    scene_id: i.checked_div(per_scene).unwrap_or(0) as u32,
                    im_id: i as u32,
                },
                camera: SceneCamera::without_world(
                    [500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0],
                    1.0,
                ),
                gt: vec![GtEntry::new(obj_id, &synthgen_core::Pose::IDENTITY)],
                gt_info: None,
                rgb,
                depth: None,
                masks: vec![None],
                masks_visib: vec![None],
            })
            .collect();
        FakeSource {
            root: root.to_path_buf(),
            frames,
        }
    }
}

impl FrameSource for FakeSource {
    fn root(&self) -> &Path {
        &self.root
    }
    fn camera(&self) -> synthgen_formats::bop::CameraInfo {
        synthgen_formats::bop::CameraInfo::new(&synthgen_core::Intrinsics::LINEMOD, 1.0)
    }
    fn models_info(&self) -> Option<&BTreeMap<u32, ModelInfo>> {
        None
    }
    fn splits(&self) -> Vec<String> {
        vec!["train_pbr".into()]
    }
    fn models_info_path(&self) -> PathBuf {
        self.root.join("models").join("models_info.json")
    }
    fn model_file(&self, obj_id: u32) -> PathBuf {
        self.root
            .join("models")
            .join(format!("obj_{obj_id:06}.ply"))
    }
    fn model_path(&self, _: u32) -> Option<PathBuf> {
        None
    }
    fn frames(&self, _: &[String]) -> Result<Vec<SourceFrame>> {
        Ok(self.frames.clone())
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]
    #[test]
    fn same_seed_byte_identical_manifest(seed in any::<u64>(), real_count in 0usize..20) {
        let dir = tempfile::tempdir().unwrap();
        let objects: Vec<u32> = (0..30).map(|i| 1 + i % 3).collect();
        let real = FakeSource::new(&dir.path().join("real"), &objects);
        let synth = FakeSource::new(&dir.path().join("synth"), &objects[..12]);
        let opts = MixOptions {
            counts: MixCounts { real: real_count, synth: 5, test: None },
            seed,
            command_line: vec!["synthgen".into(), "mix".into()],
            force: false,
            exclude_shared: false,
            test_scenes: Vec::new(),
        };
        let mut texts = Vec::new();
        for out in ["a", "b"] {
            let out = dir.path().join(out);
            let r = write_mix(
                &real,
                &synth,
                &out,
                &opts,
                Completion::default(),
                &synthgen_core::NoProgress,
            ).unwrap();
            prop_assert_eq!((r.train_real, r.train_synth, r.test), (real_count, 5, 3));
            texts.push((
                std::fs::read(out.join("synthgen.json")).unwrap(),
                std::fs::read(out.join(PROVENANCE_FILE)).unwrap(),
                std::fs::read(out.join("train/000000/scene_gt.json")).unwrap(),
            ));
        }
        prop_assert_eq!(&texts[0], &texts[1]);
    }
}

fn keys_strategy() -> impl Strategy<Value = Vec<u8>> {
    prop::collection::vec(0u8..4, 0..120)
}

proptest! {
    #[test]
    fn plan_properties(
        real in keys_strategy(),
        synth in keys_strategy(),
        a in 0.0f64..1.0,
        b in 0.0f64..1.0,
        t in 0.0f64..0.5,
        seed in any::<u64>(),
    ) {
        let test = (t * real.len() as f64) as usize;
        let pool = real.len() - test;
        let counts = |f: f64| MixCounts {
            real: (f * pool as f64) as usize,
            synth: ((1.0 - f) * synth.len() as f64) as usize,
            test: Some(test),
        };
        let pa = plan_mix(&real, &synth, counts(a), seed, p(), p()).unwrap();
        let pb = plan_mix(&real, &synth, counts(b), seed, p(), p()).unwrap();
        // Counts exact.
        prop_assert_eq!(pa.test.len(), test);
        let nr = pa.train.iter().filter(|x| x.0 == Origin::Real).count();
        prop_assert_eq!(nr, counts(a).real);
        prop_assert_eq!(pa.train.len() - nr, counts(a).synth);
        // No duplicates.
        let set: BTreeSet<_> = pa.train.iter().collect();
        prop_assert_eq!(set.len(), pa.train.len());
        // Test split disjoint from training and the same for every ratio.
        for &(o, i) in &pa.train {
            prop_assert!(o == Origin::Synth || pa.test.binary_search(&i).is_err());
        }
        prop_assert_eq!(&pa.test, &pb.test);
        // Same seed, same plan.
        let again = plan_mix(&real, &synth, counts(a), seed, p(), p()).unwrap();
        prop_assert_eq!(pa, again);
    }
}

#[test]
fn a_given_test_split_is_kept_out_of_training() {
    let real = vec![1u32; 10];
    let synth = vec![1u32; 4];
    let c = MixCounts {
        real: 7,
        synth: 4,
        test: Some(99),
    };
    let plan = plan_mix_with_test(&real, &synth, c, vec![2, 3, 4], "", 1, p(), p()).unwrap();
    assert_eq!(plan.test, [2, 3, 4]);
    let mut real_train: Vec<usize> = plan
        .train
        .iter()
        .filter(|t| t.0 == Origin::Real)
        .map(|t| t.1)
        .collect();
    real_train.sort_unstable();
    assert_eq!(real_train, [0, 1, 5, 6, 7, 8, 9]);
    let c = MixCounts { real: 8, ..c };
    let e = plan_mix_with_test(&real, &synth, c, vec![2, 3, 4], " (why)", 1, p(), p())
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "asked for 8 real training frames but only 7 are available (why): /data/x"
    );
}

fn scene_mix(
    real: &FakeSource,
    synth: &FakeSource,
    out: &Path,
    real_count: usize,
    test: Option<usize>,
    scenes: &[&str],
) -> Result<MixReport> {
    let opts = MixOptions {
        counts: MixCounts {
            real: real_count,
            synth: 3,
            test,
        },
        seed: 4,
        command_line: vec!["synthgen".into(), "mix".into()],
        force: true,
        exclude_shared: false,
        test_scenes: scenes.iter().map(|s| s.parse().unwrap()).collect(),
    };
    write_mix(
        real,
        synth,
        out,
        &opts,
        Completion::default(),
        &synthgen_core::NoProgress,
    )
}

/// (split, source scene, origin) of every frame of a mix's provenance.json.
fn provenance_scenes(out: &Path) -> Vec<(String, u64, String)> {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(PROVENANCE_FILE)).unwrap()).unwrap();
    v.as_array()
        .unwrap()
        .iter()
        .map(|e| {
            (
                e["split"].as_str().unwrap().to_string(),
                e["source_scene_id"].as_u64().unwrap(),
                e["origin"].as_str().unwrap().to_string(),
            )
        })
        .collect()
}

#[test]
fn test_scenes_hold_out_whole_scenes_for_every_count() {
    let dir = tempfile::tempdir().unwrap();
    // Three scenes of 6 frames; the objects differ by scene as in a video dataset.
    let objects: Vec<u32> = (0..18).map(|i| 1 + (i / 6) as u32).collect();
    let real = FakeSource::in_scenes(&dir.path().join("real"), &objects, 6);
    let synth = FakeSource::new(&dir.path().join("synth"), &[1, 2, 3, 1, 2]);
    let mut tests = Vec::new();
    for real_count in [0, 5, 12] {
        let out = dir.path().join(format!("mix{real_count}"));
        let r = scene_mix(&real, &synth, &out, real_count, None, &["1"]).unwrap();
        assert_eq!((r.test, r.train_real, r.train_synth), (6, real_count, 3));
        let prov = provenance_scenes(&out);
        let test: Vec<u64> = prov
            .iter()
            .filter(|p| p.0 == TEST_SPLIT)
            .map(|p| p.1)
            .collect();
        assert_eq!(test, [1; 6], "every frame of scene 1, nothing else");
        assert!(prov
            .iter()
            .filter(|p| p.0 == TRAIN_SPLIT && p.2 == "real")
            .all(|p| p.1 != 1));
        tests.push(std::fs::read(out.join("test/000000/scene_gt.json")).unwrap());
        let manifest: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("synthgen.json")).unwrap())
                .unwrap();
        assert_eq!(
            manifest["extra"]["mix"]["test_scenes"],
            serde_json::json!(["1"])
        );
    }
    assert!(tests.windows(2).all(|w| w[0] == w[1]));

    // Two scenes held out: 12 test frames, training only from scene 0.
    let out = dir.path().join("two");
    let r = scene_mix(&real, &synth, &out, 6, None, &["2", "1"]).unwrap();
    assert_eq!(r.test, 12);
    let prov = provenance_scenes(&out);
    assert!(prov
        .iter()
        .all(|p| p.2 == "synth" || (p.1 == 0) == (p.0 == TRAIN_SPLIT)));
}

#[test]
fn test_scenes_errors_name_what_is_there() {
    let dir = tempfile::tempdir().unwrap();
    let real = FakeSource::in_scenes(&dir.path().join("real"), &[1; 12], 4);
    let synth = FakeSource::new(&dir.path().join("synth"), &[1; 3]);
    let out = dir.path().join("mix");
    let e = scene_mix(&real, &synth, &out, 1, None, &["5"]).unwrap_err();
    assert!(matches!(e, Error::UnknownScenes { .. }), "{e}");
    assert!(e.to_string().contains("its scenes are 0, 1, 2"), "{e}");
    let e = scene_mix(&real, &synth, &out, 9, None, &["0"])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("only 8 are available (12 real frames, 4 of them in the test scenes 0)"),
        "{e}"
    );
    let e = scene_mix(&real, &synth, &out, 1, Some(2), &["0"])
        .unwrap_err()
        .to_string();
    assert!(e.contains("do not go together"), "{e}");
}
