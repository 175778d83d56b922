//! Checks shared by every format: finite positions, indices in range, at least one face, and
//! unit normals.
//!
//! Normals policy: file normals are renormalized; a zero, NaN or infinite normal is replaced by
//! the area-weighted average of the adjacent face normals (or +z for a vertex no face uses).
//! Missing normals stay `None`: the renderer then shades with face normals, which is the honest
//! look of a mesh that has none (smoothing would round off deliberate hard edges).

use std::path::Path;

use synthgen_core::glam::Vec3;
use synthgen_core::{Model, Primitive, Progress};

use crate::Error;

/// Validates a whole model in raw units and repairs its normals.
pub(crate) fn validate_model(model: &mut Model, progress: &dyn Progress) -> Result<(), Error> {
    let path = model.source.clone();
    let mut vertex_base = 0usize;
    let mut triangle_base = 0usize;
    let mut replaced = 0usize;
    for prim in &mut model.primitives {
        check_primitive(prim, &path, vertex_base, triangle_base)?;
        replaced += repair_normals(prim);
        vertex_base += prim.positions_m.len();
        triangle_base += prim.triangles.len();
    }
    if replaced > 0 {
        progress.warn(&format!(
            "replaced {replaced} invalid vertex normals by smooth normals: {}",
            path.display()
        ));
    }
    // Primitives without triangles carry nothing the renderer can use.
    model.primitives.retain(|p| !p.triangles.is_empty());
    if model.primitives.is_empty() {
        return Err(Error::NoFaces { path });
    }
    Ok(())
}

fn check_primitive(
    prim: &mut Primitive,
    path: &Path,
    vertex_base: usize,
    triangle_base: usize,
) -> Result<(), Error> {
    if let Some(i) = prim.positions_m.iter().position(|p| !p.is_finite()) {
        return Err(Error::NonFiniteVertex {
            vertex: vertex_base + i,
            path: path.to_path_buf(),
        });
    }
    let n = prim.positions_m.len();
    for (t, tri) in prim.triangles.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&i| i as usize >= n) {
            return Err(Error::IndexOutOfRange {
                face: triangle_base + t,
                index: i64::from(bad),
                vertex_count: n,
                path: path.to_path_buf(),
            });
        }
    }
    // Attributes of the wrong length would index out of bounds in the renderer: drop them.
    if prim.normals.as_ref().is_some_and(|v| v.len() != n) {
        prim.normals = None;
    }
    if prim.colors.as_ref().is_some_and(|v| v.len() != n) {
        prim.colors = None;
    }
    if prim.uvs.as_ref().is_some_and(|v| v.len() != n) {
        prim.uvs = None;
    }
    if let Some(colors) = &mut prim.colors {
        for c in colors.iter_mut() {
            for x in c.iter_mut() {
                *x = if x.is_finite() {
                    x.clamp(0.0, 1.0)
                } else {
                    0.0
                };
            }
        }
    }
    if let Some(uvs) = &mut prim.uvs {
        for uv in uvs.iter_mut() {
            if !uv.is_finite() {
                *uv = Default::default();
            }
        }
    }
    Ok(())
}

/// Renormalizes normals; returns how many were invalid and replaced.
fn repair_normals(prim: &mut Primitive) -> usize {
    let Some(normals) = &mut prim.normals else {
        return 0;
    };
    let mut invalid = Vec::new();
    for (i, nrm) in normals.iter_mut().enumerate() {
        let len = nrm.length();
        if len.is_finite() && len > 1e-12 {
            *nrm /= len;
        } else {
            invalid.push(i);
        }
    }
    if invalid.is_empty() {
        return 0;
    }
    let smooth = smooth_normals(&prim.positions_m, &prim.triangles);
    for &i in &invalid {
        normals[i] = smooth[i];
    }
    invalid.len()
}

/// Area-weighted vertex normals; +z where a vertex has no (non-degenerate) face.
pub(crate) fn smooth_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut acc = vec![Vec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| i as usize);
        let (Some(&pa), Some(&pb), Some(&pc)) =
            (positions.get(a), positions.get(b), positions.get(c))
        else {
            continue;
        };
        // The cross product's length is twice the area: area weighting for free.
        let n = (pb - pa).cross(pc - pa);
        acc[a] += n;
        acc[b] += n;
        acc[c] += n;
    }
    acc.into_iter()
        .map(|n| n.try_normalize().unwrap_or(Vec3::Z))
        .collect()
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;
    use std::path::PathBuf;
    use synthgen_core::NoProgress;

    fn tri_model() -> Model {
        Model {
            name: "t".into(),
            source: PathBuf::from("/x/t.ply"),
            primitives: vec![Primitive {
                positions_m: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
                triangles: vec![[0, 1, 2]],
                normals: Some(vec![Vec3::Z * 3.0, Vec3::ZERO, Vec3::splat(f32::NAN)]),
                ..Default::default()
            }],
        }
    }

    #[test]
    fn normals_are_renormalized_and_invalid_ones_replaced() {
        let mut m = tri_model();
        validate_model(&mut m, &NoProgress).unwrap();
        assert_eq!(m.primitives[0].normals.as_ref().unwrap(), &vec![Vec3::Z; 3]);
    }

    #[test]
    fn out_of_range_index_is_an_error() {
        let mut m = tri_model();
        m.primitives[0].triangles.push([0, 1, 7]);
        let e = validate_model(&mut m, &NoProgress).unwrap_err().to_string();
        assert!(
            e.contains("face 1 refers to vertex 7") && e.ends_with("/x/t.ply"),
            "{e}"
        );
    }

    #[test]
    fn no_triangles_is_an_error() {
        let mut m = tri_model();
        m.primitives[0].triangles.clear();
        let e = validate_model(&mut m, &NoProgress).unwrap_err().to_string();
        assert_eq!(e, "mesh has no faces: /x/t.ply");
    }
}
