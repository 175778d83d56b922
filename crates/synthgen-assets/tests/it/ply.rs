//! PLY: ASCII and binary agree, unknown elements and properties are skipped, write_ply round
//! trips.

use std::path::Path;

use synthgen_assets::{load_model, write_ply, Units};
use synthgen_core::glam::{Vec2, Vec3};
use synthgen_core::{Material, Model, NoProgress, Primitive};

use crate::shared_data;

/// A square pyramid: 5 vertices, a quad base (fan-triangulated) and 4 triangles. Each vertex
/// also has an unknown float `quality` and an unknown list `tags`; each face an unknown `flags`
/// int; an unknown `edge` element sits between vertices and faces.
const VERTS: [[f32; 9]; 5] = [
    // x y z nx ny nz r g b (uchar)
    [0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 255.0, 0.0, 0.0],
    [10.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 255.0, 0.0],
    [10.0, 10.0, 0.0, 0.0, 0.0, -2.0, 0.0, 0.0, 255.0],
    [0.0, 10.0, 0.0, 0.0, 0.0, -1.0, 10.0, 20.0, 30.0],
    [5.0, 5.0, 7.5, 0.0, 0.0, 1.0, 128.0, 128.0, 128.0],
];
const FACES: &[&[i32]] = &[
    &[0, 3, 2, 1],
    &[0, 1, 4],
    &[1, 2, 4],
    &[2, 3, 4],
    &[3, 0, 4],
];

const HEADER_TAIL: &str = "element vertex 5
property float x
property float y
property float z
property float quality
property list uchar int tags
property float nx
property float ny
property float nz
property uchar red
property uchar green
property uchar blue
property uchar alpha
element edge 2
property int vertex1
property list uchar uint extra
property int vertex2
element face 5
property list uchar int vertex_indices
property int flags
end_header
";

pub fn ascii_pyramid() -> String {
    let mut s = format!("ply\nformat ascii 1.0\ncomment made by a test\n{HEADER_TAIL}");
    for (i, v) in VERTS.iter().enumerate() {
        let tags = if i % 2 == 0 { "2 7 8" } else { "0" };
        s += &format!(
            "{} {} {} 0.5 {tags} {} {} {} {} {} {} 255\n",
            v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8]
        );
    }
    s += "0 3 1 2 3 1\n4 1 0 2\n";
    for f in FACES {
        let idx: Vec<String> = f.iter().map(|i| i.to_string()).collect();
        s += &format!("{} {} 9\n", f.len(), idx.join(" "));
    }
    s
}

pub fn binary_pyramid() -> Vec<u8> {
    let mut b = format!("ply\nformat binary_little_endian 1.0\n{HEADER_TAIL}").into_bytes();
    for (i, v) in VERTS.iter().enumerate() {
        for c in &v[..3] {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.extend_from_slice(&0.5f32.to_le_bytes());
        if i % 2 == 0 {
            b.push(2);
            b.extend_from_slice(&7i32.to_le_bytes());
            b.extend_from_slice(&8i32.to_le_bytes());
        } else {
            b.push(0);
        }
        for c in &v[3..6] {
            b.extend_from_slice(&c.to_le_bytes());
        }
        b.extend_from_slice(&[v[6] as u8, v[7] as u8, v[8] as u8, 255]);
    }
    // edges: vertex1, list extra (uint), vertex2
    b.extend_from_slice(&0i32.to_le_bytes());
    b.push(1);
    b.extend_from_slice(&2u32.to_le_bytes());
    b.extend_from_slice(&3i32.to_le_bytes());
    b.extend_from_slice(&4i32.to_le_bytes());
    b.push(0);
    b.extend_from_slice(&2i32.to_le_bytes());
    for f in FACES {
        b.push(f.len() as u8);
        for i in *f {
            b.extend_from_slice(&i.to_le_bytes());
        }
        b.extend_from_slice(&9i32.to_le_bytes());
    }
    b
}

fn load(path: &Path, units: Units) -> Model {
    load_model(path, units, &NoProgress).unwrap().model
}

#[test]
fn ascii_and_binary_of_the_same_mesh_give_the_same_model() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a/pyr.ply"), dir.path().join("b/pyr.ply"));
    std::fs::create_dir_all(a.parent().unwrap()).unwrap();
    std::fs::create_dir_all(b.parent().unwrap()).unwrap();
    std::fs::write(&a, ascii_pyramid()).unwrap();
    std::fs::write(&b, binary_pyramid()).unwrap();
    let mut ma = load(&a, Units::Mm);
    let mb = load(&b, Units::Mm);
    ma.source = mb.source.clone();
    assert_eq!(ma, mb);

    let p = &ma.primitives[0];
    assert_eq!(p.positions_m[4], Vec3::new(0.005, 0.005, 0.0075));
    // Quad 0 3 2 1 as a fan, then the four triangles, winding kept.
    assert_eq!(
        p.triangles,
        vec![
            [0, 3, 2],
            [0, 2, 1],
            [0, 1, 4],
            [1, 2, 4],
            [2, 3, 4],
            [3, 0, 4]
        ]
    );
    assert_eq!(
        p.colors.as_ref().unwrap()[3],
        [10.0 / 255.0, 20.0 / 255.0, 30.0 / 255.0]
    );
    // Normal (0, 0, -2) renormalized.
    assert_eq!(p.normals.as_ref().unwrap()[2], Vec3::new(0.0, 0.0, -1.0));
}

