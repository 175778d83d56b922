//! A tiny ASCII PLY reader for tests and benches (vertices with optional normals and
//! colours, triangle faces). The real loader lives in synthgen-assets.

use std::path::Path;

use synthgen_core::glam::Vec3;
use synthgen_core::{Model, Primitive};

/// Reads an ASCII PLY, scaling positions by `scale` (0.001 for millimetre models).
pub fn read_ascii_ply(path: &Path, scale: f32) -> anyhow::Result<Model> {
    let text = std::fs::read_to_string(path)?;
    let mut lines = text.lines();
    anyhow::ensure!(lines.next() == Some("ply"), "not a ply: {}", path.display());
    let mut props: Vec<String> = Vec::new();
    let (mut nv, mut nf) = (0usize, 0usize);
    let mut in_vertex = false;
    for line in lines.by_ref() {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            ["format", f, ..] => anyhow::ensure!(*f == "ascii", "only ascii ply"),
            ["element", "vertex", n] => {
                nv = n.parse()?;
                in_vertex = true;
            }
            ["element", "face", n] => {
                nf = n.parse()?;
                in_vertex = false;
            }
            ["element", ..] => in_vertex = false,
            ["property", _, name] if in_vertex => props.push(name.to_string()),
            ["end_header"] => break,
            _ => {}
        }
    }
    let col = |name: &str| props.iter().position(|p| p == name);
    let need = |name: &str| col(name).ok_or_else(|| anyhow::anyhow!("no vertex property {name}"));
    let (ix, iy, iz) = (need("x")?, need("y")?, need("z")?);
    let normal_cols = col("nx").zip(col("ny")).zip(col("nz"));
    let color_cols = col("red").zip(col("green")).zip(col("blue"));
    let mut positions_m = Vec::with_capacity(nv);
    let mut normals = Vec::with_capacity(nv);
    let mut colors = Vec::with_capacity(nv);
    for _ in 0..nv {
        let v: Vec<f32> = lines
            .next()
            .ok_or_else(|| anyhow::anyhow!("short file"))?
            .split_whitespace()
            .map(|s| s.parse::<f32>())
            .collect::<Result<_, _>>()?;
        positions_m.push(Vec3::new(v[ix], v[iy], v[iz]) * scale);
        if let Some(((a, b), c)) = normal_cols {
            normals.push(Vec3::new(v[a], v[b], v[c]).normalize_or_zero());
        }
        if let Some(((a, b), c)) = color_cols {
            colors.push([v[a] / 255.0, v[b] / 255.0, v[c] / 255.0]);
        }
    }
    let mut triangles = Vec::with_capacity(nf);
    for _ in 0..nf {
        let f: Vec<u32> = lines
            .next()
            .ok_or_else(|| anyhow::anyhow!("short file"))?
            .split_whitespace()
            .map(|s| s.parse::<u32>())
            .collect::<Result<_, _>>()?;
        anyhow::ensure!(f[0] as usize + 1 == f.len(), "bad face");
        for k in 2..f[0] as usize {
            triangles.push([f[1], f[k], f[k + 1]]);
        }
    }
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    Ok(Model {
        name,
        source: path.to_path_buf(),
        primitives: vec![Primitive {
            positions_m,
            normals: normal_cols.map(|_| normals),
            colors: color_cols.map(|_| colors),
            uvs: None,
            triangles,
            // Scanned colours are the surface colour: do not tint them.
            material: synthgen_core::Material {
                base_color: [1.0; 3],
                ..Default::default()
            },
        }],
    })
}
