//! One Full training step (`--model full`: TNet's offsets and RNet's rotation branch on the
//! shared point features, the confidence-weighted per-pixel ADD loss with the minimum over
//! the symmetries, backward, AdamW) on 32 instances of 500 points with 48-pixel crops, width
//! 128 and 100 loss points per object (asymmetric objects), the defaults of
//! `synthgen train --model full`, with mimalloc as the allocator, as the `synthgen` binary has
//! it. The peer is `benches/peers/full_torch.py`.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod rgbd_common;

#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

use criterion::{criterion_group, criterion_main, Criterion};
use synthgen_train::models::ModelKind;

fn full(c: &mut Criterion) {
    rgbd_common::step(c, ModelKind::Full, "full_step_32x500_c48_w128");
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = full
}
criterion_main!(benches);
