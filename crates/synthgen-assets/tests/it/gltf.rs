//! glTF/GLB: tiny files generated here (a triangle with normals and uvs), checking node
//! transforms, colours, textures and the skipping of non-triangle primitives.

use std::path::Path;

use synthgen_assets::{load_model, Units};
use synthgen_core::glam::{Vec2, Vec3};

use crate::Warnings;

fn base64(bytes: &[u8]) -> String {
    const A: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (u32::from(c[0]) << 16)
            | (u32::from(*c.get(1).unwrap_or(&0)) << 8)
            | u32::from(*c.get(2).unwrap_or(&0));
        for k in 0..4 {
            if k <= c.len() {
                s.push(A[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                s.push('=');
            }
        }
    }
    s
}

/// Binary buffer: positions (36 B), normals (36 B), uvs (24 B), u16 indices (6 B + 2 pad).
fn buffer() -> Vec<u8> {
    let mut b = Vec::new();
    for v in [[0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        v.iter().for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
    }
    for _ in 0..3 {
        [0f32, 0.0, 1.0]
            .iter()
            .for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
    }
    for uv in [[0.25f32, 0.5], [0.75, 0.5], [0.25, 0.5]] {
        uv.iter()
            .for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
    }
    for i in [0u16, 1, 2] {
        b.extend_from_slice(&i.to_le_bytes());
    }
    b.extend_from_slice(&[0, 0]);
    b
}

/// The document; `buffer_uri` is `None` for GLB's BIN chunk. `image` is the images entry.
fn document(buffer_uri: Option<String>, image: Option<String>, node1_scale: [f32; 3]) -> String {
    let uri = buffer_uri
        .map(|u| format!(r#""uri": "{u}","#))
        .unwrap_or_default();
    let (textures, images, tex_ref) = match image {
        Some(img) => (
            r#""textures": [{"source": 0}],"#.to_string(),
            format!(r#""images": [{img}],"#),
            r#", "baseColorTexture": {"index": 0}"#,
        ),
        None => (String::new(), String::new(), ""),
    };
    format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [
    {{"translation": [1, 2, 3], "children": [1]}},
    {{"scale": {node1_scale:?}, "mesh": 0}}
  ],
  "meshes": [{{"primitives": [
    {{"attributes": {{"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}}, "indices": 3, "material": 0}},
    {{"attributes": {{"POSITION": 0}}, "mode": 0}}
  ]}}],
  "materials": [{{"doubleSided": true, "pbrMetallicRoughness": {{
    "baseColorFactor": [0.214041, 1.0, 0.0, 1.0]{tex_ref}}}}}],
  {textures}
  {images}
  "buffers": [{{{uri} "byteLength": 104}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 72, "byteLength": 24}},
    {{"buffer": 0, "byteOffset": 96, "byteLength": 6}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
      "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"}},
    {{"bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC2"}},
    {{"bufferView": 3, "componentType": 5123, "count": 3, "type": "SCALAR"}}
  ]
}}"#
    )
}

fn embedded(image: Option<String>, scale: [f32; 3]) -> String {
    let uri = format!("data:application/octet-stream;base64,{}", base64(&buffer()));
    document(Some(uri), image, scale)
}

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn gltf_applies_node_transforms_and_converts_the_colour_factor() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "tri.gltf", &embedded(None, [2.0, 2.0, 2.0]));
    let warnings = Warnings::default();
    let loaded = load_model(&path, Units::Auto, &warnings).unwrap();
    let w = warnings.take();
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].starts_with("skipped a Points primitive") && w[0].ends_with("tri.gltf"));

    assert_eq!(loaded.units_used, Units::M);
    let m = &loaded.model;
    assert_eq!(m.primitives.len(), 1);
    let p = &m.primitives[0];
    // translation (1, 2, 3) ∘ scale 2.
    assert_eq!(
        p.positions_m,
        vec![
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(3.0, 2.0, 3.0),
            Vec3::new(1.0, 4.0, 3.0)
        ]
    );
    assert_eq!(p.triangles, vec![[0, 1, 2]]);
    assert_eq!(p.normals.as_ref().unwrap(), &vec![Vec3::Z; 3]);
    assert_eq!(p.uvs.as_ref().unwrap()[1], Vec2::new(0.75, 0.5));
    // Linear 0.214041 is sRGB 0.5.
    let c = p.material.base_color;
    assert!(
        (c[0] - 0.5).abs() < 1e-4 && c[1] == 1.0 && c[2] == 0.0,
        "{c:?}"
    );
    assert!(p.material.double_sided);
    assert!(p.material.texture.is_none());

    // Units are obeyed for glTF too.
    let mm = load_model(&path, Units::Mm, &warnings).unwrap();
    assert_eq!(
        mm.model.primitives[0].positions_m[1],
        Vec3::new(0.003, 0.002, 0.003)
    );
}

