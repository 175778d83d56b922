//! Pose models and their evaluation for synthgen: BOP data loading, TNet, RNet, Full and the RGB
//! model (candle), the training loop, and the pose metrics (ADD, ADD-S, 5cm5°, BOP's AR) with
//! BOP results CSV scoring.
//!
//! ```no_run
//! use std::path::Path;
//! use synthgen_core::NoProgress;
//! use synthgen_train::data::{load_instances, DataOptions};
//!
//! let set = load_instances(Path::new("out/drill"), &DataOptions::default(), &NoProgress)?;
//! println!("{} instances, {} skipped (too few pixels)", set.instances.len(), set.skipped_few_pixels);
//! # Ok::<(), synthgen_train::Error>(())
//! ```

pub mod baseline;
pub mod bop;
pub mod data;
pub mod dataset_objects;
mod error;
pub mod eval;
pub mod losses;
pub mod metrics;
pub mod models;
pub mod plot;
pub mod pose_model;
mod quat;
pub mod region;
pub mod results;
pub mod rgb_input;
pub mod stability;
pub mod train;

pub use error::{Error, Result};
