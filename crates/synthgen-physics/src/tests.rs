#![allow(clippy::unwrap_used, clippy::expect_used)]

use std::sync::Arc;

use synthgen_core::glam::Vec3;
use synthgen_core::scene::{Orientation, PlacementMode};
use synthgen_core::{Model, SceneSampler, SceneSpec};

use super::*;

fn objects() -> Vec<SceneObject> {
    let models = [
        Model::cuboid("box", Vec3::new(0.1, 0.06, 0.04)),
        Model::cuboid("tall", Vec3::new(0.04, 0.05, 0.16)),
        Model::cuboid("cube", Vec3::splat(0.05)),
    ];
    (0..5)
        .map(|i| {
            let m = &models[i % 3];
            SceneObject {
                model_index: i % 3,
                obj_id: i as u32 + 1,
                name: m.name.clone(),
                support_points_m: m.support_points(64),
                up: Default::default(),
                tilt_deg: 0.0,
                rest_poses: Arc::from([]),
            }
        })
        .collect()
}

fn sampler(orientation: Orientation, seed: u64) -> (SceneSampler, Arc<PhysicsSettler>) {
    let mut spec = SceneSpec::default();
    spec.placement.mode = PlacementMode::Physics;
    spec.placement.orientation = orientation;
    let objs = objects();
    let settler = Arc::new(PhysicsSettler::new(&objs, spec.placement.physics.clone()).unwrap());
    let s = SceneSampler::new(spec, objs, seed)
        .unwrap()
        .with_settle(settler.clone());
    (s, settler)
}

fn world_poses(s: &SceneSampler, frame: u64) -> Vec<Pose> {
    let f = s.sample(frame).unwrap();
    f.objects
        .iter()
        .map(|o| f.world_from_cam.compose(&o.cam_from_obj))
        .collect()
}

fn iso(p: &Pose) -> rapier3d::math::Pose {
    let q = DQuat::from_mat3(&p.rotation).normalize();
    let t = p.translation_m;
    rapier3d::math::Pose::from_parts(
        Vector::new(t.x as f32, t.y as f32, t.z as f32),
        Rotation::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32),
    )
}

#[test]
fn settled_objects_rest_on_the_plane_without_interpenetrating() {
    for orientation in [Orientation::Random, Orientation::Upright] {
        let (s, settler) = sampler(orientation, 3);
        let objs = objects();
        let mut touching = 0;
        for frame in 0..10 {
            let poses = world_poses(&s, frame);
            for (o, p) in objs.iter().zip(&poses) {
                let zmin = o
                    .support_points_m
                    .iter()
                    .map(|v| p.transform_point(v.as_dvec3()).z)
                    .fold(f64::INFINITY, f64::min);
                // Nothing sinks into the plane; objects are on it unless they lean on
                // another object (then they are higher, never hovering alone: checked below).
                assert!(
                    zmin > -0.002,
                    "{orientation:?} frame {frame}: {} sinks to {zmin}",
                    o.name
                );
                if zmin < 0.002 {
                    touching += 1;
                } else {
                    // Resting on something else: it must touch another object.
                    let near = objs.iter().zip(&poses).any(|(o2, p2)| {
                        !std::ptr::eq(o, o2)
                            && rapier3d::parry::query::distance(
                                &iso(p),
                                settler.hull(o.model_index).unwrap().as_ref(),
                                &iso(p2),
                                settler.hull(o2.model_index).unwrap().as_ref(),
                            )
                            .unwrap()
                            .distance
                                < 0.002
                    });
                    assert!(
                        near,
                        "{orientation:?} frame {frame}: {} hovers at {zmin}",
                        o.name
                    );
                }
            }
            for i in 0..objs.len() {
                for j in i + 1..objs.len() {
                    let c = rapier3d::parry::query::contact(
                        &iso(&poses[i]),
                        settler.hull(objs[i].model_index).unwrap().as_ref(),
                        &iso(&poses[j]),
                        settler.hull(objs[j].model_index).unwrap().as_ref(),
                        0.0,
                    )
                    .unwrap();
                    if let Some(c) = c {
                        assert!(
                            c.dist > -0.002,
                            "{orientation:?} frame {frame}: objects {i} and {j} penetrate by {} m",
                            -c.dist
                        );
                    }
                }
            }
        }
        assert!(
            touching >= 45,
            "{orientation:?}: only {touching} of 50 on the plane"
        );
        assert!(
            s.physics_fallbacks().is_empty(),
            "{:?}",
            s.physics_fallbacks()
        );
    }
}

