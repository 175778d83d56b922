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
    let mtl_problems: RefCell<Vec<String>> = RefCell::new(Vec::new());
    let obj_err = |reason: String| Error::Obj {
        reason,
        path: path.to_path_buf(),
    };
    let (models, materials) = crate::guard_parser("tobj", || {
        tobj::load_obj_buf(&mut std::io::Cursor::new(&bytes), &options, |mtl| {
            let mtl_path = dir.join(mtl);
            let text = match std::fs::read(&mtl_path) {
                Ok(b) => String::from_utf8_lossy(&b).into_owned(),
                Err(e) => {
                    failed_mtl
                        .borrow_mut()
                        .push((mtl_path.clone(), e.to_string()));
                    return Err(tobj::LoadError::OpenFileFailed);
                }
            };
            let (text, problems) = sanitize_mtl(&text);
            mtl_problems.borrow_mut().extend(
                problems
                    .into_iter()
                    .map(|p| format!("{p}: {}", mtl_path.display())),
            );
            tobj::load_mtl_buf(&mut std::io::Cursor::new(text.as_bytes())).inspect_err(|e| {
                failed_mtl
                    .borrow_mut()
                    .push((mtl_path.clone(), e.to_string()));
            })
        })
    })
    .map_err(obj_err)?
    .map_err(|e| obj_err(e.to_string()))?;
    for p in mtl_problems.into_inner() {
        progress.warn(&p);
    }
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

/// An MTL file's text as tobj may read it, and what was wrong with it (one message per
/// line, "MTL line N: ..."). tobj panics on a colour with fewer than three numbers and
/// gives up on the whole file at one bad number; real files carry such lines, so a bad line
/// is dropped (its value stays the default) and said, the rest of the file kept:
/// - `Ka`/`Kd`/`Ks`/`Ke`: three numbers, or one (a grey, as the MTL spec allows); others,
///   and non-finite values, drop the line; values outside 0..1 are clamped.
/// - `Ns`, `Ni`, `d`: one finite number; `illum`: an integer 0..255; a texture key: a name.
pub(crate) fn sanitize_mtl(text: &str) -> (String, Vec<String>) {
    let mut out = String::with_capacity(text.len());
    let mut problems = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let key = words.next().unwrap_or("");
        let args: Vec<&str> = words.collect();
        let mut problem = |what: String| problems.push(format!("MTL line {}: {what}", i + 1));
        match key {
            "Ka" | "Kd" | "Ks" | "Ke" => {
                let nums: Option<Vec<f32>> = args.iter().take(3).map(|a| a.parse().ok()).collect();
                let nums = match nums {
                    Some(n) if n.len() == 3 => n,
                    Some(n) if n.len() == 1 && args.len() == 1 => vec![n[0]; 3],
                    _ => {
                        problem(format!(
                            "`{}` needs three numbers (or one); ignored, the default is used",
                            line.trim()
                        ));
                        continue;
                    }
                };
                if nums.iter().any(|v| !v.is_finite()) {
                    problem(format!(
                        "`{}` is not a colour (not finite); ignored, the default is used",
                        line.trim()
                    ));
                    continue;
                }
                if nums.iter().any(|v| !(0.0..=1.0).contains(v)) {
                    problem(format!("`{}` lies outside 0..1; clamped", line.trim()));
                }
                let c: Vec<String> = nums.iter().map(|v| v.clamp(0.0, 1.0).to_string()).collect();
                out.push_str(&format!("{key} {}\n", c.join(" ")));
                continue;
            }
            "Ns" | "Ni" | "d"
                if !args
                    .first()
                    .and_then(|a| a.parse::<f32>().ok())
                    .is_some_and(f32::is_finite) =>
            {
                problem(format!(
                    "`{}` needs one finite number; ignored, the default is used",
                    line.trim()
                ));
                continue;
            }
            "illum" if args.first().and_then(|a| a.parse::<u8>().ok()).is_none() => {
                problem(format!(
                    "`{}` needs an integer 0..255; ignored",
                    line.trim()
                ));
                continue;
            }
            k if (k.starts_with("map_") || k == "bump") && args.is_empty() => {
                problem(format!("`{k}` names no file; ignored"));
                continue;
            }
            _ => {}
        }
        out.push_str(line);
        out.push('\n');
    }
    (out, problems)
}

/// The file name in a `map_Kd` value, which may start with options (`-bm 0.5 -clamp on x.png`)
/// and use Windows separators.
pub(crate) fn texture_file_name(value: &str) -> Option<String> {
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

    /// Regression (issue 50): `Kd 0.5 0.5` and a bare `Ka` made tobj panic and the error blamed
    /// the OBJ; `Kd nan -1 5` was used as it stood.
    #[test]
    fn malformed_mtl_lines_are_dropped_and_said_the_rest_kept() {
        let (text, problems) = sanitize_mtl(
            "newmtl m\nKa\nKd 0.5 0.5\nKs 0.2\nKe nan -1 5\nKd 2 -1 0.5\nNs x\nillum 2\nmap_Kd\nmap_Kd t.png\n",
        );
        assert_eq!(
            text,
            "newmtl m\nKs 0.2 0.2 0.2\nKd 1 0 0.5\nillum 2\nmap_Kd t.png\n"
        );
        let joined = problems.join("\n");
        for want in [
            "line 2: `Ka`",
            "line 3: `Kd 0.5 0.5`",
            "line 5: `Ke nan -1 5`",
            "line 6: `Kd 2 -1 0.5` lies outside 0..1; clamped",
            "line 7: `Ns x`",
            "line 9: `map_Kd`",
        ] {
            assert!(joined.contains(want), "{want} not in {joined}");
        }
        assert_eq!(problems.len(), 6);
    }

    #[test]
    fn an_obj_with_a_malformed_mtl_loads_and_the_warning_names_the_mtl() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("a.mtl"), "newmtl m\nKd 0.5 0.5\nKs 1 1 1\n").unwrap();
        std::fs::write(
            d.join("a.obj"),
            "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n",
        )
        .unwrap();
        struct Warnings(std::sync::Mutex<Vec<String>>);
        impl Progress for Warnings {
            fn warn(&self, m: &str) {
                self.0.lock().unwrap().push(m.to_string());
            }
        }
        let w = Warnings(std::sync::Mutex::new(Vec::new()));
        let mut cache = TextureCache::new();
        let model = load_obj(&d.join("a.obj"), &mut cache, &w).unwrap();
        let mat = &model.primitives[0].material;
        assert_eq!(mat.base_color, Material::default().base_color);
        assert!(mat.specular > 0.0 || mat.shininess > 0.0);
        let warnings = w.0.into_inner().unwrap();
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("MTL line 2: `Kd 0.5 0.5`") && warnings[0].ends_with("a.mtl"),
            "{warnings:?}"
        );
    }
}
