//! BOP writer and reader, end to end on tiny synthetic frames.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
mod errors;
mod format;
mod lmo;
mod python;
mod roundtrip;
