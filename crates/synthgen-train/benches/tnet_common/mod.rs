//! The TNet step benchmark body, shared by `tnet_step` (system allocator) and
//! `tnet_step_mimalloc`.

use candle_core::{DType, Device};
use candle_nn::{Optimizer, ParamsAdamW, VarBuilder, VarMap};
use criterion::Criterion;
use rand::{Rng, SeedableRng};
use synthgen_nn::optim::FusedAdamW;
use synthgen_train::models::tnet::{make_batch, offset_l1_loss, TNet, DEFAULT_SCALE};

pub fn tnet_step(c: &mut Criterion) {
    let dev = Device::Cpu;
    let varmap = VarMap::new();
    let net = TNet::new(128, 0, VarBuilder::from_varmap(&varmap, DType::F32, &dev)).unwrap();
    let mut opt = FusedAdamW::new(varmap.all_vars(), ParamsAdamW::default()).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let clouds: Vec<Vec<[f32; 3]>> = (0..32)
        .map(|_| {
            (0..500)
                .map(|_| {
                    [
                        rng.gen_range(-0.1..0.1),
                        rng.gen_range(-0.1..0.1),
                        rng.gen_range(0.6..0.9),
                    ]
                })
                .collect()
        })
        .collect();
    let centres: Vec<[f32; 3]> = (0..32).map(|_| [0.0, 0.0, 0.75]).collect();
    let refs: Vec<&[[f32; 3]]> = clouds.iter().map(Vec::as_slice).collect();
    let batch = make_batch(&refs, Some(&centres), DEFAULT_SCALE, &dev).unwrap();
    // The step's parts, to see where candle's time goes (forward; forward + loss + backward).
    c.bench_function("tnet_forward_32x500_w128", |b| {
        b.iter(|| net.forward(&batch.points, None).unwrap())
    });
    c.bench_function("tnet_forward_backward_32x500_w128", |b| {
        b.iter(|| {
            offset_l1_loss(&net.forward(&batch.points, None).unwrap(), &batch.offsets)
                .unwrap()
                .backward()
                .unwrap()
        })
    });
    c.bench_function("tnet_step_32x500_w128", |b| {
        b.iter(|| {
            let loss =
                offset_l1_loss(&net.forward(&batch.points, None).unwrap(), &batch.offsets).unwrap();
            opt.backward_step(&loss).unwrap();
            loss.to_scalar::<f32>().unwrap()
        })
    });
}
