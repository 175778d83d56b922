//! Replays the fuzz corpus (`fuzz/corpus/<target>/*`, the seeds and every input that once
//! crashed a reader) through the same harnesses as `cargo fuzz`: no input may panic.

#[allow(dead_code)]
mod harness {
    include!("../../../../fuzz/src/harness.rs");
}

use std::path::Path;

fn replay(target: &str, f: fn(&[u8])) {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../fuzz/corpus")
        .join(target);
    let mut n = 0;
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    for p in files {
        let bytes = std::fs::read(&p).unwrap();
        let r = std::panic::catch_unwind(|| f(&bytes));
        assert!(r.is_ok(), "{target}: {} panics", p.display());
        n += 1;
    }
    assert!(n > 0, "empty corpus {}", dir.display());
    let _ = std::fs::remove_dir_all(harness::scratch());
}

#[test]
fn fuzz_corpus_ply() {
    replay("ply", harness::fuzz_ply);
}

#[test]
fn fuzz_corpus_obj_mtl() {
    replay("obj_mtl", harness::fuzz_obj_mtl);
}

#[test]
fn fuzz_corpus_gltf() {
    replay("gltf", harness::fuzz_gltf);
}

#[test]
fn fuzz_corpus_bop_json() {
    replay("bop_json", harness::fuzz_bop_json);
}

#[test]
fn fuzz_corpus_linemod_yaml() {
    replay("linemod_yaml", harness::fuzz_linemod_yaml);
}

#[test]
fn fuzz_corpus_scene_toml() {
    replay("scene_toml", harness::fuzz_scene_toml);
}

#[test]
fn fuzz_corpus_ycbv_mat() {
    replay("ycbv_mat", harness::fuzz_ycbv_mat);
}

/// tobj 4.0.5 panics (unwrap in parse_float3) on an MTL colour with fewer than 3 numbers.
/// Such lines are read as the MTL spec reads them (one number: a grey) or left out with a
/// warning naming the MTL and the line, before tobj sees them: the model loads, no panic.
#[test]
fn tobj_mtl_short_colour_is_read_or_warned_about_not_a_panic() {
    struct Warnings(std::sync::Mutex<Vec<String>>);
    impl synthgen_core::Progress for Warnings {
        fn warn(&self, m: &str) {
            self.0.lock().unwrap().push(m.to_string());
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.obj");
    std::fs::write(
        &p,
        "mtllib m.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    for (kd, colour, warned) in [("Kd 0.25", [0.25f32; 3], false), ("Kd 1 0", [0.8; 3], true)] {
        std::fs::write(dir.path().join("m.mtl"), format!("newmtl red\n{kd}\n")).unwrap();
        let w = Warnings(std::sync::Mutex::new(Vec::new()));
        let m = synthgen_assets::load_model(&p, synthgen_assets::Units::M, &w).unwrap();
        let got = m.model.primitives[0].material.base_color;
        let default = synthgen_core::Material::default().base_color;
        assert_eq!(got, if warned { default } else { colour }, "{kd}");
        let warnings = w.0.into_inner().unwrap();
        assert_eq!(warnings.len(), usize::from(warned), "{kd}: {warnings:?}");
        if warned {
            assert!(
                warnings[0].contains("MTL line 2: `Kd 1 0`") && warnings[0].ends_with("m.mtl"),
                "{warnings:?}"
            );
        }
    }
}

/// gltf-json 1.4.1 panics (index out of bounds) validating a POSITION accessor that does not
/// exist.
#[test]
fn gltf_json_position_accessor_out_of_range_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("m.gltf");
    std::fs::write(
        &p,
        r#"{"asset":{"version":"2.0"},"meshes":[{"primitives":[{"attributes":{"POSITION":7}}]}]}"#,
    )
    .unwrap();
    let e = synthgen_assets::load_model(&p, synthgen_assets::Units::M, &synthgen_core::NoProgress)
        .unwrap_err()
        .to_string();
    assert!(e.contains("cannot load gltf"), "{e}");
    assert!(e.ends_with(&p.display().to_string()), "{e}");
}
