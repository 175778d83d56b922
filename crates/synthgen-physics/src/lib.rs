//! Physics placement for synthgen: objects dropped onto the plane z = 0 (and into the
//! `[bin]`'s walls, fixed cuboids, when there is one) settle under gravity (rapier3d,
//! convex-hull colliders from the models' extreme points) and the resting poses are used. Deterministic: rapier's `enhanced-determinism` feature and a fixed step count
//! per scene make the result a pure function of the drop poses.
//!
//! ```
//! use std::sync::Arc;
//! use synthgen_core::glam::Vec3;
//! use synthgen_core::sample::SceneObject;
//! use synthgen_core::scene::PlacementMode;
//! use synthgen_core::{Model, SceneSampler, SceneSpec};
//! use synthgen_physics::PhysicsSettler;
//!
//! let m = Model::cuboid("box", Vec3::new(0.1, 0.06, 0.04));
//! let objects = vec![SceneObject::new(0, 1, &m)];
//! let mut spec = SceneSpec::default();
//! spec.placement.mode = PlacementMode::Physics;
//! let settler = PhysicsSettler::new(&objects, spec.placement.physics.clone())?;
//! let sampler = SceneSampler::new(spec, objects, 7)?.with_settle(Arc::new(settler));
//! let frame = sampler.sample(0)?;
//! assert!(sampler.physics_fallbacks().is_empty());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::BTreeMap;

pub mod align;
pub mod refine;
mod rest;
pub use rest::stable_rest_poses;

use rapier3d::prelude::*;
use synthgen_core::bin_spec::BinWall;
use synthgen_core::glam::{DMat3, DQuat, DVec3};
use synthgen_core::sample::SceneObject;
use synthgen_core::scene::PhysicsSpec;
use synthgen_core::{Pose, Settle};

/// Errors building the colliders.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(
        "cannot build a convex hull collider for object {name} (degenerate or too few points)"
    )]
    Hull { name: String },
}

/// Settles scenes with rapier3d; one convex hull per model, built once.
pub struct PhysicsSettler {
    spec: PhysicsSpec,
    /// Collider shape per `SceneObject::model_index`.
    hulls: BTreeMap<usize, SharedShape>,
    /// Static boxes besides the ground (the `[bin]` walls).
    walls: Vec<BinWall>,
}

/// Half size of the ground slab, metres: far larger than any placement area.
const GROUND_HALF_M: f32 = 50.0;

impl PhysicsSettler {
    pub fn new(objects: &[SceneObject], spec: PhysicsSpec) -> Result<PhysicsSettler, Error> {
        let mut hulls = BTreeMap::new();
        for o in objects {
            if hulls.contains_key(&o.model_index) {
                continue;
            }
            let pts: Vec<Vector> = o
                .support_points_m
                .iter()
                .map(|p| Vector::new(p.x, p.y, p.z))
                .collect();
            let hull = SharedShape::convex_hull(&pts).ok_or_else(|| Error::Hull {
                name: o.name.clone(),
            })?;
            hulls.insert(o.model_index, hull);
        }
        Ok(PhysicsSettler {
            spec,
            hulls,
            walls: Vec::new(),
        })
    }

    /// Adds fixed cuboid colliders for `walls` (`BinSpec::walls`), so that objects settle
    /// inside the bin.
    pub fn with_bin(mut self, walls: &[BinWall]) -> PhysicsSettler {
        self.walls = walls.to_vec();
        self
    }

    /// The collider shape of a model, for distance checks.
    pub fn hull(&self, model_index: usize) -> Option<&SharedShape> {
        self.hulls.get(&model_index)
    }

    /// Drops the objects from `world_from_objs` and returns their resting poses, with the
    /// number of steps it took.
    pub fn simulate(
        &self,
        objects: &[SceneObject],
        world_from_objs: &[Pose],
    ) -> Result<(Vec<Pose>, u32), String> {
        let s = &self.spec;
        let mut world = PhysicsWorld::new();
        world.gravity = Vector::new(0.0, 0.0, -9.81);
        world.integration_parameters.dt = s.timestep_s as f32;
        // A slab whose top face is the plane z = 0.
        world.insert(
            RigidBodyBuilder::fixed().translation(Vector::new(0.0, 0.0, -1.0)),
            ColliderBuilder::cuboid(GROUND_HALF_M, GROUND_HALF_M, 1.0)
                .friction(s.friction as f32)
                .restitution(s.restitution as f32),
        );
        for w in &self.walls {
            let (c, h) = (w.center_m, w.size_m * 0.5);
            world.insert(
                RigidBodyBuilder::fixed()
                    .translation(Vector::new(c.x as f32, c.y as f32, c.z as f32)),
                ColliderBuilder::cuboid(h.x as f32, h.y as f32, h.z as f32)
                    .friction(s.friction as f32)
                    .restitution(s.restitution as f32),
            );
        }
        let mut handles = Vec::with_capacity(objects.len());
        for (o, p) in objects.iter().zip(world_from_objs) {
            let shape = self
                .hulls
                .get(&o.model_index)
                .ok_or_else(|| format!("no collider for object {}", o.name))?;
            let q = DQuat::from_mat3(&p.rotation).normalize();
            let t = p.translation_m;
            let pose = rapier3d::math::Pose::from_parts(
                Vector::new(t.x as f32, t.y as f32, t.z as f32),
                Rotation::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32),
            );
            let (h, _) = world.insert(
                RigidBodyBuilder::dynamic().pose(pose).ccd_enabled(true),
                ColliderBuilder::new(shape.clone())
                    .density(500.0)
                    .friction(s.friction as f32)
                    .restitution(s.restitution as f32),
            );
            handles.push(h);
        }
        let mut steps = 0;
        let settled = |world: &PhysicsWorld| {
            handles.iter().all(|h| {
                let b = &world.bodies[*h];
                b.is_sleeping()
                    || (b.linvel().length() < s.settle_speed_m_s as f32
                        && b.angvel().length() < 0.05)
            })
        };
        // A few steps first: everything starts at rest in the air.
        while steps < s.max_steps {
            world.step();
            steps += 1;
            if steps > 5 && settled(&world) {
                break;
            }
        }
        if !settled(&world) {
            return Err(format!("objects still moving after {steps} steps"));
        }
        let mut out = Vec::with_capacity(handles.len());
        for (h, o) in handles.iter().zip(objects) {
            let b = &world.bodies[*h];
            let t = b.translation();
            let r = b.rotation();
            if !(t.x.is_finite() && t.y.is_finite() && t.z.is_finite()) {
                return Err(format!("object {} has a non-finite pose", o.name));
            }
            if t.z < -0.01 || t.x.abs() > GROUND_HALF_M || t.y.abs() > GROUND_HALF_M {
                return Err(format!("object {} left the plane", o.name));
            }
            let q = DQuat::from_xyzw(r.x as f64, r.y as f64, r.z as f64, r.w as f64).normalize();
            out.push(Pose::new(
                DMat3::from_quat(q),
                DVec3::new(t.x as f64, t.y as f64, t.z as f64),
            ));
        }
        Ok((out, steps))
    }
}

impl Settle for PhysicsSettler {
    fn settle(
        &self,
        objects: &[SceneObject],
        world_from_objs: &[Pose],
    ) -> Result<Vec<Pose>, String> {
        self.simulate(objects, world_from_objs).map(|(p, _)| p)
    }
}

#[cfg(test)]
mod tests;
