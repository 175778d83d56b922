//! Models converted once, at renderer construction, into the layout the rasterizer wants:
//! positions as structure-of-arrays, one triangle list with global vertex indices, colours
//! already in linear light.

use std::sync::Arc;

use synthgen_core::glam::{Vec2, Vec3};
use synthgen_core::{Model, Texture};

use crate::color::srgb_to_linear_f32;
use crate::Error;

/// Per-vertex shading attributes, interleaved so a pixel's three vertices cost three cache
/// lines at most (two vertices per 64-byte line).
#[derive(Debug, Clone, Copy, Default)]
#[repr(C, align(32))]
pub(crate) struct ShadeVert {
    pub p: Vec3,
    /// Unit normal, zero when the primitive has none.
    pub n: Vec3,
    /// sRGB vertex colour (white when the primitive has none).
    pub rgb: [u8; 3],
}

/// One primitive's triangles (a range of the model's list) and material.
#[derive(Debug)]
pub(crate) struct PreparedPrimitive {
    pub tri_start: u32,
    pub tri_end: u32,
    pub vert_base: u32,
    pub double_sided: bool,
    pub has_normals: bool,
    pub has_colors: bool,
    /// Material base colour in linear light.
    pub base_linear: [f32; 3],
    /// Texture and uvs (indexed by global vertex index minus `vert_base`), only when both are
    /// present.
    pub texture: Option<(Arc<Texture>, Vec<Vec2>)>,
}

/// A model laid out for the rasterizer: positions as structure-of-arrays for the vertex
/// transform, triangles and vertices reordered along a Morton curve so that neighbouring
/// pixels touch neighbouring memory, shading attributes interleaved.
#[derive(Debug)]
pub(crate) struct PreparedModel {
    pub name: String,
    pub xs: Vec<f32>,
    pub ys: Vec<f32>,
    pub zs: Vec<f32>,
    pub verts: Vec<ShadeVert>,
    /// Global vertex indices (validated in range).
    pub tris: Vec<[u32; 3]>,
    pub prims: Vec<PreparedPrimitive>,
    /// Runs of consecutive triangles (never across primitives) with bounds for culling a
    /// whole run that faces away from the camera.
    pub clusters: Vec<Cluster>,
}

/// Triangles per cluster. The Morton order makes consecutive triangles a small patch.
const CLUSTER_TRIS: usize = 16;

/// A run of triangles `start..end`, with a cone holding all their normals (`axis`, and
/// `cutoff` = sine of the cone's half angle; > 1 when the run cannot be culled) and a sphere
/// holding their vertices.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Cluster {
    pub start: u32,
    pub end: u32,
    pub double_sided: bool,
    /// False when the normals spread too wide for the cone test (or double-sided).
    pub cull: bool,
    pub axis: Vec3,
    pub cutoff: f32,
    pub center: Vec3,
    pub radius: f32,
}

impl Cluster {
    /// True when every triangle faces away from a camera at `eye` (object frame), with the
    /// conservative cone test of meshoptimizer's `meshopt_computeClusterBounds`.
    #[inline]
    pub fn faces_away(&self, eye: Vec3) -> bool {
        let d = self.center - eye;
        self.cull && d.dot(self.axis) >= self.cutoff * d.length() + self.radius
    }
}

