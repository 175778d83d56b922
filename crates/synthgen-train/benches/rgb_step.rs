//! The RGB model (seed 001): one training step (jittered crops of 32 boxes, forward, smooth L1
//! and rotation point loss, backward, AdamW) and one prediction per crop (batches of 64), at
//! the default sizes (64-pixel crops, width 256, 5 classes, 100 loss points per object), with
//! mimalloc as the allocator, as the `synthgen` binary has it.
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use std::collections::BTreeMap;

use candle_core::Device;
use candle_nn::{Optimizer, ParamsAdamW};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use rand::{Rng, SeedableRng};
use synthgen_core::glam::{DMat3, DVec3};
use synthgen_core::Pose;
use synthgen_nn::optim::FusedAdamW;
use synthgen_train::data::Instance;
use synthgen_train::metrics::EvalObject;
use synthgen_train::models::rgb::{Pinhole, Translation};
use synthgen_train::pose_model::{PoseModel, TrainObject};
use synthgen_train::rgb_input::BoxRegion;

fn setup(n: usize) -> (Vec<Instance>, BTreeMap<u32, TrainObject>) {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let (w, h) = (640u32, 480u32);
    let image: Vec<u8> = (0..w * h * 3).map(|_| rng.gen()).collect();
    let camera = Pinhole {
        fx: 572.4,
        fy: 573.6,
        cx: 325.3,
        cy: 242.0,
    };
    let classes = [1u32, 5, 6, 8, 9];
    let instances = (0..n)
        .map(|i| {
            let bw = rng.gen_range(40.0..160.0);
            let bbox = [
                rng.gen_range(0.0..400.0),
                rng.gen_range(0.0..300.0),
                bw,
                bw * 0.8,
            ];
            Instance {
                scene_id: 0,
                im_id: i as u32,
                gt_id: 0,
                obj_id: classes[i % classes.len()],
                points_m: vec![],
                crop_xy: vec![],
                crop_rgb: vec![],
                region: Some(BoxRegion::from_image(&image, w, h, bbox, 64, camera)),
                pose: Pose::new(
                    DMat3::from_rotation_x(rng.gen_range(-1.0..1.0)),
                    DVec3::new(0.05, -0.02, rng.gen_range(0.5..1.1)),
                ),
            }
        })
        .collect();
    let points: Vec<DVec3> = (0..100)
        .map(|_| {
            DVec3::new(
                rng.gen_range(-0.05..0.05),
                rng.gen_range(-0.05..0.05),
                rng.gen_range(-0.05..0.05),
            )
        })
        .collect();
    let objects = classes
        .iter()
        .map(|&id| {
            (
                id,
                TrainObject {
                    loss_points_m: points.clone(),
                    symmetries: vec![Pose::IDENTITY],
                    eval: EvalObject {
                        points_m: points.clone(),
                        diameter_m: 0.15,
                        symmetric: false,
                    },
                },
            )
        })
        .collect();
    (instances, objects)
}

fn rgb(c: &mut Criterion) {
    let dev = Device::Cpu;
    let model = PoseModel::rgb(Translation::CentreTz, &[1, 5, 6, 8, 9], 256, 64, 0, &dev).unwrap();
    let mut opt = FusedAdamW::new(model.varmap.all_vars(), ParamsAdamW::default()).unwrap();
    let (instances, objects) = setup(64);
    let batch: Vec<&Instance> = instances.iter().take(32).collect();
    let mut step = 0u64;
    c.bench_function("rgb_step_32x64_w256", |b| {
        b.iter(|| {
            step += 1;
            let loss = model.run_training(&batch, Some(&objects), step).unwrap();
            opt.backward_step(&loss).unwrap();
            loss.to_scalar::<f32>().unwrap()
        })
    });
    // The network's step alone on a batch made ready before (what the peer times, and what
    // the trainer runs while it prepares the next batch: `train::pipelined`).
    let prepared = model.prepare(&batch, Some(&objects), Some(1)).unwrap();
    c.bench_function("rgb_net_step_32x64_w256", |b| {
        b.iter(|| {
            let loss = model.loss_of(&prepared).unwrap();
            opt.backward_step(&loss).unwrap();
            loss.to_scalar::<f32>().unwrap()
        })
    });
    let all: Vec<&Instance> = instances.iter().collect();
    let mut g = c.benchmark_group("rgb_predict");
    g.throughput(Throughput::Elements(all.len() as u64));
    g.bench_function("rgb_predict_64x64_w256", |b| {
        b.iter(|| model.predict(&all, Some(&objects), 64).unwrap())
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = rgb
}
criterion_main!(benches);
