//! glTF 2.0 (.gltf with external or embedded buffers, .glb) through the gltf crate.
//!
//! The default scene (or the first, or every root node when there is none) is flattened:
//! each triangle primitive becomes one of ours with its node's world transform applied
//! (normals with the normal matrix; winding flipped under a mirroring transform).

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use ::gltf::image::Source;
use ::gltf::mesh::Mode;
use ::gltf::Semantic;
use synthgen_core::glam::{Mat3, Mat4, Vec2, Vec3};
use synthgen_core::{Material, Model, Primitive, Progress, Texture};

use crate::texture::TextureCache;
use crate::Error;

/// Deeper node nesting than this is taken as a cycle (invalid glTF).
const MAX_DEPTH: usize = 256;

struct Ctx<'a> {
    path: &'a Path,
    base: &'a Path,
    buffers: &'a [::gltf::buffer::Data],
    textures: &'a mut TextureCache,
    embedded: HashMap<usize, Option<Arc<Texture>>>,
    progress: &'a dyn Progress,
    primitives: Vec<Primitive>,
}

/// Loads a glTF/GLB file in its raw units (metres by the spec).
pub(crate) fn load_gltf(
    path: &Path,
    textures: &mut TextureCache,
    progress: &dyn Progress,
) -> Result<Model, Error> {
    // The gltf crate also panics while reading primitives of some malformed files (an
    // `unreachable!` in gltf 1.4.1's mesh reader, found by fuzzing), so the whole load is
    // guarded.
    crate::guard_parser("gltf", || load_gltf_unguarded(path, textures, progress)).map_err(
        |reason| Error::Gltf {
            reason,
            path: path.to_path_buf(),
        },
    )?
}

fn load_gltf_unguarded(
    path: &Path,
    textures: &mut TextureCache,
    progress: &dyn Progress,
) -> Result<Model, Error> {
    let gltf_err = |reason: String| Error::Gltf {
        reason,
        path: path.to_path_buf(),
    };
    let bytes = crate::read_file(path)?;
    let ::gltf::Gltf { document, blob } =
        crate::guard_parser("gltf", || ::gltf::Gltf::from_slice(&bytes))
            .map_err(gltf_err)?
            .map_err(|e| gltf_err(e.to_string()))?;
    let base = crate::model_dir(path);
    // import_buffers reports a missing .bin as a bare "No such file or directory": name it.
    for buffer in document.buffers() {
        if let ::gltf::buffer::Source::Uri(uri) = buffer.source() {
            if uri.starts_with("data:") {
                continue;
            }
            let file = base.join(percent_decode(uri));
            if !file.is_file() {
                return Err(gltf_err(format!(
                    "buffer {} ({uri:?}) is missing: {}",
                    buffer.index(),
                    file.display()
                )));
            }
        }
    }
    let buffers = crate::guard_parser("gltf", || {
        ::gltf::import_buffers(&document, Some(&base), blob)
    })
    .map_err(gltf_err)?
    .map_err(|e| gltf_err(format!("buffers: {e}")))?;

    let roots: Vec<::gltf::Node> = match document
        .default_scene()
        .or_else(|| document.scenes().next())
    {
        Some(scene) => scene.nodes().collect(),
        None => {
            let children: Vec<usize> = document
                .nodes()
                .flat_map(|n| n.children().map(|c| c.index()).collect::<Vec<_>>())
                .collect();
            document
                .nodes()
                .filter(|n| !children.contains(&n.index()))
                .collect()
        }
    };
    let mut ctx = Ctx {
        path,
        base: &base,
        buffers: &buffers,
        textures,
        embedded: HashMap::new(),
        progress,
        primitives: Vec::new(),
    };
    for node in roots {
        walk(&mut ctx, &node, Mat4::IDENTITY, 0)?;
    }
    Ok(Model {
        name: crate::file_stem(path),
        source: path.to_path_buf(),
        primitives: ctx.primitives,
    })
}

