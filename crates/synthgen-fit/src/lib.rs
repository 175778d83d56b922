//! Fitting synthgen to real captures: what the real frames of a dataset say about the sensor
//! and the scenes, turned into files `synthgen render` reads.
//!
//! - [`sensor`]: the depth sensor model (`synthgen sensor fit`): holes, noise and edge
//!   behaviour measured on real depth images against the depth their GT poses render to, the
//!   fit of a sensor TOML, the comparison of real and rendered depth, and the plots.
//! - [`scene_fit`]: a scene spec from real annotated frames (`synthgen scene fit`): table
//!   plane, camera distances and elevations, object rest poses, counts and occlusion.
//! - [`rgb_compare`]: how close rendered colour images are to the real ones they replay
//!   (`synthgen sensor compare-rgb`).
//!
//! Every fit reads its frames through `synthgen_formats::source::FrameSource`, so it works on
//! BOP, Linemod and YCB-Video folders alike.

pub mod appearance;
pub mod edge_refine;
mod raster;
pub mod region;
pub mod rgb_compare;
pub mod scene_fit;
pub mod sensor;
