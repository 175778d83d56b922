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
