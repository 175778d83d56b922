//! In-memory 3D models: triangles in metres in the object frame, with colour sources.

use std::path::PathBuf;
use std::sync::Arc;

use glam::{DVec3, Vec2, Vec3};

/// An 8-bit sRGB texture, rows top to bottom (v = 1 is the top row, as in OBJ/glTF after the
/// loader's flip: loaders store `uv` so that `v = 0` is the first row).
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    /// `width * height * 3` bytes, row-major, sRGB.
    pub rgb: Vec<u8>,
    pub source: PathBuf,
}

/// Surface appearance of a primitive.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// sRGB base colour in 0..1, multiplied with the texture or vertex colour when present.
    pub base_color: [f32; 3],
    pub texture: Option<Arc<Texture>>,
    /// Specular weight (0..1) and Blinn-Phong exponent.
    pub specular: f32,
    pub shininess: f32,
    /// Render both sides of each triangle. When false, triangles facing away from the camera
    /// (clockwise seen from the camera; front faces are counter-clockwise seen from outside,
    /// as in OBJ, PLY and glTF) are culled.
    pub double_sided: bool,
}

impl Default for Material {
    fn default() -> Self {
        Self {
            base_color: [0.7, 0.7, 0.7],
            texture: None,
            specular: 0.2,
            shininess: 32.0,
            double_sided: false,
        }
    }
}

/// One indexed triangle list with a single material.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Primitive {
    /// Vertex positions in metres, object frame.
    pub positions_m: Vec<Vec3>,
    /// Unit vertex normals; when absent the renderer uses face normals.
    pub normals: Option<Vec<Vec3>>,
    /// Per-vertex sRGB colour in 0..1.
    pub colors: Option<Vec<[f32; 3]>>,
    /// Texture coordinates; `v = 0` is the texture's first (top) row.
    pub uvs: Option<Vec<Vec2>>,
    pub triangles: Vec<[u32; 3]>,
    pub material: Material,
}

/// A loaded object model: one or more primitives in the object frame, metres.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Model {
    /// Short name (file stem), used in messages.
    pub name: String,
    pub source: PathBuf,
    pub primitives: Vec<Primitive>,
}

/// Axis-aligned bounding box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
}

impl Model {
    pub fn vertex_count(&self) -> usize {
        self.primitives.iter().map(|p| p.positions_m.len()).sum()
    }

    pub fn triangle_count(&self) -> usize {
        self.primitives.iter().map(|p| p.triangles.len()).sum()
    }

    /// Every triangle's corners (metres, object frame); triangles with an index past their
    /// primitive's vertices are left out.
    pub fn triangles_m(&self) -> Vec<[DVec3; 3]> {
        self.primitives
            .iter()
            .flat_map(|p| {
                p.triangles.iter().filter_map(|t| {
                    let v = |i: u32| p.positions_m.get(i as usize).map(|v| v.as_dvec3());
                    Some([v(t[0])?, v(t[1])?, v(t[2])?])
                })
            })
            .collect()
    }

    pub fn positions(&self) -> impl Iterator<Item = Vec3> + '_ {
        self.primitives
            .iter()
            .flat_map(|p| p.positions_m.iter().copied())
    }

    /// Bounding box of all vertices; `None` for a model with no vertices.
    pub fn aabb(&self) -> Option<Aabb> {
        let mut it = self.positions();
        let first = it.next()?;
        let (min, max) = it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p)));
        Some(Aabb { min, max })
    }

    /// Points that can be extreme in some direction: a superset-approximation of the convex
    /// hull's vertices, used for placement (lowest point) and the diameter. Picks, for each of
    /// `directions` well-spread directions, the vertex furthest along it.
    pub fn support_points(&self, directions: usize) -> Vec<Vec3> {
        let pts: Vec<Vec3> = self.positions().collect();
        if pts.len() <= directions {
            return pts;
        }
        let mut idx: Vec<usize> = fibonacci_sphere(directions)
            .map(|d| {
                let mut best = 0;
                let mut best_v = f32::NEG_INFINITY;
                for (i, p) in pts.iter().enumerate() {
                    let v = p.dot(d);
                    if v > best_v {
                        best_v = v;
                        best = i;
                    }
                }
                best
            })
            .collect();
        idx.sort_unstable();
        idx.dedup();
        idx.into_iter().map(|i| pts[i]).collect()
    }

    /// Largest distance between any two vertices, in metres (the BOP `diameter`, which
    /// bop_toolkit computes over all model points). Exact for up to 20k vertices; larger models
    /// use the extreme points along 4096 directions, which can only underestimate, by at most
    /// about 0.1% on the scanned BOP models.
    pub fn diameter_m(&self) -> f64 {
        let pts: Vec<Vec3> = if self.vertex_count() <= 20_000 {
            self.positions().collect()
        } else {
            self.support_points(4096)
        };
        let mut best = 0.0f64;
        for (i, a) in pts.iter().enumerate() {
            let a = a.as_dvec3();
            for b in &pts[i + 1..] {
                best = best.max(a.distance_squared(b.as_dvec3()));
            }
        }
        best.sqrt()
    }
}

