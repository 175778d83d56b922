//! Writing a model as one binary PLY, the way BOP's `models/obj_XXXXXX.ply` are stored.

use std::path::Path;

use synthgen_core::glam::Vec3;
use synthgen_core::Model;

use crate::texture::sample_bilinear;
use crate::validate::smooth_normals;
use crate::Error;

/// Writes `model` as a single binary_little_endian PLY with positions multiplied by `scale`
/// (1000.0 writes millimetres, as BOP and Linemod want).
///
/// Properties: `x y z` float; `nx ny nz` float when any primitive has normals (primitives
/// without get smooth normals); `red green blue alpha` uchar, always: the colour a renderer
/// would show, i.e. vertex colour × material base colour × the texture sampled at the vertex
/// uv, so flat-coloured and texture-only models keep their colour (a texture becomes per-vertex
/// colour, as coarse as the mesh). Faces: `list uchar int vertex_indices`, primitives merged.
///
/// The file is written to a temporary file in the same directory and renamed into place, so
/// a reader never sees half a model.
pub fn write_ply(path: &Path, model: &Model, scale: f32) -> Result<(), Error> {
    let bytes = encode_ply(model, scale).map_err(|reason| Error::Write {
        path: path.to_path_buf(),
        source: std::io::Error::new(std::io::ErrorKind::InvalidInput, reason),
    })?;
    synthgen_core::atomic::write_atomic(path, &bytes, true).map_err(|(_, source)| Error::Write {
        path: path.to_path_buf(),
        source,
    })
}

fn encode_ply(model: &Model, scale: f32) -> Result<Vec<u8>, String> {
    let nv = model.vertex_count();
    let nt = model.triangle_count();
    if i32::try_from(nv).is_err() {
        return Err(format!("{nv} vertices do not fit a ply int index"));
    }
    let with_normals = model.primitives.iter().any(|p| p.normals.is_some());

    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    header.push_str(&format!("comment synthgen {}\n", synthgen_core::VERSION));
    header.push_str(&format!("element vertex {nv}\n"));
    header.push_str("property float x\nproperty float y\nproperty float z\n");
    if with_normals {
        header.push_str("property float nx\nproperty float ny\nproperty float nz\n");
    }
    header.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
    header.push_str("property uchar alpha\n");
    header.push_str(&format!("element face {nt}\n"));
    header.push_str("property list uchar int vertex_indices\nend_header\n");

    let vertex_size = 12 + if with_normals { 12 } else { 0 } + 4;
    let mut out = Vec::with_capacity(header.len() + nv * vertex_size + nt * 13);
    out.extend_from_slice(header.as_bytes());

    for prim in &model.primitives {
        let normals = vertex_normals(prim, with_normals);
        for (i, p) in prim.positions_m.iter().enumerate() {
            for c in (*p * scale).to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
            if let Some(n) = &normals {
                let n = n.get(i).copied().unwrap_or(Vec3::Z);
                for c in n.to_array() {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
            for c in shown_color(prim, i) {
                out.push(to_u8(c));
            }
            out.push(255);
        }
    }

    let mut base = 0u32;
    for prim in &model.primitives {
        for tri in &prim.triangles {
            out.push(3);
            for &i in tri {
                // Fits: nv < i32::MAX was checked above and indices are below nv.
                out.extend_from_slice(&((base + i) as i32).to_le_bytes());
            }
        }
        base += prim.positions_m.len() as u32;
    }
    Ok(out)
}

/// A primitive's vertex normals: its own, else smooth ones when the file gets normals.
fn vertex_normals(prim: &synthgen_core::Primitive, with_normals: bool) -> Option<Vec<Vec3>> {
    match &prim.normals {
        Some(n) => Some(n.clone()),
        None if with_normals => Some(smooth_normals(&prim.positions_m, &prim.triangles)),
        None => None,
    }
}

/// The colour a renderer shows at vertex `i`: vertex colour × base colour × texture at its uv.
fn shown_color(prim: &synthgen_core::Primitive, i: usize) -> [f32; 3] {
    let mut rgb = prim
        .colors
        .as_ref()
        .and_then(|c| c.get(i).copied())
        .unwrap_or([1.0; 3]);
    let texture = prim.material.texture.as_deref().zip(prim.uvs.as_deref());
    if let Some((tex, uvs)) = texture {
        if let Some(&uv) = uvs.get(i) {
            let t = sample_bilinear(tex, uv);
            rgb = [rgb[0] * t[0], rgb[1] * t[1], rgb[2] * t[2]];
        }
    }
    let base = prim.material.base_color;
    [rgb[0] * base[0], rgb[1] * base[1], rgb[2] * base[2]]
}

/// Writes `model` as one OBJ with positions multiplied by `scale`, the colour a renderer
/// shows as vertex colours (`v x y z r g b`, as YCB-Video's `textured_simple.obj` has them),
/// vertex normals when any primitive has them, and beside it `<file>.mtl` with one white,
/// opaque material (`Kd 1 1 1`, `d 1`), so that loaders show the vertex colours alone.
/// Textures become per-vertex colour, as coarse as the mesh. Both files are written
/// atomically.
pub fn write_obj(path: &Path, model: &Model, scale: f32) -> Result<(), Error> {
    use std::fmt::Write as _;
    let file_name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "model.obj".into());
    let mtl_name = format!("{file_name}.mtl");
    let with_normals = model.primitives.iter().any(|p| p.normals.is_some());
    let mut out = String::with_capacity(model.vertex_count() * 80 + model.triangle_count() * 30);
    let _ = writeln!(out, "# synthgen {}", synthgen_core::VERSION);
    let _ = writeln!(out, "mtllib ./{mtl_name}");
    let _ = writeln!(out, "usemtl material_0");
    for prim in &model.primitives {
        let normals = vertex_normals(prim, with_normals);
        for (i, p) in prim.positions_m.iter().enumerate() {
            if let Some(n) = &normals {
                let n = n.get(i).copied().unwrap_or(Vec3::Z);
                let _ = writeln!(out, "vn {} {} {}", n.x, n.y, n.z);
            }
            let p = *p * scale;
            let [r, g, b] = shown_color(prim, i).map(|c| c.clamp(0.0, 1.0));
            let _ = writeln!(out, "v {} {} {} {r:.6} {g:.6} {b:.6}", p.x, p.y, p.z);
        }
    }
    let mut base = 1usize;
    for prim in &model.primitives {
        for tri in &prim.triangles {
            let [a, b, c] = tri.map(|i| base + i as usize);
            if with_normals {
                let _ = writeln!(out, "f {a}//{a} {b}//{b} {c}//{c}");
            } else {
                let _ = writeln!(out, "f {a} {b} {c}");
            }
        }
        base += prim.positions_m.len();
    }
    let mtl = "newmtl material_0\nKa 0.200000 0.200000 0.200000\nKd 1.000000 1.000000 1.000000\n\
               Ks 0.000000 0.000000 0.000000\nd 1.000000\nillum 1\n";
    let write = |p: &Path, bytes: &[u8]| {
        synthgen_core::atomic::write_atomic(p, bytes, true).map_err(|(_, source)| Error::Write {
            path: p.to_path_buf(),
            source,
        })
    };
    write(&path.with_file_name(&mtl_name), mtl.as_bytes())?;
    write(path, out.as_bytes())
}

fn to_u8(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0).round() as u8
}
