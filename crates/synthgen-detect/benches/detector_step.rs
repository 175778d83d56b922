//! One training step of the box detector (forward, focal loss + L1, backward, AdamW with the
//! detector's lr 2e-3 and weight decay 1e-4, the loss read back) at `synthgen detector
//! train`'s defaults: 16 frames of 160x120, the 8 LM-O classes, from input and target tensors
//! built beforehand (the training loop also resamples, augments and builds the targets each
//! step). mimalloc is the allocator, as the `synthgen` binary has it. The peer is
//! `benches/peers/detector_torch.py`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use candle_core::{Device, Tensor};
use candle_nn::{Optimizer, ParamsAdamW, VarMap};
use criterion::{criterion_group, criterion_main, Criterion};
use rand::{Rng, SeedableRng};
use synthgen_detect::detector::DetectorConfig;
use synthgen_detect::net::{detector_loss, DetectorNet, DET_STRIDE};
use synthgen_nn::optim::FusedAdamW;

/// LM-O's objects, one heatmap each.
const CLASSES: [u32; 8] = [1, 5, 6, 8, 9, 10, 11, 12];

/// Targets of `boxes` (per frame: class index and `[x0, y0, x1, y1]` in input pixels) on the
/// (h/4, w/4) map: heatmaps (B, h, w, C), offset + log size (B, h, w, C, 4), centre cells
/// (B, h, w, C). The same as `synthgen_detect::detector::targets` (private there), which
/// builds them from its private `Sample`s.
fn targets(boxes: &[Vec<(usize, [f64; 4])>], input: [u32; 2], nc: usize) -> [Tensor; 3] {
    let dev = Device::Cpu;
    let (mw, mh) = (
        (input[0] / DET_STRIDE) as usize,
        (input[1] / DET_STRIDE) as usize,
    );
    let b = boxes.len();
    let mut heat = vec![0f32; b * mh * mw * nc];
    let mut reg = vec![0f32; b * mh * mw * nc * 4];
    let mut centres = vec![0f32; b * mh * mw * nc];
    let s = f64::from(DET_STRIDE);
    for (bi, frame) in boxes.iter().enumerate() {
        for &(c, [x0, y0, x1, y1]) in frame {
            let (cx, cy) = ((x0 + x1) / 2.0 / s, (y0 + y1) / 2.0 / s);
            let (bw, bh) = ((x1 - x0) / s, (y1 - y0) / s);
            let (ix, iy) = (
                (cx.floor() as usize).min(mw - 1),
                (cy.floor() as usize).min(mh - 1),
            );
            let (sgx, sgy) = ((0.09 * bw).max(0.5), (0.09 * bh).max(0.5));
            let (rx, ry) = ((3.0 * sgx).ceil() as i64, (3.0 * sgy).ceil() as i64);
            for y in (iy as i64 - ry).max(0)..=(iy as i64 + ry).min(mh as i64 - 1) {
                for x in (ix as i64 - rx).max(0)..=(ix as i64 + rx).min(mw as i64 - 1) {
                    let (dx, dy) = (x as f64 - ix as f64, y as f64 - iy as f64);
                    let g = (-(dx * dx) / (2.0 * sgx * sgx) - (dy * dy) / (2.0 * sgy * sgy)).exp();
                    let at = ((bi * mh + y as usize) * mw + x as usize) * nc + c;
                    heat[at] = heat[at].max(g as f32);
                }
            }
            let at = ((bi * mh + iy) * mw + ix) * nc + c;
            heat[at] = 1.0;
            centres[at] = 1.0;
            reg[at * 4..at * 4 + 4].copy_from_slice(&[
                (cx - ix as f64) as f32,
                (cy - iy as f64) as f32,
                bw.max(1e-3).ln() as f32,
                bh.max(1e-3).ln() as f32,
            ]);
        }
    }
    [
        Tensor::from_vec(heat, (b, mh, mw, nc), &dev).unwrap(),
        Tensor::from_vec(reg, (b, mh, mw, nc, 4), &dev).unwrap(),
        Tensor::from_vec(centres, (b, mh, mw, nc), &dev).unwrap(),
    ]
}

fn detector(c: &mut Criterion) {
    // Boxes only (the network benches/peers has in PyTorch), then with the mask branch.
    detector_step(c, false);
    detector_step(c, true);
}

fn detector_step(c: &mut Criterion, masks: bool) {
    let dev = Device::Cpu;
    let cfg = DetectorConfig::new("unused".into(), "train".into(), CLASSES.to_vec());
    let [iw, ih] = cfg.input;
    let nc = cfg.classes.len();
    let varmap = VarMap::new();
    let vb = synthgen_nn::init::seeded_var_builder(&varmap, cfg.seed, &dev);
    let net = DetectorNet::new(nc, masks, vb).unwrap();
    let vars = varmap.all_vars();
    // To check against the peer's "params".
    let params: usize = vars.iter().map(|v| v.elem_count()).sum();
    eprintln!("detector: {params} parameters");
    let mut opt = FusedAdamW::new(
        vars,
        ParamsAdamW {
            lr: cfg.lr,
            weight_decay: cfg.weight_decay,
            ..Default::default()
        },
    )
    .unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    // Colours normalized as the detector's input: (v/255 − 0.5) / 0.25, NHWC.
    let x: Vec<f32> = (0..cfg.batch * (iw * ih * 3) as usize)
        .map(|_| (f32::from(rng.gen::<u8>()) / 255.0 - 0.5) / 0.25)
        .collect();
    let x = Tensor::from_vec(x, (cfg.batch, ih as usize, iw as usize, 3), &dev).unwrap();
    // Every class once per frame, 10 to 50 px (LM-O's objects in a 640x480 frame at 1/4).
    let boxes: Vec<Vec<(usize, [f64; 4])>> = (0..cfg.batch)
        .map(|_| {
            (0..nc)
                .map(|k| {
                    let (w, h) = (rng.gen_range(10.0..50.0), rng.gen_range(10.0..50.0));
                    let x0 = rng.gen_range(0.0..f64::from(iw) - w);
                    let y0 = rng.gen_range(0.0..f64::from(ih) - h);
                    (k, [x0, y0, x0 + w, y0 + h])
                })
                .collect()
        })
        .collect();
    let [heat, reg, centres] = targets(&boxes, cfg.input, nc);
    // The boxes filled as masks, at half the input's size.
    let mask_targets = masks.then(|| {
        let (ow, oh) = ((iw / 2) as usize, (ih / 2) as usize);
        let mut t = vec![0f32; cfg.batch * oh * ow * nc];
        for (bi, list) in boxes.iter().enumerate() {
            for &(k, [x0, y0, x1, y1]) in list {
                for y in (y0 / 2.0) as usize..((y1 / 2.0) as usize).min(oh) {
                    for x in (x0 / 2.0) as usize..((x1 / 2.0) as usize).min(ow) {
                        t[((bi * oh + y) * ow + x) * nc + k] = 1.0;
                    }
                }
            }
        }
        Tensor::from_vec(t, (cfg.batch, oh, ow, nc), &dev).unwrap()
    });
    let name = if masks {
        "detector_step_masks_16x160x120_c8"
    } else {
        "detector_step_16x160x120_c8"
    };
    c.bench_function(name, |b| {
        b.iter(|| {
            let out = net.forward(&x).unwrap();
            let loss = detector_loss(&out, &heat, &reg, &centres, mask_targets.as_ref()).unwrap();
            let value = loss.to_scalar::<f32>().unwrap();
            opt.backward_step(&loss).unwrap();
            value
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = detector
}
criterion_main!(benches);
