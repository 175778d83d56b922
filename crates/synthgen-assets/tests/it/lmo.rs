//! The real Linemod-Occluded models (ASCII PLY, millimetres, normals, RGBA).

use std::time::Instant;

use synthgen_assets::{load_model, Units};
use synthgen_core::NoProgress;

use crate::shared_data;

/// `element vertex N` and `element face M` from the header.
fn header_counts(text: &str) -> (usize, usize) {
    let count = |name: &str| {
        text.lines()
            .take_while(|l| *l != "end_header")
            .find_map(|l| l.strip_prefix(&format!("element {name} ")))
            .unwrap()
            .trim()
            .parse()
            .unwrap()
    };
    (count("vertex"), count("face"))
}

fn check_model(id: u32) {
    let data = shared_data();
    let path = data.join(format!("lmo/models/obj_{id:06}.ply"));
    let info: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(data.join("lmo/models/models_info.json")).unwrap(),
    )
    .unwrap();
    let info = &info[id.to_string()];
    let text = std::fs::read_to_string(&path).unwrap();
    let (nv, nf) = header_counts(&text);

    let loaded = load_model(&path, Units::Auto, &NoProgress).unwrap();
    assert_eq!(loaded.units_used, Units::Mm);
    let note = loaded.auto_note.as_deref().unwrap();
    assert!(
        note.starts_with(&format!("auto units: obj_{id:06}.ply bbox diagonal "))
            && note.ends_with("→ millimetres"),
        "{note}"
    );
    let m = &loaded.model;
    assert_eq!(m.name, format!("obj_{id:06}"));
    assert_eq!(m.source, path);
    assert_eq!(m.primitives.len(), 1);
    assert_eq!(m.vertex_count(), nv);
    assert_eq!(m.triangle_count(), nf, "all lmo faces are triangles");

    let bb = m.aabb().unwrap();
    for (axis, min, size) in [
        (0, "min_x", "size_x"),
        (1, "min_y", "size_y"),
        (2, "min_z", "size_z"),
    ] {
        let want_min = info[min].as_f64().unwrap() / 1000.0;
        let want_size = info[size].as_f64().unwrap() / 1000.0;
        let (got_min, got_size) = (f64::from(bb.min[axis]), f64::from(bb.size()[axis]));
        assert!(
            (got_min - want_min).abs() < 1e-4,
            "{min}: {got_min} vs {want_min}"
        );
        assert!(
            (got_size - want_size).abs() < 1e-4,
            "{size}: {got_size} vs {want_size}"
        );
    }

    let p = &m.primitives[0];
    let colors = p.colors.as_ref().expect("lmo models have vertex colours");
    assert_eq!(colors.len(), nv);
    assert!(colors.iter().any(|c| c != &colors[0]), "colours vary");
    assert_eq!(p.material.base_color, [1.0; 3]);
    let normals = p.normals.as_ref().expect("lmo models have normals");
    assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
    assert!(p.uvs.is_none() && p.material.texture.is_none());

    // First vertex line of the file, as read: "x y z nx ny nz r g b a" in mm.
    let first = text
        .lines()
        .skip_while(|l| *l != "end_header")
        .nth(1)
        .unwrap();
    let v: Vec<f32> = first
        .split_whitespace()
        .map(|t| t.parse().unwrap())
        .collect();
    assert!((p.positions_m[0].x - v[0] / 1000.0).abs() < 1e-7);
    assert!((colors[0][0] - v[6] / 255.0).abs() < 1e-6);
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn lmo_obj_000001_ape_loads_in_metres() {
    check_model(1);
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn lmo_obj_000008_driller_loads_in_metres() {
    check_model(8);
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn lmo_all_models_load() {
    for id in [1, 5, 6, 8, 9, 10, 11, 12] {
        check_model(id);
    }
}

/// Not an assertion: prints the load time (`cargo test -p synthgen-assets --release lmo_load_time
/// -- --nocapture`).
#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn lmo_load_time() {
    let data = shared_data();
    let path = data.join("lmo/models/obj_000008.ply");
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        let m = load_model(&path, Units::Mm, &NoProgress).unwrap();
        best = best.min(t.elapsed().as_secs_f64());
        assert!(m.model.vertex_count() > 0);
    }
    eprintln!("obj_000008.ply loaded in {:.1} ms (best of 5)", best * 1e3);
}