#[test]
fn ascii_with_crlf_double_coordinates_and_uv_names() {
    let text = "ply\r\nformat ascii 1.0\r\nelement vertex 3\r\nproperty double x\r\n\
                property double y\r\nproperty double z\r\nproperty float s\r\nproperty float t\r\n\
                element face 1\r\nproperty list uint uint vertex_index\r\nend_header\r\n\
                0 0 0 0 0\r\n1 0 0 1 0\r\n\r\n0 1 0 0 1\r\n3 0 1 2\r\n";
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tri.ply");
    std::fs::write(&path, text).unwrap();
    let loaded = load_model(&path, Units::Auto, &NoProgress).unwrap();
    assert_eq!(loaded.units_used, Units::M);
    let p = &loaded.model.primitives[0];
    assert_eq!(p.positions_m, vec![Vec3::ZERO, Vec3::X, Vec3::Y]);
    // PLY v = 0 is the bottom: stored flipped.
    assert_eq!(
        p.uvs.as_ref().unwrap(),
        &vec![Vec2::new(0.0, 1.0), Vec2::new(1.0, 1.0), Vec2::ZERO]
    );
    assert!(p.normals.is_none() && p.colors.is_none());
    assert_eq!(p.material, Material::default());
}

#[test]
fn write_ply_round_trips_positions_colours_and_faces() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("pyr.ply");
    std::fs::write(&src, ascii_pyramid()).unwrap();
    let original = load(&src, Units::Mm);

    let out = dir.path().join("out.ply");
    write_ply(&out, &original, 1000.0).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    let back = load(&out, Units::Mm);
    let (p, q) = (&original.primitives[0], &back.primitives[0]);
    assert_eq!(q.positions_m.len(), p.positions_m.len());
    for (a, b) in p.positions_m.iter().zip(&q.positions_m) {
        assert!((*a - *b).abs().max_element() < 1e-9, "{a} vs {b}");
    }
    assert_eq!(q.colors, p.colors);
    assert_eq!(q.normals, p.normals);
    assert_eq!(q.triangles, p.triangles);
    // No temporary file left behind.
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

#[test]
fn write_ply_merges_primitives_and_bakes_flat_colours() {
    let mut model = Model::cuboid("box", Vec3::new(0.1, 0.2, 0.3));
    model.primitives[0].material.base_color = [1.0, 0.5, 0.0];
    let mut second = Model::cuboid("b2", Vec3::splat(0.05)).primitives.remove(0);
    second.colors = Some(vec![[0.5, 0.5, 1.0]; 8]);
    second.material.base_color = [1.0, 1.0, 0.5];
    model.primitives.push(second);

    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("box.ply");
    write_ply(&out, &model, 1.0).unwrap();
    let back = load(&out, Units::M);
    assert_eq!(back.primitives.len(), 1);
    let q = &back.primitives[0];
    assert_eq!(q.positions_m.len(), 16);
    assert!(q.normals.is_none(), "no primitive had normals");
    let merged: Vec<Vec3> = model.positions().collect();
    assert_eq!(q.positions_m, merged);
    let colors = q.colors.as_ref().unwrap();
    assert_eq!(colors[0], [1.0, 128.0 / 255.0, 0.0]);
    assert_eq!(colors[8], [128.0 / 255.0, 128.0 / 255.0, 128.0 / 255.0]);
    assert_eq!(q.triangles[..12], model.primitives[0].triangles[..]);
    let shifted: Vec<[u32; 3]> = model.primitives[1]
        .triangles
        .iter()
        .map(|t| t.map(|i| i + 8))
        .collect();
    assert_eq!(q.triangles[12..], shifted[..]);
}