impl Model {
    /// An axis-aligned box centred on the origin with outward-facing triangles (counter-
    /// clockwise seen from outside), in metres. Used for tests, distractors and occluders.
    pub fn cuboid(name: &str, size_m: Vec3) -> Model {
        let h = size_m * 0.5;
        let positions_m = vec![
            Vec3::new(-h.x, -h.y, -h.z),
            Vec3::new(h.x, -h.y, -h.z),
            Vec3::new(h.x, h.y, -h.z),
            Vec3::new(-h.x, h.y, -h.z),
            Vec3::new(-h.x, -h.y, h.z),
            Vec3::new(h.x, -h.y, h.z),
            Vec3::new(h.x, h.y, h.z),
            Vec3::new(-h.x, h.y, h.z),
        ];
        let triangles = vec![
            [0, 2, 1],
            [0, 3, 2],
            [4, 5, 6],
            [4, 6, 7],
            [0, 1, 5],
            [0, 5, 4],
            [2, 3, 7],
            [2, 7, 6],
            [1, 2, 6],
            [1, 6, 5],
            [0, 4, 7],
            [0, 7, 3],
        ];
        Model {
            name: name.to_string(),
            source: PathBuf::from(format!("<{name}>")),
            primitives: vec![Primitive {
                positions_m,
                triangles,
                ..Default::default()
            }],
        }
    }
}

/// Distance from point `p` to triangle (a, b, c) (Ericson, Real-Time Collision Detection).
pub fn point_triangle_distance(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (p - a).length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (p - b).length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (p - (a + ab * v)).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (p - c).length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (p - (a + ac * w)).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (p - (a + ab * v + ac * w)).length()
}

/// `n` roughly uniform unit directions on the sphere (Fibonacci lattice).
pub fn fibonacci_sphere(n: usize) -> impl Iterator<Item = Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..n).map(move |i| {
        let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
        let r = (1.0 - y * y).max(0.0).sqrt();
        let th = golden * i as f32;
        Vec3::new(r * th.cos(), y, r * th.sin())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube(half_m: f32) -> Model {
        Model::cuboid("cube", Vec3::splat(2.0 * half_m))
    }

    #[test]
    fn cube_diameter_and_aabb() {
        let m = cube(0.05);
        let d = m.diameter_m();
        assert!((d - 0.1 * 3f64.sqrt()).abs() < 1e-6, "{d}");
        let bb = m.aabb().unwrap();
        assert_eq!(bb.size(), Vec3::splat(0.1));
        assert_eq!(m.support_points(64).len(), 8);
    }

    #[test]
    fn point_triangle_distance_regions() {
        let (a, b, c) = (DVec3::ZERO, DVec3::X, DVec3::Y);
        // Above the face, beyond a vertex, beside an edge.
        assert!((point_triangle_distance(DVec3::new(0.2, 0.2, 0.5), a, b, c) - 0.5).abs() < 1e-12);
        assert!((point_triangle_distance(DVec3::new(-1.0, 0.0, 0.0), a, b, c) - 1.0).abs() < 1e-12);
        let d = point_triangle_distance(DVec3::new(1.0, 1.0, 0.0), a, b, c);
        assert!((d - 0.5f64.sqrt()).abs() < 1e-12, "{d}");
    }

    #[test]
    fn fibonacci_directions_are_unit() {
        for d in fibonacci_sphere(100) {
            assert!((d.length() - 1.0).abs() < 1e-5);
        }
    }
}
