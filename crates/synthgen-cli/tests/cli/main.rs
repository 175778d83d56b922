//! End-to-end tests of the `synthgen` binary: one test binary, a module per area.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod annotate;
#[cfg(feature = "blender")]
mod blender;
#[cfg(not(feature = "blender"))]
#[test]
#[ignore = "needs `--features blender` (render --backend blender through bpy; docs/blender.md)"]
fn blender_backend() {}
mod bop_eval;
mod careless;
mod careless3;
mod coco;
mod common;
mod corpus;
mod detector;
mod detector_eval;
mod errors;
mod experiment;
mod help;
mod inspect;
mod linemod;
mod mix;
mod model_align;
mod outputs_apart;
mod predict;
// The README's commands run in a temporary clone whose ../shared/data links the real one.
#[cfg(unix)]
mod readme;
mod real_rotations;
mod render;
mod replay;
mod rgb;
mod rgb_refine;
mod scale;
mod scene_extras;
mod scene_fit;
mod scenes;
mod sensor;
mod sim2real;
mod stdout;
mod surfaces;
mod train;
mod train_linemod;
mod training_threads;
mod view;
mod view_browser;
mod ycbv;
