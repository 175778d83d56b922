//! Integration tests of the CPU renderer, one module per area.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod background;
mod common;
mod correspondences;
mod determinism;
mod geometry;
mod golden;
mod linemod;
mod occlusion;
mod surfaces;