#[test]
fn same_seed_same_poses_and_tumbled_objects_fall_flat() {
    let (a, _) = sampler(Orientation::Random, 9);
    let (b, _) = sampler(Orientation::Random, 9);
    for f in 0..3 {
        assert_eq!(a.sample(f).unwrap(), b.sample(f).unwrap());
    }
    // With random orientations the footprint sampler rests each box on its lowest vertex;
    // after settling, a box lies on a face (one of its axes vertical) unless it leans on
    // another box.
    let mut flat = 0;
    for f in 0..6 {
        for p in world_poses(&a, f) {
            let up = [p.rotation.x_axis, p.rotation.y_axis, p.rotation.z_axis]
                .iter()
                .map(|a| a.z.abs())
                .fold(0.0, f64::max);
            flat += usize::from(up > 0.99);
        }
    }
    assert!(flat >= 27, "only {flat} of 30 boxes lie on a face");
}

#[test]
fn a_scene_that_cannot_settle_falls_back_to_the_footprint_poses() {
    let mut spec = SceneSpec::default();
    spec.placement.mode = PlacementMode::Physics;
    spec.placement.physics.max_steps = 2;
    let objs = objects();
    let settler = Arc::new(PhysicsSettler::new(&objs, spec.placement.physics.clone()).unwrap());
    let mut plain = spec.clone();
    plain.placement.mode = PlacementMode::Sample;
    let s = SceneSampler::new(spec, objs.clone(), 1)
        .unwrap()
        .with_settle(settler);
    let p = SceneSampler::new(plain, objs, 1).unwrap();
    assert_eq!(s.sample(4).unwrap(), p.sample(4).unwrap());
    let fb = s.physics_fallbacks();
    assert_eq!(fb.len(), 1);
    assert_eq!(fb[0].0, 4);
    assert!(fb[0].1.contains("still moving"), "{}", fb[0].1);
}

#[test]
fn physics_mode_without_an_engine_is_an_error() {
    let mut spec = SceneSpec::default();
    spec.placement.mode = PlacementMode::Physics;
    let e = SceneSampler::new(spec, objects(), 1)
        .unwrap()
        .sample(0)
        .unwrap_err();
    assert!(e.to_string().contains("physics"), "{e}");
}

#[test]
fn objects_settle_inside_the_bin_and_above_its_floor() {
    let mut spec = SceneSpec::default();
    spec.placement.mode = PlacementMode::Physics;
    spec.placement.orientation = Orientation::Random;
    spec.placement.area_m = [0.3, 0.24];
    spec.placement.min_gap_m = 0.0;
    spec.placement.max_tries = 400;
    spec.placement.physics.drop_height_m = [0.05, 0.15];
    spec.bin.enabled = true;
    spec.bin.size_m = [0.45, 0.38];
    let objs = objects();
    let walls = spec.bin.walls();
    let settler = Arc::new(
        PhysicsSettler::new(&objs, spec.placement.physics.clone())
            .unwrap()
            .with_bin(&walls),
    );
    let [bx, by] = spec.bin.size_m;
    let s = SceneSampler::new(spec, objs.clone(), 11)
        .unwrap()
        .with_settle(settler)
        .with_bin_models(3);
    let tol = 0.002;
    let mut near_wall = 0;
    for f in 0..10 {
        let frame = s.sample(f).unwrap();
        // The four walls are unannotated instances of the two wall models.
        assert_eq!(frame.distractors.len(), 4);
        assert!(frame
            .distractors
            .iter()
            .all(|d| d.obj_id == 0 && d.model_index >= 3));
        for (o, w) in objs.iter().zip(world_poses(&s, f)) {
            let pts: Vec<DVec3> = o
                .support_points_m
                .iter()
                .map(|p| w.transform_point(p.as_dvec3()))
                .collect();
            for p in &pts {
                assert!(
                    p.z > -tol,
                    "frame {f}: {} below the floor ({} m)",
                    o.name,
                    p.z
                );
                assert!(
                    p.x.abs() < bx / 2.0 + tol && p.y.abs() < by / 2.0 + tol,
                    "frame {f}: {} outside the bin at ({}, {})",
                    o.name,
                    p.x,
                    p.y
                );
            }
            let reach = pts
                .iter()
                .map(|p| (bx / 2.0 - p.x.abs()).min(by / 2.0 - p.y.abs()))
                .fold(f64::INFINITY, f64::min);
            near_wall += usize::from(reach < 0.01);
        }
    }
    assert!(
        s.physics_fallbacks().is_empty(),
        "{:?}",
        s.physics_fallbacks()
    );
    // The walls matter: some objects end against them.
    assert!(near_wall > 0, "no object came within 1 cm of a wall");
}