fn walk(ctx: &mut Ctx, node: &::gltf::Node, parent: Mat4, depth: usize) -> Result<(), Error> {
    if depth > MAX_DEPTH {
        return Err(Error::Gltf {
            reason: format!("node hierarchy deeper than {MAX_DEPTH} (a cycle?)"),
            path: ctx.path.to_path_buf(),
        });
    }
    let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
    if let Some(mesh) = node.mesh() {
        for prim in mesh.primitives() {
            if prim.mode() != Mode::Triangles {
                ctx.progress.warn(&format!(
                    "skipped a {:?} primitive of mesh {}: only triangles are supported: {}",
                    prim.mode(),
                    mesh.name().unwrap_or("(unnamed)"),
                    ctx.path.display()
                ));
                continue;
            }
            if let Some(p) = convert_primitive(ctx, &prim, world)? {
                ctx.primitives.push(p);
            }
        }
    }
    for child in node.children() {
        walk(ctx, &child, world, depth + 1)?;
    }
    Ok(())
}

fn convert_primitive(
    ctx: &mut Ctx,
    prim: &::gltf::Primitive,
    world: Mat4,
) -> Result<Option<Primitive>, Error> {
    let buffers = ctx.buffers;
    let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.0.as_slice()));
    // The reader answers `None` both for an absent attribute and for an accessor outside its
    // buffer; the second is a broken file, not a missing attribute.
    let check = |read: bool, declared: bool, what: &str| {
        if declared && !read {
            Err(Error::Gltf {
                reason: format!("{what} accessor lies outside its buffer"),
                path: ctx.path.to_path_buf(),
            })
        } else {
            Ok(())
        }
    };
    let positions = reader.read_positions();
    check(
        positions.is_some(),
        prim.get(&Semantic::Positions).is_some(),
        "POSITION",
    )?;
    let Some(positions) = positions else {
        ctx.progress.warn(&format!(
            "skipped a primitive without positions: {}",
            ctx.path.display()
        ));
        return Ok(None);
    };
    let positions_m: Vec<Vec3> = positions
        .map(|p| world.transform_point3(Vec3::from(p)))
        .collect();
    let n = positions_m.len();
    let normal_from_obj = Mat3::from_mat4(world).inverse().transpose();
    let normals = reader.read_normals().map(|it| {
        it.map(|v| normal_from_obj * Vec3::from(v))
            .collect::<Vec<_>>()
    });
    check(
        normals.is_some(),
        prim.get(&Semantic::Normals).is_some(),
        "NORMAL",
    )?;
    // glTF vertex colours are linear; ours are sRGB.
    let colors = reader.read_colors(0).map(|it| {
        it.into_rgb_f32()
            .map(|c| c.map(linear_to_srgb))
            .collect::<Vec<_>>()
    });
    check(
        colors.is_some(),
        prim.get(&Semantic::Colors(0)).is_some(),
        "COLOR_0",
    )?;

    let indices = reader.read_indices();
    check(indices.is_some(), prim.indices().is_some(), "indices")?;
    let mut triangles: Vec<[u32; 3]> = match indices {
        Some(idx) => {
            let idx: Vec<u32> = idx.into_u32().collect();
            idx.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
        }
        None => (0..(n / 3) as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect(),
    };
    if world.determinant() < 0.0 {
        // A mirroring transform turns counter-clockwise into clockwise.
        for t in &mut triangles {
            t.swap(1, 2);
        }
    }

    let gm = prim.material();
    let pbr = gm.pbr_metallic_roughness();
    let [r, g, b, _a] = pbr.base_color_factor();
    let info = pbr.base_color_texture();
    let texture = info
        .as_ref()
        .and_then(|i| load_texture(ctx, &i.texture().source()));
    // glTF's v = 0 is already the top row.
    let uv_set = info.as_ref().map_or(0, |i| i.tex_coord());
    let uvs = reader
        .read_tex_coords(uv_set)
        .map(|it| it.into_f32().map(Vec2::from).collect::<Vec<_>>());
    let declared = prim.get(&Semantic::TexCoords(uv_set)).is_some();
    check(uvs.is_some(), declared, "TEXCOORD")?;
    let roughness = pbr.roughness_factor().clamp(0.0, 1.0);
    let metallic = pbr.metallic_factor().clamp(0.0, 1.0);
    // Rough Blinn-Phong equivalent of metallic-roughness: exponent from the GGX alpha (Walter
    // et al. 2007: n = 2/α² − 2), weight fading with roughness.
    let alpha = (roughness * roughness).max(0.03);
    let material = Material {
        base_color: [r, g, b].map(linear_to_srgb),
        texture,
        specular: (1.0 - roughness) * (0.25 + 0.75 * metallic),
        shininess: (2.0 / (alpha * alpha) - 2.0).clamp(1.0, 1000.0),
        double_sided: gm.double_sided(),
    };
    Ok(Some(Primitive {
        positions_m,
        normals,
        colors,
        uvs,
        triangles,
        material,
    }))
}

