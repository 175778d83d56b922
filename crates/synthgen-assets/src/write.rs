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
        let computed;
        let normals: Option<&[Vec3]> = match &prim.normals {
            Some(n) => Some(n),
            None if with_normals => {
                computed = smooth_normals(&prim.positions_m, &prim.triangles);
                Some(&computed)
            }
            None => None,
        };
        let base = prim.material.base_color;
        let texture = prim.material.texture.as_deref().zip(prim.uvs.as_deref());
        for (i, p) in prim.positions_m.iter().enumerate() {
            for c in (*p * scale).to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
            if let Some(n) = normals {
                let n = n.get(i).copied().unwrap_or(Vec3::Z);
                for c in n.to_array() {
                    out.extend_from_slice(&c.to_le_bytes());
                }
            }
            let mut rgb = prim
                .colors
                .as_ref()
                .and_then(|c| c.get(i).copied())
                .unwrap_or([1.0; 3]);
            if let Some((tex, uvs)) = texture {
                if let Some(&uv) = uvs.get(i) {
                    let t = sample_bilinear(tex, uv);
                    rgb = [rgb[0] * t[0], rgb[1] * t[1], rgb[2] * t[2]];
                }
            }
            for (c, b) in rgb.iter().zip(base) {
                out.push(to_u8(c * b));
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

fn to_u8(x: f32) -> u8 {
    (x.clamp(0.0, 1.0) * 255.0).round() as u8
}
