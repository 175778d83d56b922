//! End-to-end tests of the `synthgen` binary: one test binary, a module per area.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
mod errors;
mod help;
mod render;
mod train;
