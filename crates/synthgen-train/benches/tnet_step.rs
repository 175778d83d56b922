//! One TNet training step (forward, L1 offset loss, backward, AdamW) on 32 clouds of 500
//! points with width 128, the size the issue compares against PyTorch on the CPU.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod tnet_common;

use criterion::{criterion_group, criterion_main, Criterion};

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = tnet_common::tnet_step
}
criterion_main!(benches);
