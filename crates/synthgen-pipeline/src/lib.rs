//! The synthgen render pipeline as a library: models, sampler, physics, renderer and sensor
//! assembled once, then frames written to a dataset folder or handed over in memory.
//!
//! ```no_run
//! use synthgen_assets::Units;
//! use synthgen_core::{NoProgress, SceneSpec};
//! use synthgen_pipeline::{Format, ObjectSource, RenderJob, SinkOptions, WriteOptions};
//!
//! # fn main() -> Result<(), synthgen_pipeline::Error> {
//! let job = RenderJob::new(SceneSpec::default())
//!     .objects(&[ObjectSource::new("driller.ply", Units::Mm)])
//!     .frames(0..100)
//!     .seed(7)
//!     .build(&NoProgress)?;
//! for frame in job.frames() {
//!     let frame = frame?;
//!     println!("frame {}: {} objects", frame.index, frame.objects.len());
//! }
//! let report = job.write(&WriteOptions::new("out", SinkOptions::new(Format::Bop)), &NoProgress)?;
//! println!("wrote {}", report.description);
//! # Ok(())
//! # }
//! ```
//!
//! Frame `i` depends only on the spec, the objects, the seed and `i`: not on the thread
//! count, nor on which frames were rendered before.

mod backend;
mod error;
mod extras;
mod frame;
mod job;
mod objects;
mod resume;
mod sink;
mod write;

pub use backend::{renderer_for, Backend, BlenderSettings};
pub use error::{Error, Result};
pub use frame::{Frame, FrameObject};
pub use job::{render_annotated, Frames, PreparedJob, RenderJob};
pub use objects::{ycbv_class_index, ObjectSource};
pub use resume::RUN_PLAN;
pub use sink::{Format, ImageFormat, Layout, Record, Sink, SinkOptions, SinkSummary, YcbvSink};
pub use write::{error_chain, WriteOptions, WriteReport};

#[cfg(test)]
mod test_support {
    use std::path::PathBuf;

    use synthgen_assets::Units;
    use synthgen_core::scene::DepthModel;
    use synthgen_core::{NoProgress, SceneSpec};

    use crate::{ObjectSource, PreparedJob, RenderJob};

    /// Two drillers at 160x120 (they occlude each other now and then) with ToF depth noise,
    /// so masks, visibility and the sensor model all matter.
    pub fn job(frames: std::ops::Range<u64>, threads: usize) -> PreparedJob {
        let mesh =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../datasets/meshes/driller.ply");
        let mut spec = SceneSpec::default();
        let k = spec.camera.intrinsics().unwrap();
        spec.camera.width = Some(k.width / 4);
        spec.camera.height = Some(k.height / 4);
        spec.camera.fx = Some(k.fx / 4.0);
        spec.camera.fy = Some(k.fy / 4.0);
        spec.camera.cx = Some(k.cx / 4.0);
        spec.camera.cy = Some(k.cy / 4.0);
        spec.sensor.depth = DepthModel::Tof;
        spec.validate().unwrap();
        RenderJob::new(spec)
            .objects(&[ObjectSource {
                count: 2,
                ..ObjectSource::new(mesh, Units::Mm)
            }])
            .frames(frames)
            .seed(11)
            .threads(threads)
            .build(&NoProgress)
            .unwrap()
    }
}
