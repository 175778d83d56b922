//! Distractor meshes and the per-frame choice of distractors: primitive shapes (boxes,
//! cylinders, spheres) in a bank of sizes, and other models given by the caller.

use glam::Vec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::color::srgb_to_linear;
use crate::distractor_spec::{DistractorShape, DistractorSpec};
use crate::frame_scene::SceneObject;
use crate::mesh::{Material, Model, Primitive};

/// Segments around a cylinder or sphere.
const SEGMENTS: u32 = 24;

/// The primitive bank of a spec: `variants` models per shape in `shapes`, with sizes drawn
/// from `size_m` by an RNG of fixed seed (so the bank is the same for every run of a spec).
/// White base colour: each frame's colour comes from the instance tint.
pub fn primitive_models(spec: &DistractorSpec) -> Vec<Model> {
    let mut out = Vec::new();
    let [lo, hi] = spec.size_m;
    for (si, &shape) in spec.shapes.iter().enumerate() {
        let mut rng = ChaCha8Rng::seed_from_u64(0xD157_AC70 + si as u64);
        for v in 0..spec.variants {
            let mut size = || -> f32 {
                if hi > lo {
                    rng.gen_range(lo..=hi) as f32
                } else {
                    lo as f32
                }
            };
            let mut m = match shape {
                DistractorShape::Box => {
                    Model::cuboid(&format!("box_{v}"), Vec3::new(size(), size(), size()))
                }
                DistractorShape::Cylinder => {
                    let (d, h) = (size(), size());
                    cylinder(&format!("cylinder_{v}"), d * 0.5, h)
                }
                DistractorShape::Sphere => sphere(&format!("sphere_{v}"), size() * 0.5),
            };
            m.name = format!("distractor_{}", m.name);
            for p in &mut m.primitives {
                p.material.base_color = [1.0; 3];
            }
            out.push(m);
        }
    }
    out
}

fn model(name: &str, positions_m: Vec<Vec3>, normals: Vec<Vec3>, tris: Vec<[u32; 3]>) -> Model {
    Model {
        name: name.to_string(),
        source: format!("<{name}>").into(),
        primitives: vec![Primitive {
            positions_m,
            normals: Some(normals),
            triangles: tris,
            material: Material::default(),
            ..Default::default()
        }],
    }
}

/// A cylinder of `radius_m` and `height_m` along z, centred on the origin; front faces
/// counter-clockwise seen from outside.
pub fn cylinder(name: &str, radius_m: f32, height_m: f32) -> Model {
    let h = height_m * 0.5;
    let (mut p, mut n, mut t) = (Vec::new(), Vec::new(), Vec::new());
    let ring = |i: u32| {
        let a = std::f32::consts::TAU * i as f32 / SEGMENTS as f32;
        Vec3::new(a.cos(), a.sin(), 0.0)
    };
    // Sides: vertices 2i (bottom) and 2i+1 (top), radial normals.
    for i in 0..SEGMENTS {
        let r = ring(i);
        p.push(r * radius_m - Vec3::Z * h);
        p.push(r * radius_m + Vec3::Z * h);
        n.extend([r, r]);
    }
    for i in 0..SEGMENTS {
        let j = (i + 1) % SEGMENTS;
        let (b0, t0, b1, t1) = (2 * i, 2 * i + 1, 2 * j, 2 * j + 1);
        t.push([b0, b1, t0]);
        t.push([b1, t1, t0]);
    }
    // Caps: a centre and a ring each, flat normals.
    for (z, nz) in [(h, Vec3::Z), (-h, -Vec3::Z)] {
        let c = p.len() as u32;
        p.push(Vec3::new(0.0, 0.0, z));
        n.push(nz);
        for i in 0..SEGMENTS {
            p.push(ring(i) * radius_m + Vec3::Z * z);
            n.push(nz);
        }
        for i in 0..SEGMENTS {
            let (a, b) = (c + 1 + i, c + 1 + (i + 1) % SEGMENTS);
            t.push(if z > 0.0 { [c, a, b] } else { [c, b, a] });
        }
    }
    model(name, p, n, t)
}

