//! The pose models: TNet (centre), RNet (rotation) and Full (both), see docs/training.md.

pub mod dense;
pub mod full;
pub mod fused;
pub mod rnet;
pub mod tnet;

use serde::{Deserialize, Serialize};

/// Which model a run trains.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// Object centre from the point cloud (PointNet offsets).
    Tnet,
    /// Rotation from colour + points (DenseFusion style), quaternion-confidence loss.
    Rnet,
    /// Both heads on shared point features, per-pixel ADD loss (min over symmetries).
    Full,
}

impl ModelKind {
    pub fn name(self) -> &'static str {
        match self {
            ModelKind::Tnet => "tnet",
            ModelKind::Rnet => "rnet",
            ModelKind::Full => "full",
        }
    }

    /// Whether the model reads RGB crops.
    pub fn needs_rgb(self) -> bool {
        self != ModelKind::Tnet
    }
}
