//! Scene builders and geometry helpers shared by the render tests.

use std::path::PathBuf;

use synthgen_core::glam::{DMat3, DVec3, Vec3};
use synthgen_core::sample::{BackgroundSample, GroundInstance, ObjectInstance, PointLight};
use synthgen_core::scene::BackgroundKind;
use synthgen_core::{FrameScene, Intrinsics, Pose};

pub fn instance(model_index: usize, cam_from_obj: Pose) -> ObjectInstance {
    ObjectInstance {
        model_index,
        obj_id: model_index as u32 + 1,
        cam_from_obj,
        brightness: 1.0,
        specular: 0.3,
        shininess: 24.0,
        tint: [1.0; 3],
        hue_deg: 0.0,
        metallic: 0.0,
    }
}

pub fn scene(intrinsics: Intrinsics, objects: Vec<ObjectInstance>) -> FrameScene {
    FrameScene {
        frame_index: 0,
        intrinsics,
        world_from_cam: Pose::IDENTITY,
        objects,
        distractors: vec![],
        lights: vec![PointLight {
            position_cam_m: DVec3::new(0.3, -0.5, 0.0),
            color: [1.0, 0.95, 0.9],
            intensity: 0.9,
        }],
        ambient: 0.25,
        shadows: false,
        ambient_occlusion: 0.0,
        shading: synthgen_core::scene::Shading::Phong,
        environment: None,
        ground: None,
        walls: vec![],
        background: BackgroundSample {
            kind: BackgroundKind::Color,
            color: [0.1, 0.2, 0.3],
            seed: 7,
        },
    }
}

/// A ground plane below the camera's view: the plane's z axis points toward the camera.
pub fn ground_facing(cam_from_plane: Pose) -> GroundInstance {
    GroundInstance {
        cam_from_plane,
        size_m: 3.0,
        color: [0.55, 0.5, 0.45],
        texture_strength: 0.4,
        texture_seed: 99,
        texture: None,
    }
}

pub fn at(rotation: DMat3, x: f64, y: f64, z: f64) -> Pose {
    Pose::new(rotation, DVec3::new(x, y, z))
}

/// A small deterministic generator for test poses (no rand dependency needed).
pub struct TestRng(u64);

impl TestRng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_f64(&mut self) -> f64 {
        self.0 = synthgen_core::rng::splitmix64(self.0);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
    pub fn rotation(&mut self) -> DMat3 {
        let axis = DVec3::new(
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
        )
        .normalize_or(DVec3::Z);
        DMat3::from_axis_angle(axis, self.range(0.0, std::f64::consts::TAU))
    }
}

/// Points (pixel centres) strictly inside the convex hull of `pts` (2D), counted by brute
/// force over the image; the reference coverage of a convex object's silhouette.
pub fn convex_hull(mut pts: Vec<[f64; 2]>) -> Vec<[f64; 2]> {
    pts.sort_by(|a, b| a.partial_cmp(b).unwrap());
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut lower: Vec<[f64; 2]> = Vec::new();
    for &p in &pts {
        while lower.len() >= 2 && cross(lower[lower.len() - 2], lower[lower.len() - 1], p) <= 0.0 {
            lower.pop();
        }
        lower.push(p);
    }
    let mut upper: Vec<[f64; 2]> = Vec::new();
    for &p in pts.iter().rev() {
        while upper.len() >= 2 && cross(upper[upper.len() - 2], upper[upper.len() - 1], p) <= 0.0 {
            upper.pop();
        }
        upper.push(p);
    }
    lower.pop();
    upper.pop();
    lower.extend(upper);
    lower
}

/// Signed distance of `p` to a convex polygon's boundary, positive inside (hull from
/// `convex_hull`, counter-clockwise in a y-up sense).
pub fn inside_distance(hull: &[[f64; 2]], p: [f64; 2]) -> f64 {
    let mut d = f64::INFINITY;
    for i in 0..hull.len() {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        let (ex, ey) = (b[0] - a[0], b[1] - a[1]);
        let len = (ex * ex + ey * ey).sqrt();
        let s = (ex * (p[1] - a[1]) - ey * (p[0] - a[0])) / len;
        d = d.min(s);
    }
    d
}

pub fn polygon_area(poly: &[[f64; 2]]) -> f64 {
    let mut a = 0.0;
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        a += p[0] * q[1] - q[0] * p[1];
    }
    a.abs() * 0.5
}

/// Projected corners of an axis-aligned box of `size` at `pose`.
pub fn projected_box(k: &Intrinsics, pose: &Pose, size: Vec3) -> Vec<[f64; 2]> {
    let h = size.as_dvec3() * 0.5;
    let mut out = Vec::new();
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            for sz in [-1.0, 1.0] {
                let p = pose.transform_point(DVec3::new(sx * h.x, sy * h.y, sz * h.z));
                let (u, v) = k.project(p).unwrap();
                out.push([u, v]);
            }
        }
    }
    out
}

/// Distance from `p` to the surface of an origin-centred box with half extents `h`.
pub fn box_surface_distance(p: DVec3, h: DVec3) -> f64 {
    let q = p.abs() - h;
    if q.max_element() <= 0.0 {
        -q.max_element()
    } else {
        q.max(DVec3::ZERO).length()
    }
}

pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.partial_cmp(b).unwrap());
    v[v.len() / 2]
}

/// The Linemod-Occluded models folder: `$SYNTHGEN_LMO_DIR/models` or `../shared/data/lmo`
/// next to the workspace (the tests that use it are ignored without the shared data).
pub fn lmo_models_dir() -> PathBuf {
    let root = std::env::var_os("SYNTHGEN_LMO_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/lmo")
        });
    let dir = root.join("models");
    assert!(
        dir.join("obj_000001.ply").exists(),
        "Linemod models not found in {}",
        dir.display()
    );
    dir
}
