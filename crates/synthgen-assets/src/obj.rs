//! OBJ + MTL through tobj: one primitive per OBJ object/material group.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use synthgen_core::glam::{Vec2, Vec3};
use synthgen_core::{Material, Model, Primitive, Progress};

use crate::texture::TextureCache;
use crate::Error;

/// Loads an OBJ file in its raw units. A missing MTL file or texture is a warning, not an
/// error: the model still has its geometry.
pub(crate) fn load_obj(
    path: &Path,
    textures: &mut TextureCache,
    progress: &dyn Progress,
) -> Result<Model, Error> {
    let bytes = crate::read_file(path)?;
    let dir = crate::model_dir(path);
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let failed_mtl: RefCell<Vec<(PathBuf, String)>> = RefCell::new(Vec::new());
    let obj_err = |reason: String| Error::Obj {
        reason,
        path: path.to_path_buf(),
    };
    let (models, materials) = crate::guard_parser("tobj", || {
        tobj::load_obj_buf(&mut std::io::Cursor::new(&bytes), &options, |mtl| {
            let mtl_path = dir.join(mtl);
            tobj::load_mtl(&mtl_path).inspect_err(|e| {
                failed_mtl
                    .borrow_mut()
                    .push((mtl_path.clone(), e.to_string()));
            })
        })
    })
    .map_err(obj_err)?
    .map_err(|e| obj_err(e.to_string()))?;
    for (mtl_path, reason) in failed_mtl.into_inner() {
        progress.warn(&format!(
            "material library unreadable ({reason}), using default materials: {}",
            mtl_path.display()
        ));
    }
    let materials = materials.unwrap_or_default();

    let mut primitives = Vec::with_capacity(models.len());
    for m in models {
        let mesh = m.mesh;
        let n = mesh.positions.len() / 3;
        let positions_m = mesh
            .positions
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect();
        let normals = (mesh.normals.len() == 3 * n && n > 0).then(|| {
            mesh.normals
                .chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2]))
                .collect()
        });
        // OBJ's v = 0 is the bottom of the image; ours is the first (top) row.
        let uvs = (mesh.texcoords.len() == 2 * n && n > 0).then(|| {
            mesh.texcoords
                .chunks_exact(2)
                .map(|c| Vec2::new(c[0], 1.0 - c[1]))
                .collect()
        });
        let colors = (mesh.vertex_color.len() == 3 * n && n > 0).then(|| {
            mesh.vertex_color
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect()
        });
        let triangles = mesh
            .indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let material = match mesh.material_id.and_then(|i| materials.get(i)) {
            Some(mtl) => convert_material(mtl, &dir, textures, progress),
            None => Material::default(),
        };
        primitives.push(Primitive {
            positions_m,
            normals,
            colors,
            uvs,
            triangles,
            material,
        });
    }
    Ok(Model {
        name: crate::file_stem(path),
        source: path.to_path_buf(),
        primitives,
    })
}

/// MTL → our material.
///
/// - `Kd` is the base colour; but when `map_Kd` loads, the base colour is white: Blender (which
///   wrote the YCB files) exports the unused default colour as `Kd` beside a texture, and
///   multiplying by it would darken every scan by a third. Blender's and trimesh's importers
///   likewise show the texture alone.
/// - Highlights: Blender writes `Ns = (1 − roughness)² · 1000`, so the specular weight is
///   mean(`Ks`) · √(`Ns` / 1000) and the Blinn-Phong exponent is `Ns` (clamped to 1..1000);
///   `Ns 0` (fully rough, as in the YCB scans, whose lighting is baked in) gives no highlight.
fn convert_material(
    mtl: &tobj::Material,
    dir: &Path,
    textures: &mut TextureCache,
    progress: &dyn Progress,
) -> Material {
    let defaults = Material::default();
    let ks = mtl
        .specular
        .map_or(defaults.specular, |k| (k[0] + k[1] + k[2]) / 3.0);
    let (specular, shininess) = match mtl.shininess {
        Some(ns) if ns.is_finite() => (
            ks * (ns.clamp(0.0, 1000.0) / 1000.0).sqrt(),
            ns.clamp(1.0, 1000.0),
        ),
        _ => (ks, defaults.shininess),
    };
    let kd = mtl.diffuse.unwrap_or(defaults.base_color);
    let texture = mtl
        .diffuse_texture
        .as_deref()
        .and_then(texture_file_name)
        .and_then(|name| textures.load(&dir.join(name), "the Kd colour", progress));
    Material {
        base_color: if texture.is_some() { [1.0; 3] } else { kd },
        texture,
        specular: specular.clamp(0.0, 1.0),
        shininess,
        double_sided: false,
    }
}

/// The file name in a `map_Kd` value, which may start with options (`-bm 0.5 -clamp on x.png`)
/// and use Windows separators.
fn texture_file_name(value: &str) -> Option<String> {
    let value = value.trim();
    let name = if value.starts_with('-') {
        value.split_ascii_whitespace().last()?
    } else {
        value
    };
    (!name.is_empty()).then(|| name.replace('\\', "/"))
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    #[test]
    fn map_kd_options_and_separators() {
        assert_eq!(
            texture_file_name("texture_map.png").unwrap(),
            "texture_map.png"
        );
        assert_eq!(
            texture_file_name("-bm 0.2 tex\\a.png").unwrap(),
            "tex/a.png"
        );
        assert_eq!(texture_file_name("  "), None);
    }
}