#[test]
fn gltf_mirroring_transform_keeps_triangles_front_facing() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "mirror.gltf", &embedded(None, [-1.0, 1.0, 1.0]));
    let m = load_model(&path, Units::M, &Warnings::default())
        .unwrap()
        .model;
    let p = &m.primitives[0];
    assert_eq!(p.triangles, vec![[0, 2, 1]]);
    // The normal matrix of a mirror in x leaves +z normals alone.
    assert_eq!(p.normals.as_ref().unwrap()[0], Vec3::Z);
    let [a, b, c] = p.triangles[0].map(|i| p.positions_m[i as usize]);
    assert!(
        (b - a).cross(c - a).z > 0.0,
        "counter-clockwise seen from +z"
    );
}

fn png_data_uri() -> String {
    let img = image::RgbImage::from_raw(2, 1, vec![255, 0, 0, 0, 0, 255]).unwrap();
    let mut png = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
        .unwrap();
    format!(r#"{{"uri": "data:image/png;base64,{}"}}"#, base64(&png))
}

#[test]
fn gltf_embedded_texture_is_decoded() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "tex.gltf",
        &embedded(Some(png_data_uri()), [1.0; 3]),
    );
    let m = load_model(&path, Units::M, &Warnings::default())
        .unwrap()
        .model;
    let tex = m.primitives[0].material.texture.as_ref().expect("texture");
    assert_eq!((tex.width, tex.height), (2, 1));
    assert_eq!(tex.rgb, vec![255, 0, 0, 0, 0, 255]);
}

#[test]
fn gltf_missing_texture_file_warns_and_falls_back() {
    let dir = tempfile::tempdir().unwrap();
    let img = r#"{"uri": "missing.png"}"#.to_string();
    let path = write(dir.path(), "tex.gltf", &embedded(Some(img), [1.0; 3]));
    let warnings = Warnings::default();
    let m = load_model(&path, Units::M, &warnings).unwrap().model;
    assert!(m.primitives[0].material.texture.is_none());
    let missing = dir.path().canonicalize().unwrap().join("missing.png");
    let w = warnings.take();
    assert!(
        w.contains(&format!(
            "texture not found, using the base colour factor: {}",
            missing.display()
        )),
        "{w:?}"
    );
}

#[test]
fn glb_with_bin_chunk_loads() {
    let json = document(None, None, [1.0; 3]);
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin = buffer();
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut glb = Vec::new();
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json);
    glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&bin);

    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tri.glb");
    std::fs::write(&path, glb).unwrap();
    let m = load_model(&path, Units::M, &Warnings::default())
        .unwrap()
        .model;
    assert_eq!(m.name, "tri");
    assert_eq!(m.primitives[0].positions_m[2], Vec3::new(1.0, 3.0, 3.0));
}

#[test]
fn gltf_accessor_past_its_buffer_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let text = embedded(None, [1.0; 3]).replacen(
        r#""count": 3, "type": "VEC3","#,
        r#""count": 300, "type": "VEC3","#,
        1,
    );
    let path = write(dir.path(), "bad.gltf", &text);
    let err = load_model(&path, Units::M, &Warnings::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("cannot load gltf") && err.ends_with("bad.gltf"),
        "{err}"
    );
}

/// Issue 13, item 15: a .gltf whose external buffer file is gone said only "No such file or
/// directory"; the error names the buffer and the file it looked for.
#[test]
fn gltf_missing_buffer_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "tri.gltf",
        &document(Some("my%20mesh.bin".into()), None, [1.0; 3]),
    );
    let e = load_model(&path, Units::M, &Warnings::default())
        .unwrap_err()
        .to_string();
    let want = dir.path().canonicalize().unwrap().join("my mesh.bin");
    assert!(
        e.contains("buffer 0 (\"my%20mesh.bin\") is missing")
            && e.contains(&want.display().to_string()),
        "{e}"
    );
    assert!(e.ends_with(&path.display().to_string()), "{e}");
    // With the file there, it loads.
    std::fs::write(dir.path().join("my mesh.bin"), buffer()).unwrap();
    load_model(&path, Units::M, &Warnings::default()).unwrap();
}
