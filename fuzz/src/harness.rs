// Shared by the fuzz crate (src/lib.rs) and the corpus replay test; plain items only.

/// The readers turn third-party parser panics into errors (catch_unwind); libfuzzer-sys's
/// panic hook would abort before that, so use a silent hook. A panic that escapes the
/// readers still aborts: libfuzzer-sys checks every input's catch_unwind result.
pub fn quiet_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| std::panic::set_hook(Box::new(|_| {})));
}

/// A per-process scratch folder (on /dev/shm when there is one, for speed).
pub fn scratch() -> std::path::PathBuf {
    let base = if std::path::Path::new("/dev/shm").is_dir() {
        std::path::PathBuf::from("/dev/shm")
    } else {
        std::env::temp_dir()
    };
    let t = std::thread::current().id();
    let dir = base.join(format!("synthgen-fuzz-{}-{:?}", std::process::id(), t).replace(['(', ')'], ""));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Splits fuzz input at the first 0xFF byte (absent: everything goes to the first part).
pub fn split2(data: &[u8]) -> (&[u8], &[u8]) {
    match data.iter().position(|&b| b == 0xFF) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[]),
    }
}

fn load(path: &std::path::Path, units: synthgen_assets::Units) {
    if let Ok(m) = synthgen_assets::load_model(path, units, &synthgen_core::NoProgress) {
        // Touch what the renderer would use.
        let _ = m.model.aabb();
        let _ = m.model.diameter_m();
    }
}

/// PLY (ascii and binary) through `load_model`.
pub fn fuzz_ply(data: &[u8]) {
    let dir = scratch();
    let p = dir.join("m.ply");
    std::fs::write(&p, data).unwrap();
    load(&p, synthgen_assets::Units::Auto);
}

/// OBJ with its MTL (`mtllib m.mtl`): bytes before the first 0xFF are the OBJ, after it the MTL.
pub fn fuzz_obj_mtl(data: &[u8]) {
    let dir = scratch();
    let (obj, mtl) = split2(data);
    std::fs::write(dir.join("m.mtl"), mtl).unwrap();
    let p = dir.join("m.obj");
    std::fs::write(&p, obj).unwrap();
    load(&p, synthgen_assets::Units::M);
}

/// glTF: the first byte picks `.glb` (odd) or `.gltf` (even); the rest is the file.
pub fn fuzz_gltf(data: &[u8]) {
    let Some((&first, rest)) = data.split_first() else {
        return;
    };
    let dir = scratch();
    let p = dir.join(if first % 2 == 1 { "m.glb" } else { "m.gltf" });
    std::fs::write(&p, rest).unwrap();
    load(&p, synthgen_assets::Units::M);
}

/// Every BOP JSON reader on the same bytes.
pub fn fuzz_bop_json(data: &[u8]) {
    use synthgen_formats::bop::reader as r;
    let dir = scratch();
    let p = dir.join("scene_gt.json");
    std::fs::write(&p, data).unwrap();
    let _ = r::read_scene_gt(&p);
    let _ = r::read_scene_camera(&p);
    let _ = r::read_scene_gt_info(&p);
    let _ = r::read_camera_info(&p);
    let _ = r::read_models_info(&p);
    let _ = synthgen_formats::manifest::read_manifest(&dir);
}

/// Every Linemod YAML reader (and the id list) on the same bytes.
pub fn fuzz_linemod_yaml(data: &[u8]) {
    use synthgen_formats::linemod::reader as r;
    let dir = scratch();
    let p = dir.join("gt.yml");
    std::fs::write(&p, data).unwrap();
    let _ = r::read_gt_yml(&p);
    let _ = r::read_info_yml(&p);
    let _ = r::read_models_info_yml(&p);
    let _ = r::read_id_list(&p);
}

/// The scene spec, from a string and from a file.
pub fn fuzz_scene_toml(data: &[u8]) {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = synthgen_core::SceneSpec::from_toml_str(text);
    }
    let dir = scratch();
    let p = dir.join("scene.toml");
    std::fs::write(&p, data).unwrap();
    let _ = synthgen_core::SceneSpec::from_toml_file(&p);
}

/// A YCB-Video `-meta.mat` through the MAT v5 reader and `read_meta`'s checks.
pub fn fuzz_ycbv_mat(data: &[u8]) {
    let dir = scratch();
    let p = dir.join("000001-meta.mat");
    std::fs::write(&p, data).unwrap();
    let _ = synthgen_formats::ycbv::read_meta(&p, Some(21));
    let _ = synthgen_mat::read_mat(std::io::Cursor::new(data), None);
}
