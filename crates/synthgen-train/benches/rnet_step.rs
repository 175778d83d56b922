//! One RNet training step (`--model rnet`: point stem and colour CNN, fusion, per-pixel
//! quaternion and confidence, the confidence-weighted quaternion loss, backward, AdamW) on 32
//! instances of 500 points with 48-pixel crops and width 128, the defaults of
//! `synthgen train --model rnet`, with mimalloc as the allocator, as the `synthgen` binary has
//! it. The peer is `benches/peers/rnet_torch.py`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod rgbd_common;

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use criterion::{criterion_group, criterion_main, Criterion};
use synthgen_train::models::ModelKind;

fn rnet(c: &mut Criterion) {
    rgbd_common::step(c, ModelKind::Rnet, "rnet_step_32x500_c48_w128");
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = rnet
}
criterion_main!(benches);