fn load_texture(ctx: &mut Ctx, image: &::gltf::Image) -> Option<Arc<Texture>> {
    const FALLBACK: &str = "the base colour factor";
    // A plain relative file: through the shared cache, with its "not found" warning.
    if let Source::Uri { uri, .. } = image.source() {
        if !uri.contains(':') && !uri.contains('%') {
            return ctx
                .textures
                .load(&ctx.base.join(uri), FALLBACK, ctx.progress);
        }
    }
    if let Some(t) = ctx.embedded.get(&image.index()) {
        return t.clone();
    }
    let label = format!("{}#image{}", ctx.path.display(), image.index());
    let decoded = ::gltf::image::Data::from_source(image.source(), Some(ctx.base), ctx.buffers)
        .map_err(|e| e.to_string())
        .and_then(|d| to_texture(d, &label));
    let texture = match decoded {
        Ok(t) => Some(Arc::new(t)),
        Err(reason) => {
            ctx.progress.warn(&format!(
                "texture unreadable ({reason}), using {FALLBACK}: {label}"
            ));
            None
        }
    };
    ctx.embedded.insert(image.index(), texture.clone());
    texture
}

/// 8- and 16-bit grey, grey+alpha, RGB and RGBA images to 8-bit RGB.
fn to_texture(d: ::gltf::image::Data, label: &str) -> Result<Texture, String> {
    use ::gltf::image::Format as F;
    let (channels, bytes_per_channel) = match d.format {
        F::R8 => (1, 1),
        F::R8G8 => (2, 1),
        F::R8G8B8 => (3, 1),
        F::R8G8B8A8 => (4, 1),
        F::R16 => (1, 2),
        F::R16G16 => (2, 2),
        F::R16G16B16 => (3, 2),
        F::R16G16B16A16 => (4, 2),
        other => return Err(format!("unsupported pixel format {other:?}")),
    };
    let pixel = channels * bytes_per_channel;
    let count = d.width as usize * d.height as usize;
    if d.pixels.len() < count * pixel {
        return Err("pixel data shorter than the image".into());
    }
    let channel = |px: &[u8], c: usize| -> u8 {
        if bytes_per_channel == 1 {
            px[c]
        } else {
            // The decoder's 16-bit samples are native-endian.
            (u16::from_ne_bytes([px[2 * c], px[2 * c + 1]]) >> 8) as u8
        }
    };
    let mut rgb = Vec::with_capacity(count * 3);
    for px in d.pixels.chunks_exact(pixel).take(count) {
        if channels >= 3 {
            rgb.extend_from_slice(&[channel(px, 0), channel(px, 1), channel(px, 2)]);
        } else {
            let v = channel(px, 0);
            rgb.extend_from_slice(&[v, v, v]);
        }
    }
    Ok(Texture {
        width: d.width,
        height: d.height,
        rgb,
        source: label.into(),
    })
}

/// Linear to sRGB transfer function (IEC 61966-2-1).
pub(crate) fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x == 1.0 {
        // Exact, so the default factor 1 leaves textures and vertex colours untouched (the
        // formula gives 0.99999994 in f32).
        1.0
    } else if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// A URI's %XX escapes decoded (glTF buffer URIs are URI references: `my%20mesh.bin`).
fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        match (
            b[i],
            b.get(i + 1).copied().and_then(hex),
            b.get(i + 2).copied().and_then(hex),
        ) {
            (b'%', Some(h), Some(l)) => {
                out.push((h * 16 + l) as u8);
                i += 3;
            }
            (c, _, _) => {
                out.push(c);
                i += 1;
            }
        }
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn srgb_transfer_known_values() {
        assert_eq!(linear_to_srgb(0.0), 0.0);
        assert_eq!(linear_to_srgb(1.0), 1.0);
        assert!((linear_to_srgb(0.214_041) - 0.5).abs() < 1e-4);
    }
}
