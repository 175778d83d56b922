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

/// Writes the OBJ file `src` moved by `m` (`p' = m · p` in the file's own units) into `out_dir`
/// under its own name, with its material files and the textures they name copied beside it:
/// `v` positions and `vn` normals are transformed, every other line (UVs, faces, groups,
/// materials, per-vertex colours after the position) is kept as it is. Returns the files
/// written. Texture names are read as [`load_model`](crate::load_model) reads them (options,
/// backslashes and trailing spaces allowed); a missing texture is an error naming it.
pub fn write_moved_obj(
    src: &Path,
    out_dir: &Path,
    m: synthgen_core::glam::DMat4,
) -> Result<Vec<std::path::PathBuf>, Error> {
    let io = |path: &Path, e: std::io::Error| Error::Write {
        path: path.to_path_buf(),
        source: e,
    };
    let read = |path: &Path, e: std::io::Error| Error::Read {
        path: path.to_path_buf(),
        source: e,
    };
    let text = std::fs::read_to_string(src).map_err(|e| read(src, e))?;
    let dir = src.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(out_dir).map_err(|e| io(out_dir, e))?;
    let normal_m = synthgen_core::glam::DMat3::from_mat4(m)
        .inverse()
        .transpose();
    let mut out = String::with_capacity(text.len());
    let mut mtllibs = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let t = line.trim_start();
        let mut parts = t.split_ascii_whitespace();
        match parts.next() {
            Some(kind @ ("v" | "vn")) => {
                let nums: Vec<&str> = parts.collect();
                let xyz: Option<Vec<f64>> =
                    nums.iter().take(3).map(|s| s.parse::<f64>().ok()).collect();
                let xyz = xyz.filter(|v| v.len() == 3 && v.iter().all(|x| x.is_finite()));
                if xyz.is_none() && kind == "vn" {
                    // Scans ship NaN normals (YCB's tuna can and mug); readers replace them.
                    out.push_str(line);
                    out.push('\n');
                    continue;
                }
                let Some(xyz) = xyz else {
                    return Err(Error::Obj {
                        reason: format!("line {}: `{kind}` needs three finite numbers", n + 1),
                        path: src.to_path_buf(),
                    });
                };
                let p = synthgen_core::glam::DVec3::new(xyz[0], xyz[1], xyz[2]);
                let q = if kind == "v" {
                    m.transform_point3(p)
                } else {
                    (normal_m * p).normalize_or_zero()
                };
                out.push_str(&format!("{kind} {:.9} {:.9} {:.9}", q.x, q.y, q.z));
                for rest in &nums[3..] {
                    out.push(' ');
                    out.push_str(rest);
                }
                out.push('\n');
            }
            Some("mtllib") => {
                mtllibs.extend(
                    t["mtllib".len()..]
                        .split_ascii_whitespace()
                        .map(str::to_string),
                );
                out.push_str(line);
                out.push('\n');
            }
            _ => {
                out.push_str(line);
                out.push('\n');
            }
        }
    }
    let name = src.file_name().unwrap_or_default();
    let obj_out = out_dir.join(name);
    std::fs::write(&obj_out, out).map_err(|e| io(&obj_out, e))?;
    let mut written = vec![obj_out];
    for lib in mtllibs {
        let mtl = dir.join(&lib);
        let mtl_text = std::fs::read_to_string(&mtl).map_err(|e| read(&mtl, e))?;
        let dst = out_dir.join(&lib);
        std::fs::write(&dst, &mtl_text).map_err(|e| io(&dst, e))?;
        written.push(dst);
        for l in mtl_text.lines() {
            let l = l.trim_start();
            let Some((key, value)) = l.split_once(char::is_whitespace) else {
                continue;
            };
            if !key.starts_with("map_") && key != "bump" && key != "disp" && key != "norm" {
                continue;
            }
            let Some(tex) = texture_file_name(value) else {
                continue;
            };
            let (from, to) = (dir.join(&tex), out_dir.join(&tex));
            if written.contains(&to) {
                continue;
            }
            if let Some(p) = to.parent() {
                std::fs::create_dir_all(p).map_err(|e| io(p, e))?;
            }
            std::fs::copy(&from, &to).map_err(|e| read(&from, e))?;
            written.push(to);
        }
    }
    Ok(written)
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

    /// Positions and normals move, everything else is kept; the MTL and the texture it names
    /// (with a trailing space, as YCB ships it) are copied; NaN normals are left for readers.
    #[test]
    fn a_moved_obj_keeps_its_uvs_faces_and_textures() {
        use synthgen_core::glam::{DMat3, DMat4, DVec3};
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(
            d.join("a.obj"),
            "# scan\nmtllib a.mtl\nv 1 0 0 0.5 0.5 0.5\nv 0 1 0\nv 0 0 1\nvt 0.1 0.2\nvn 1 0 0\nvn nan nan nan\nusemtl m\nf 1/1/1 2/1/1 3/1/2\n",
        )
        .unwrap();
        std::fs::write(d.join("a.mtl"), "newmtl m\nmap_Kd tex.png \n").unwrap();
        std::fs::write(d.join("tex.png"), b"png").unwrap();
        let m = DMat4::from_rotation_translation(
            synthgen_core::glam::DQuat::from_mat3(&DMat3::from_rotation_z(
                std::f64::consts::FRAC_PI_2,
            )),
            DVec3::new(0.0, 0.0, 2.0),
        );
        let out = d.join("out");
        let written = write_moved_obj(&d.join("a.obj"), &out, m).unwrap();
        assert_eq!(written.len(), 3);
        let text = std::fs::read_to_string(out.join("a.obj")).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "# scan");
        assert_eq!(lines[1], "mtllib a.mtl");
        assert_eq!(
            lines[2],
            "v 0.000000000 1.000000000 2.000000000 0.5 0.5 0.5"
        );
        assert_eq!(lines[5], "vt 0.1 0.2");
        assert_eq!(lines[6], "vn 0.000000000 1.000000000 0.000000000");
        assert_eq!(lines[7], "vn nan nan nan");
        assert_eq!(lines[9], "f 1/1/1 2/1/1 3/1/2");
        assert_eq!(std::fs::read(out.join("tex.png")).unwrap(), b"png");
        // A missing texture is an error naming it.
        std::fs::remove_file(d.join("tex.png")).unwrap();
        let e = write_moved_obj(&d.join("a.obj"), &d.join("out2"), m).unwrap_err();
        assert!(e.to_string().contains("tex.png"), "{e}");
    }
}
