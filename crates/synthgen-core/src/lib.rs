//! Core types of synthgen: poses, cameras, meshes, scene specs, deterministic sampling and
//! the maths behind BOP annotations. No heavy dependencies.
//!
//! ```
//! use synthgen_core::{Intrinsics, Pose};
//! use glam::DVec3;
//! let k = Intrinsics::LINEMOD;
//! let cam_from_obj = Pose::new(glam::DMat3::IDENTITY, DVec3::new(0.0, 0.0, 1.0));
//! let (u, v) = k.project(cam_from_obj.transform_point(DVec3::ZERO)).unwrap();
//! assert!((u - k.cx).abs() < 1e-9 && (v - k.cy).abs() < 1e-9);
//! ```

pub mod annotate;
pub mod atomic;
mod bin;
pub mod bin_spec;
pub mod camera;
pub mod color;
pub mod depth_features;
pub mod distractor;
mod distractor_spec;
mod error;
mod frame_scene;
pub mod jacobi;
pub mod mesh;
pub mod paths;
pub mod pnp;
pub mod pose;
pub mod pose_render;
pub mod progress;
mod range;
pub mod rest;
pub mod rng;
pub mod sample;
pub mod scene;
mod sensor_spec;
pub mod symmetry;
mod user_error;
pub mod view;
mod walls;
mod walls_spec;

pub use annotate::{annotate, AloneDepth, GtInfo, ObjectAnnotation, RenderedFrame};
pub use camera::Intrinsics;
pub use error::Error;
pub use glam;
pub use mesh::{Aabb, Material, Model, Primitive, Texture};
pub use pose::Pose;
pub use pose_render::{DepthRenderer, DepthWindowMm, PoseRenderer};
pub use progress::{NoProgress, Progress};
pub use sample::{FrameScene, ObjectInstance, SceneObject, SceneSampler, Settle};
pub use scene::SceneSpec;
pub use symmetry::Symmetries;
pub use user_error::UserError;
pub use view::{ViewCheck, Visibility};

/// The synthgen version, written into every manifest.
pub const VERSION: &str = env!("CARGO_PKG_VERSION");
