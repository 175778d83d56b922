//! Operations on whole datasets: what a user does with datasets once they exist.
//!
//! - [`mix`]: a training set of N real and M synthetic frames (`synthgen mix`), with a
//!   held-out real test split of frames or whole scenes, provenance and resumable output.
//! - [`stats`]: per-object statistics of a dataset (visibility, distances, rotations) and
//!   their plots, to put a synthetic set beside a real one (`synthgen stats`).
//! - [`preview`]: contact sheets of frames with their masks and boxes (`synthgen preview`).
//!
//! Every operation reads its frames through `synthgen_formats::source::FrameSource`.

pub mod mix;
pub mod preview;
pub mod stats;
