//! The YCB OBJ meshes (metres): the drill's texture is missing, the banana's is present.

use synthgen_assets::{load_model, load_model_cached, TextureCache, Units};

use crate::{shared_data, Warnings};

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn ycb_drill_warns_once_about_the_missing_texture_and_uses_kd() {
    let data = shared_data();
    let path = data.join("ycb/YcbPowerDrill/textured_simple_reoriented.obj");
    let warnings = Warnings::default();
    let loaded = load_model(&path, Units::Auto, &warnings).unwrap();

    let missing = data.join("ycb/YcbPowerDrill/texture_map.png");
    assert_eq!(
        warnings.take(),
        vec![format!(
            "texture not found, using the Kd colour: {}",
            missing.display()
        )]
    );
    assert_eq!(loaded.units_used, Units::M);
    assert!(loaded.auto_note.unwrap().ends_with("→ metres"));
    let m = &loaded.model;
    assert_eq!(m.name, "textured_simple_reoriented");
    assert_eq!(m.primitives.len(), 1);
    let p = &m.primitives[0];
    assert_eq!(p.material.base_color, [0.639216; 3]);
    assert!(p.material.texture.is_none());
    // Ns 0: fully rough, no highlight.
    assert_eq!(p.material.specular, 0.0);
    assert!(m.triangle_count() > 1000);
    // A power drill is roughly 10-30 cm in each direction.
    let size = m.aabb().unwrap().size();
    assert!(
        size.max_element() > 0.1 && size.max_element() < 0.4,
        "{size}"
    );
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn ycb_banana_loads_its_texture_and_uvs() {
    let data = shared_data();
    let path = data.join("ycb/YcbBanana/textured_simple_reoriented.obj");
    let warnings = Warnings::default();
    let mut cache = TextureCache::new();
    let loaded = load_model_cached(&path, Units::Auto, &warnings, &mut cache).unwrap();
    assert!(warnings.take().is_empty());
    assert_eq!(loaded.units_used, Units::M);

    let (w, h) = image::image_dimensions(data.join("ycb/YcbBanana/texture_map.png")).unwrap();
    let p = &loaded.model.primitives[0];
    let tex = p.material.texture.as_ref().expect("banana texture loads");
    assert_eq!((tex.width, tex.height), (w, h));
    assert_eq!(tex.rgb.len(), (w * h * 3) as usize);
    assert_eq!(p.material.base_color, [1.0; 3]);
    let uvs = p.uvs.as_ref().expect("banana has uvs");
    assert_eq!(uvs.len(), p.positions_m.len());
    assert!(uvs.iter().all(|uv| uv.x.is_finite() && uv.y.is_finite()));
    // A banana is mostly yellow: the texture sampled at its uvs is more red+green than blue.
    let mean_rg_minus_b: f32 = uvs
        .iter()
        .take(2000)
        .map(|uv| {
            let x = ((uv.x.clamp(0.0, 1.0) * (w - 1) as f32) as usize).min(w as usize - 1);
            let y = ((uv.y.clamp(0.0, 1.0) * (h - 1) as f32) as usize).min(h as usize - 1);
            let px = &tex.rgb[(y * w as usize + x) * 3..][..3];
            (f32::from(px[0]) + f32::from(px[1])) / 2.0 - f32::from(px[2])
        })
        .sum::<f32>()
        / 2000.0;
    assert!(mean_rg_minus_b > 30.0, "{mean_rg_minus_b}");

    // Loading again with the same cache shares the decoded texture.
    let again = load_model_cached(&path, Units::Auto, &warnings, &mut cache).unwrap();
    let tex2 = again.model.primitives[0].material.texture.as_ref().unwrap();
    assert!(std::sync::Arc::ptr_eq(tex, tex2));
    assert_eq!(cache.len(), 1);
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn ycb_scissors_load_with_texture() {
    let data = shared_data();
    let path = data.join("ycb/YcbScissors/textured_simple_reoriented.obj");
    let warnings = Warnings::default();
    let loaded = load_model(&path, Units::M, &warnings).unwrap();
    assert!(warnings.take().is_empty());
    assert!(loaded.auto_note.is_none());
    assert!(loaded.model.primitives[0].material.texture.is_some());
}
