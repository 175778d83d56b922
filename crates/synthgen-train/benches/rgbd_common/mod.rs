//! The RGB-D models' (RNet, Full) step benchmark body, shared by `rnet_step` and `full_step`:
//! a batch of synthetic instances at `synthgen train --model rnet|full`'s defaults (32
//! instances of 500 points, 48-pixel crops, width 128, 100 loss points per object) and one
//! training step through the public API (`PoseModel::run_training`, AdamW with candle's
//! defaults, the loss read back), as the peers `benches/peers/{rnet,full}_torch.py` time it.

use std::collections::BTreeMap;

use candle_core::Device;
use candle_nn::{Optimizer, ParamsAdamW};
use criterion::Criterion;
use rand::{Rng, SeedableRng};
use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::Pose;
use synthgen_nn::optim::FusedAdamW;
use synthgen_train::data::Instance;
use synthgen_train::metrics::EvalObject;
use synthgen_train::models::rnet::DEFAULT_CROP;
use synthgen_train::models::tnet::DEFAULT_SCALE;
use synthgen_train::models::ModelKind;
use synthgen_train::pose_model::{PoseModel, TrainObject};

pub const BATCH: usize = 32;
pub const POINTS: usize = 500;
pub const WIDTH: usize = 128;
pub const LOSS_POINTS: usize = 100;
/// Objects in the batch (each instance one of them, in turn); none has a symmetry.
const OBJECTS: u32 = 4;

/// A point drawn uniformly in a 10 cm cube around the object's origin (metres).
fn model_point(rng: &mut rand_chacha::ChaCha8Rng) -> DVec3 {
    DVec3::new(
        rng.gen_range(-0.05..0.05),
        rng.gen_range(-0.05..0.05),
        rng.gen_range(-0.05..0.05),
    )
}

/// `BATCH` instances of `OBJECTS` asymmetric point objects in random poses 0.6–1.0 m away:
/// `POINTS` posed model points each, their positions in a `DEFAULT_CROP` crop 20 cm across
/// centred on the object, random crop colours; and the objects (`LOSS_POINTS` loss points,
/// the identity as their only symmetry).
pub fn setup() -> (Vec<Instance>, BTreeMap<u32, TrainObject>) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let models: Vec<Vec<DVec3>> = (0..OBJECTS)
        .map(|_| (0..4 * POINTS).map(|_| model_point(&mut rng)).collect())
        .collect();
    let crop = DEFAULT_CROP;
    let side = f64::from(crop);
    let instances = (0..BATCH)
        .map(|i| {
            let obj = i as u32 % OBJECTS;
            let axis = DVec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
            )
            .normalize_or(DVec3::Z);
            let t = DVec3::new(
                rng.gen_range(-0.1..0.1),
                rng.gen_range(-0.1..0.1),
                rng.gen_range(0.6..1.0),
            );
            let pose = Pose::new(
                DMat3::from_axis_angle(axis, rng.gen_range(0.0..std::f64::consts::PI)),
                t,
            );
            let model = &models[obj as usize];
            let mut points_m = Vec::with_capacity(POINTS);
            let mut crop_xy = Vec::with_capacity(POINTS);
            for _ in 0..POINTS {
                let c = pose.transform_point(model[rng.gen_range(0..model.len())]);
                points_m.push(c.as_vec3().to_array());
                let px = (((c.x - t.x) / 0.2 + 0.5) * side).clamp(0.0, side - 1.0);
                let py = (((c.y - t.y) / 0.2 + 0.5) * side).clamp(0.0, side - 1.0);
                crop_xy.push([px as f32, py as f32]);
            }
            Instance {
                scene_id: 0,
                im_id: i as u32,
                gt_id: 0,
                obj_id: obj + 1,
                points_m,
                crop_xy,
                crop_rgb: (0..crop * crop * 3).map(|_| rng.gen()).collect(),
                region: None,
                pose,
            }
        })
        .collect();
    let objects = models
        .iter()
        .enumerate()
        .map(|(k, model)| {
            let loss_points_m = model[..LOSS_POINTS].to_vec();
            (
                k as u32 + 1,
                TrainObject {
                    loss_points_m: loss_points_m.clone(),
                    symmetries: vec![Pose::IDENTITY],
                    eval: EvalObject {
                        points_m: loss_points_m,
                        diameter_m: 0.17,
                        symmetric: false,
                    },
                },
            )
        })
        .collect();
    (instances, objects)
}

/// One training step of `kind` (RNet or Full), timed as `name`.
pub fn step(c: &mut Criterion, kind: ModelKind, name: &str) {
    let dev = Device::Cpu;
    let model = PoseModel::new(kind, WIDTH, DEFAULT_SCALE, DEFAULT_CROP, 0, &dev).unwrap();
    let vars = model.varmap.all_vars();
    // To check against the peer's "params".
    let params: usize = vars.iter().map(|v| v.elem_count()).sum();
    eprintln!("{name}: {params} parameters");
    let mut opt = FusedAdamW::new(vars, ParamsAdamW::default()).unwrap();
    let (instances, objects) = setup();
    let batch: Vec<&Instance> = instances.iter().collect();
    let mut seed = 0u64;
    c.bench_function(name, |b| {
        b.iter(|| {
            seed += 1;
            let loss = model.run_training(&batch, Some(&objects), seed).unwrap();
            opt.backward_step(&loss).unwrap();
            loss.to_scalar::<f32>().unwrap()
        })
    });
    // The network's step alone on a batch made ready before (what the peer times, and what
    // the trainer runs while it prepares the next batch: `train::pipelined`).
    let prepared = model.prepare(&batch, Some(&objects), Some(1)).unwrap();
    c.bench_function(&name.replace("_step_", "_net_step_"), |b| {
        b.iter(|| {
            let loss = model.loss_of(&prepared).unwrap();
            opt.backward_step(&loss).unwrap();
            loss.to_scalar::<f32>().unwrap()
        })
    });
}