fn clusters_of(out: &PreparedModel, prim: &PreparedPrimitive, clusters: &mut Vec<Cluster>) {
    let pos = |i: u32| out.verts[i as usize].p;
    let mut start = prim.tri_start as usize;
    while start < prim.tri_end as usize {
        let end = (start + CLUSTER_TRIS).min(prim.tri_end as usize);
        let tris = &out.tris[start..end];
        let normals: Vec<Vec3> = tris
            .iter()
            .filter_map(|t| {
                (pos(t[1]) - pos(t[0]))
                    .cross(pos(t[2]) - pos(t[0]))
                    .try_normalize()
            })
            .collect();
        let axis = normals.iter().copied().sum::<Vec3>().normalize_or_zero();
        let min_dot = normals.iter().map(|n| n.dot(axis)).fold(1.0f32, f32::min);
        let (lo, hi) = tris.iter().flatten().fold(
            (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
            |(a, b), &i| (a.min(pos(i)), b.max(pos(i))),
        );
        let center = (lo + hi) * 0.5;
        let radius = tris
            .iter()
            .flatten()
            .map(|&i| (pos(i) - center).length())
            .fold(0.0f32, f32::max);
        // A little slack so rounding never culls a triangle that the exact test keeps.
        let cull = !prim.double_sided && axis != Vec3::ZERO && min_dot > 0.05;
        clusters.push(Cluster {
            start: start as u32,
            end: end as u32,
            double_sided: prim.double_sided,
            cull,
            axis,
            cutoff: (1.0 - min_dot * min_dot).max(0.0).sqrt() + 1e-3,
            center,
            radius: radius * 1.001 + 1e-6,
        });
        start = end;
    }
}

impl PreparedModel {
    /// The primitive holding triangle `tri`; `hint` is the index that matched last time.
    #[inline]
    pub fn prim_of(&self, tri: u32, hint: usize) -> usize {
        let p = &self.prims[hint];
        if tri >= p.tri_start && tri < p.tri_end {
            return hint;
        }
        self.prims
            .iter()
            .position(|p| tri >= p.tri_start && tri < p.tri_end)
            .unwrap_or(0)
    }
}

/// Spreads the low 10 bits of `v` to every third bit.
fn spread3(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | (x << 16)) & 0x0300_00ff;
    x = (x | (x << 8)) & 0x0300_f00f;
    x = (x | (x << 4)) & 0x030c_30c3;
    x = (x | (x << 2)) & 0x0924_9249;
    x
}

/// Triangle order (by the Morton code of the centroid) and the vertex renumbering that
/// follows it (`new_of_old`, vertices in order of first use; unused ones last).
fn locality_order(positions: &[Vec3], triangles: &[[u32; 3]]) -> (Vec<usize>, Vec<u32>) {
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(a, b), p| (a.min(*p), b.max(*p)),
    );
    let scale = 1023.0 / (hi - lo).max(Vec3::splat(1e-12));
    let mut order: Vec<(u32, usize)> = triangles
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let c =
                (positions[t[0] as usize] + positions[t[1] as usize] + positions[t[2] as usize])
                    / 3.0;
            let q = ((c - lo) * scale).clamp(Vec3::ZERO, Vec3::splat(1023.0));
            let code =
                spread3(q.x as u32) | (spread3(q.y as u32) << 1) | (spread3(q.z as u32) << 2);
            (code, i)
        })
        .collect();
    order.sort_unstable();
    let mut new_of_old = vec![u32::MAX; positions.len()];
    let mut next = 0u32;
    for &(_, t) in &order {
        for &v in &triangles[t] {
            if new_of_old[v as usize] == u32::MAX {
                new_of_old[v as usize] = next;
                next += 1;
            }
        }
    }
    for n in new_of_old.iter_mut().filter(|n| **n == u32::MAX) {
        *n = next;
        next += 1;
    }
    (order.into_iter().map(|(_, t)| t).collect(), new_of_old)
}

pub(crate) fn validate_texture(t: &Texture) -> Result<(), Error> {
    let want = t.width as usize * t.height as usize * 3;
    if t.width == 0 || t.height == 0 || t.rgb.len() != want {
        return Err(Error::InvalidTexture {
            width: t.width,
            height: t.height,
            len: t.rgb.len(),
            want,
            path: t.source.clone(),
        });
    }
    Ok(())
}