/// A UV sphere of `radius_m` centred on the origin, smooth normals.
pub fn sphere(name: &str, radius_m: f32) -> Model {
    let lat = SEGMENTS / 2;
    let (mut p, mut n, mut t) = (Vec::new(), Vec::new(), Vec::new());
    for j in 0..=lat {
        let th = std::f32::consts::PI * j as f32 / lat as f32;
        for i in 0..=SEGMENTS {
            let ph = std::f32::consts::TAU * i as f32 / SEGMENTS as f32;
            let d = Vec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            p.push(d * radius_m);
            n.push(d);
        }
    }
    let idx = |j: u32, i: u32| j * (SEGMENTS + 1) + i;
    for j in 0..lat {
        for i in 0..SEGMENTS {
            let (a, b, c, d) = (idx(j, i), idx(j + 1, i), idx(j + 1, i + 1), idx(j, i + 1));
            if j + 1 < lat {
                t.push([a, b, c]);
            }
            if j > 0 {
                t.push([a, c, d]);
            }
        }
    }
    model(name, p, n, t)
}

/// Distractor objects a sampler can draw from: primitives get a random colour each frame,
/// meshes keep their own.
#[derive(Debug, Clone, Default)]
pub struct DistractorPool {
    pub primitives: Vec<SceneObject>,
    pub meshes: Vec<SceneObject>,
}

/// One frame's distractor: which object and its linear-light tint.
pub(crate) struct Chosen<'a> {
    pub object: &'a SceneObject,
    pub tint: [f32; 3],
}

impl DistractorPool {
    pub fn is_empty(&self) -> bool {
        self.primitives.is_empty() && self.meshes.is_empty()
    }

    pub(crate) fn choose<'a>(
        &'a self,
        spec: &DistractorSpec,
        rng: &mut ChaCha8Rng,
    ) -> Vec<Chosen<'a>> {
        if self.is_empty() {
            return Vec::new();
        }
        let n = rng.gen_range(spec.count[0]..=spec.count[1]);
        (0..n)
            .map(|_| {
                let mesh = !self.meshes.is_empty()
                    && (self.primitives.is_empty() || rng.gen_bool(spec.mesh_probability));
                if mesh {
                    let object = &self.meshes[rng.gen_range(0..self.meshes.len())];
                    Chosen {
                        object,
                        tint: [1.0; 3],
                    }
                } else {
                    let object = &self.primitives[rng.gen_range(0..self.primitives.len())];
                    let tint = std::array::from_fn(|i| {
                        let t: f32 = rng.gen();
                        srgb_to_linear(
                            spec.color_min[i] + t * (spec.color_max[i] - spec.color_min[i]),
                        )
                    });
                    Chosen { object, tint }
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every triangle's normal points away from the centre (counter-clockwise from outside).
    fn assert_outward(m: &Model) {
        let p = &m.primitives[0];
        for t in &p.triangles {
            let [a, b, c] = t.map(|i| p.positions_m[i as usize]);
            let nrm = (b - a).cross(c - a);
            assert!(nrm.length() > 0.0, "{}: degenerate triangle", m.name);
            assert!(
                nrm.dot((a + b + c) / 3.0) > 0.0,
                "{}: inward face {t:?}",
                m.name
            );
        }
    }

    #[test]
    fn primitives_face_outward_and_bank_is_fixed() {
        assert_outward(&cylinder("c", 0.05, 0.1));
        assert_outward(&sphere("s", 0.05));
        assert_outward(&Model::cuboid("b", Vec3::splat(0.1)));
        let spec = DistractorSpec::default();
        let a = primitive_models(&spec);
        assert_eq!(a.len(), 3 * spec.variants as usize);
        assert_eq!(a, primitive_models(&spec));
        for m in &a {
            let bb = m.aabb().unwrap();
            let ext = bb.max - bb.min;
            assert!(
                ext.max_element() <= 0.12 + 1e-5 && ext.min_element() >= 0.03 - 1e-5,
                "{}: {ext}",
                m.name
            );
        }
    }
}