#[test]
fn write_ply_bakes_textures_into_vertex_colours() {
    let tex = synthgen_core::Texture {
        width: 2,
        height: 1,
        rgb: vec![255, 0, 0, 0, 0, 255],
        source: "t.png".into(),
    };
    let prim = Primitive {
        positions_m: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        uvs: Some(vec![
            Vec2::new(0.25, 0.5),
            Vec2::new(0.75, 0.5),
            Vec2::new(0.25, 0.5),
        ]),
        triangles: vec![[0, 1, 2]],
        material: Material {
            base_color: [1.0; 3],
            texture: Some(std::sync::Arc::new(tex)),
            ..Default::default()
        },
        ..Default::default()
    };
    let model = Model {
        name: "t".into(),
        source: "t".into(),
        primitives: vec![prim],
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.ply");
    write_ply(&out, &model, 1.0).unwrap();
    let back = load(&out, Units::M);
    let c = back.primitives[0].colors.clone().unwrap();
    assert_eq!(c, vec![[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]);
}

#[test]
#[cfg_attr(
    not(has_shared_data),
    ignore = "needs ../shared/data beside the checkout (probed when the crate was built)"
)]
fn lmo_model_written_in_mm_reads_back_identically() {
    let data = shared_data();
    let original = load(&data.join("lmo/models/obj_000001.ply"), Units::Mm);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("obj_000001.ply");
    write_ply(&out, &original, 1000.0).unwrap();
    let back = load(&out, Units::Auto);
    let (p, q) = (&original.primitives[0], &back.primitives[0]);
    assert_eq!(q.triangles, p.triangles);
    assert_eq!(q.colors, p.colors);
    for (a, b) in p.positions_m.iter().zip(&q.positions_m) {
        assert!((*a - *b).abs().max_element() < 1e-7, "{a} vs {b}");
    }
    for (a, b) in p
        .normals
        .as_ref()
        .unwrap()
        .iter()
        .zip(q.normals.as_ref().unwrap())
    {
        assert!((*a - *b).abs().max_element() < 1e-6);
    }
}

#[test]
fn ply_texture_file_comment_loads_the_texture() {
    let dir = tempfile::tempdir().unwrap();
    image::RgbImage::from_raw(1, 2, vec![1, 2, 3, 4, 5, 6])
        .unwrap()
        .save(dir.path().join("obj_000001.png"))
        .unwrap();
    let text = "ply\nformat ascii 1.0\ncomment TextureFile obj_000001.png\nelement vertex 3\n\
                property float x\nproperty float y\nproperty float z\nproperty float texture_u\n\
                property float texture_v\nelement face 1\nproperty list uchar int vertex_indices\n\
                end_header\n0 0 0 0 0\n10 0 0 1 0\n0 10 0 0 1\n3 0 1 2\n";
    let path = dir.path().join("obj_000001.ply");
    std::fs::write(&path, text).unwrap();
    let warnings = crate::Warnings::default();
    let m = load_model(&path, Units::Mm, &warnings).unwrap().model;
    assert!(warnings.take().is_empty());
    let mat = &m.primitives[0].material;
    let tex = mat
        .texture
        .as_ref()
        .expect("texture from the TextureFile comment");
    assert_eq!(
        (tex.width, tex.height, tex.rgb.clone()),
        (1, 2, vec![1, 2, 3, 4, 5, 6])
    );
    assert_eq!(mat.base_color, [1.0; 3]);

    // Missing: a warning naming the file, and the model still loads.
    std::fs::remove_file(dir.path().join("obj_000001.png")).unwrap();
    let m = load_model(&path, Units::Mm, &warnings).unwrap().model;
    assert!(m.primitives[0].material.texture.is_none());
    let w = warnings.take();
    assert_eq!(w.len(), 1);
    assert!(
        w[0].starts_with("texture not found") && w[0].ends_with("obj_000001.png"),
        "{w:?}"
    );
}