pub(crate) fn prepare(model: Model) -> Result<PreparedModel, Error> {
    let Model {
        name,
        source,
        primitives,
    } = model;
    let bad = |primitive: usize, reason: String| Error::InvalidModel {
        model: name.clone(),
        primitive,
        reason,
        path: source.clone(),
    };
    let nv: usize = primitives.iter().map(|p| p.positions_m.len()).sum();
    let nt: usize = primitives.iter().map(|p| p.triangles.len()).sum();
    if nv >= u32::MAX as usize || nt >= u32::MAX as usize {
        return Err(bad(
            0,
            format!("{nv} vertices and {nt} triangles exceed u32"),
        ));
    }
    let mut out = PreparedModel {
        name: name.clone(),
        xs: Vec::with_capacity(nv),
        verts: Vec::with_capacity(nv),
        ys: Vec::with_capacity(nv),
        zs: Vec::with_capacity(nv),
        tris: Vec::with_capacity(nt),
        prims: Vec::with_capacity(primitives.len()),
        clusters: Vec::new(),
    };
    for (pi, p) in primitives.into_iter().enumerate() {
        let n = p.positions_m.len();
        if let Some(v) = p.positions_m.iter().find(|v| !v.is_finite()) {
            return Err(bad(pi, format!("non-finite vertex position {v}")));
        }
        let check_len = |what: &str, len: usize| {
            if len == n {
                Ok(())
            } else {
                Err(bad(pi, format!("{len} {what} for {n} vertices")))
            }
        };
        if let Some(c) = &p.colors {
            check_len("colors", c.len())?;
        }
        if let Some(c) = &p.normals {
            check_len("normals", c.len())?;
        }
        if let Some(c) = &p.uvs {
            check_len("uvs", c.len())?;
        }
        if let Some(t) = &p.material.texture {
            validate_texture(t)?;
        }
        let base = out.xs.len() as u32;
        let tri_start = out.tris.len() as u32;
        for (ti, t) in p.triangles.iter().enumerate() {
            if let Some(&i) = t.iter().find(|&&i| i as usize >= n) {
                return Err(bad(pi, format!("triangle {ti} uses vertex {i} of {n}")));
            }
        }
        let (tri_order, new_of_old) = locality_order(&p.positions_m, &p.triangles);
        for &t in &tri_order {
            out.tris
                .push(p.triangles[t].map(|i| new_of_old[i as usize] + base));
        }
        let mut old_of_new = vec![0usize; n];
        for (old, &new) in new_of_old.iter().enumerate() {
            old_of_new[new as usize] = old;
        }
        for &old in &old_of_new {
            let v = p.positions_m[old];
            out.xs.push(v.x);
            out.ys.push(v.y);
            out.zs.push(v.z);
            let to_byte = |c: f32| (c.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            out.verts.push(ShadeVert {
                p: v,
                n: p.normals
                    .as_ref()
                    .map_or(Vec3::ZERO, |ns| ns[old].normalize_or_zero()),
                rgb: p.colors.as_ref().map_or([255; 3], |c| c[old].map(to_byte)),
            });
        }
        let m = &p.material;
        let texture = match (&m.texture, &p.uvs) {
            (Some(t), Some(uv)) => Some((t.clone(), old_of_new.iter().map(|&o| uv[o]).collect())),
            _ => None,
        };
        out.prims.push(PreparedPrimitive {
            tri_start,
            tri_end: out.tris.len() as u32,
            vert_base: base,
            double_sided: m.double_sided,
            has_normals: p.normals.is_some(),
            has_colors: p.colors.is_some(),
            base_linear: m.base_color.map(srgb_to_linear_f32),
            texture,
        });
    }
    let mut clusters = Vec::new();
    for prim in &out.prims {
        clusters_of(&out, prim, &mut clusters);
    }
    out.clusters = clusters;
    if out.prims.is_empty() {
        // `prim_of` indexes prims[hint]; an empty model has no triangles to ask about, but
        // keep one empty primitive so the index is always valid.
        out.prims.push(PreparedPrimitive {
            tri_start: 0,
            tri_end: 0,
            vert_base: 0,
            double_sided: false,
            has_normals: false,
            has_colors: false,
            base_linear: [0.5; 3],
            texture: None,
        });
    }
    Ok(out)
}
