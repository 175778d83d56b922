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
#[test]
fn tobj_mtl_short_colour_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("m.mtl"), "newmtl red\nKd 1\n").unwrap();
    let p = dir.path().join("m.obj");
    std::fs::write(
        &p,
        "mtllib m.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let e = synthgen_assets::load_model(&p, synthgen_assets::Units::M, &synthgen_core::NoProgress)
        .unwrap_err()
        .to_string();
    assert!(e.contains("tobj parser failed on malformed input"), "{e}");
    assert!(e.ends_with(&p.display().to_string()), "{e}");
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
