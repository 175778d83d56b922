//! OBJ + MTL written here: materials, uv flip, texture found and cached, missing MTL.

use std::path::Path;

use synthgen_assets::{load_model, Units};
use synthgen_core::glam::{Vec2, Vec3};

use crate::Warnings;

const OBJ: &str = "mtllib two.mtl
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 2
o first
usemtl red
f 1/1/1 2/2/1 3/3/1 4/4/1
o second
usemtl textured
f 1/1/1 3/3/1 4/4/1
o third
usemtl textured_too
f 1/1/1 2/2/1 3/3/1
";

const MTL: &str = "newmtl red
Kd 1 0 0
Ks 0.5 0.5 0.5
Ns 250
newmtl textured
Kd 0.5 0.5 0.5
map_Kd tex.png
newmtl textured_too
Kd 0.2 0.2 0.2
map_Kd -clamp on tex.png
";

fn write_png(path: &Path) {
    image::RgbImage::from_raw(2, 2, vec![255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255])
        .unwrap()
        .save(path)
        .unwrap();
}

#[test]
fn obj_materials_uvs_and_shared_textures() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("two.obj"), OBJ).unwrap();
    std::fs::write(dir.path().join("two.mtl"), MTL).unwrap();
    write_png(&dir.path().join("tex.png"));
    let warnings = Warnings::default();
    let loaded = load_model(&dir.path().join("two.obj"), Units::Mm, &warnings).unwrap();
    assert!(warnings.take().is_empty());
    let m = &loaded.model;
    assert_eq!(m.name, "two");
    assert_eq!(m.primitives.len(), 3);

    let red = &m.primitives[0];
    assert_eq!(red.triangles.len(), 2, "the quad is triangulated");
    assert_eq!(red.positions_m[2], Vec3::new(0.001, 0.001, 0.0));
    assert_eq!(red.material.base_color, [1.0, 0.0, 0.0]);
    assert!(red.material.texture.is_none());
    // Ks 0.5 · √(250 / 1000) and exponent Ns.
    assert!((red.material.specular - 0.25).abs() < 1e-6);
    assert_eq!(red.material.shininess, 250.0);
    assert_eq!(red.normals.as_ref().unwrap()[0], Vec3::Z);
    // OBJ v = 0 is the image's bottom row: stored as 1 − v.
    let uvs = red.uvs.as_ref().unwrap();
    let pos_uv: Vec<(Vec3, Vec2)> = red
        .positions_m
        .iter()
        .copied()
        .zip(uvs.iter().copied())
        .collect();
    assert!(
        pos_uv.contains(&(Vec3::ZERO, Vec2::new(0.0, 1.0))),
        "{pos_uv:?}"
    );
    assert!(pos_uv.contains(&(Vec3::new(0.001, 0.001, 0.0), Vec2::new(1.0, 0.0))));

    let (t1, t2) = (&m.primitives[1].material, &m.primitives[2].material);
    let tex = t1.texture.as_ref().expect("tex.png loads");
    assert_eq!((tex.width, tex.height), (2, 2));
    assert_eq!(
        &tex.rgb[..6],
        &[255, 0, 0, 0, 255, 0],
        "first row is the top row"
    );
    assert_eq!(t1.base_color, [1.0; 3], "the texture replaces Kd");
    assert!(
        std::sync::Arc::ptr_eq(tex, t2.texture.as_ref().unwrap()),
        "decoded once"
    );
}

#[test]
fn obj_missing_mtl_warns_and_uses_the_default_material() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("two.obj"), OBJ).unwrap();
    let warnings = Warnings::default();
    let m = load_model(&dir.path().join("two.obj"), Units::M, &warnings)
        .unwrap()
        .model;
    let w = warnings.take();
    let mtl = dir.path().canonicalize().unwrap().join("two.mtl");
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].starts_with("material library unreadable")
            && w[0].ends_with(&mtl.display().to_string()),
        "{w:?}"
    );
    assert_eq!(m.primitives[0].material, synthgen_core::Material::default());
}

#[test]
fn obj_unreadable_texture_warns_and_falls_back_to_kd() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("two.obj"), OBJ).unwrap();
    std::fs::write(dir.path().join("two.mtl"), MTL).unwrap();
    std::fs::write(dir.path().join("tex.png"), b"not a png").unwrap();
    let warnings = Warnings::default();
    let m = load_model(&dir.path().join("two.obj"), Units::M, &warnings)
        .unwrap()
        .model;
    let w = warnings.take();
    assert_eq!(
        w.len(),
        1,
        "one warning for the file both materials use: {w:?}"
    );
    assert!(
        w[0].starts_with("texture unreadable (") && w[0].contains("using the Kd colour: "),
        "{w:?}"
    );
    assert_eq!(m.primitives[1].material.base_color, [0.5; 3]);
    assert_eq!(m.primitives[2].material.base_color, [0.2; 3]);
}

#[test]
fn images_in_dir_are_sorted_and_bad_ones_skipped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("b.png"));
    image::RgbImage::from_raw(1, 1, vec![9, 9, 9])
        .unwrap()
        .save(dir.path().join("a.JPG"))
        .unwrap();
    std::fs::write(dir.path().join("c.png"), b"junk").unwrap();
    std::fs::write(dir.path().join("notes.txt"), b"not an image").unwrap();
    let warnings = Warnings::default();
    let images = synthgen_assets::load_images_in_dir(dir.path(), &warnings).unwrap();
    let names: Vec<String> = images
        .iter()
        .map(|t| t.source.file_name().unwrap().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names, ["a.JPG", "b.png"]);
    assert_eq!((images[1].width, images[1].height), (2, 2));
    let w = warnings.take();
    assert_eq!(w.len(), 1);
    assert!(
        w[0].starts_with("image unreadable (") && w[0].ends_with("c.png"),
        "{w:?}"
    );

    let missing = dir.path().join("nope");
    let err = synthgen_assets::load_images_in_dir(&missing, &warnings)
        .unwrap_err()
        .to_string();
    assert!(
        err.starts_with("cannot read file") && err.ends_with("nope"),
        "{err}"
    );
}
